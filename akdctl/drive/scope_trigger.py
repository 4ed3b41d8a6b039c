"""When a recording starts: one trigger grammar for every scope source.

Why one grammar: a technician asks "start when the velocity passes 100 rpm" or "start at the fault" the same way
whether the host polls, the drive's recorder samples or the PDO stream flows; the poll and PDO sources evaluate a
:class:`Trigger` on the host, the recorder source translates it into REC.TRIGTYPE/TRIGPARAM/TRIGVAL/TRIGSLOPE/
TRIGMASK (:meth:`Trigger.recorder_settings`).

Grammar (``--trigger``, a recipe's ``trigger``):

* ``immediate`` (default): the first sample;
* ``rise:SIGNAL:LEVEL`` / ``fall:SIGNAL:LEVEL``: the first sample at which SIGNAL crossed LEVEL upwards / downwards
  (an edge: a signal already above LEVEL at the start does not fire a ``rise``);
* ``above:SIGNAL:LEVEL`` / ``below:SIGNAL:LEVEL``: the first sample at which SIGNAL is above / below LEVEL (a level);
* ``bit:N`` / ``bit:N=0``: status-word bit N becomes 1 (or 0) (an edge of the CiA 402 statusword or ZSW1);
* ``fault``: the status word's fault bit (bit 3 in both) becomes 1.
"""

from __future__ import annotations

import math
from typing import Any

from akdctl.errors import UsageError
from akdctl.protocol.record import Record

KINDS = ("immediate", "rise", "fall", "above", "below", "bit")
FAULT_BIT = 3
TRIGGER_HELP = ("immediate | rise:SIGNAL:LEVEL | fall:SIGNAL:LEVEL | above:SIGNAL:LEVEL | below:SIGNAL:LEVEL | "
                "bit:N[=0|1] | fault")


class Trigger(Record):
    """``kind`` (KINDS); ``signal`` and ``level`` for the signal kinds; ``bit`` and ``state`` for ``bit``."""

    __slots__ = ("bit", "kind", "level", "signal", "state", "text")

    def __init__(self, kind: str = "immediate", signal: str | None = None, level: float = 0.0, bit: int = 0,
                 state: int = 1, text: str = "immediate") -> None:
        self.kind = kind
        self.signal = signal
        self.level = level
        self.bit = bit
        self.state = state
        self.text = text

    @property
    def on_status(self) -> bool:
        """Whether the trigger watches the status word (the source reads it beside the channels)."""
        return self.kind == "bit"

    def fires(self, previous: float | None, value: float) -> bool:
        """Whether this sample (``value``; ``previous`` the sample before, None for the first) fires."""
        kind = self.kind
        if kind == "immediate":
            return True
        if kind == "above":
            return value > self.level
        if kind == "below":
            return value < self.level
        if previous is None:
            return False
        if kind == "rise":
            return previous <= self.level < value
        if kind == "fall":
            return previous >= self.level > value
        mask = 1 << self.bit
        was, now = bool(int(previous) & mask), bool(int(value) & mask)
        return was != now and now == bool(self.state)

    def recorder_settings(self) -> list[tuple[str, str]]:
        """REC.* writes that make the drive's recorder fire on this trigger (type 5 bitmask: [I] newer firmware;
        a level kind becomes the drive's edge trigger, which fires on the crossing only: docs/scope.md)."""
        if self.kind == "immediate":
            return [("REC.TRIGTYPE", "0")]
        if self.kind == "bit":
            mask = 1 << self.bit
            return [("REC.TRIGTYPE", "5"), ("REC.TRIGPARAM", "DS402.STATUSWORD"), ("REC.TRIGMASK", str(mask)),
                    ("REC.TRIGVAL", str(mask if self.state else 0))]
        rising = self.kind in ("rise", "above")
        return [("REC.TRIGTYPE", "2"), ("REC.TRIGPARAM", str(self.signal)), ("REC.TRIGVAL", f"{self.level:g}"),
                ("REC.TRIGSLOPE", "1" if rising else "0")]

    def to_json(self) -> dict[str, Any]:
        return {"condition": self.text, "kind": self.kind, "signal": self.signal, "level": self.level,
                "bit": self.bit if self.kind == "bit" else None}


def parse_trigger(text: str | None) -> Trigger:
    """A trigger from its text (module doc); UsageError (exit 2) naming the grammar when it is not one."""
    raw = (text or "immediate").strip()
    low = raw.lower()
    if low in ("immediate", "now", ""):
        return Trigger()
    if low == "fault":
        return Trigger("bit", bit=FAULT_BIT, state=1, text="fault (status word bit 3)")
    kind, _, rest = raw.partition(":")
    kind = kind.lower()
    if kind == "bit":
        number, _, state = rest.partition("=")
        try:
            bit = int(number.strip())
            wanted = int(state.strip()) if state.strip() else 1
        except ValueError:
            raise UsageError(f"bad trigger {raw!r}: bit:N[=0|1] needs a bit number 0..15; "
                             f"triggers: {TRIGGER_HELP}") from None
        if not 0 <= bit <= 15 or wanted not in (0, 1):
            raise UsageError(f"bad trigger {raw!r}: bit number 0..15 and state 0 or 1; triggers: {TRIGGER_HELP}")
        return Trigger("bit", bit=bit, state=wanted, text=f"status word bit {bit} -> {wanted}")
    if kind in ("rise", "fall", "above", "below"):
        signal, _, level_text = rest.rpartition(":")
        try:
            level = float(level_text)
        except ValueError:
            level = math.nan
        if not signal.strip() or not math.isfinite(level):
            raise UsageError(f"bad trigger {raw!r}: {kind}:SIGNAL:LEVEL needs a signal and a finite level; "
                             f"triggers: {TRIGGER_HELP}")
        return Trigger(kind, signal=signal.strip(), level=level, text=f"{kind} {signal.strip()} {level:g}")
    raise UsageError(f"bad trigger {raw!r}; triggers: {TRIGGER_HELP}")


def check_pretrigger(percent: float, trigger: Trigger) -> float:
    """The pre-trigger share in percent (0..100); usage error outside; 0 for an immediate trigger."""
    if not math.isfinite(percent) or not 0 <= percent <= 100:
        raise UsageError(f"--pretrigger {percent:g} is outside 0..100 %")
    if trigger.kind == "immediate" and percent:
        raise UsageError("--pretrigger needs a trigger other than immediate (nothing happened before the start)")
    return percent
