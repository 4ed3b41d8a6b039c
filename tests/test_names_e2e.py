"""Parameters by name on every transport against ONE simulated drive (issue 24, "Done when").

One ``sim serve`` process offers the drive over the ASCII channel (akd://), Modbus TCP (mb://), EtherNet/IP
(eip://), the ETG.8200 gateway (ecat-udp://) and slcan on a pseudo-terminal (can://); ``sim`` is the same drive
in-process. The same names read the same value and unit everywhere, a write by name on any one shows on all the
others, and a parameter file dumped over one transport restores over another with ``param diff`` then silent.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.harness import SimServer, run_akdctl

pytestmark = pytest.mark.slow

#: A dozen everyday names every one of the six transports reaches (a CoE object and a number n each).
NAMES = ["VL.KP", "VL.KI", "HOME.MODE", "HOME.DIR", "IL.FB", "DRV.MOTIONSTAT", "AIN.CUTOFF", "AIN.DEADBAND",
         "AIN.OFFSET", "AOUT.ISCALE", "UNIT.PLINEAR", "VBUS.VALUE", "MOTOR.TEMP", "MODBUS.PSCALE"]
SETUP = ["VL.KP=1.5", "VL.KI=120", "HOME.MODE=4", "HOME.DIR=0", "AIN.CUTOFF=500", "AIN.DEADBAND=0.125",
         "AIN.OFFSET=-0.25", "AOUT.ISCALE=2.5", "UNIT.PLINEAR=1", "MODBUS.PSCALE=20"]


class Drive:
    """The served drive's targets, by transport."""

    def __init__(self, server: SimServer, link: Path, state: Path) -> None:
        self.state = state
        def port(prefix: str) -> int:
            import re

            line = next(line for line in server.ready if line.startswith(prefix))
            return int(re.search(r"127\.0\.0\.1:(\d+)", line).group(1))  # type: ignore[union-attr]

        self.targets = {
            "sim": "sim",
            "akd": f"akd://127.0.0.1:{port('akd ascii')}",
            "mb": f"mb://127.0.0.1:{port('modbus')}",
            "eip": f"eip://127.0.0.1:{port('ethernetip')}",
            "ecat-udp": f"ecat-udp://127.0.0.1:{port('ethercat-udp')}/1001",
            "can": f"can://slcan/{link.as_posix().replace('/', '%2F')}/2?sleep_after_open=0",
        }

    def run(self, transport: str, *args: str) -> tuple[int, str, str]:
        result = run_akdctl("-T", self.targets[transport], "--timeout", "3", *args,
                            env={"AKDCTL_STATE_DIR": str(self.state)})  # the served drive's state, for sim
        return result.code, result.stdout, result.stderr

    def get(self, transport: str, *names: str) -> dict[str, tuple[object, object]]:
        code, out, err = self.run(transport, "--json", "param", "get", *names)
        assert code == 0, f"{transport}: {err}"
        return {p["name"]: (p["value"], p["unit"]) for p in json.loads(out)["parameters"]}


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Drive]:
    state = tmp_path_factory.mktemp("state")
    link = tmp_path_factory.mktemp("tty") / "slcan-tty"
    with SimServer("--akd", "127.0.0.1:0", "--modbus", "127.0.0.1:0", "--ethernetip", "127.0.0.1:0",
                   "--eip-io-port", "0", "--ethercat-udp", "127.0.0.1:0", "--ecat-stations", "1001=default",
                   "--can", f"slcan-pty:{link}:2", faces=5, env={"AKDCTL_STATE_DIR": str(state)},
                   duration=900) as server:  # serves the whole module (stopped on exit): 120 s ran out under load
        served = Drive(server, link, state)
        code, _, err = served.run("akd", "-y", "param", "set", *SETUP)
        assert code == 0, err
        yield served


def test_the_same_names_read_the_same_on_every_transport(drive: Drive) -> None:
    reference = drive.get("akd", *NAMES)
    assert reference["VL.KP"] == (1.5, "A/(rad/s)") and reference["AIN.OFFSET"] == (-0.25, "V")
    for transport in ("sim", "mb", "eip", "ecat-udp", "can"):
        assert drive.get(transport, *NAMES) == reference, transport


@pytest.mark.parametrize("writer", ["sim", "akd", "mb", "eip", "ecat-udp", "can"])
def test_a_write_by_name_on_one_shows_on_all_others(drive: Drive, writer: str) -> None:
    value = {"sim": 0.25, "akd": 0.5, "mb": 0.75, "eip": 1.125, "ecat-udp": 2.0, "can": 3.5}[writer]
    code, _, err = drive.run(writer, "-y", "param", "set", f"VL.KP={value}", f"HOME.MODE={int(value * 4)}")
    assert code == 0, err
    for reader in drive.targets:
        assert drive.get(reader, "VL.KP", "HOME.MODE") == {"VL.KP": (value, "A/(rad/s)"),
                                                            "HOME.MODE": (int(value * 4), None)}, reader


def test_a_file_dumped_over_one_transport_restores_over_another(drive: Drive, tmp_path: Path) -> None:
    dumped = tmp_path / "axis.akd"
    code, _, err = drive.run("akd", "param", "dump", str(dumped))
    assert code == 0, err
    text = dumped.read_bytes()
    assert b"\r\n" in text and b"VL.KP " in text and text.startswith(b"# ")
    code, _, err = drive.run("mb", "-y", "param", "set", "VL.KP=9.5", "VL.KI=33")   # the drive drifts
    assert code == 0, err
    code, out, _ = drive.run("can", "param", "diff", str(dumped))
    assert code == 5 and "VL.KP" in out and "VL.KI" in out
    code, out, err = drive.run("ecat-udp", "--json", "-y", "param", "restore", str(dumped))
    assert code == 0, err
    assert {w["name"] for w in json.loads(out)["written"]} == {"VL.KP", "VL.KI"}   # only what differed
    for transport in ("can", "akd", "eip"):
        code, out, err = drive.run(transport, "--json", "param", "diff", str(dumped))
        assert code == 0 and json.loads(out)["differences"] == [], (transport, out, err)


def test_restore_dry_run_writes_nothing(drive: Drive, tmp_path: Path) -> None:
    path = tmp_path / "one.akd"
    path.write_bytes(b"# hand written\nVL.KI 77.5 # a comment\n")
    before = drive.get("akd", "VL.KI")
    code, out, err = drive.run("eip", "param", "restore", str(path), "--dry-run")
    assert code == 0 and "VL.KI" in out and "77.500" in out, err
    assert drive.get("akd", "VL.KI") == before


def test_over_profinet_a_name_without_pnu_names_the_ways(drive: Drive) -> None:
    from akdctl.catalog.akd_params import lookup

    row = lookup("VL.KP")
    assert row is not None and row.pnu is None
    result = run_akdctl("-T", "pn://127.0.0.1:9", "--timeout", "0.3", "param", "get", "VL.KP")
    # pn:// needs the drive before it can say which route; without one the refusal comes from the catalogue
    assert result.code in (2, 3)
