"""Running one motion to its end: stop the axis on Ctrl-C, on any error and at the deadline.

Beside the planner (drive/motion_plan.py): the planner decides what may run, MotionRun supervises it.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from akdctl.drive.axis.base import Axis, AxisStatus
from akdctl.errors import (
    AkdError,
    DriveError,
    DriveFault,
    Interrupted,
)


class MotionRun:
    """Run one motion to its end, stopping the axis on Ctrl-C, on any error, and at the deadline.

    ``interrupted`` is a callable the CLI's signal handler flips; it is checked between polls
    so a Ctrl-C never lands in the middle of a request.
    """

    def __init__(self, axis: Axis, interrupted: Callable[[], bool],
                 progress: Callable[[AxisStatus], None] | None = None) -> None:
        self.axis = axis
        self.interrupted = interrupted
        self.progress = progress

    def _stop_and_raise(self, exc: AkdError) -> None:
        _, outcome = self.axis.safe_stop()
        exc.details.setdefault("stop", outcome)
        if "stop" not in exc.message:
            exc.message = f"{exc.message} ({outcome})"
        raise exc

    def run(self, start: Callable[[], None], finished: Callable[[AxisStatus], bool | None], *,
            deadline_s: float, what: str, on_deadline: str = "error") -> AxisStatus:
        """``start`` then poll ``finished`` (True done / False failed / None running) until ``deadline_s``.

        ``on_deadline='stop'`` ends the motion at the deadline as a success (jog --for).
        """
        with _collector_spares_older_objects():
            return self._run(start, finished, deadline_s, what, on_deadline)

    def _run(self, start: Callable[[], None], finished: Callable[[AxisStatus], bool | None], deadline_s: float,
             what: str, on_deadline: str) -> AxisStatus:
        try:
            start()
        except AkdError as exc:
            self._stop_and_raise(exc)
        end = time.monotonic() + deadline_s
        poll = self.axis.poll()
        ours: int | None = None  # the control word our start left; nothing of ours writes it while we poll
        while True:
            if self.interrupted():
                _, outcome = self.axis.safe_stop()
                raise Interrupted(f"interrupted during {what}; {outcome}", details={"stop": outcome})
            try:
                status = poll.read(self.axis.read_motion_status)
            except AkdError as exc:
                self._stop_and_raise(exc)
            poll.observe(status.word)
            if self.progress is not None:
                self.progress(status)
            if status.fault:
                self.axis.safe_stop()
                raise DriveFault(f"drive fault during {what}: {status.fault_summary()}",
                                 details={"faults": status.faults})
            if ours is None:
                ours = status.control
            cause = ended_elsewhere(status, ours)
            if cause is not None:
                # Nothing is written: a stop or disable from elsewhere is obeyed, never undone by our stop.
                raise DriveError(f"{what} ended by something else: {cause}; "
                                 f"{'the axis is at standstill' if status.standstill else 'the axis is stopping'}",
                                 details={"ended_by": cause, "state": status.state, "word": status.word,
                                          "control": status.control})
            try:
                result = finished(status)
            except AkdError as exc:
                self._stop_and_raise(exc)
            if result is True:
                return status
            if result is False:
                self._stop_and_raise(DriveError(f"{what} failed: the drive ended it without success "
                                                f"(state {status.state}, word 0x{status.word:04X})"))
            if time.monotonic() > end:
                if on_deadline == "stop":
                    return status
                self._stop_and_raise(DriveError(f"{what} did not finish within {deadline_s:.1f} s"))
            poll.pause()


@contextmanager
def _collector_spares_older_objects() -> Iterator[None]:
    """While a motion runs, the garbage collector leaves alone every object that existed when it started.

    Why: a poll of a fast motion (the simulator at 1000x) takes about a millisecond, and a collection of the middle
    generation that lands in it walks whatever the command built before - the catalogue it just parsed, the click
    tree - for about 2.5 ms, which is when the command sees the motion end (measured: benchmarks row home). Nothing of
    that is garbage the loop could free. Frozen (``gc.freeze``), those objects are skipped by every collection of the
    run; what the polls create is still collected as before. Afterwards they are handed back to the collector
    (``gc.unfreeze``), unless the host process had frozen objects of its own (then it keeps them frozen, as it chose).
    """
    frozen_before = gc.get_freeze_count()
    gc.freeze()
    try:
        yield
    finally:
        if not frozen_before:
            gc.unfreeze()


def ended_elsewhere(status: AxisStatus, ours: int) -> str | None:
    """Why a running motion stopped that this command did not stop, in words; None while it runs as commanded.

    Read from what every poll already has (no extra request): the power stage lost (another command's
    ``disable``, a lost hardware enable, STO), a quick stop, or a control word that is no longer the one our
    start left (``akdctl stop`` from a second shell, another master). A CIP axis reports no control word (0):
    only the first two apply there.
    """
    if not status.enabled:
        return ("the power stage was disabled (a 'disable' from another command or master, a lost hardware "
                f"enable or safe torque off; state {status.state_text})")
    if "quick stop" in status.state_text.lower() or status.state_text == "switching off":
        return f"a quick stop or switch-off is active (from another command or master; state {status.state_text})"
    if status.control != ours:
        return (f"another command or master changed the control word from 0x{ours:04X} to 0x{status.control:04X} "
                "(e.g. 'akdctl stop' from a second shell)")
    return None
