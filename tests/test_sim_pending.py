"""The lock file's pending state (``akdctl/sim/drive.py``): a motion's changes are not saved as a state file each.

The contract: every other process sees exactly the drive it saw when each change saved the state file -- the same
answers, the same model (bit for bit: clock, position, homing flags, the watchdog, faults) -- mid-motion, after
another process read or wrote, after the polls stopped long enough for the watchdog, and after the command ended
the motion. Each scenario runs twice on a fake wall clock, once as the store runs and once with ``PENDING_MAX = 0``
(every change saved, as before the pending state), and the two runs must agree on everything an observer sees.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from akdctl.catalog import pnus
from akdctl.protocol import bmp
from akdctl.sim import drive as sim_drive
from akdctl.sim.drive import SimDrive

BASE = 0x0406  # STW1: control by PLC, no coast stop, no quick stop
OPERATE = BASE | 0x0009  # ON + enable operation
START_HOMING = 1 << 11
ZSW1_HOME_POSITION_SET = 1 << 11


def _change(pnu: int, value: int) -> bytes:
    return bmp.encode_request(bmp.ParameterRequest(1, bmp.REQ_CHANGE, 0, (bmp.ParameterAddress(pnu),),
                                                   (bmp.ParameterValue.of(pnus.lookup(pnu).wire_format, value),)))


def _read(*numbers: int) -> bytes:
    return bmp.encode_request(bmp.ParameterRequest(1, bmp.REQ_READ, 0,
                                                   tuple(bmp.ParameterAddress(p) for p in numbers)))


POLL = _read(2, 1, 930, 6, 52, 1002, 28)  # what the PROFIdrive axis reads per status poll
START = [_change(930, 2), _change(1, BASE), _change(1, OPERATE), _change(1001, 1), _change(1, OPERATE),
         _change(1, OPERATE | START_HOMING)]


def _zsw1(answer: bytes) -> int:
    first = bmp.decode_response(answer).results[0]
    assert isinstance(first, bmp.ParameterValue)
    return int(first.values[0])


class _Run:
    """One scenario's run on a fake wall clock in ``directory``; ``seen`` is what observer processes saw."""

    def __init__(self, directory: Path, pending_max: int, monkeypatch: pytest.MonkeyPatch) -> None:
        monkeypatch.setattr(sim_drive, "PENDING_MAX", pending_max)
        self.now = 1_700_000_000.0
        monkeypatch.setattr(sim_drive, "time", SimpleNamespace(time=lambda: self.now, monotonic=time.monotonic,
                                                               sleep=time.sleep))
        self.saves = 0
        save = SimDrive._save

        def counted(drive: SimDrive, model: Any, meta: dict[str, Any]) -> None:
            self.saves += 1
            save(drive, model, meta)

        monkeypatch.setattr(SimDrive, "_save", counted)
        self.directory = directory
        self.seen: list[Any] = []
        self.poller = SimDrive("default", directory)

    def request(self, drive: SimDrive, request: bytes, wall_s: float) -> bytes:
        self.now += wall_s
        return drive.handle_bmp(request)

    def observe(self, what: str) -> None:
        """Another process opens the drive now and looks without advancing: the whole model and its wall time."""
        other = SimDrive("default", self.directory)
        with other.transaction(advance=False) as model:
            self.seen.append((what, json.dumps(model.to_state(), sort_keys=True), other.meta["wall"]))
        other.close()

    def other_request(self, what: str, request: bytes, wall_s: float) -> None:
        """Another process (``akdctl status``, ``pnu set``) sends one request now."""
        other = SimDrive("default", self.directory)
        self.seen.append((what, self.request(other, request, wall_s).hex()))
        other.close()


def _homing_with_observers(run: _Run) -> None:
    run.poller.set_time_scale(100.0)  # the homing ends after about 20 of the polls
    for request in START:
        run.request(run.poller, request, 0.001)
    for i in range(40):
        answer = run.request(run.poller, POLL, 0.0013)
        run.seen.append(("poll", answer.hex()))
        run.observe(f"after poll {i}")
        if i % 9 == 4:
            run.other_request(f"another process reads after poll {i}", POLL, 0.0004)
        if i == 22:
            run.other_request("another process writes", _change(1005, 300), 0.0002)
    run.request(run.poller, _change(1, OPERATE), 0.0005)  # the end of the homing: bit 11 dropped (a write)
    run.observe("after the homing's end")


def test_observers_see_what_they_saw_when_every_poll_saved(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pending = _Run(tmp_path / "pending", sim_drive.PENDING_MAX, monkeypatch)
    _homing_with_observers(pending)
    pending_saves = pending.saves  # (the next run's counter wraps this one's)
    saving = _Run(tmp_path / "saving", 0, monkeypatch)
    _homing_with_observers(saving)
    assert pending.seen == saving.seen
    # the scenario means something: the axis moved between polls, the homing finished within it ...
    polls = [bytes.fromhex(seen[1]) for seen in pending.seen if seen[0] == "poll"]
    states = [seen[1] for seen in pending.seen if seen[0].startswith("after poll")]
    assert len(set(states)) > 30
    assert not _zsw1(polls[0]) & ZSW1_HOME_POSITION_SET and _zsw1(polls[-1]) & ZSW1_HOME_POSITION_SET
    # ... and the lock file carried the moving axis's changes instead of a save each
    assert pending_saves < saving.saves - 20


def test_a_watchdog_trip_after_pending_polls_is_seen_alike(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The polls stop mid-motion: an observer a wall second and a half later sees the same watchdog stop, warning and
    position whether the polls pended or saved."""

    def scenario(run: _Run) -> None:
        run.poller.set_time_scale(10.0)  # a long homing: the watchdog's 1 s of wall time ends it
        for request in START:
            run.request(run.poller, request, 0.001)
        for _ in range(5):
            run.seen.append(("poll", run.request(run.poller, POLL, 0.05).hex()))
        run.now += 1.5
        run.other_request("another process reads", POLL, 0.0)
        run.observe("after the watchdog")

    pending = _Run(tmp_path / "pending", sim_drive.PENDING_MAX, monkeypatch)
    scenario(pending)
    saving = _Run(tmp_path / "saving", 0, monkeypatch)
    scenario(saving)
    assert pending.seen == saving.seen
    assert '"watchdog_tripped": true' in pending.seen[-1][1]


def _pending_bytes(directory: Path) -> int:
    return int.from_bytes((directory / "sim-default.lock").read_bytes()[32:36], "little")


def test_writes_at_rest_save_and_the_write_that_starts_a_motion_pends(tmp_path: Path,
                                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    run = _Run(tmp_path, sim_drive.PENDING_MAX, monkeypatch)
    run.poller.set_time_scale(10.0)
    for request in START[:-1]:  # mode, enable, homing mode: the drive stays at rest
        saves = run.saves
        run.request(run.poller, request, 0.001)
        assert run.saves == saves + 1 and _pending_bytes(tmp_path) == 0
    saves = run.saves
    run.request(run.poller, START[-1], 0.001)  # homing starts: the axis moves
    assert run.saves == saves and _pending_bytes(tmp_path) > 0
    lock = (tmp_path / "sim-default.lock").read_bytes()
    pending = json.loads(lock[40:40 + _pending_bytes(tmp_path)])
    with run.poller.transaction(advance=False) as model:
        assert pending == json.loads(json.dumps({**model.to_state(), "sim": run.poller.meta}))


def test_pending_changes_are_bounded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run = _Run(tmp_path, 4, monkeypatch)
    run.poller.set_time_scale(10.0)
    for request in START:
        run.request(run.poller, request, 0.001)
    saves, pending = run.saves, 1  # the homing's start pends
    for i in range(11):
        run.request(run.poller, POLL, 0.01)  # a homing at 10x runs longer than these reads
        if pending == 4:
            pending, saves = 0, saves + 1  # the fifth change in a row is saved, the pending state emptied
            assert _pending_bytes(tmp_path) == 0, i
        else:
            pending += 1
            assert _pending_bytes(tmp_path) > 0, i
        assert run.saves == saves, i
    assert saves - 2 == run.saves - 2 >= 0 and run.saves >= 2


def _homing_polled_and_ended(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple["_Run", int]:
    """A command's homing at 100x, polled until done, then its write that ends it (STW1 back to operation): that
    write pends, no save on the command's way out. The run and its saves so far."""
    run = _Run(tmp_path, sim_drive.PENDING_MAX, monkeypatch)
    run.poller.set_time_scale(100.0)
    for request in START:
        run.request(run.poller, request, 0.001)
    while not _zsw1(run.request(run.poller, POLL, 0.0013)) & ZSW1_HOME_POSITION_SET:
        pass
    saves = run.saves
    run.request(run.poller, _change(1, OPERATE), 0.0005)
    assert run.saves == saves and _pending_bytes(tmp_path) > 0
    return run, saves


def test_the_end_of_a_motion_pends_and_the_next_commands_first_write_saves(tmp_path: Path,
                                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    run, saves = _homing_polled_and_ended(tmp_path, monkeypatch)
    run.poller.close()
    run.observe("the next command loads")
    loaded = json.loads(run.seen[-1][1])["components"]["motion"]
    assert loaded["homed"] and loaded["homing_done"] and loaded["stw1"] == OPERATE  # the ended homing, our last write
    nxt = SimDrive("default", tmp_path)
    run.request(nxt, _change(1001, 3), 0.001)  # the next command's first write, at rest: saved, pending emptied
    assert run.saves == saves + 1 and _pending_bytes(tmp_path) == 0
    with SimDrive("default", tmp_path).transaction(advance=False) as model:
        assert model.stored_pnu(1001) == [3]


def test_reads_at_rest_pend_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run = _Run(tmp_path, sim_drive.PENDING_MAX, monkeypatch)
    run.request(run.poller, _change(930, 2), 0.001)
    token = (tmp_path / "sim-default.lock").read_bytes()
    for _ in range(20):
        run.request(run.poller, POLL, 0.01)
    assert (tmp_path / "sim-default.lock").read_bytes() == token


@pytest.mark.parametrize("damage", ["last byte", "cut short", "huge length"])
def test_a_damaged_pending_state_leaves_the_drive_as_last_saved(
        damage: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """What a machine crash can leave of a pending state (written without fsync): a changed byte, data cut short, a
    head announcing more than was written. The drive is then as its state file last saved it (the module doc's
    promise for a crash), not a corrupt state that only a reset ends."""
    run = _Run(tmp_path, sim_drive.PENDING_MAX, monkeypatch)
    run.poller.set_time_scale(10.0)
    for request in START:
        run.request(run.poller, request, 0.001)
    run.request(run.poller, POLL, 0.01)
    size = _pending_bytes(tmp_path)
    assert size > 0
    last_saved = tmp_path / "last-saved"  # the state file alone, loaded where no lock file announces anything
    last_saved.mkdir()
    (last_saved / "sim-default.json").write_bytes((tmp_path / "sim-default.json").read_bytes())
    head = sim_drive._HEAD_BYTES
    pending = json.loads((tmp_path / "sim-default.lock").read_bytes()[head:head + size])
    fd = os.open(tmp_path / "sim-default.lock", os.O_RDWR)
    try:
        if damage == "last byte":
            os.pwrite(fd, b"]", head + size - 1)  # its last byte ("}") changed: the CRC fails
        elif damage == "cut short":
            os.ftruncate(fd, head + size // 2)
        else:
            os.pwrite(fd, (sim_drive.MAX_STATE_BYTES + 1).to_bytes(4, "little"), sim_drive.TOKEN_BYTES)
    finally:
        os.close(fd)
    states = []
    for where in (tmp_path, last_saved):
        drive = SimDrive("default", where)
        try:
            with drive.transaction(advance=False) as model:
                states.append((model.to_state(), dict(drive.meta)))
        finally:
            drive.close()
    assert states[0] == states[1]
    del pending["sim"]
    assert json.loads(json.dumps(states[0][0])) != pending  # the homing's progress since the save: lost, as promised


def test_a_save_cut_short_leaves_the_pending_state_to_load(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A process dies between the new token and the new state file: the next one loads the pending state (the newest
    complete state), not the older state file."""
    run = _Run(tmp_path, sim_drive.PENDING_MAX, monkeypatch)
    run.poller.set_time_scale(10.0)
    for request in START:
        run.request(run.poller, request, 0.001)
    run.request(run.poller, POLL, 0.01)
    run.observe("before")
    file_state = (tmp_path / "sim-default.json").read_text()

    def killed(drive: SimDrive, model: Any, meta: dict[str, Any]) -> None:
        raise RuntimeError("killed while saving")

    monkeypatch.setattr(SimDrive, "_save", killed)
    other = SimDrive("default", tmp_path)
    with pytest.raises(RuntimeError), other.transaction() as model:  # a change outside a PROFIdrive request saves
        model.set_stored_pnu(1005, [300])
    other.close()
    assert (tmp_path / "sim-default.json").read_text() == file_state and _pending_bytes(tmp_path) > 0
    run.observe("after")
    assert run.seen[-1][1:] == run.seen[0][1:]


def test_only_the_write_right_after_the_polls_pends_at_rest(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A process that polled a motion (a recipe: a move, then parameter writes) pends the write that ends it; its
    next write at rest saves."""
    run, saves = _homing_polled_and_ended(tmp_path, monkeypatch)
    run.request(run.poller, _change(1005, 300), 0.0005)
    assert run.saves == saves + 1 and _pending_bytes(tmp_path) == 0
