"""Issue 23.11: a write over any face goes through the drive's persistence, and a write it cannot keep is refused
in the face's protocol's words.

Before, ``eip param set EIP.POSUNIT 70000`` answered success, but the value lived in the EtherNet/IP face only:
after a restart of ``sim serve`` it read 65536 again, and a full state disk still gave exit 0.
"""

from __future__ import annotations

import errno
import json
import os
import struct
from pathlib import Path

import pytest

from tests.harness import SimServer


def _tcp(server: SimServer) -> str:
    return next(line.split()[1] for line in server.ready if line.startswith("ethernetip"))


def _faces(link: Path) -> tuple[str, ...]:
    return ("--profinet", "127.0.0.1:0", "--ethercat-udp", "127.0.0.1:0", "--ethernetip", "127.0.0.1:0",
            "--eip-io-port", "0", "--can", f"slcan-pty:{link}:5")


@pytest.mark.slow
def test_a_write_on_every_face_survives_a_restart_of_sim_serve(akd, tmp_path: Path) -> None:
    link = tmp_path / "slcan-tty"
    with SimServer(*_faces(link), faces=4) as server:
        pn = "pn://{}:{}".format(*server.address_of("profinet"))
        ecat = "ecat-udp://{}:{}/1001".format(*server.address_of("ethercat-udp"))
        eip, can = f"eip://{_tcp(server)}", f"can://slcan/{link}/5?sleep_after_open=0"
        for args in ((pn, "pnu", "set", "930=2"), (ecat, "sdo", "write", "0x6065", "1234"),
                     (can, "sdo", "write", "0x6065", "4321"), (eip, "eip", "param", "set", "EIP.POSUNIT", "70000")):
            result = akd("-T", args[0], "-y", *args[1:], timeout=60)
            assert result.returncode == 0, (args, result.stderr)
    link.unlink(missing_ok=True)
    with SimServer(*_faces(link), faces=4) as server:
        pn = "pn://{}:{}".format(*server.address_of("profinet"))
        eip = f"eip://{_tcp(server)}"
        got = json.loads(akd("-T", pn, "--json", "pnu", "get", "930", timeout=60).stdout)["parameters"][0]["values"]
        assert got == [2]
        result = akd("-T", eip, "--json", "eip", "param", "get", "EIP.POSUNIT", timeout=60)
        assert result.returncode == 0, result.stderr
        assert "70000" in result.stdout
        can = f"can://slcan/{link}/5?sleep_after_open=0"
        assert json.loads(akd("-T", can, "--json", "sdo", "read", "0x6065", timeout=60).stdout)["value"] == 4321


def test_an_eip_write_the_drive_cannot_keep_is_refused_resource_unavailable(tmp_path: Path, monkeypatch) -> None:
    """The face's reply is CIP general status 0x02 "resource unavailable", and the value is not taken."""
    import akdctl.sim.drive as store
    from akdctl.catalog import eip_parameters
    from akdctl.protocol import cip
    from akdctl.sim.cip_device import CipDevice
    from akdctl.sim.drive import SimDrive

    device = CipDevice(SimDrive("default", tmp_path))
    instance = eip_parameters.by_name("EIP.POSUNIT").instance  # type: ignore[union-attr]
    path = cip.Path(cip.PARAMETER, instance, 1).encode()

    def request(service: int, data: bytes = b"") -> cip.Response:
        return cip.Response.decode(device.handle(cip.Request(service, path, data).encode()))

    before = request(cip.GET_ATTRIBUTE_SINGLE)

    def full(*args: object, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with monkeypatch.context() as patch:
        patch.setattr(store, "atomic_open", full)
        refused = request(cip.SET_ATTRIBUTE_SINGLE, struct.pack("<I", 70000))
    assert refused.status == cip.RESOURCE_UNAVAILABLE
    assert request(cip.GET_ATTRIBUTE_SINGLE).data == before.data  # not taken
    assert request(cip.SET_ATTRIBUTE_SINGLE, struct.pack("<I", 70000)).status == cip.SUCCESS
    assert SimDrive("default", tmp_path).snapshot()["named"] == {"EIP.POSUNIT": 70000}
