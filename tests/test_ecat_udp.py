"""EtherCAT through the ETG.8200 gateway face: the real CLI over real UDP against `akdctl sim serve --ethercat-udp`.

Covers the reference notes' worked example bytes, lost replies (recovered by retries), mailbox error replies, SDO
aborts, an unknown station and a vanished gateway (exit 3, never a hang), and tshark dissection of our --pcap.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.harness import CliResult, SimServer, closed_udp_port, run_akdctl

pytestmark = pytest.mark.slow
# Reference notes (ethercat-mailbox.md), ETG.8200 worked example: upload 0x1018:01 from station 4
GW_REQUEST = bytes.fromhex("10 50 0a 00 04 00 00 03 00 20 40 18 10 01 00 00 00 00")
GW_REPLY_HEAD = bytes.fromhex("10 50 0a 00 04 00 00")  # then type/counter, CoE 0x3000, 0x43 18 10 01, value


class Gateway(SimServer):
    """The ETG.8200 face on a port it binds itself (reported on its ready line), three stations."""

    def __init__(self, *extra: str) -> None:
        super().__init__("--ethercat-udp", "127.0.0.1:0", "--ecat-stations", "4=default,1001=default,1002=axis2",
                         *extra, duration=60)

    def cli(self, station: int, *args: str, timeout: str = "0.5") -> CliResult:
        return run_akdctl("-T", f"ecat-udp://127.0.0.1:{self.port}/{station}", "--timeout", timeout, *args)


@pytest.fixture
def gateway() -> Iterator[Gateway]:
    with Gateway() as gw:
        yield gw


# argv, station, expected exit code, text expected on stdout (or None)
COMMANDS = [
    (["sdo", "read", "0x1018:1"], 1001, 0, "106"),
    (["sdo", "read", "0x1008:0"], 1001, 0, "AKD"),
    (["--json", "sdo", "read", "0x1018:2"], 1002, 0, "\"index\": 4120"),
    (["sdo", "write", "0x6060:0", "3"], 1002, 0, None),
    (["sdo", "read", "0x6060:0"], 1002, 0, "3"),
    (["sdo", "read", "0x5FFF:0", "u8"], 1001, 1, None),  # object does not exist: SDO abort
    (["info"], 1001, 0, "106"),
    (["-y", "enable"], 1001, 0, "operation enabled"),
    (["status"], 1001, 0, "operation enabled"),
    (["-y", "disable"], 1001, 0, "drive disabled"),
    (["pdo", "show"], 1001, 0, "0x1701"),
    (["fault", "list"], 1001, 0, None),
    (["-y", "move", "1000"], 1001, 4, None),  # not homed: a safety refusal, over EtherCAT as on sim
    (["sdo", "read", "0x1018:1"], 1003, 3, None),  # unknown station: the gateway stays silent
]


def test_cli_commands_over_gateway(gateway: Gateway) -> None:
    for argv, station, code, text in COMMANDS:
        result = gateway.cli(station, *argv)
        assert result.returncode == code, (argv, station, result.stdout, result.stderr)
        if text is not None:
            assert text in result.stdout, (argv, result.stdout)
        if code:
            assert "Traceback" not in result.stderr and result.stderr.startswith("akdctl: error:")


def test_worked_example_bytes_against_face(gateway: Gateway) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(5)
        s.sendto(GW_REQUEST, ("127.0.0.1", gateway.port))
        reply = s.recv(2048)
    assert reply[:7] == GW_REPLY_HEAD
    assert reply[7] & 0x0F == 3  # CoE (the example's counter 2 is the master's; ours is free)
    assert reply[8:14] == bytes.fromhex("00 30 43 18 10 01")  # SDO response, expedited 4 bytes, 0x1018:01
    assert reply[14:18] == (0x6A).to_bytes(4, "little")  # Kollmorgen's vendor id


def test_lost_replies_are_recovered() -> None:
    with Gateway("--ecat-inject", "drop=2") as gw:
        for _ in range(3):
            result = gw.cli(1001, "sdo", "read", "0x1018:1", timeout="0.3")
            assert result.returncode == 0, result.stderr


@pytest.mark.parametrize("inject, code, words", [("mbxerr=1", (1, 3), "mailbox"), ("abort=1", (1,), "General error")])
def test_mailbox_error_and_abort(inject: str, code: tuple[int, ...], words: str) -> None:
    with Gateway("--ecat-inject", inject) as gw:
        result = gw.cli(1001, "sdo", "read", "0x1018:1")
        assert result.returncode in code, result.stderr
        assert words.lower() in result.stderr.lower() and "Traceback" not in result.stderr


def test_vanished_gateway_exits_3() -> None:
    with closed_udp_port() as port:  # nothing listens there: the datagrams bounce
        result = run_akdctl("-T", f"ecat-udp://127.0.0.1:{port}/1001", "--timeout", "0.2", "sdo", "read", "0x1018:1",
                            timeout=30)
    assert result.returncode == 3 and "no answer" in result.stderr


@pytest.mark.skipif(shutil.which("tshark") is None and os.environ.get("CI") != "true", reason="tshark not installed")
def test_tshark_dissects_gateway_pcap(gateway: Gateway, tmp_path: Path) -> None:
    pcap = tmp_path / "gw.pcap"
    result = gateway.cli(1001, "--pcap", str(pcap), "sdo", "read", "0x1018:1")
    assert result.returncode == 0, result.stderr
    fields = subprocess.run(
        ["tshark", "-r", str(pcap), "-d", f"udp.port=={gateway.port},ecatf", "-T", "fields", "-e",
         "ecat_mailbox.type", "-e", "ecat_mailbox.coe.sdoidx", "-e", "ecat_mailbox.coe.sdosub", "-e",
         "ecat_mailbox.coe.sdodata"], capture_output=True, text=True, timeout=60)
    rows = [line.split("\t") for line in fields.stdout.splitlines() if line.strip()]
    assert len(rows) == 2, fields.stdout + fields.stderr
    assert all(r[0] in ("3", "0x03", "0x3") for r in rows)  # CoE
    assert all(r[1].lower() in ("0x1018", "4120") for r in rows) and all(r[2] in ("1", "0x01") for r in rows)
    assert rows[1][3].lower().replace("0x", "").lstrip("0") in ("6a",)
