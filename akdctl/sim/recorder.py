"""The simulated AKD's recorder: REC.* with the drive's semantics, sampling the simulated motion.

Why here, and why sampled at exact virtual times: WorkBench's scope and every Telnet tool read the AKD's own
recorder (REC.*), which samples on the drive's 16 kHz base (62.5 us) every ``REC.GAP`` ticks. A recorder that
copied numbers once per request would show steps, not the ramp a technician looks for; so while the recorder runs,
:meth:`Recorder.advance` splits each advance of the model's clock at the sample instants and integrates the motion
up to each one before it samples. The signals are the model's live values, never stored numbers.

Facts (shared/reference/foe-alias-recorder.md §C1, akd-ascii-channel.md §2.3 and §7) [V unless marked]:

* base 16 kHz; ``REC.GAP`` 1..65535; 6 channels ``REC.CH1..6`` (``0``/``CLR``/``CLEAR`` frees one);
  ``REC.NUMPOINTS`` 1..10000 (10000 = aakd's "max buffer size" [I]);
* ``REC.TRIGTYPE`` 0 immediate, 1 next command, 2 parameter (``REC.TRIGPARAM``/``TRIGVAL``/``TRIGSLOPE``),
  3 boolean; 5 bitmask with ``REC.TRIGMASK`` (newer firmware, [I]); ``REC.TRIGPOS`` % pre-trigger (1..100);
* ``REC.STOPTYPE`` 0 one-shot, 1 continuous ring; ``REC.TRIG`` arms (clears old data); ``REC.DONE``,
  ``REC.ACTIVE``, ``REC.OFF``;
* retrieval: ``REC.RETRIEVE`` = ``Recording``, ``<N>,<gap>``, the channel names, N rows; ``REC.RETRIEVEHDR`` the
  header alone; ``REC.RETRIEVEDATA [index]`` rows in chunks of ``REC.RETRIEVESIZE`` continuing from the last index,
  one first line (its content is undocumented: here ``<first index>,<rows>`` [I]); an overflow error when a
  continuous recording overwrote rows not yet retrieved; ``REC.RETRIEVEFRMT`` 0 standard (``-0.086``), 1 internal
  (``F3-0x56``: 10^-3 times a signed hex integer; the default).

Simulator choices [I] (docs/scope.md): positions in revolutions and velocities in rpm (the model's units, not
UNIT.*), currents in A against a simulated 6 A peak; the error texts; a trigger is looked for only once the
pre-trigger part is full, so a recording always holds exactly NUMPOINTS rows; trigger type 1 fires at the next
command the ASCII face reports through :meth:`Recorder.note_command`; trigger type 3 fires when the parameter
becomes non-zero (slope 1) or zero (slope 0); type 5 when ``value & mask`` becomes equal to ``TRIGVAL & mask``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akdctl.sim.component import Component

if TYPE_CHECKING:
    from akdctl.sim.model import DriveModel

BASE_HZ = 16000
BASE_S = 1.0 / BASE_HZ
MAX_CHANNELS = 6
MAX_POINTS = 10000
MAX_GAP = 65535
#: The simulated drive's peak current (A) behind IL.FB / IL.CMD [I: a simulator value].
SIM_IPEAK_A = 6.0
#: An advance longer than this many sample instants integrates the earlier part in one step (a drive left alone
#: for hours must not cost hours of sampling); only the last instants are sampled.
MAX_SAMPLES_PER_ADVANCE = 2 * MAX_POINTS
TRIGGER_TYPES = (0, 1, 2, 3, 5)


class RecorderError(Exception):
    """A REC.* request the drive refuses; ``str()`` is the drive's error text (without ``Error:``)."""


def _signals() -> dict[str, tuple[Callable[[DriveModel], float], str]]:
    """The recordable signals: name -> (live value of the model, unit)."""
    from akdctl.sim.kinematics import FOLLOWING_LAG_S
    from akdctl.sim.power_states import ENABLED

    def axis(m: DriveModel) -> Any:
        return m.motion.axis

    def feedback_rpm(vel: float, acc: float) -> float:
        """The velocity the feedback shows: the command as it was one position-loop lag ago (never of the other
        sign: a start from rest lags, it does not reverse)."""
        fb = vel - acc * FOLLOWING_LAG_S
        return 0.0 if fb * vel < 0 or (vel == 0 and acc) else fb * 60.0

    def current(m: DriveModel) -> float:
        return m.motion._current_fraction() * SIM_IPEAK_A

    return {
        "VL.CMD": (lambda m: axis(m).vel * 60.0, "rpm"),
        "VL.FB": (lambda m: feedback_rpm(axis(m).vel, axis(m).acc_now), "rpm"),
        "PL.CMD": (lambda m: axis(m).pos + axis(m).offset, "rev"),
        "PL.FB": (lambda m: axis(m).pos + axis(m).offset - axis(m).following_error, "rev"),
        "PL.ERR": (lambda m: axis(m).following_error, "rev"),
        "IL.CMD": (current, "A"),
        "IL.FB": (current, "A"),
        "DS402.STATUSWORD": (lambda m: float(m.motion.cia.statusword()), ""),
        "DRV.ACTIVE": (lambda m: 1.0 if m.motion.state == ENABLED else 0.0, ""),
    }


_SIGNALS: dict[str, tuple[Callable[[DriveModel], float], str]] | None = None


def signals() -> dict[str, tuple[Callable[[DriveModel], float], str]]:
    global _SIGNALS
    if _SIGNALS is None:
        _SIGNALS = _signals()
    return _SIGNALS


def signal_unit(name: str) -> str | None:
    """The unit of a recordable signal (``""`` for a dimensionless one), None when it is not recordable."""
    entry = signals().get(name.upper())
    return None if entry is None else entry[1]


_SETTINGS: dict[str, tuple[float, float, float]] = {  # name -> (min, max, default)
    "GAP": (1, MAX_GAP, 1),
    "NUMPOINTS": (1, MAX_POINTS, 1000),
    "STOPTYPE": (0, 1, 0),
    "TRIGPOS": (1, 100, 10),
    "TRIGSLOPE": (0, 1, 1),
    "RETRIEVESIZE": (1, MAX_POINTS, 100),
    "RETRIEVEFRMT": (0, 1, 1),
    "TRIGMASK": (0, 0xFFFFFFFF, 0),
}


class Recorder(Component):
    """REC.* of one simulated drive (state persisted with the model, so a recording survives between processes)."""

    name = "recorder"
    FIELDS = ("settings", "channels", "trigtype", "trigparam", "trigval", "state", "next_t", "pre", "rows",
              "written", "trigger_index", "retrieved", "last", "command_seen")

    def __init__(self, model: DriveModel) -> None:
        super().__init__(model)
        self.settings = {k: v[2] for k, v in _SETTINGS.items()}
        self.channels: list[str] = [""] * MAX_CHANNELS
        self.trigtype = 0
        self.trigparam = "VL.FB"
        self.trigval = 0.0
        self.state = "idle"  # idle, armed (filling pre-trigger / waiting), recording, done
        self.next_t = 0.0  # virtual time of the next sample
        self.pre: list[list[float]] = []  # ring of pre-trigger rows while armed
        self.rows: list[list[float]] = []  # the recording (a ring of NUMPOINTS rows when continuous)
        self.written = 0  # rows recorded since the trigger (continuous: also those the ring overwrote)
        self.trigger_index = 0
        self.retrieved = 0  # REC.RETRIEVEDATA's next row (absolute, counted like ``written``)
        self.last: float | None = None  # the trigger signal's previous value (edges)
        self.command_seen = False

    # ------------------------------------------------------------------ helpers
    @property
    def active_channels(self) -> list[str]:
        return [c for c in self.channels if c]

    @property
    def gap_s(self) -> float:
        return self.settings["GAP"] * BASE_S

    @property
    def numpoints(self) -> int:
        return int(self.settings["NUMPOINTS"])

    @property
    def running(self) -> bool:
        return self.state in ("armed", "recording")

    def note_command(self) -> None:
        """The ASCII face handled a command that is not REC.* (trigger type 1 fires on it)."""
        if self.state == "armed" and self.trigtype == 1:
            self.command_seen = True

    # ------------------------------------------------------------------ time
    def advance(self, dt: float, step: Callable[[float], None]) -> None:
        """Advance the model by ``dt`` through ``step`` (the model's own advance), stopping at each sample instant
        to sample; without a running recording this is one ``step(dt)``."""
        clock = self.model.clock
        end = clock + dt
        if not self.running or self.next_t > end:
            step(dt)
            return
        instants = math.floor((end - self.next_t) / self.gap_s + 1e-9) + 1
        if instants > MAX_SAMPLES_PER_ADVANCE:  # skip ahead: integrate the early part at once
            skip = instants - MAX_SAMPLES_PER_ADVANCE
            target = self.next_t + skip * self.gap_s
            step(max(0.0, target - clock - self.gap_s))
            self.next_t = target
            clock = self.model.clock
        next_t, gap_s, taken = self.next_t, self.gap_s, 0
        axis = self.model.motion.axis
        while self.state in ("armed", "recording") and next_t <= end + 1e-12:
            if axis.gen is None and not axis.vel and not axis.acc_now:
                # at rest nothing changes between requests (motion starts only on one): integrate to the last
                # instant at once; every sample in between reads the same values it would have read
                count = math.floor((end - next_t) / gap_s + 1e-9) + 1
                last = next_t + (count - 1) * gap_s
                if last - clock > 0:
                    step(last - clock)
                    clock = self.model.clock
                for _ in range(count):
                    if self.state not in ("armed", "recording"):
                        break
                    self._sample()
                    taken += 1
                    next_t += gap_s
                continue
            piece = next_t - clock
            if piece > 0:
                step(piece)
                clock = self.model.clock
            self._sample()
            taken += 1
            next_t += gap_s
        self.next_t = next_t  # assigned once: a tracked field (sim/component.Tracked) costs a compare per write
        if taken:
            self.changed()  # the rows and the pre-trigger ring are containers: one revision bump per advance
        if end - clock > 0:
            step(end - clock)

    def _row(self) -> list[float]:
        table = signals()
        return [float(table[name][0](self.model)) for name in self.active_channels]

    def _trigger_value(self) -> float:
        entry = signals().get(self.trigparam.upper())
        return float(entry[0](self.model)) if entry else 0.0

    def _fires(self) -> bool:
        kind = self.trigtype
        if kind == 0:
            return True
        if kind == 1:
            return bool(self.command_seen)
        value = self._trigger_value()
        last, self.last = self.last, value
        if last is None:
            return False
        rising = self.settings["TRIGSLOPE"] == 1
        if kind == 2:
            level = self.trigval
            return (last < level <= value) if rising else (last > level >= value)
        if kind == 3:
            return (last == 0 and value != 0) if rising else (last != 0 and value == 0)
        mask = int(self.settings["TRIGMASK"])
        want = int(self.trigval) & mask
        return (int(last) & mask) != want and (int(value) & mask) == want

    def _sample(self) -> None:
        row = self._row()
        if self.state == "armed":
            pre_n = self.pre_points
            self.pre.append(row)
            if len(self.pre) > pre_n + 1:
                del self.pre[0]
            if len(self.pre) < pre_n + 1:  # the pre-trigger part must be full first (module doc)
                if self.trigtype >= 2:
                    self._fires()  # keep the edge detector current
                return
            if not self._fires():
                if len(self.pre) > pre_n:
                    del self.pre[0]
                return
            self.rows = list(self.pre)
            self.pre = []
            self.trigger_index = pre_n
            self.written = len(self.rows)
            self.state = "recording"
        else:
            if self.settings["STOPTYPE"] == 1 and len(self.rows) >= self.numpoints:
                del self.rows[0]
            self.rows.append(row)
            self.written += 1
        if self.settings["STOPTYPE"] == 0 and len(self.rows) >= self.numpoints:
            self.state = "done"

    @property
    def pre_points(self) -> int:
        if self.trigtype == 0:
            return 0
        return min(self.numpoints - 1, round(self.numpoints * self.settings["TRIGPOS"] / 100.0))

    # ------------------------------------------------------------------ commands
    def handle(self, name: str, arg: str | None) -> str:
        key = name.upper().removeprefix("REC.")
        arg = arg.strip() if arg is not None and arg.strip() else None
        if key in _SETTINGS:
            if arg is None:
                return _number(self.settings[key])
            self._refuse_while_running(key)
            low, high, _ = _SETTINGS[key]
            self.settings = {**self.settings, key: _int_arg(arg, low, high)}
            return ""
        if len(key) == 3 and key.startswith("CH") and key[2] in "123456":
            slot = int(key[2]) - 1
            if arg is None:
                return self.channels[slot] or "0"
            self._refuse_while_running(key)
            channels = list(self.channels)
            channels[slot] = "" if arg.upper() in ("0", "CLR", "CLEAR") else _signal_arg(arg)
            self.channels = channels
            return ""
        if key == "TRIGTYPE":
            if arg is None:
                return str(self.trigtype)
            self._refuse_while_running(key)
            value = _int_arg(arg, 0, 5)
            if value not in TRIGGER_TYPES:
                raise RecorderError(f"Value {value} is not a supported trigger type")
            self.trigtype = value
            return ""
        if key == "TRIGPARAM":
            if arg is None:
                return self.trigparam
            self._refuse_while_running(key)
            self.trigparam = _signal_arg(arg)
            return ""
        if key == "TRIGVAL":
            if arg is None:
                return _number(self.trigval)
            self._refuse_while_running(key)
            try:
                level = float(arg)
            except ValueError:
                raise RecorderError(f"Argument is not a number: {arg}") from None
            if not math.isfinite(level):
                raise RecorderError(f"Argument is not a number: {arg}")
            self.trigval = level
            return ""
        if key not in _COMMANDS:
            raise RecorderError(f"Command was not found (REC.{key})")
        if arg is not None:
            raise RecorderError(f"REC.{key} takes no argument")
        return self._command(key)

    def _command(self, key: str) -> str:
        if key == "TRIG":
            if not self.active_channels:
                raise RecorderError("No recording channel selected (REC.CH1..REC.CH6)")
            self.state = "armed"
            self.pre, self.rows, self.written, self.retrieved = [], [], 0, 0
            self.trigger_index, self.last, self.command_seen = 0, None, False
            self.next_t = self.model.clock
            return ""
        if key == "OFF":
            if self.running:
                self.state = "done" if self.rows else "idle"
            return ""
        if key == "DONE":
            return "1" if self.state == "done" or (self.state == "recording" and self.settings["STOPTYPE"] == 1
                                                   and len(self.rows) >= self.numpoints) else "0"
        if key == "ACTIVE":
            return "1" if self.running else "0"
        if key == "RETRIEVE":
            return "\r\n".join(self._header() + self._format_rows(self.rows))
        if key == "RETRIEVEHDR":
            return "\r\n".join(self._header())
        if key == "RETRIEVEDATA":
            return self._retrieve_data()
        if key == "RECPRMLIST" or key == "TRIGPRMLIST":
            return "\r\n".join(sorted(signals()))
        raise RecorderError(f"Command was not found (REC.{key})")

    def retrieve_from(self, index: int) -> str:
        """``REC.RETRIEVEDATA index``: set the next row to send, then send a chunk."""
        if index < 0:
            raise RecorderError("Value is out of range")
        self.retrieved = index
        return self._retrieve_data()

    def _retrieve_data(self) -> str:
        if not self.rows and not self.running:
            raise RecorderError("No data recorded")
        oldest = self.written - len(self.rows)
        if self.retrieved < oldest:
            raise RecorderError(f"Recorder retrieve overflow: rows {self.retrieved}..{oldest - 1} were overwritten")
        start = self.retrieved - oldest
        chunk = self.rows[start:start + int(self.settings["RETRIEVESIZE"])]
        first = self.retrieved
        self.retrieved = first + len(chunk)
        return "\r\n".join([f"{first},{len(chunk)}", *self._format_rows(chunk)])

    def _header(self) -> list[str]:
        return ["Recording", f"{len(self.rows)},{int(self.settings['GAP'])}", ",".join(self.active_channels)]

    def _format_rows(self, rows: list[list[float]]) -> list[str]:
        internal = self.settings["RETRIEVEFRMT"] == 1
        return [",".join(_internal(v) if internal else f"{v:.3f}" for v in row) for row in rows]

    def _refuse_while_running(self, key: str) -> None:
        if self.running:
            raise RecorderError(f"REC.{key} cannot be changed while the recorder is active (REC.OFF first)")

    # ------------------------------------------------------------------ persistence
    def to_state(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in self.FIELDS}

    def load_state(self, state: dict[str, Any]) -> None:
        for name in self.FIELDS:
            if name in state:
                setattr(self, name, state[name])


_COMMANDS = frozenset({"TRIG", "OFF", "DONE", "ACTIVE", "RETRIEVE", "RETRIEVEHDR", "RETRIEVEDATA", "RECPRMLIST",
                       "TRIGPRMLIST"})


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else f"{value:.3f}"


def _int_arg(text: str, low: float, high: float) -> int:
    try:
        value = float(text)
    except ValueError:
        raise RecorderError(f"Argument is not a number: {text}") from None
    if not math.isfinite(value) or not value.is_integer():
        raise RecorderError(f"Argument must be an integer: {text}")
    if not low <= value <= high:
        raise RecorderError(f"Value is out of range ({int(low)} to {int(high)})")
    return int(value)


def _signal_arg(text: str) -> str:
    name = text.strip().upper()
    if name not in signals():
        raise RecorderError(f"{text.strip()} is not a recordable parameter")
    return name


def _internal(value: float) -> str:
    """Internal format: ``F<d><signed hex>`` = hex times 10^-d (``F3-0x56`` = -0.086). The simulator sends 6
    decimals (a following error of a few thousandths of a revolution keeps its shape) [I: the drive's d per
    parameter is not documented]."""
    scaled = round(value * 1_000_000)
    return f"F6{'-' if scaled < 0 else ''}0x{abs(scaled):X}"


def recorder_of(model: DriveModel) -> Recorder:
    """The model's recorder (attached by sim/model.py)."""
    return model.recorder  # type: ignore[attr-defined, no-any-return]


def handle_rec(model: DriveModel, name: str, arg: str | None) -> str:
    """One REC.* command of the ASCII channel: ``name`` as typed (``REC.GAP``, case-insensitive), ``arg`` the rest
    of the line or None. Returns the reply text (empty for a write); raises :class:`RecorderError` with the drive's
    text when refused."""
    key = name.strip().upper()
    if not key.startswith("REC."):
        raise RecorderError(f"Command was not found ({name})")
    recorder = recorder_of(model)
    if key == "REC.RETRIEVEDATA" and arg is not None and arg.strip():
        try:
            index = int(arg.strip())
        except ValueError:
            raise RecorderError(f"Argument is not a number: {arg.strip()}") from None
        return recorder.retrieve_from(index)
    return recorder.handle(key, arg)
