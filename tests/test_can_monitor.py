"""Issue 28 item 2: ``akdctl can monitor`` (emergencies as AKD faults, heartbeats and their timeouts, NMT state
changes, boot-ups) and ``status --watch --count/--for``.

The end-to-end case puts the simulator's CAN face on python-can's ``udp_multicast`` bus inside a private network
namespace (as tests/test_can_e2e.py), raises a fault with ``sim fault`` and reads the monitor's JSON lines; the
rules of each event are checked on :class:`akdctl.drive.can_events.BusWatch` with a stepped clock.
SPEC-NOTES 21: faults reach a CANopen client as emergencies.
"""

from __future__ import annotations

import json
import signal
import struct
import subprocess
import threading
import time
from collections.abc import Callable
from typing import IO

import pytest

from akdctl.drive.can_events import BusWatch, describe, emcy_faults
from tests.harness import SimServer, run_akdctl, start_akdctl

GROUP = "239.74.163.2"
NODE = 2


def test_emergency_decodes_to_the_akd_fault() -> None:
    watch = BusWatch()
    frame = struct.pack("<HB", 0x3210, 0x05) + struct.pack("<H", 501) + bytes(3)
    (event,) = watch.frame(1.0, 0x080 + 5, frame)
    assert event["kind"] == "emergency" and event["node"] == 5 and event["emcy"] == "0x3210"
    assert [f["code"] for f in event["faults"]] == ["F501"]
    assert "F501" in describe(event) and "over-voltage" in describe(event).lower()
    (reset,) = watch.frame(2.0, 0x085, bytes(8))
    assert reset["kind"] == "emergency-reset" and reset["faults"] == []


def test_unknown_emcy_code_names_no_fault() -> None:
    assert emcy_faults(0x1234, bytes(5)) == []
    (event,) = BusWatch().frame(0.0, 0x081, struct.pack("<HB", 0x1234, 1) + bytes(5))
    assert "no AKD fault" in describe(event)


def test_heartbeat_states_bootup_and_timeout() -> None:
    watch = BusWatch()
    kinds = [e["kind"] for e in watch.frame(0.0, 0x703, b"\x00")]
    assert kinds == ["boot-up", "nmt-state"]
    assert watch.frame(0.1, 0x703, b"\x7f") == []  # PRE-OPERATIONAL, as the boot-up announced
    assert watch.frame(0.2, 0x703, b"\x7f") == []
    assert watch.limit(3) == pytest.approx(0.3)  # 3 periods of 0.1 s
    (change,) = watch.frame(0.3, 0x703, b"\x05")
    assert change == {"time": 0.3, "kind": "nmt-state", "node": 3, "state": "OPERATIONAL", "was": "PRE-OPERATIONAL"}
    assert watch.tick(0.55) == []
    (lost,) = watch.tick(0.65)
    assert lost["kind"] == "heartbeat-lost" and lost["node"] == 3 and lost["last_state"] == "OPERATIONAL"
    assert watch.tick(0.9) == []  # reported once
    (back,) = watch.frame(1.0, 0x703, b"\x05")
    assert back["kind"] == "heartbeat-back"


def test_fixed_timeout_and_node_filter_and_nmt_command() -> None:
    watch = BusWatch(heartbeat_timeout=1.0, nodes={4})
    assert watch.frame(0.0, 0x703, b"\x05") == []  # node 3 is not watched
    watch.frame(0.0, 0x704, b"\x05")
    assert watch.tick(0.9) == [] and watch.tick(1.1)[0]["kind"] == "heartbeat-lost"
    assert watch.frame(0.0, 0x000, b"\x01\x04")[0]["command"] == "start"
    assert watch.frame(0.0, 0x000, b"\x81\x00")[0]["node"] == "all"
    assert watch.frame(0.0, 0x000, b"\x81\x03") == []
    assert watch.frame(0.0, 0x184, bytes(8)) == []  # a PDO is not an event


def test_monitor_needs_a_can_target(akd_inproc) -> None:
    code, _, err = akd_inproc("can", "monitor", "--for", "0.1")
    assert code == 2 and "can://" in err and err.count("\n") == 1


class Events:
    """The monitor's ``--json`` lines as they come (a reader thread), so the test waits for an event instead of
    sleeping and hoping the monitor (a cold start, maybe on a loaded machine) saw it by then."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.lines: list[dict] = []  # type: ignore[type-arg]
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(proc.stdout,), daemon=True)
        self._thread.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            with self._cond:
                self.lines.append(json.loads(line))
                self._cond.notify_all()

    def rest(self) -> list[dict]:  # type: ignore[type-arg]
        """Every event, once the monitor has ended (its stdout closed)."""
        self._thread.join(timeout=30)
        assert not self._thread.is_alive(), "the monitor's output did not end"
        return list(self.lines)

    def wait_for(self, holds: Callable[[list[dict]], object], what: str, timeout: float = 60.0) -> list[dict]:  # type: ignore[type-arg]
        """Wait until ``holds(events so far)``; the events then. Fails naming *what* after *timeout* s."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not holds(self.lines):
                left = deadline - time.monotonic()
                assert left > 0, f"timed out after {timeout} s waiting for {what}; events: {self.lines}"
                self._cond.wait(min(left, 0.5))
            return list(self.lines)


def _kinds(events: list[dict], kind: str) -> list[dict]:  # type: ignore[type-arg]
    return [e for e in events if e["kind"] == kind and e.get("node") in (NODE, None)]


@pytest.mark.slow
@pytest.mark.root
def test_monitor_shows_the_simulators_emergency_and_lost_heartbeat() -> None:
    """Each step waits for the monitor to show the event before the next (a loaded machine stretches every step;
    ``--for`` only bounds the run). ``--heartbeats`` makes each heartbeat visible, so the test knows the monitor has
    measured the period again after the reset's boot-up before it silences the node."""
    pytest.importorskip("msgpack", reason="python-can's udp_multicast interface needs msgpack")
    from tests.netns import LoopbackNetns

    target = f"can://udp_multicast/{GROUP}/{NODE}"
    with LoopbackNetns("akdmon") as netns:
        server = SimServer("--can", f"udp_multicast:{GROUP}:{NODE}", "--can-heartbeat", "100", netns=netns.name)
        server.start()
        mon = start_akdctl("-T", target, "can", "monitor", "--heartbeats", "--for", "120", "--json",
                           netns=netns.name)
        try:
            seen = Events(mon)
            try:
                seen.wait_for(lambda ev: len(_kinds(ev, "heartbeat")) >= 2, "the node's heartbeats")
                assert run_akdctl("sim", "fault", "F501").code == 0
                seen.wait_for(lambda ev: _kinds(ev, "emergency"), "the emergency of F501")
                nmt = run_akdctl("-T", target, "can", "nmt", "reset", netns=netns.name)  # a boot-up follows
                assert nmt.code == 0, nmt.stderr

                def measured_again(ev: list[dict]) -> bool:  # type: ignore[type-arg]
                    boots = _kinds(ev, "boot-up")
                    return bool(boots) and len([e for e in _kinds(ev, "heartbeat") if e["time"] > boots[0]["time"]]) >= 2
                seen.wait_for(measured_again, "two heartbeats after the boot-up")
            finally:
                server.stop()  # the node goes silent: its heartbeat is lost

            def lost_for_good(ev: list[dict]) -> bool:  # type: ignore[type-arg]
                """A heartbeat-lost after the node's last heartbeat (a stalled server may have been reported lost
                and back before; that one is not the loss of the stopped node)."""
                beats = [i for i, e in enumerate(ev) if e["kind"] in ("heartbeat", "heartbeat-back")]
                losses = [i for i, e in enumerate(ev) if e["kind"] == "heartbeat-lost"]
                return bool(losses) and (not beats or losses[-1] > beats[-1])
            seen.wait_for(lost_for_good, "the heartbeat to be reported lost")
            mon.send_signal(signal.SIGINT)  # Ctrl-C ends the monitor (exit 0)
            code = mon.wait(timeout=30)
            events = seen.rest()
            err = mon.stderr.read() if mon.stderr else ""
        finally:
            if mon.poll() is None:
                mon.kill()
                mon.wait(timeout=10)
            for stream in (mon.stdout, mon.stderr):
                if stream is not None:
                    stream.close()
    assert code == 0, err
    kinds = [e["kind"] for e in events]
    assert "nmt-state" in kinds
    emcy = next(e for e in events if e["kind"] == "emergency")
    assert emcy["node"] == NODE and emcy["emcy"] == "0x3210"
    assert [f["code"] for f in emcy["faults"]] == ["F501"] and "over-voltage" in emcy["faults"][0]["text"].lower()
    boot = next(e for e in events if e["kind"] == "boot-up")
    assert boot["node"] == NODE and boot["time"] > emcy["time"]
    assert any(e["kind"] == "nmt-command" and e["command"] == "reset" for e in events)
    lost = [e for e in events if e["kind"] == "heartbeat-lost"][-1]
    assert lost["node"] == NODE and lost["time"] > boot["time"]


@pytest.mark.slow
def test_status_watch_count_and_for() -> None:
    result = run_akdctl("status", "--watch", "--count", "3", "--interval", "0.05", "--json")
    assert result.code == 0, result.stderr
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(lines) == 3 and all("status" in line for line in lines)
    result = run_akdctl("status", "--watch", "--for", "2", "--interval", "0.2", "--json", timeout=60)
    # --for ends the watch by itself (run_akdctl's timeout would fail a run that hangs). At most one reading per
    # interval: readings start at least 0.2 s apart and none starts after 2 s, so never more than 10. At least
    # two: it reads again after the first. (A lower bound of 3 in one second failed on a loaded machine, where one
    # reading of the simulator alone can take most of a second; two in two seconds leave that margin.)
    assert result.code == 0, result.stderr
    assert 2 <= len(result.stdout.splitlines()) <= 10, result.stdout
    bad = run_akdctl("status", "--count", "2")
    assert bad.code == 2 and "--watch" in bad.stderr


def test_every_heartbeat_on_request() -> None:
    watch = BusWatch(every_heartbeat=True)
    assert [e["kind"] for e in watch.frame(0.0, 0x702, b"\x05")] == ["heartbeat", "nmt-state"]
    (beat,) = watch.frame(0.1, 0x702, b"\x05")
    assert beat["kind"] == "heartbeat" and describe(beat) == "node 2: heartbeat (OPERATIONAL)"
