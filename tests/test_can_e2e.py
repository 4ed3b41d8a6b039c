"""End to end over CAN: ``akdctl sim serve --can ...`` and the CLI in separate processes.

Two inter-process CAN buses:
* python-can's ``udp_multicast`` interface (IPv4 group 239.74.163.2), needs ``msgpack``.  Multicast on the host
  would leave through the default-route interface onto the LAN, so the server and every CLI run share a network
  namespace the test creates (only ``lo``, a multicast route on it) and removes: these tests need root
  (``@pytest.mark.root``; CI runs them) and ``test_multicast_stays_in_its_namespace`` checks the namespace is real;
* slcan over a pseudo-terminal (no network at all, no root): the simulator plays an slcan USB adapter
  (``--can slcan-pty:LINK``), the CLI uses python-can's slcan interface through pyserial.
Commands are listed in one table so later commands can be added as rows.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.harness import SimServer, run_akdctl
from tests.netns import LoopbackNetns

GROUP = "239.74.163.2"
NODE = 2

pytestmark = pytest.mark.slow


@dataclass
class UdpBus:
    """A served drive on ``udp_multicast`` inside *netns*; ``run`` is the CLI run in that same namespace."""

    target: str
    netns: LoopbackNetns
    server: SimServer

    def run(self, *args: str) -> tuple[int, str, str]:
        return run_akdctl(*args, netns=self.netns.name)


@pytest.fixture
def udp_bus() -> Iterator[UdpBus]:
    pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack (pip install msgpack)")
    # The namespace is private to this test, so python-can's default port cannot collide with another run.
    with LoopbackNetns() as netns, SimServer("--can", f"udp_multicast:{GROUP}:{NODE}", netns=netns.name) as server:
        assert server.ready[0].startswith("can udp_multicast"), server.ready
        yield UdpBus(f"can://udp_multicast/{GROUP}/{NODE}", netns, server)


@pytest.fixture
def slcan_target(tmp_path: Path) -> Iterator[str]:
    link = tmp_path / "slcan-tty"
    with SimServer("--can", f"slcan-pty:{link}:{NODE}") as server:
        tty = server.ready[0].split()[2]  # "can slcan-pty /dev/pts/N node 2"
        assert os.path.realpath(link) == tty
        yield f"can://slcan/{link.as_posix().replace('/', '%2F')}/{NODE}?sleep_after_open=0"
    assert not link.exists()  # the face removes its symlink


@pytest.mark.root
def test_multicast_stays_in_its_namespace(udp_bus: UdpBus) -> None:
    """The multicast server runs in the test's namespace (not the host's), and that namespace has no NIC but lo."""
    assert udp_bus.netns.name in LoopbackNetns.created
    assert udp_bus.netns.holds(udp_bus.server.pid)
    assert os.stat(f"/proc/{udp_bus.server.pid}/ns/net").st_ino != os.stat("/proc/self/ns/net").st_ino
    assert udp_bus.netns.links() == ["lo"]
    rc, out, err = udp_bus.run("sdo", "read", "0x1018:1")  # the CLI reaches it from inside the namespace
    assert rc == 0 and "106" in out, err


# argv after -T TARGET, expected exit code, text that must be in stdout (JSON commands are parsed)
COMMANDS: list[tuple[list[str], int, str]] = [
    (["sdo", "read", "0x1018:1"], 0, "106"),
    (["sdo", "write", "0x2032:0", "vs", "written-over-can", "--verify"], 0, "written-over-can"),
    (["sdo", "read", "0x2032:0", "vs"], 0, "written-over-can"),
    (["sdo", "read", "0x7777:0", "u8"], 1, ""),
    (["sdo", "write", "0x1018:1", "u32", "1"], 2, ""),  # the catalogue already says read-only
    (["can", "scan", "--nodes", "1-4", "--wait", "0.5"], 0, "AKD"),
    (["can", "nmt", "preop"], 0, "PRE-OPERATIONAL"),
    (["can", "nmt", "start"], 4, ""),  # OPERATIONAL acts on a master's RPDOs: consent (drive/nmt.py)
    (["-y", "can", "nmt", "start"], 0, "OPERATIONAL"),
    (["can", "nmt", "stop"], 0, "STOPPED"),
    (["--timeout", "0.3", "sdo", "read", "0x1018:1"], 3, ""),  # no SDO while STOPPED
    (["can", "nmt", "reset"], 0, "PRE-OPERATIONAL"),
    (["can", "nmt", "reset-comm", str(NODE)], 0, "PRE-OPERATIONAL"),
    (["-y", "can", "nmt", "start", "all"], 0, "not confirmed"),
]


def _run_table(target: str, run=run_akdctl) -> None:  # noqa: ANN001 - the runner (host or namespace)
    for argv, code, text in COMMANDS:
        rc, out, err = run("-T", target, *argv)
        assert rc == code, (argv, rc, out, err)
        assert text in out, (argv, out)
        if code:
            lines = [line for line in err.splitlines() if line.strip()]
            assert len(lines) == 1 and lines[0].startswith("akdctl: error:"), (argv, err)
            assert "Traceback" not in err


@pytest.mark.root
def test_cli_over_udp_multicast(udp_bus: UdpBus) -> None:
    _run_table(udp_bus.target, udp_bus.run)


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


@pytest.mark.root
def test_motion_fault_pdo_commands_over_canopen(udp_bus: UdpBus) -> None:
    assert run_akdctl("sim", "speed", "1000")[0] == 0  # the served drive shares the state dir
    for argv, code, text in FEATURE_COMMANDS:
        rc, out, err = udp_bus.run("-T", udp_bus.target, *argv)
        assert rc == code, (argv, rc, out, err)
        assert text in out, (argv, out)
        assert "Traceback" not in err


def test_cli_over_slcan_pty(slcan_target: str) -> None:
    _run_table(slcan_target)


@pytest.mark.root
def test_scan_json_and_block_transfer(udp_bus: UdpBus) -> None:
    rc, out, err = udp_bus.run("-T", udp_bus.target, "--json", "can", "scan", "--wait", "0.5")
    assert rc == 0, err
    nodes = json.loads(out)["nodes"]
    assert [(n["node"], n["vendor_id"], n["nmt_state"]) for n in nodes] == [(NODE, 0x6A, "PRE-OPERATIONAL")]
    block = udp_bus.target + "?block=1"
    value = "block-transfer-over-udp-multicast"[:32]
    rc, out, err = udp_bus.run("-T", block, "sdo", "write", "0x2032:0", "vs", value, "--verify")
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
