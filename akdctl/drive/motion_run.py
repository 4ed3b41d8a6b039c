"""Running one motion to its end: stop the axis on Ctrl-C, on any error and at the deadline.

Beside the planner (drive/motion_plan.py): the planner decides what may run, MotionRun supervises it.
"""

from __future__ import annotations

import time
from collections.abc import Callable

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
        try:
            start()
        except AkdError as exc:
            self._stop_and_raise(exc)
        end = time.monotonic() + deadline_s
        poll = self.axis.poll()
        while True:
            if self.interrupted():
                _, outcome = self.axis.safe_stop()
                raise Interrupted(f"interrupted during {what}; {outcome}", details={"stop": outcome})
            try:
                status = poll.read(self.axis.read_status)
            except AkdError as exc:
                self._stop_and_raise(exc)
            poll.observe(status.word)
            if self.progress is not None:
                self.progress(status)
            if status.fault:
                self.axis.safe_stop()
                raise DriveFault(f"drive fault during {what}: {status.fault_summary()}",
                                 details={"faults": status.faults})
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
