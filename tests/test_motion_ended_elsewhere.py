"""Issue 23 item 5: a move or jog stopped by another command is noticed within a poll or two and said in words,
not after its whole timeout; and this command then writes nothing (a stop or disable from elsewhere is obeyed).

Through the real CLI on the simulated drive in real time: a `move 10` at 60 rpm would take ~10 s; a `stop` or
`disable` from a second process ends it, and the move must exit within a second of that command's end.
"""

from __future__ import annotations

import fcntl
import os
import selectors
import signal
import subprocess
import time

import pytest

from akdctl.drive.axis.base import AxisStatus
from akdctl.drive.motion_run import ended_elsewhere
from akdctl.sim.drive import SimDrive
from tests.harness import finish, wait_until
from tests.harness import run_akdctl as run
from tests.harness import start_akdctl as popen


def _status(**kw: object) -> AxisStatus:
    base = dict(profile="cia402", state="operation enabled", state_text="operation enabled", word=0x0237,
                control=0x2F, mode=1, mode_text="profile position", enabled=True, fault=False, warning=False)
    base.update(kw)
    return AxisStatus(**base)  # type: ignore[arg-type]


def test_words_for_each_way_a_motion_is_ended_elsewhere() -> None:
    assert ended_elsewhere(_status(), 0x2F) is None
    assert "control word from 0x002F to 0x010F" in ended_elsewhere(_status(control=0x10F), 0x2F)
    assert "power stage was disabled" in ended_elsewhere(_status(enabled=False, state_text="switch on disabled"), 0x2F)
    assert "quick stop" in ended_elsewhere(_status(state_text="quick stop active"), 0x2F)
    assert "switch-off" in ended_elsewhere(_status(profile="profidrive", state="S5", state_text="switching off"), 0x43F)


def _moving() -> bool:
    with SimDrive("default").transaction() as model:
        return not model.component("motion").standstill


@pytest.mark.slow
@pytest.mark.parametrize("profile, home", [("profidrive", "0"), ("cia402", "35")])
@pytest.mark.parametrize("other", ["stop", "disable"])
def test_a_stop_or_disable_from_a_second_process_ends_the_move_at_once(profile: str, home: str, other: str) -> None:
    target = f"sim?drive={profile}"
    proc, first = _move_under_way(target, home)
    try:
        assert run("-T", target, other).code == 0
        stopped = time.monotonic()
        result = finish(proc, timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    err = first + result.err
    assert time.monotonic() - stopped < 1.5, "the move waited after another command stopped it"
    assert result.code == 1, err
    assert "ended by something else" in err and "did not finish within" not in err
    assert "akdctl stop" in err or "disabled" in err


def _move_under_way(target: str, home: str) -> tuple[subprocess.Popen[str], str]:
    """A `move 10` at 60 rpm (~10 s) in real time on a homed axis, started in the background, once it moves and has
    made its first poll (its first progress line, returned): that poll keeps the control word the move left, which
    the second command then changes. Without that wait a loaded host once ran the whole `stop` before the move's
    first poll, so the move took the stopped control word for its own."""
    assert run("sim", "speed", "--realtime").code == 0
    assert run("-T", target, "-y", "home", "--mode", home).code == 0
    proc = popen("-T", target, "-y", "move", "10", "--velocity", "60")
    try:
        wait_until(_moving, "the move to start")
        return proc, _first_line(proc, timeout=20.0)
    except BaseException:
        proc.kill()
        proc.wait(10)
        raise


def _first_line(proc: subprocess.Popen[str], timeout: float) -> str:
    """The first line the background CLI writes to stderr, waited for at most ``timeout`` s."""
    assert proc.stderr is not None
    with selectors.DefaultSelector() as selector:
        selector.register(proc.stderr, selectors.EVENT_READ)
        if not selector.select(timeout):
            pytest.fail(f"the move wrote no progress line within {timeout:g} s")
    line = proc.stderr.readline()
    assert line.startswith("akdctl: move to "), line
    return line


@pytest.mark.slow
@pytest.mark.parametrize("profile, home", [("profidrive", "0"), ("cia402", "35")])
def test_a_move_that_polls_only_after_the_whole_stop_still_says_it_was_ended_elsewhere(profile: str,
                                                                                        home: str) -> None:
    """A loaded host can hold the move's process for the whole of another command's ``stop``: the move then never
    sees the stop's halt word, only what the stop left. That must still read as ended elsewhere, not as a "target
    reached" somewhere else (CiA 402 once left the very control word an absolute move leaves, 0x002F). The move is
    held with SIGSTOP across the stop, so the case is made, not waited for."""
    target = f"sim?drive={profile}"
    proc, first = _move_under_way(target, home)
    try:
        _pause_outside_the_drive_lock(proc)
        try:
            assert run("-T", target, "stop").code == 0
        finally:
            os.kill(proc.pid, signal.SIGCONT)
        result = finish(proc, timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    err = first + result.err
    assert result.code == 1, err
    assert "ended by something else" in err and "akdctl stop" in err, err


def _pause_outside_the_drive_lock(proc: subprocess.Popen[str]) -> None:
    """SIGSTOP the move at a moment it does not hold the simulated drive's lock (held, it would lock out the
    ``stop`` under test): stopped inside a transaction, it is let go for a moment and stopped again."""
    deadline = time.monotonic() + 20.0
    fd = os.open(SimDrive("default").lock_path, os.O_RDWR)
    try:
        while True:
            os.kill(proc.pid, signal.SIGSTOP)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.kill(proc.pid, signal.SIGCONT)
                assert time.monotonic() < deadline, "the move held the drive's lock for 20 s"
                time.sleep(0.005)
                continue
            fcntl.flock(fd, fcntl.LOCK_UN)
            return
    finally:
        os.close(fd)
