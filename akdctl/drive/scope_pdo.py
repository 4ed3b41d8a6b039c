"""The PDO source: one sample per EtherCAT bus cycle from the mapped TxPDO, with this host as the master.

Why a separate source: the AKD refreshes its TxPDO inputs every cycle (FBUS.SAMPLEPERIOD, 250 us and up), so a
master gets position, velocity, following error and torque at the bus rate with no request per sample
(foe-alias-recorder.md §C2); only PDO-mappable objects can be recorded, and the master keeps writing outputs each
cycle to get fresh inputs [I]. The bus itself (SAFE-OP, the exchange, taking the slave back) is
:mod:`akdctl.drive.scope_pdo_bus`; this module decides what is recorded and turns cycles into rows, against a small
interface (:class:`CyclicInputs`) that tests fake in-process.

What is decided before anything happens (:func:`plan`, exit 2 on bad input): the target runs cyclic process data as
master (``Connection.has_process_data``); every signal and the trigger's signal resolve as the poll source resolves
them on an object channel (``VL.FB`` -> 0x606C in rpm, ``0x6041``, an AKD name the catalogue maps) and are in the
mapped TxPDO (the message names what is mapped); the cycle is one the AKD runs (a multiple of 62.5 us, at least
250 us: profiles/units.py), by default the drive's own 0x60C2.

Time: ``t = bus cycle number x cycle time`` (the bus clock, not the host's). The host paces the cycle; a cycle it
was too late for is not sent and leaves a gap at its place (never a burst that would squeeze time), and when fewer
than :data:`RATE_TOLERANCE` of the cycles were exchanged the recording is partial and exits 3.

Pre-trigger: until the trigger fires, the rows of the last ``pre`` cycles stay in a ring; the trigger is looked for
only once the ring is full, so the recording holds the requested share before it (as the poll source and the
drive's recorder do), and ``Recording.trigger_index`` is the trigger row.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from akdctl.drive.ecat_pdo_watch import field_value
from akdctl.drive.scope_model import Channel, Recording, utc_now
from akdctl.drive.scope_trigger import Trigger
from akdctl.errors import AkdError, Interrupted, TriggerTimeout, UsageError
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.connection import Connection

#: The share of the bus cycles the host must have exchanged for the recording to count as whole.
RATE_TOLERANCE = 0.9
#: The slowest cycle the pdo source runs (a look at the axis, not a logger; 0x60C2 may be set slower).
MAX_CYCLE_S = 0.1
#: Bus cycles in one recording at most (as the poll source's samples).
MAX_CYCLES = 1_000_000


class CyclicInputs(Protocol):
    """What a cyclic EtherCAT master offers the scope: its cycle time and, per cycle, the slave's TxPDO bytes."""

    cycle_s: float

    def next_inputs(self, timeout: float) -> tuple[int, bytes]:
        """(bus cycle number, the input image of that cycle): the next cycle the host reached (a number skips the
        cycles it was too late for). CommError/DriveError when the cycle stops (no frame, a working counter
        drop, the slave leaving its state)."""
        ...

    def bus_time(self, host_t: float) -> float:
        """The bus time (s, cycle 0 = 0) of a host monotonic instant (a recorded jog's start and end)."""
        ...


class Column(Record):
    """Where one value sits in the TxPDO image (``bit``, ``bits``, ``signed``) and how its raw value becomes the
    signal's unit (``convert``)."""

    __slots__ = ("bit", "bits", "channel", "convert", "signed")

    def __init__(self, channel: Channel, bit: int, bits: int, signed: bool, convert: Callable[[Any], float]) -> None:
        self.channel = channel
        self.bit = bit
        self.bits = bits
        self.signed = signed
        self.convert = convert


class PdoSpec(Record):
    """The planned recording: ``columns`` (recorded, then the hidden trigger/status values), ``width`` (how many
    are recorded), ``cycle_s``, ``cycles`` in all, ``pre`` of them before the trigger, ``trigger_slot`` and
    ``status_slot`` (row indexes, or None), the ``rx``/``tx`` layouts the bus needs."""

    __slots__ = ("columns", "cycle_s", "cycles", "notes", "pre", "rx", "status_slot", "trigger_slot", "tx", "width")

    def __init__(self, columns: list[Column], width: int, cycle_s: float, cycles: int, pre: int, *,
                 trigger_slot: int | None = None, status_slot: int | None = None, rx: Any = None, tx: Any = None,
                 notes: list[str] | None = None) -> None:
        self.columns = columns
        self.width = width
        self.cycle_s = cycle_s
        self.cycles = cycles
        self.pre = pre
        self.trigger_slot = trigger_slot
        self.status_slot = status_slot
        self.rx = rx
        self.tx = tx
        self.notes = notes or []

    def decode(self, image: bytes) -> list[float]:
        """One row (recorded and hidden values) out of one cycle's input image (drive/ecat_pdo_watch.field_value:
        the one reading of an entry out of the image)."""
        value = int.from_bytes(image, "little")
        return [float(c.convert(field_value(value, c.bit, c.bits, c.signed))) for c in self.columns]

    def decoder(self) -> Callable[[bytes], list[float]]:
        """:meth:`decode` compiled for one recording: the columns' raw values read at once
        (drive/ecat_pdo_watch.image_reader: what field_value reads, one struct when the entries are whole bytes)."""
        from akdctl.drive.ecat_pdo_watch import image_reader

        fields = [(c.bit, c.bits, c.signed) for c in self.columns]
        converts = [c.convert for c in self.columns]
        if all(convert is float for convert in converts):  # raw values recorded as they are (float(float(x)))
            return image_reader(fields, float)  # type: ignore[return-value]
        read = image_reader(fields)

        def decode(image: bytes) -> list[float]:
            return [float(convert(raw)) for convert, raw in zip(converts, read(image))]
        return decode


# ---------------------------------------------------------------------- plan: what is recorded, how fast
def cycle_for(rate_hz: float | None, drive_cycle: tuple[int, int] | None) -> tuple[float, str]:
    """The bus cycle in seconds and where it came from: ``--rate`` (a cycle the AKD runs, else exit 2 naming the
    nearest ones), else the drive's 0x60C2 (units, exponent), else 2 ms (the AKD's default 0x60C2)."""
    from akdctl.profiles.units import cycle_tick_s, min_cycle_s

    tick, shortest = float(cycle_tick_s()), float(min_cycle_s())
    if rate_hz is None:
        if drive_cycle is None:
            return 0.002, "2 ms: the drive did not answer 0x60C2"
        from akdctl.profiles.units import cycle_time_problem, cycle_time_s

        units, exponent = drive_cycle
        if cycle_time_problem(units, exponent) is None and cycle_time_s(units, exponent) <= MAX_CYCLE_S:
            return float(cycle_time_s(units, exponent)), f"the drive's cycle time 0x60C2 = {units}e{exponent} s"
        return 0.002, f"2 ms: the drive's 0x60C2 = {units}e{exponent} s is not a cycle the scope runs"
    cycle = 1.0 / rate_hz
    ticks = cycle / tick
    if cycle < shortest - 1e-12:
        raise UsageError(f"--rate {rate_hz:g}: the pdo source samples once per bus cycle and the AKD's shortest cycle "
                         f"is {shortest * 1e6:g} us ({1 / shortest:g}/s)")
    if cycle > MAX_CYCLE_S + 1e-12:
        raise UsageError(f"--rate {rate_hz:g}: the pdo source runs the bus at {1 / MAX_CYCLE_S:g} cycles/s at least; "
                         "for a slower look use --source poll")
    if abs(ticks - round(ticks)) > 1e-6:
        low, high = max(4, math.floor(ticks)), math.ceil(ticks)
        raise UsageError(f"--rate {rate_hz:g}: a bus cycle is a multiple of {tick * 1e6:g} us; the nearest rates are "
                         f"{1 / (high * tick):.6g} and {1 / (low * tick):.6g}/s")
    return cycle, f"--rate {rate_hz:g}"


def resolve_columns(tx: Any, names: Sequence[str], trigger: Trigger) -> tuple[list[Column], int, int | None, int | None]:
    """(columns, recorded width, trigger slot, status slot) for ``names`` and the trigger's signal, each in the
    TxPDO layout ``tx``; UsageError naming what is mapped when one is not. The status word (0x6041) rides along
    hidden when it is mapped, so a recorded motion is watched for a fault from the image itself."""
    from akdctl.drive.scope_signals import Resolver

    resolver = Resolver(False, True, prefer_objects=True)

    def column(name: str) -> Column:
        signal = resolver.resolve(name)
        found = tx.field(signal.index, signal.sub)
        if found is None:
            raise UsageError(f"signal {name}: 0x{signal.index:04X}:{signal.sub:02X} is not in the mapped TxPDO "
                             f"({tx.mapped()}); map it first ('akdctl pdo map') or use --source poll")
        bit, bits, signed = found
        return Column(Channel(name, signal.unit, f"TxPDO {signal.address}"), bit, bits, signed, signal.convert)

    columns = [column(name) for name in names]
    width = len(columns)

    def slot_of(name: str) -> int:
        """The row index of ``name``: a recorded column of that name, else a hidden one added for it."""
        for i, c in enumerate(columns):
            if c.channel.name.upper() == name.upper():
                return i
        columns.append(column(name))
        return len(columns) - 1

    trigger_slot = None
    if trigger.on_status:
        trigger_slot = slot_of("STATUSWORD")
    elif trigger.signal is not None:
        trigger_slot = slot_of(trigger.signal)
    status_slot = None
    if tx.field(0x6041, 0) is not None:
        status_slot = slot_of("STATUSWORD")
    return columns, width, trigger_slot, status_slot


def plan(conn: "Connection", request: Any, trigger: Trigger) -> PdoSpec:
    """Check everything for ``--source pdo`` (reading only: the mapping, 0x60C2) and decide the recording."""
    if not conn.has_process_data:
        raise UsageError(f"--source pdo needs this host as the EtherCAT master (an ecat://IFNAME[/POSITION] target); "
                         f"{conn.target.display} is not one: use --source poll")
    from akdctl.drive.ecat_pdo_watch import layouts

    mapping, rx, tx = layouts(conn)
    if not tx.fields:
        raise UsageError("--source pdo: the slave maps no TxPDO (0x1C13 assigns nothing): nothing to record; "
                         "map one first ('akdctl pdo map') or use --source poll")
    drive_cycle = None
    if request.rate_hz is None:
        drive_cycle = _drive_cycle(conn)
    cycle_s, why = cycle_for(request.rate_hz, drive_cycle)
    columns, width, trigger_slot, status_slot = resolve_columns(tx, request.signals, trigger)
    if request.samples is not None:
        cycles = request.samples
    else:
        cycles = max(2, round((request.duration_s if request.duration_s is not None else 1.0) / cycle_s))
    if cycles > MAX_CYCLES:
        raise UsageError(f"--for {cycles * cycle_s:g} s at {1 / cycle_s:g} cycles/s is {cycles} cycles; at most "
                         f"{MAX_CYCLES}")
    pre = min(cycles - 1, round(cycles * request.pretrigger / 100.0))
    tx_pdos = ", ".join(f"0x{n:04X}" for n in mapping["tx"].assigned)
    notes = [f"one sample per bus cycle of {cycle_s * 1e3:g} ms ({why}), TxPDO {tx_pdos} ({tx.bytes} bytes), "
             "t = cycle number x cycle time",
             "the slave runs in SAFE-OP while recording: inputs flow, the outputs (all 0) are not applied, so the "
             "axis stays under SDO control; it is left in PRE-OP"]
    return PdoSpec(columns, width, cycle_s, cycles, pre, trigger_slot=trigger_slot, status_slot=status_slot, rx=rx,
                   tx=tx, notes=notes)


def _drive_cycle(conn: "Connection") -> tuple[int, int] | None:
    """0x60C2 (units, exponent), or None when the drive does not answer it."""
    from akdctl.drive.values import read_object

    try:
        return int(read_object(conn.objects(), 0x60C2, 1)), int(read_object(conn.objects(), 0x60C2, 2))
    except AkdError:
        return None


# ---------------------------------------------------------------------- record: cycles -> rows
def record(inputs: CyclicInputs, spec: PdoSpec, recording: Recording, trigger: Trigger, *, stopped: Callable[[], bool],
           timeout_s: float, on_first: Callable[[], None] | None = None,
           on_row: Callable[[list[float]], None] | None = None, on_tick: Callable[[], None] | None = None,
           on_sample: Callable[[Recording], None] | None = None,
           events: dict[str, float] | None = None) -> AkdError | None:
    """Fill ``recording`` with ``spec.cycles`` bus cycles, ``spec.pre`` of them before the trigger. ``on_first``
    runs once the trigger is armed: the first cycle, or once the pre-trigger ring is full (a recorded motion starts
    there, so its edge is looked for), ``on_row`` sees every row with its hidden values
    (a recorded motion is watched there), ``on_tick`` runs before each cycle; ``events`` (host monotonic instants
    stamped meanwhile) become the recording's events on the bus clock. Returns the error that ended the
    recording early (it is then marked partial and keeps its rows), else None."""
    width, cycle_s = spec.width, spec.cycle_s
    paused = [0]  # cycles the host spent between cycles on purpose: a recorded motion's SDO requests, the live plot

    def timed(call: Callable[..., None] | None) -> Callable[..., None] | None:
        if call is None:
            return None

        def run(*args: Any) -> None:
            began = time.monotonic()
            try:
                call(*args)
            finally:
                paused[0] += int((time.monotonic() - began) / cycle_s)
        return run

    on_first, on_tick, on_sample = timed(on_first), timed(on_tick), timed(on_sample)
    next_inputs, decode, add = inputs.next_inputs, spec.decoder(), recording.add
    pre, trigger_slot, end = spec.pre, spec.trigger_slot, spec.cycles - spec.pre - 1
    whole = len(spec.columns) == width  # no hidden columns: a row is recorded as it is
    ring: deque[tuple[int, list[float]]] = deque()
    armed = False
    fired = trigger.kind == "immediate"
    previous: float | None = None
    first: int | None = None
    trigger_cycle = 0
    last = 0
    taken = 0
    try:
        while True:
            if stopped():
                raise Interrupted("interrupted while recording")
            if on_tick is not None:
                on_tick()
            number, image = next_inputs(timeout_s)
            row = decode(image)
            taken += 1
            last = number
            if first is None:
                first = number
                recording.started = utc_now()
            if not armed and (fired or number - first >= pre):
                # armed: the pre-trigger ring is full, so a recorded motion starts now, never while the trigger
                # is not yet looked for (its edge would pass unseen)
                armed = True
                if on_first is not None:
                    on_first()
            if on_row is not None:
                on_row(row)
            if not fired:
                ring.append((number, row))
                while ring and ring[0][0] < number - pre:
                    ring.popleft()
                value = row[trigger_slot] if trigger_slot is not None else 0.0
                if number - first >= pre and trigger.fires(previous, value):
                    fired = True
                    trigger_cycle = number
                    for n, r in ring:
                        add(n * cycle_s, r[:width])
                    recording.trigger_index = len(recording) - 1
                    ring.clear()
                else:
                    previous = value
                    if (number - first) * cycle_s > timeout_s + pre * cycle_s:
                        raise TriggerTimeout(f"the trigger ({trigger.text}) did not fire within {timeout_s:g} s")
                    continue
            else:
                if recording.trigger_index is None:
                    recording.trigger_index = 0
                    trigger_cycle = number
                add(number * cycle_s, row if whole else row[:width])
            if on_sample is not None:
                on_sample(recording)
            if number - trigger_cycle >= end:
                break
    except AkdError as exc:
        if not fired:  # the cycles taken while waiting for the trigger are kept (no trigger index)
            for n, r in ring:
                recording.add(n * cycle_s, r[:width])
        recording.mark_partial(_why(exc, len(recording)))
        _finish(recording, spec, taken, first, last, inputs, events, paused[0])
        return exc
    _finish(recording, spec, taken, first, last, inputs, events, paused[0])
    return _check_kept(recording, spec, taken, first, last, paused[0])


def _finish(recording: Recording, spec: PdoSpec, taken: int, first: int | None, last: int, inputs: CyclicInputs,
            events: dict[str, float] | None, paused: int) -> None:
    if events:
        recording.events = {name: inputs.bus_time(t) for name, t in events.items()}
    recording.shift_to_trigger()
    recording.notes.extend(spec.notes)
    if first is not None and last > first:
        spanned = last - first + 1
        if taken < spanned:
            recording.notes.append(f"no sample for {spanned - taken} of {spanned} bus cycles (the host late, a frame "
                                   "lost): each is a gap at its place on the time axis")
        if paused:
            recording.notes.append(f"{paused} of those cycles passed while the host worked between cycles on "
                                   "purpose (the recorded motion's SDO requests, the live plot): not counted against "
                                   "the rate")


def _check_kept(recording: Recording, spec: PdoSpec, taken: int, first: int | None, last: int,
                paused: int) -> AkdError | None:
    """Fewer than RATE_TOLERANCE of the cycles exchanged, the motion's SDO pauses aside: partial, exit 3."""
    if first is None or last <= first:
        return None
    spanned = max(taken, last - first + 1 - paused)
    if taken < RATE_TOLERANCE * spanned:
        why = (f"the host exchanged {taken} of {spanned} bus cycles of {spec.cycle_s * 1e3:g} ms "
               f"({100 * taken / spanned:.0f} %)")
        recording.mark_partial(why)
        from akdctl.drive.scope_poll import RateNotReached

        return RateNotReached(f"rate not reached: {why}; use a slower --rate; the file holds the cycles taken, at "
                           "their bus times")
    return None


def _why(exc: AkdError, taken: int) -> str:
    if isinstance(exc, TriggerTimeout):
        return f"{exc.message}; only pre-trigger cycles ({taken}), no trigger"
    if isinstance(exc, Interrupted):
        return f"interrupted after {taken} cycles"
    return f"stopped after {taken} cycles: {exc.message}"


__all__ = ["Column", "CyclicInputs", "PdoSpec", "cycle_for", "plan", "record", "resolve_columns"]
