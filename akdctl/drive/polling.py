"""How often a wait asks the drive for its status: fast after a command or a change, then a steady rate.

Why one rule: every wait of the axis (a state change, a mode switch, a motion to its end) polls the drive, and a
fixed 50 ms pause made each of them return up to 50 ms after the drive was done - for a short move, and for every
motion on the simulator at 100× or 1000×, that pause was most of the command's time. Polling fast all the time is
no answer either: a real drive that homes for half a minute must not be asked hundreds of times a second.

The rule (:class:`Poll`):

* the first pause after a command is ``POLL_FIRST_S`` (2 ms) and each further pause is ``POLL_GROWTH`` (1.25×)
  longer, up to the steady pause ``POLL_S`` (50 ms): what ends quickly is seen quickly, what takes long is polled
  at 20 reads/s as before;
* a change of the status word starts the fast phase again - a drive in a transition (standstill, target reached,
  homing attained) is near the end of it - but at most once per ``POLL_BURST_S`` (0.25 s), so a word that
  flickers cannot keep the polling fast;
* a pause is never shorter than the last status read took, so a slow link spends at most half its time polling;
* a drive whose time runs faster than the wall clock (``time_scale`` > 1: only the simulator under ``sim speed``)
  has every pause shortened by that factor, down to ``POLL_MIN_S`` (0.5 ms), and no pause tied to the read's
  length: there is no bus to spare, and at 1000× a wall millisecond is a virtual second of motion.

On a real drive (time scale 1) that is at most 15 reads in the first ~0.2 s after a command or a change of the
status word (~70 reads/s on average there), then at most 20 reads/s; whatever the word does, at most 16 reads in any
0.25 s (64 reads/s), and never more than one read per read time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from time import monotonic, sleep
from typing import TypeVar

T = TypeVar("T")

POLL_FIRST_S = 0.002
POLL_S = 0.05
POLL_GROWTH = 1.25
POLL_MIN_S = 0.0005
POLL_BURST_S = 0.25


class Poll:
    """The pauses of one wait. Call :meth:`observe` with each status word read, :meth:`pause` between reads."""

    def __init__(self, time_scale: float = 1.0, deadline: float | None = None) -> None:
        scale = time_scale if math.isfinite(time_scale) and time_scale > 1.0 else 1.0
        self.first = max(POLL_MIN_S, POLL_FIRST_S / scale)
        self.steady = max(self.first, POLL_S / scale)
        self.next = self.first
        self.paced_by_reads = scale == 1.0
        self.deadline = deadline
        self._word: object = None
        self._read_s = 0.0
        self._burst = monotonic()

    def read(self, read_status: Callable[[], T]) -> T:
        """``read_status()``, timed (on a real drive the pause after it is at least as long as the read took)."""
        started = monotonic()
        try:
            return read_status()
        finally:
            self._read_s = monotonic() - started

    def observe(self, word: object) -> None:
        """The status just read: a change from the previous one starts the fast phase again."""
        if self._word is not None and word != self._word and monotonic() - self._burst >= POLL_BURST_S:
            self.next = self.first
            self._burst = monotonic()
        self._word = word

    def pause(self) -> None:
        """Sleep until the next read (never past the deadline), then lengthen the following pause."""
        wait = max(self.next, self._read_s) if self.paced_by_reads else self.next
        if self.deadline is not None:
            wait = min(wait, max(0.0, self.deadline - monotonic()))
        sleep(wait)
        self.next = min(self.steady, self.next * POLL_GROWTH)


#: The longest slice of a pause that must notice a stop request (Ctrl-C, SIGTERM) promptly.
STOP_SLICE_S = 0.05


def pause_unless_stopped(seconds: float, stopped: Callable[[], bool]) -> bool:
    """Sleep ``seconds`` in slices of at most :data:`STOP_SLICE_S`, checking ``stopped()`` before each; True as soon
    as it says stop (the rest is not slept), False after the whole pause. The one way a command waits on the wall
    clock while a signal may end it (``status --watch``, ``eip io --for``, a recipe's ``wait``)."""
    end = monotonic() + seconds
    while True:
        if stopped():
            return True
        left = end - monotonic()
        if left <= 0:
            return False
        sleep(min(STOP_SLICE_S, left))
