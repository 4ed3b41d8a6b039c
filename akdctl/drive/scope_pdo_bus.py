"""The bus under the scope's pdo source: the raw master cycles the slave's process data in SAFE-OP.

Why SAFE-OP and not OP: in SAFE-OP the slave's inputs (TxPDO) are valid and refreshed while its outputs are not
applied (ETG.1000.6 state machine), so the all-zero RxPDO the master must keep writing never reaches the drive.
In OP the same zeros would be the drive's controlword and set points every cycle (a mapped controlword wins over
SDO writes, SPEC-NOTES 23): the axis would be disabled under a recorded jog. So the recording needs no consent of
its own, and a recorded motion is the same SDO-commanded jog as for the other sources, behind the one motion gate.
Whether a real AKD refreshes SM3 in SAFE-OP while SM2 is written but not applied is [I] (foe-alias-recorder.md
hardware check 4); the simulator does.

Why synchronous (one exchange inside each :meth:`BusInputs.next_inputs`, no thread): the master's socket and its
frame index are not shared between threads, and the bus clock is simply the cycle number times the cycle time.
The host paces the cycles against the monotonic clock; a cycle it reaches too late is skipped (its number is not
used), so a late host shows as gaps, never as squeezed time. SDO traffic between cycles (a recorded jog starting
or ending) delays the next cycle in the same way.

The steps (bring-up, the verdict on each cycle's working counter and AL status, taking the slave back to PRE-OP
with outputs 0 whatever ended the run, Ctrl-C included) are ``ecat pdo watch``'s: drive/ecat_pdo_watch.py.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from types import TracebackType
from typing import Any

from akdctl.drive.ecat_pdo_watch import enter, leave, left_state, wkc_dropped
from akdctl.errors import NoAnswer
from akdctl.protocol import ethercat as ec

#: How often the AL status rides along in the cycle's frame (a working-counter drop is seen at once anyway).
STATUS_EVERY_S = 0.1
#: Cycles exchanged and dropped after SAFE-OP is reached, before cycle 0: the first input images can predate the
#: slave's first application cycle (all zero in the simulator, whose task runs every 4 ms) [I: how long a real
#: AKD takes is not documented; 20 ms is five of its slowest usual cycles].
WARMUP_S = 0.02


class BusInputs:
    """:class:`~akdctl.drive.scope_pdo.CyclicInputs` over our master's ``ProcessDataCycle`` (``Connection.
    process_data``): a context manager that takes the slave to SAFE-OP on entry and back to PRE-OP on exit."""

    def __init__(self, cycle: Any, cycle_s: float, clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep, lost_limit_s: float = 1.0) -> None:
        self.cycle = cycle
        self.cycle_s = cycle_s
        #: frames that did not come back (each a gap); the cycle counts as stopped after ``lost_limit_s`` of them
        self.lost = 0
        self.lost_limit_s = lost_limit_s
        self._last_good: float | None = None
        self._clock, self._sleep = clock, sleep
        self._zeros = bytes(cycle.rx_bytes)
        self._expected_wkc: int = cycle.safeop_wkc  # (fixed by the mapping: read once, not per cycle)
        self.t0: float | None = None  # host instant of bus cycle 0
        self._number = -1
        self._next_status = 0.0

    def __enter__(self) -> "BusInputs":
        try:
            enter(self.cycle, ec.AlState.SAFEOP)
            for _ in range(max(1, round(WARMUP_S / self.cycle_s))):
                self._sleep(self.cycle_s)
                self.cycle.exchange(self._zeros, with_status=False)
        except BaseException:
            leave(self.cycle)
            raise
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        leave(self.cycle)

    def bus_time(self, host_t: float) -> float:
        """The bus time (s since cycle 0) of a host monotonic instant."""
        return host_t - (self.t0 if self.t0 is not None else host_t)

    def next_inputs(self, timeout: float) -> tuple[int, bytes]:
        """Wait for the next cycle's slot, exchange (outputs 0), judge the working counter and, every
        :data:`STATUS_EVERY_S`, the AL status: (cycle number, TxPDO image). A lost frame is FrameLost after the
        master's frame timeout (exit 3), a working-counter drop CommError (exit 3), the slave out of SAFE-OP a
        DriveError naming its AL status code (exit 1)."""
        cycle, clock = self.cycle, self._clock
        while True:
            # The next cycle's slot, waited for; a slot already past is skipped (late: the slots passed are gaps).
            now = clock()
            number = self._number + 1
            t0 = self.t0
            if t0 is None:
                self.t0 = self._last_good = now
                number = 0
            else:
                due = t0 + number * self.cycle_s
                if now < due:
                    self._sleep(due - now)
                    now = clock()
                else:
                    number = max(number, int((now - t0) / self.cycle_s))
            check = now >= self._next_status
            try:
                inputs, wkc, al = cycle.exchange(self._zeros, check)
                break
            except NoAnswer:
                # one lost frame is one gap (a loaded host or wire); frames lost for lost_limit_s: the cycle stopped
                self.lost += 1
                self._number = number
                if self._last_good is None or clock() - self._last_good > self.lost_limit_s:
                    raise
        self._last_good = now
        expected = self._expected_wkc
        if not check and wkc == expected:  # the usual cycle: nothing more to judge
            self._number = number
            return number, inputs
        if check:
            self._next_status = now + STATUS_EVERY_S
        if al is None and wkc != expected:
            al = cycle.exchange(self._zeros)[2]  # why did it drop: a slave out of SAFE-OP says so
        if al is not None:  # read every STATUS_EVERY_S, or after a working-counter drop
            left = left_state(cycle, al, ec.AlState.SAFEOP)
            if left is not None:
                raise left
        if wkc != expected:
            raise wkc_dropped(cycle, wkc, expected)
        self._number = number
        return number, inputs


__all__ = ["STATUS_EVERY_S", "WARMUP_S", "BusInputs"]
