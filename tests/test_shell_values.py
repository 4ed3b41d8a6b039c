"""Issue 14, values with meaning: enumerations and bit fields in words (catalog/meanings.py, shown by
drive/values.py), ``info`` names the vendor and the model, ``status`` names the warnings."""

from __future__ import annotations

import json

import pytest

from akdctl.catalog.meanings import object_meaning, pnu_meaning
from akdctl.drive.identity import summary
from akdctl.drive.values import pnu_display, value_words
from akdctl.errors import EXIT_OK


def test_enumerations_and_bit_fields_in_words() -> None:
    assert pnu_display(930, 0, 2) == "2 (position)"
    assert pnu_display(930, 0, 7) == "7"  # no words for an unknown value: the number alone
    assert value_words(9, pnu=922) == "standard telegram 9 (MDI positioning, application class 3)"
    assert value_words(0x0100, pnu=964, element=0) == "Kollmorgen"
    assert value_words(0x0100, pnu=964, element=1) is None  # element 1 is the drive unit type
    assert value_words(501, pnu=947, element=3).startswith("F501")
    assert value_words(6, obj=(0x6061, 0)) == "homing"
    assert value_words(0x6A, obj=(0x1018, 1)) == "Kollmorgen"
    assert value_words(0, obj=(0x1001, 0)) == "no error"
    assert value_words(0x0237, obj=(0x6041, 0)) == ("ready to switch on, switched on, operation enabled, "
                                                    "voltage enabled, quick stop not active, remote")
    assert "set-point acknowledge / homing attained" in value_words(1 << 12, obj=(0x6041, 0))
    assert value_words(503, obj=(0x2000, 2)).startswith("n503")
    assert pnu_meaning(9999) is None and object_meaning(0x6041, 1) is None


def test_pnu_get_shows_words(akd_inproc) -> None:
    code, out, err = akd_inproc("pnu", "get", "930", "922")
    assert code == EXIT_OK, err
    assert "1 (velocity)" in out and "1 (standard telegram 1" in out
    code, out, _ = akd_inproc("-y", "pnu", "set", "930=2")
    code, out, _ = akd_inproc("pnu", "get", "930")
    assert "2 (position)" in out
    data = json.loads(akd_inproc("pnu", "get", "930", "964", "--json")[1])
    assert data["parameters"][0]["values"] == [2] and data["parameters"][0]["meanings"] == ["position"]
    assert data["parameters"][1]["meanings"][0] == "Kollmorgen"


def test_sdo_read_shows_words(akd_inproc) -> None:
    code, out, _ = akd_inproc("sdo", "read", "0x6061")
    assert code == EXIT_OK and "(profile velocity)" in out
    data = json.loads(akd_inproc("sdo", "read", "0x1018:1", "--json")[1])
    assert data["value"] == 0x6A and data["meaning"] == "Kollmorgen"


def test_info_names_vendor_and_model(akd_inproc) -> None:
    code, out, err = akd_inproc("info")
    assert code == EXIT_OK, err
    lines = out.splitlines()
    assert lines[1].split() == ["vendor", "Kollmorgen"] and lines[2].split() == ["model", "AKD-P00606-NBCC-E000"]  # DRV.MODEL (issue 23.8)
    assert "manufacturer      256 (0x100, Kollmorgen)" in out
    data = json.loads(akd_inproc("info", "--json")[1])
    assert data["summary"]["vendor"] == "Kollmorgen" and data["summary"]["profile"] == "PROFIdrive 4.1"
    assert data["profidrive"]["drive_unit"]["manufacturer"] == 256  # the raw reading stays as it was


def test_summary_prefers_the_most_specific_source() -> None:
    identity = {"profidrive": {"drive_unit": {"manufacturer": 0x0100, "drive_unit_type": 1, "software_version": "1.20"},
                               "profile": {"name": "PROFIdrive", "version": "4.1"}},
                "im0": {"vendor_id": "0x0100", "order_id": "AKD-P00306-NBPN-0000", "serial_number": "SIM0001",
                        "hardware_revision": 3, "software_revision": "V1.20.0"}}
    brief = summary(identity)
    assert brief["vendor"] == "Kollmorgen" and brief["model"] == "AKD-P00306-NBPN-0000"
    assert brief["serial"] == "SIM0001" and brief["firmware"] == "1.20"  # one spelling per face (issue 23.8)
    assert summary({"profidrive": {"drive_unit": {"manufacturer": 42, "drive_unit_type": 7}}}) == {
        "vendor": "vendor 42 (0x2A)", "model": "drive unit type 7"}


@pytest.mark.parametrize("target", ["sim", "sim?drive=cia402"])
def test_status_names_warnings(akd_inproc, target: str) -> None:
    assert akd_inproc("sim", "fault", "n503")[0] == EXIT_OK
    code, out, err = akd_inproc("-T", target, "status")
    assert code == EXIT_OK, err
    assert "warning     n503 " in out and "DC Bus" in out
    status = json.loads(akd_inproc("-T", target, "status", "--json")[1])["status"]
    assert status["warning"] is True and [w["code"] for w in status["warnings"]] == ["n503"]
    assert akd_inproc("sim", "clear")[0] == EXIT_OK
    code, out, _ = akd_inproc("-T", target, "status")
    assert "warning     none" in out


def test_pnu_describe_lists_the_values_and_set_shows_words(akd_inproc) -> None:
    code, out, _ = akd_inproc("pnu", "describe", "930")
    assert code == EXIT_OK and "0 torque, 1 velocity, 2 position" in out
    assert json.loads(akd_inproc("pnu", "describe", "930", "--json")[1])["catalogue"]["values"].startswith("0 torque")
    code, out, _ = akd_inproc("-y", "pnu", "set", "930=2")
    assert code == EXIT_OK and "2 (position)" in out
