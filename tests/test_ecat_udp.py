"""EtherCAT through the ETG.8200 gateway face: the real CLI over real UDP against `akdctl sim serve --ethercat-udp`.

Covers the reference notes' worked example bytes, lost replies (recovered by retries), mailbox error replies, SDO
aborts, an unknown station and a vanished gateway (exit 3, never a hang), and tshark dissection of our --pcap.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
# Reference notes (ethercat-mailbox.md), ETG.8200 worked example: upload 0x1018:01 from station 4
GW_REQUEST = bytes.fromhex("10 50 0a 00 04 00 00 03 00 20 40 18 10 01 00 00 00 00")
GW_REPLY_HEAD = bytes.fromhex("10 50 0a 00 04 00 00")  # then type/counter, CoE 0x3000, 0x43 18 10 01, value


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _env(tmp: Path) -> dict[str, str]:
    env = dict(os.environ, AKDCTL_STATE_DIR=str(tmp), PYTHONPATH=str(ROOT))
    env.pop("AKDCTL_TARGET", None)
    return env


class Gateway:
    def __init__(self, tmp: Path, *extra: str) -> None:
        self.port = _free_port()
        self.env = _env(tmp)
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "akdctl", "sim", "serve", "--ethercat-udp", f"127.0.0.1:{self.port}",
             "--ecat-stations", "4=default,1001=default,1002=axis2", "--duration", "60", *extra],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=self.env, cwd=ROOT)
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        assert line.startswith("listening: ethercat-udp"), (line, self.proc.stderr.read() if self.proc.poll() else "")

    def cli(self, station: int, *args: str, timeout: str = "0.5") -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "akdctl", "-T", f"ecat-udp://127.0.0.1:{self.port}/{station}", "--timeout",
             timeout, *args], capture_output=True, text=True, env=self.env, cwd=ROOT, timeout=60)

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        for stream in (self.proc.stdout, self.proc.stderr):
            if stream:
                stream.close()


@pytest.fixture
def gateway(tmp_path: Path) -> Iterator[Gateway]:
    gw = Gateway(tmp_path)
    try:
        yield gw
    finally:
        gw.stop()


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


@pytest.mark.slow
def test_cli_commands_over_gateway(gateway: Gateway) -> None:
    for argv, station, code, text in COMMANDS:
        result = gateway.cli(station, *argv)
        assert result.returncode == code, (argv, station, result.stdout, result.stderr)
        if text is not None:
            assert text in result.stdout, (argv, result.stdout)
        if code:
            assert "Traceback" not in result.stderr and result.stderr.startswith("akdctl: error:")


@pytest.mark.slow
def test_worked_example_bytes_against_face(gateway: Gateway) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(5)
        s.sendto(GW_REQUEST, ("127.0.0.1", gateway.port))
        reply = s.recv(2048)
    assert reply[:7] == GW_REPLY_HEAD
    assert reply[7] & 0x0F == 3  # CoE (the example's counter 2 is the master's; ours is free)
    assert reply[8:14] == bytes.fromhex("00 30 43 18 10 01")  # SDO response, expedited 4 bytes, 0x1018:01
    assert reply[14:18] == (0x6A).to_bytes(4, "little")  # Kollmorgen's vendor id


@pytest.mark.slow
def test_lost_replies_are_recovered(tmp_path: Path) -> None:
    gw = Gateway(tmp_path, "--ecat-inject", "drop=2")
    try:
        for _ in range(3):
            result = gw.cli(1001, "sdo", "read", "0x1018:1", timeout="0.3")
            assert result.returncode == 0, result.stderr
    finally:
        gw.stop()


@pytest.mark.slow
@pytest.mark.parametrize("inject, code, words", [("mbxerr=1", (1, 3), "mailbox"), ("abort=1", (1,), "General error")])
def test_mailbox_error_and_abort(tmp_path: Path, inject: str, code: tuple[int, ...], words: str) -> None:
    gw = Gateway(tmp_path, "--ecat-inject", inject)
    try:
        result = gw.cli(1001, "sdo", "read", "0x1018:1")
        assert result.returncode in code, result.stderr
        assert words.lower() in result.stderr.lower() and "Traceback" not in result.stderr
    finally:
        gw.stop()


@pytest.mark.slow
def test_vanished_gateway_exits_3(tmp_path: Path) -> None:
    port = _free_port()  # nothing listens there
    result = subprocess.run([sys.executable, "-m", "akdctl", "-T", f"ecat-udp://127.0.0.1:{port}/1001", "--timeout",
                             "0.2", "sdo", "read", "0x1018:1"], capture_output=True, text=True, env=_env(tmp_path),
                            cwd=ROOT, timeout=30)
    assert result.returncode == 3 and "no answer" in result.stderr


@pytest.mark.slow
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
