"""A served drive keeps its state lock between requests and hands it over (``SimDrive.serve_faces``, issue 29.3).

What must hold: the served drive answers without taking the lock per request, yet every other process still gets
the drive when it asks (within its own lock timeout), and the served drive sees what that process saved before it
answers its next request; parallel writers beside it lose no update; a locker that does not ask, and a removed lock
file, are not locked out for good.
"""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from akdctl.sim.drive import SimDrive
from tests.harness import ROOT, akdctl_env, wait_until

READ_PNU_930 = bytes.fromhex("01 01 00 01 10 01 03 A2 00 00")
READ_PNU_1005 = bytes.fromhex("01 01 00 01 10 01 03 ED 00 00")


def _set_930(value: int) -> bytes:
    from akdctl.protocol import bmp

    return bmp.encode_request(bmp.ParameterRequest(1, bmp.REQ_CHANGE, 0, (bmp.ParameterAddress(930),),
                                                   (bmp.ParameterValue.of(bmp.Format.WORD, value),)))


def _locked_elsewhere(path: Path) -> bool:
    """Whether another open file holds the flock on ``path`` (tried without waiting)."""
    fd = os.open(path, os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def _served() -> SimDrive:
    drive = SimDrive("default")
    drive.serve_faces()
    return drive


def test_a_served_drive_keeps_its_lock_and_a_plain_one_does_not(isolated_env: Path) -> None:
    plain, served = SimDrive("plain"), _served()
    plain.handle_bmp(READ_PNU_930)
    served.handle_bmp(READ_PNU_930)
    try:
        assert not _locked_elsewhere(isolated_env / "sim-plain.lock")
        assert _locked_elsewhere(isolated_env / "sim-default.lock")  # kept between requests
    finally:
        served.close()
    assert not _locked_elsewhere(isolated_env / "sim-default.lock")


def test_the_served_drive_sees_each_write_of_another_drive_before_its_next_answer(isolated_env: Path) -> None:
    """Another ``SimDrive`` (its own lock descriptor, as another process has) asks for the kept lock, writes, and
    the served drive's very next request answers with that write; and the other way round."""
    served, other = _served(), SimDrive("default")
    try:
        current = served.handle_bmp(READ_PNU_930)[-1]
        for _ in range(6):
            theirs = {1: 2, 2: 1}[current]
            other.handle_bmp(_set_930(theirs))
            assert served.handle_bmp(READ_PNU_930)[-1] == theirs
            current = {1: 2, 2: 1}[theirs]
            served.handle_bmp(_set_930(current))
            assert other.handle_bmp(READ_PNU_930)[-1] == current
    finally:
        served.close()


@pytest.mark.slow
def test_a_cli_process_writes_beside_a_busy_served_drive(isolated_env: Path) -> None:
    """``akdctl pnu set`` in another process while the served drive answers requests without pause: the command
    gets the drive, and the served drive's next answer after the command returned carries the new value."""
    served = _served()
    stop = threading.Event()
    answers: list[int] = []

    def serve() -> None:
        while not stop.is_set():
            answers.append(served.handle_bmp(READ_PNU_930)[-1])

    thread = threading.Thread(target=serve)
    thread.start()
    try:
        for value in (2, 0):
            result = subprocess.run([sys.executable, "-m", "akdctl", "pnu", "set", f"930={value}"], cwd=ROOT,
                                    env=akdctl_env(), capture_output=True, text=True, timeout=60, check=False)
            assert result.returncode == 0, result.stderr
            count = len(answers)
            wait_until(lambda count=count: len(answers) > count + 1, "the served drive's next answer")
            assert answers[count + 1] == value
    finally:
        stop.set()
        thread.join(30)
        served.close()


_BUMP = """
import sys
from akdctl.sim.drive import SimDrive
drive = SimDrive("default")
for _ in range(int(sys.argv[1])):
    with drive.transaction() as model:
        model.set_stored_pnu(1005, [model.stored_pnu(1005)[0] + 1])
"""


@pytest.mark.slow
def test_twenty_writer_processes_beside_a_served_drive_lose_no_update(isolated_env: Path) -> None:
    """20 processes increment one PNU while the served drive answers reads of it without pause and increments it
    too: no update is lost, and the served drive never answers an older value after a newer one."""
    rounds, mine = 10, 30
    with SimDrive("default").transaction() as model:
        model.set_stored_pnu(1005, [0])
    served = _served()
    served.lock_timeout = 30.0  # this test counts updates; a face's "busy" after 0.5 s is another test's subject
    stop = threading.Event()
    seen: list[int] = []

    def serve() -> None:
        while not stop.is_set():
            seen.append(int.from_bytes(served.handle_bmp(READ_PNU_1005)[-2:], "big"))

    thread = threading.Thread(target=serve)
    thread.start()
    procs = [subprocess.Popen([sys.executable, "-c", _BUMP, str(rounds)], cwd=ROOT, env=akdctl_env())
             for _ in range(20)]
    try:
        for _ in range(mine):
            with served.transaction() as model:
                model.set_stored_pnu(1005, [model.stored_pnu(1005)[0] + 1])
    finally:
        codes = [p.wait(timeout=120) for p in procs]
        stop.set()
        thread.join(30)
    try:
        assert codes == [0] * 20
        assert seen == sorted(seen), "the served drive answered an older state after a newer one"
        with served.transaction() as model:
            assert model.stored_pnu(1005) == [20 * rounds + mine]
    finally:
        served.close()
    with SimDrive("default").transaction() as model:
        assert model.stored_pnu(1005) == [20 * rounds + mine]


def test_a_locker_that_does_not_ask_gets_the_lock_once_the_served_drive_is_idle(isolated_env: Path) -> None:
    served = _served()
    served.handle_bmp(READ_PNU_930)
    fd = os.open(isolated_env / "sim-default.lock", os.O_RDWR)
    try:
        wait_until(lambda: not _try_flock(fd), "the idle served drive to let go of its lock", timeout=10)
        fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
        served.close()


def _try_flock(fd: int) -> bool:
    """True while the lock is held elsewhere; False once this descriptor took it."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    return False


def test_a_removed_lock_file_is_let_go_by_the_served_drive(isolated_env: Path) -> None:
    """Someone empties the state directory while the served drive keeps the lock: it lets go of the old file and
    answers from the state every other process sees (factory state)."""
    served = _served()
    try:
        served.handle_bmp(_set_930(2))
        for path in isolated_env.iterdir():
            path.unlink()
        wait_until(lambda: served.handle_bmp(READ_PNU_930)[-1] == 1 and (isolated_env / "sim-default.lock").exists(),
                   "the served drive to answer from the new state", timeout=10)
    finally:
        served.close()
