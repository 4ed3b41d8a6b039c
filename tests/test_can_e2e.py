"""End to end over CAN: ``akdctl sim serve --can ...`` and the CLI in separate processes.

Two inter-process CAN buses, both without root:
* python-can's ``udp_multicast`` interface (IPv4 group 239.74.163.2 on a free
  UDP port per test; multicast loops back on the host), needs ``msgpack``;
* slcan over a pseudo-terminal: the simulator plays an slcan USB adapter
  (``--can slcan-pty:LINK``), the CLI uses python-can's slcan interface through
  pyserial.
Commands are listed in one table so later commands can be added as rows.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import ROOT, run_akdctl

GROUP = "239.74.163.2"
NODE = 2


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("", 0))
        return sock.getsockname()[1]


class Served:
    def __init__(self, proc: subprocess.Popen, ready: str) -> None:
        self.proc = proc
        self.ready = ready


def _serve(spec: str, *extra: str) -> Iterator[Served]:
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "akdctl", "sim", "serve", "--can", spec, "--duration", "120", *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    try:
        line = proc.stdout.readline()  # the ready line (sim serve prints it once the face is up)
        if not line.startswith("listening: can"):
            proc.kill()
            pytest.fail(f"sim serve did not start: {line!r} {proc.stderr.read()}")
        yield Served(proc, line.strip())
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()


@pytest.fixture
def udp_target() -> Iterator[str]:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack (pip install msgpack)")
    port = _free_udp_port()
    for _ in _serve(f"udp_multicast:{GROUP}:{NODE}?port={port}"):
        yield f"can://udp_multicast/{GROUP}/{NODE}?port={port}"


@pytest.fixture
def slcan_target(tmp_path: Path) -> Iterator[str]:
    link = tmp_path / "slcan-tty"
    for served in _serve(f"slcan-pty:{link}:{NODE}"):
        tty = served.ready.split()[3]
        assert os.path.realpath(link) == tty
        yield f"can://slcan/{link.as_posix().replace('/', '%2F')}/{NODE}?sleep_after_open=0"
    assert not link.exists()  # the face removes its symlink


# argv after -T TARGET, expected exit code, text that must be in stdout (JSON commands are parsed)
COMMANDS: list[tuple[list[str], int, str]] = [
    (["sdo", "read", "0x1018:1"], 0, "106"),
    (["sdo", "write", "0x2032:0", "vs", "written-over-can", "--verify"], 0, "written-over-can"),
    (["sdo", "read", "0x2032:0", "vs"], 0, "written-over-can"),
    (["sdo", "read", "0x7777:0", "u8"], 1, ""),
    (["sdo", "write", "0x1018:1", "u32", "1"], 2, ""),  # the catalogue already says read-only
    (["can", "scan", "--nodes", "1-4", "--wait", "0.5"], 0, "AKD"),
    (["can", "nmt", "preop"], 0, "PRE-OPERATIONAL"),
    (["can", "nmt", "start"], 0, "OPERATIONAL"),
    (["can", "nmt", "stop"], 0, "STOPPED"),
    (["--timeout", "0.3", "sdo", "read", "0x1018:1"], 3, ""),  # no SDO while STOPPED
    (["can", "nmt", "reset"], 0, "PRE-OPERATIONAL"),
    (["can", "nmt", "reset-comm", str(NODE)], 0, "PRE-OPERATIONAL"),
    (["can", "nmt", "start", "all"], 0, "not confirmed"),
]


def _run_table(target: str) -> None:
    for argv, code, text in COMMANDS:
        rc, out, err = run_akdctl("-T", target, *argv)
        assert rc == code, (argv, rc, out, err)
        assert text in out, (argv, out)
        if code:
            lines = [line for line in err.splitlines() if line.strip()]
            assert len(lines) == 1 and lines[0].startswith("akdctl: error:"), (argv, err)
            assert "Traceback" not in err


def test_cli_over_udp_multicast(udp_target: str) -> None:
    _run_table(udp_target)


# Motion, fault, mapping and identity commands over CANopen (CiA 402 through SDO), in order.
FEATURE_COMMANDS: list[tuple[list[str], int, str]] = [
    (["--json", "status"], 0, "state"),
    (["--yes", "enable"], 0, "operation enabled"),
    (["--yes", "home", "--mode", "35"], 0, "homed"),
    (["--yes", "move", "0.5"], 0, "standstill"),
    (["--yes", "move", "--relative", "0.25"], 0, "target reached"),
    (["move", "1"], 4, ""),  # no terminal and no --yes: refused before anything is written
    (["fault", "dump"], 0, "none"),
    (["pdo", "show"], 0, "0x1C13"),
    (["disable"], 0, ""),
    (["info"], 0, "AKD"),
]


def test_motion_fault_pdo_commands_over_canopen(udp_target: str) -> None:
    assert run_akdctl("sim", "speed", "1000")[0] == 0  # the served drive shares the state dir
    for argv, code, text in FEATURE_COMMANDS:
        rc, out, err = run_akdctl("-T", udp_target, *argv)
        assert rc == code, (argv, rc, out, err)
        assert text in out, (argv, out)
        assert "Traceback" not in err


def test_cli_over_slcan_pty(slcan_target: str) -> None:
    _run_table(slcan_target)


def test_scan_json_and_block_transfer(udp_target: str) -> None:
    rc, out, err = run_akdctl("-T", udp_target, "--json", "can", "scan", "--wait", "0.5")
    assert rc == 0, err
    nodes = json.loads(out)["nodes"]
    assert [(n["node"], n["vendor_id"], n["nmt_state"]) for n in nodes] == [(NODE, 0x6A, "PRE-OPERATIONAL")]
    block = udp_target + "&block=1"
    value = "block-transfer-over-udp-multicast"[:32]
    rc, out, err = run_akdctl("-T", block, "sdo", "write", "0x2032:0", "vs", value, "--verify")
    assert rc == 0, err


@pytest.mark.parametrize("target, code", [
    ("can://pcan/PCAN_USBBUS1/1", 3),          # vendor library missing
    ("can://slcan/%2Fdev%2Fno-such-tty/1?sleep_after_open=0", 3),  # adapter missing
    ("can://no_such_iface/can0/1", 2),         # not a python-can interface
    ("can://socketcan/can0/200", 2),           # bad node id
])
def test_missing_adapter_is_one_line(target: str, code: int) -> None:
    rc, out, err = run_akdctl("-T", target, "sdo", "read", "0x1018:1")
    assert rc == code, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("akdctl: error:") and "Traceback" not in err


def test_can_commands_need_a_can_target() -> None:
    rc, out, err = run_akdctl("-T", "sim", "can", "scan")
    assert rc == 2 and "can://" in err
