"""Stop signals while the axis may move: SIGINT, SIGTERM and SIGHUP become a flag.

Why a flag: a signal must never land in the middle of a request (half a control
word sequence), so the handler only records it; the motion loop checks the flag
between requests, stops the axis (ramp, then quick stop) and raises
:class:`~akdctl.errors.Interrupted`. The handlers are installed even when the
signal was inherited as ignored (a background job started with ``&`` ignores
SIGINT): a motion must stop on every one of these signals.

Exit code: 128 + the signal number — 130 for SIGINT (Ctrl-C), 143 for SIGTERM,
129 for SIGHUP (README "Exit codes").
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator
from typing import Any

from akdctl.errors import Interrupted

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class StopFlag:
    """Callable "was a stop signal received?" for :class:`akdctl.drive.motion_run.MotionRun` and recipes."""

    def __init__(self) -> None:
        self.signum: int | None = None

    def __call__(self) -> bool:
        return self.signum is not None

    @property
    def name(self) -> str:
        return signal.Signals(self.signum).name if self.signum is not None else ""

    def mark(self, exc: Interrupted) -> Interrupted:
        """Give ``exc`` the exit code of the signal received (128 + number) and name it."""
        if self.signum is not None:
            exc.exit_code = 128 + self.signum  # type: ignore[misc]
            if self.name not in exc.message:
                exc.message = f"{exc.message} ({self.name})"
            exc.details.setdefault("signal", self.name)
        return exc


@contextlib.contextmanager
def stop_signals() -> Iterator[StopFlag]:
    """Install the handlers for the block; restore the previous ones (SIG_IGN included) afterwards."""
    flag = StopFlag()

    def handler(signum: int, frame: Any) -> None:
        if flag.signum is None:
            flag.signum = signum

    previous: dict[int, Any] = {}
    for sig in STOP_SIGNALS:
        try:
            previous[sig] = signal.signal(sig, handler)
        except (ValueError, OSError):  # not the main thread (a command called from a test thread)
            pass
    try:
        yield flag
        if flag():
            raise flag.mark(Interrupted("interrupted; the motion had already ended"))
    except Interrupted as exc:
        raise flag.mark(exc)
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
