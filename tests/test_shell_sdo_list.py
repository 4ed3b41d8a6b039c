"""Issue 14, ``sdo list``: the object dictionary as the drive reports it (SDO information service, CoE service 8)
and ``sdo list --catalogue``; the simulated drive answers the service from its catalogue (sim/object_info.py)."""

from __future__ import annotations

import json

import pytest

from akdctl.catalog.objects import indices, subentries
from akdctl.drive.dictionary import access_text
from akdctl.errors import EXIT_OK, EXIT_USAGE
from akdctl.sim.errors import SdoAccessError
from akdctl.sim.object_info import ARRAY, RECORD, VAR, object_info
from tests.harness import SimServer, run_akdctl


def test_the_simulator_describes_its_catalogue() -> None:
    assert object_info(0x6041).object_code == VAR and object_info(0x6041).data_type == 0x0006
    identity = object_info(0x1018)
    assert identity.object_code == ARRAY and identity.max_subindex == 4 and identity.entries[1].name == "Vendor-ID"
    assert identity.entries[1].access == 0x07  # read in every state, not writable, not mappable
    assert object_info(0x6040).entries[0].access & 0x40  # controlword: RxPDO-mappable
    with pytest.raises(SdoAccessError) as info:
        object_info(0x5FFF)
    assert info.value.code == 0x06020000
    codes = {object_info(i).object_code for i in indices()}
    assert RECORD in codes


def test_access_text() -> None:
    assert access_text(0x07) == "r-" and access_text(0x3F) == "rw" and access_text(0x07 | 0x20) == "P:r- S:r- O:rw"


def test_sdo_list_asks_the_drive(akd_inproc) -> None:
    code, out, err = akd_inproc("sdo", "list", "--json")
    assert code == EXIT_OK, err
    data = json.loads(out)
    assert data["source"] == "sim" and "service 8" in data["service"]
    objects = {o["index"]: o for o in data["objects"]}
    assert sorted(objects) == list(indices())
    status = objects[0x6041]
    assert status["name"] == "Statusword" and status["entries"] == [
        {"subindex": 0, "name": "Statusword", "type": "u16", "bits": 16, "access": "r-", "pdo": "T"}]
    catalogue = json.loads(akd_inproc("sdo", "list", "--catalogue", "--json")[1])
    assert catalogue["source"] == "catalogue"
    assert [(o["index"], o["object_code"], [(e["subindex"], e["type"], e["access"]) for e in o["entries"]])
            for o in catalogue["objects"]] == [
        (o["index"], o["object_code"], [(e["subindex"], e["type"], e["access"]) for e in o["entries"]])
        for o in data["objects"]]  # the simulated drive reports exactly its catalogue


def test_sdo_list_one_object_a_name_and_objects_only(akd_inproc) -> None:
    code, out, _ = akd_inproc("sdo", "list", "0x1018")
    assert code == EXIT_OK
    assert "Identity object" in out and "Vendor-ID" in out and "1 object(s), 5 entries" in out
    data = json.loads(akd_inproc("sdo", "list", "homing", "--objects-only", "--json")[1])
    assert data["objects"] and all("homing" in o["name"].lower() for o in data["objects"])
    assert all(o["entries"] == [] for o in data["objects"])
    assert len(subentries(0x1018)) == 5


@pytest.mark.slow
def test_sdo_list_over_the_ethercat_gateway_face() -> None:
    with SimServer("--ethercat-udp", "127.0.0.1:0", "--ecat-stations", "1001=default") as server:
        result = run_akdctl("-T", f"ecat-udp://127.0.0.1:{server.port}/1001", "sdo", "list", "0x6060")
        assert result.code == EXIT_OK, result.err
        assert "Modes of operation" in result.out and "i8" in result.out


@pytest.mark.slow
def test_sdo_list_without_the_service_names_the_catalogue() -> None:
    with SimServer("--profinet", "127.0.0.1:0") as server:  # PROFIdrive only: no object channel at all
        result = run_akdctl("-T", f"pn://127.0.0.1:{server.port}", "sdo", "list")
        assert result.code == EXIT_USAGE, result.err
        assert "--catalogue" in result.err and result.err.startswith("akdctl: error:")
