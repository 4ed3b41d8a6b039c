"""Issue 17.7: a motion command owns the axis for its duration; "target reached" only for our own set point.

The owner lock (akdctl/io/owner_lock.py, taken by akdctl/cli/consent.py for whatever passes the one consent)
and the end-position check (akdctl/drive/motion_plan.py ``confirm_own_target``). The end-to-end tests run five
``move --relative 1`` at once against the simulated drive and check the invariant that must hold whatever the
interleaving: the axis moved exactly one revolution per command that reported success, and every other command
was refused with exit 4 in words. No assertion depends on timing.
"""

from __future__ import annotations

import json
import os
import re
import signal
from pathlib import Path

import pytest

from akdctl.drive import gate
from akdctl.drive.motion_plan import MotionPlan, MotionRequest, confirm_own_target
from akdctl.errors import DriveError
from akdctl.io.owner_lock import OwnerBusy, OwnerLock, read_owner
from akdctl.transport.target import split_target
from tests.harness import finish, run_akdctl, start_akdctl, wait_until


# ---------------------------------------------------------------- in process
def test_owner_lock_excludes_a_second_holder_and_names_the_first(tmp_path: Path) -> None:
    path = tmp_path / "owners" / "x.lock"
    first, second = OwnerLock(path), OwnerLock(path)
    first.acquire("akdctl move 1")
    with pytest.raises(OwnerBusy) as busy:
        second.acquire("akdctl move 2")
    assert busy.value.owner["pid"] == os.getpid() and busy.value.owner["command"] == "akdctl move 1"
    first.release()
    first.release()  # idempotent
    second.acquire("akdctl move 2")
    assert read_owner(path)["command"] == "akdctl move 2"
    second.release()
    assert read_owner(path) == {}


@pytest.mark.parametrize("content", [b"", b"\x00\xff" * 100, b"[1,2]", b'{"pid": "1", "command": 5}',
                                     b'{"pid": true}', b'{"command": "a\\u001b]0;x\\u0007b"}'])
def test_a_hostile_owner_record_is_shown_inert(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "x.lock"
    path.write_bytes(content)
    owner = read_owner(path)
    assert set(owner) <= {"command"} and all(c.isprintable() for c in owner.get("command", ""))


def test_owner_key_names_the_drive_not_the_way_it_is_spoken_to() -> None:
    def key(text: str) -> str:
        return gate.owner_key(split_target(text))

    assert key("sim") == key("sim?drive=cia402") == key("sim://default")
    assert key("sim://a") != key("sim://b")
    assert key("ecat+soem://eth0/0") == key("ecat://eth0/0") != key("ecat://eth0/1")
    assert key("pn://10.0.0.1?axis=0") != key("pn://10.0.0.1?axis=1")
    assert key("can://socketcan/can0/1?bitrate=500000") == key("can://socketcan/can0/1")
    assert re.fullmatch(r"[A-Za-z0-9._-]+", key("can://slcan//dev/ttyACM0/1?x=../../etc"))


class _Axis:
    def __init__(self, drive_target: int | None) -> None:
        self.drive_target = drive_target

    def issued_target(self) -> int | None:
        return self.drive_target


class _Status:
    def __init__(self, position_rev: float | None) -> None:
        self.position_rev = position_rev


def _plan(end_rev: float | None, target_raw: int = 65536) -> MotionPlan:
    plan = MotionPlan(MotionRequest("move", target=1.0, relative=True), "profidrive", "position")
    plan.end_rev, plan.target_raw = end_rev, target_raw
    return plan


def test_target_reached_counts_only_where_our_set_point_puts_the_axis() -> None:
    assert confirm_own_target(_Axis(None), _plan(3.0), _Status(3.004), "move").position_rev == 3.004
    with pytest.raises(DriveError, match="stands at 4.0000 rev, not at 3.0000 rev"):
        confirm_own_target(_Axis(65536), _plan(3.0), _Status(4.0), "move")
    # Position not readable: the drive's set point must still be ours.
    confirm_own_target(_Axis(65536), _plan(None), _Status(None), "move")
    with pytest.raises(DriveError, match="set point 131072, not for 65536"):
        confirm_own_target(_Axis(131072), _plan(None), _Status(None), "move")


# ---------------------------------------------------------------- through the real CLI
def _position() -> float:
    code, out, err = run_akdctl("--json", "status")
    assert code == 0, err
    return float(json.loads(out)["status"]["position_rev"])


@pytest.mark.slow
@pytest.mark.parametrize("target", ["sim?drive=profidrive", "sim?drive=cia402"])
def test_five_parallel_relative_moves_add_up_to_the_successes(target: str) -> None:
    assert run_akdctl("sim", "speed", "10").code == 0
    assert run_akdctl("-T", target, "--yes", "home", "--mode", "0" if "profidrive" in target else "35").code == 0
    start = _position()
    procs = [start_akdctl("-T", target, "--yes", "move", "--relative", "1") for _ in range(5)]
    pids = {p.pid for p in procs}
    results = [finish(p, timeout=60) for p in procs]
    moved = _position() - start
    successes = [r for r in results if r.code == 0]
    assert successes, [r.err for r in results]
    assert abs(moved - len(successes)) < 0.02, (moved, [(r.code, r.err) for r in results])
    for r in results:
        if r.code == 0:
            assert "target reached" in r.out
            continue
        assert r.code == 4, (r.code, r.err)
        owner = re.search(r"in use by pid (\d+) \(akdctl .*move --relative 1", r.err)
        # The owner's record can be empty for an instant while it takes or lets go of the lock: still a refusal.
        assert owner or "the axis is moving" in r.err or "just starting or ending" in r.err, r.err
        if owner:
            assert int(owner.group(1)) in pids


@pytest.mark.slow
def test_a_second_motion_is_refused_naming_the_owner_and_stop_is_not() -> None:
    assert run_akdctl("sim", "speed", "--realtime").code == 0
    jog = start_akdctl("--yes", "jog", "30", "--for", "30s")
    try:
        state = Path(os.environ["AKDCTL_STATE_DIR"]) / "owners"
        wait_until(lambda: any(read_owner(p).get("pid") == jog.pid for p in state.glob("*.lock")), "the jog owns the axis")
        owned = f"in use by pid {jog.pid} (akdctl --yes jog 30 --for 30s"
        code, _, err = run_akdctl("--yes", "move", "1", "--relative")  # the planner may see the motion first
        assert code == 4 and (owned in err or "the axis is moving" in err), err
        for args in (["enable"], ["pnu", "set", "1=0x047F"], ["sdo", "write", "0x6040:0", "15"]):
            code, _, err = run_akdctl("--yes", *args)
            assert code == 4 and owned in err, (args, err)
        code, _, err = run_akdctl("stop")
        assert code == 0, err
    finally:
        if jog.poll() is None:
            jog.send_signal(signal.SIGTERM)
        finish(jog)
    # The owner is gone with its process: the next command owns the axis.
    assert run_akdctl("--yes", "enable").code == 0
