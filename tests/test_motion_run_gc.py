"""MotionRun freezes what existed when a motion started (drive/motion_run.py) and hands it back afterwards.

The freeze only changes which objects the garbage collector walks during the run; a host process (the tests, a line
run's worker, the shell) must get its collector back as it was, whether the motion succeeded, failed or was stopped.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from typing import Any

import pytest

from akdctl.drive.axis.base import AxisStatus
from akdctl.drive.motion_run import MotionRun
from akdctl.drive.polling import Poll
from akdctl.errors import DriveError


def _status() -> AxisStatus:
    return AxisStatus(profile="profidrive", state="S4", state_text="operation", word=0x0337, control=0x040F, mode=2,
                      mode_text="position", enabled=True, fault=False, warning=False)


class _Axis:
    """Reports a running motion; records the stops and the freeze count each poll saw."""

    def __init__(self) -> None:
        self.frozen_seen: list[int] = []
        self.stops = 0

    def poll(self) -> Poll:
        return Poll(1000.0)

    def read_motion_status(self) -> AxisStatus:
        self.frozen_seen.append(gc.get_freeze_count())
        return _status()

    def safe_stop(self) -> tuple[Any, str]:
        self.stops += 1
        return None, "the axis was stopped"


@pytest.fixture
def unfrozen() -> Iterator[None]:
    frozen = gc.get_freeze_count()
    gc.unfreeze()
    yield
    if frozen:
        gc.freeze()


def _finish_after(polls: int, outcome: bool | None = True) -> Any:
    seen = []

    def finished(status: AxisStatus) -> bool | None:
        seen.append(status)
        return outcome if len(seen) >= polls else None

    return finished


def test_the_polls_run_frozen_and_the_collector_is_handed_back(unfrozen: None) -> None:
    axis = _Axis()
    run = MotionRun(axis, lambda: False)  # type: ignore[arg-type]
    run.run(lambda: None, _finish_after(3), deadline_s=5.0, what="homing")
    assert len(axis.frozen_seen) == 3 and min(axis.frozen_seen) > 0
    assert gc.get_freeze_count() == 0


@pytest.mark.parametrize("how", ["failed", "error", "interrupted"])
def test_the_collector_is_handed_back_when_the_motion_ends_badly(unfrozen: None, how: str) -> None:
    axis = _Axis()
    finished: Any = _finish_after(2, False)
    if how == "error":
        def finished(status: AxisStatus) -> bool | None:
            raise DriveError("lost the drive")
    interrupted = (lambda: len(axis.frozen_seen) >= 2) if how == "interrupted" else (lambda: False)
    with pytest.raises(Exception) as caught:
        MotionRun(axis, interrupted).run(lambda: None, finished, deadline_s=5.0,  # type: ignore[arg-type]
                                         what="homing")
    assert type(caught.value).__name__ in ("DriveError", "Interrupted")
    assert axis.stops == 1  # the stop-on-exit safety still ran
    assert gc.get_freeze_count() == 0


def test_a_host_that_froze_objects_keeps_them_frozen(unfrozen: None) -> None:
    gc.freeze()
    before = gc.get_freeze_count()
    axis = _Axis()
    run = MotionRun(axis, lambda: False)  # type: ignore[arg-type]
    run.run(lambda: None, _finish_after(1), deadline_s=5.0, what="homing")
    assert gc.get_freeze_count() >= before
    gc.unfreeze()
