"""The scope operation: plan a recording (and the move it may watch), then record it.

Why an operation in the plan -> consent -> execute shape (drive/operation.py): a recording with the drive's
recorder writes REC.* settings, and a recording "during a move" moves the axis. Both are decided before anything
is written: :func:`plan` resolves the signals, checks the counts, rates and trigger, builds the REC.* writes and,
when a move is asked, the motion planner's plan (limits, homed rule, travel; drive/motion_plan.py); the CLI and the
recipe step then ask the one consent for the move and call :func:`execute`, which starts the move only after the
recording is armed (so the recording shows the start), records, and brings the axis to its end or stops it on any
error or interrupt.

Sources (docs/scope.md): ``poll`` (every transport, host-timed), ``recorder`` (the AKD's REC.* over a
:class:`~akdctl.drive.scope_recorder.CommandLink`), ``pdo`` (cyclic process data on ``ecat://``, the slave in SAFE-OP:
:mod:`akdctl.drive.scope_pdo`, :mod:`akdctl.drive.scope_pdo_bus`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from akdctl.drive.operation import PlannedWrite, WritePlan
from akdctl.drive.scope_model import Recording
from akdctl.drive.scope_trigger import Trigger, check_pretrigger, parse_trigger
from akdctl.errors import AkdError, UsageError
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.connection import Connection

SOURCES = ("auto", "poll", "recorder", "pdo")
#: --for / --samples bounds: a recording is a look, not a logger.
MAX_DURATION_S = 600.0
MAX_POLL_SAMPLES = 1_000_000
DEFAULT_TIMEOUT_S = 10.0
#: How often the axis is read while a recorded motion runs (a fault ends the recording).
WATCH_S = 0.05


class ScopeRequest(Record):
    """What the command line or a recipe step asks: signals, exactly one of ``duration_s``/``samples`` (neither:
    1 s), ``rate_hz`` (None: as fast as the source goes / the recorder's default spacing), ``source``, trigger text,
    pre-trigger percent, trigger/recorder ``timeout_s``, and an optional relative ``move`` (MotionRequest) to record."""

    __slots__ = ("duration_s", "move", "pretrigger", "rate_hz", "ring", "samples", "signals", "source", "timeout_s",
                 "trigger")

    def __init__(self, signals: Sequence[str], *, duration_s: float | None = None, samples: int | None = None,
                 rate_hz: float | None = None, source: str = "auto", trigger: str | None = None,
                 pretrigger: float = 0.0, timeout_s: float = DEFAULT_TIMEOUT_S, move: Any = None,
                 ring: int | None = None) -> None:
        self.signals = [str(s) for s in signals]
        self.duration_s = duration_s
        self.samples = samples
        self.rate_hz = rate_hz
        self.source = source
        self.trigger = trigger
        self.pretrigger = pretrigger
        self.timeout_s = timeout_s
        self.move = move
        self.ring = ring  # a continuous recorder recording streamed through a ring of this many points


def build_request(signals: Sequence[str], *, duration_s: float | None = None, samples: int | None = None,
                  rate_hz: float | None = None, source: str = "auto", trigger: str | None = None,
                  pretrigger: float = 0.0, timeout_s: float = DEFAULT_TIMEOUT_S, jog_rpm: float | None = None,
                  jog_s: float | None = None, accel: float | None = None, ring: int | None = None) -> ScopeRequest:
    """The one way the command line and a recipe step turn their words into a request (their parity): a
    recorded jog needs both its speed and its duration, and without --for/--samples the recording lasts the jog,
    its stop and a margin."""
    move = None
    if jog_rpm is not None or jog_s is not None:
        from akdctl.drive.motion_plan import MotionRequest

        if jog_rpm is None or jog_s is None:
            raise UsageError("a recorded jog needs both its speed (--jog, jog) and its duration (--jog-for, jog_for)")
        move = MotionRequest("jog", velocity=jog_rpm, duration_s=jog_s, accel=accel)
        if duration_s is None and samples is None:
            duration_s = min(MAX_DURATION_S, jog_s * 1.5 + 1.0)
    elif accel is not None:
        raise UsageError("an acceleration describes a recorded jog: give its speed and duration too")
    return ScopeRequest(signals, duration_s=duration_s, samples=samples, rate_hz=rate_hz, source=source,
                        trigger=trigger, pretrigger=pretrigger, timeout_s=timeout_s, move=move, ring=ring)


def check(request: ScopeRequest) -> Trigger:
    """Input checks that need no drive (exit 2): counts, times, rates, trigger grammar."""
    if not request.signals:
        raise UsageError("scope needs at least one SIGNAL (e.g. VL.FB)")
    if request.source not in SOURCES:
        raise UsageError(f"unknown source {request.source!r}; sources: {', '.join(SOURCES)}")
    if request.duration_s is not None and request.samples is not None:
        raise UsageError("give --for or --samples, not both")
    if request.duration_s is not None and not (math.isfinite(request.duration_s) and 0 < request.duration_s
                                               <= MAX_DURATION_S):
        raise UsageError(f"--for {request.duration_s:g}: a recording lasts more than 0 and at most "
                         f"{MAX_DURATION_S:g} s")
    if request.samples is not None and not 2 <= request.samples <= MAX_POLL_SAMPLES:
        raise UsageError(f"--samples {request.samples}: between 2 and {MAX_POLL_SAMPLES}")
    if request.rate_hz is not None and not (math.isfinite(request.rate_hz) and request.rate_hz > 0):
        raise UsageError(f"--rate {request.rate_hz:g}: a rate is a positive number of samples per second")
    if not (math.isfinite(request.timeout_s) and 0 < request.timeout_s <= 3600):
        raise UsageError(f"--timeout {request.timeout_s:g}: between 0 and 3600 s")
    if request.ring is not None:
        if request.source != "recorder":
            raise UsageError("a continuous recording (--continuous, --ring) streams the drive's recorder: "
                             "give --source recorder")
        if not 2 <= request.ring <= 10000:
            raise UsageError(f"--ring {request.ring}: the recorder's ring holds 2..10000 points (REC.NUMPOINTS)")
    trigger = parse_trigger(request.trigger)
    check_pretrigger(request.pretrigger, trigger)
    return trigger


def source_for(conn: Connection, request: ScopeRequest) -> str:
    """``auto``: the recorder where the target's scheme is the AKD's ASCII channel (``akd://``), else polling."""
    if request.source != "auto":
        return request.source
    return "recorder" if conn.target.scheme == "akd" else "poll"


def command_link_factory(conn: Connection) -> Callable[[], Any] | None:
    """A factory of the target's ASCII command link (:class:`~akdctl.drive.scope_recorder.CommandLink`), or None:
    the ``akd://`` transport's ``Connection.commands()``, the in-process simulated recorder for ``sim`` targets
    (transport/sim_commands.py)."""
    if conn.has_commands:
        return conn.commands  # type: ignore[return-value]
    if conn.target.scheme == "sim":
        from akdctl.transport.sim_commands import SimCommandLink

        return lambda: SimCommandLink(conn.transport().drive)  # type: ignore[attr-defined]
    return None


def plan(conn: Connection, request: ScopeRequest, command_link: Callable[[], Any] | None = None) -> WritePlan:
    """Check everything and decide what will be written (REC.* for the recorder) and moved (``request.move``),
    reading only. ``data`` carries what :func:`execute` needs."""
    trigger = check(request)
    source = source_for(conn, request)
    if command_link is None:
        command_link = command_link_factory(conn)
    data: dict[str, Any] = {"request": request, "trigger": trigger, "source": source}
    writes: list[PlannedWrite] = []
    notes: list[str] = []
    if source == "pdo":
        from akdctl.drive import scope_pdo

        spec_pdo = scope_pdo.plan(conn, request, trigger)
        data["pdo"] = spec_pdo
        notes += spec_pdo.notes
        notes.append(f"{spec_pdo.cycles} cycles, {spec_pdo.pre} of them before the trigger")
    elif source == "recorder":
        from akdctl.drive import scope_recorder as rec

        rec.check_signals(request.signals)
        points, gap, timing_notes = rec.timing(request.samples, request.duration_s, request.rate_hz,
                                               continuous=request.ring is not None)
        spec = rec.RecorderSpec(request.signals, points, gap, trigger, request.pretrigger, request.timeout_s,
                                ring=request.ring)
        if command_link is None:
            raise UsageError(f"--source recorder needs the AKD's ASCII channel (akd://HOST, or a sim target); "
                             f"{conn.target.display} offers none: use --source poll")
        data["link"] = command_link()
        data["spec"] = spec
        writes = [PlannedWrite(name, value, value) for name, value in spec.writes()]
        writes.append(PlannedWrite("REC.TRIG", "", "(arm)"))
        notes += timing_notes
        notes.append(f"{points} samples every {gap} x 62.5 us = {spec.rate_hz:.6g}/s, {spec.span_s:.6g} s"
                     + (f", streamed through a ring of {spec.ring} points (REC.STOPTYPE 1)" if spec.ring else ""))
    elif source == "poll":
        data["signals"], data["hidden"] = _poll_signals(conn, request.signals, trigger)
        from akdctl.drive.scope_signals import Sampler

        sampler = Sampler(conn, data["signals"] + data["hidden"])
        sampler.read()  # every signal readable before anything moves; loads what the first sample would pay for
        data["sampler"] = sampler
        notes.append(f"{sampler.requests_per_sample} request(s) per sample; the rate achieved is measured")
    if request.move is not None:
        from akdctl.drive import motion_plan
        from akdctl.drive.axis.choice import axis_class

        motion_plan.check_request(conn, request.move, axis_class(conn))
        axis = conn.axis()
        data["axis"] = axis
        data["motion"] = motion_plan.plan(conn, axis, request.move)
        notes.append(f"moves the axis during the recording: {data['motion'].what}")
    return WritePlan("scope", conn.target.display, writes, notes=notes, data=data)


def _poll_signals(conn: Connection, names: Sequence[str], trigger: Trigger) -> tuple[list[Any], list[Any]]:
    from akdctl.drive.scope_signals import Resolver

    def singleturn_bits() -> int:
        from akdctl.drive.values import read_pnu_map

        return int(read_pnu_map(conn.parameters(), [1002])[1002][0])

    from akdctl.drive.axis.choice import profile_name

    has_commands = conn.has_commands
    resolver = Resolver(conn.has_parameters, conn.has_objects, singleturn_bits,
                        prefer_objects=not has_commands and profile_name(conn) == "cia402", has_commands=has_commands)
    signals = [resolver.resolve(name) for name in names]
    hidden: list[Any] = []
    if trigger.on_status:
        hidden.append(resolver.resolve("STATUSWORD"))
    elif trigger.signal is not None:
        wanted = trigger.signal.upper()
        if not any(s.name.upper() == wanted for s in signals):
            hidden.append(resolver.resolve(trigger.signal))
    return signals, hidden


def motion_text(plan_: WritePlan) -> str | None:
    """The consent sentence of the move the plan watches (None: the recording moves nothing)."""
    motion = plan_.data.get("motion")
    return None if motion is None else f"{motion.what} (mode: {motion.mode_text}) while recording"


def execute(conn: Connection, plan_: WritePlan, *, stopped: Callable[[], bool],
            on_sample: Callable[[Recording], None] | None = None) -> tuple[Recording, AkdError | None]:
    """Record (after consent for a move): returns the recording and the error that ended it early (the recording
    is then marked partial and keeps what it has; the caller writes the files, then raises)."""
    data = plan_.data
    request: ScopeRequest = data["request"]
    trigger: Trigger = data["trigger"]
    source = data["source"]
    motion = data.get("motion")
    axis: Any = data.get("axis")
    started: list[float] = []  # monotonic time the motion started
    jog_ended = [False]
    events: dict[str, float] = {}  # host monotonic instants (the poll source's clock)

    def start_motion() -> None:
        if motion is not None and not started:
            from akdctl.drive import motion_plan

            started.append(math.nan)  # from here on an error stops the axis
            motion_plan.start(axis, motion, stopped)
            started[0] = events["motion_start"] = time.monotonic()  # the jog's time runs from the drive's start

    watched = [0.0]
    # the pdo source watches a recorded motion in the cycle's own status word when it is mapped (no SDO between
    # cycles); every other source reads the axis
    sdo_watch = not (source == "pdo" and data["pdo"].status_slot is not None)

    def tick() -> None:
        """While the motion runs: the axis is read every WATCH_S (a fault ends the recording, and the traffic tells
        the simulated drive's watchdog someone is there); a timed jog ends at its duration (ramp to standstill)."""
        if started and sdo_watch and time.monotonic() - watched[0] >= WATCH_S:
            watched[0] = time.monotonic()
            _watch(axis)
        r = motion.request if motion is not None else None
        if started and not jog_ended[0] and r is not None and r.kind == "jog" and r.duration_s is not None \
                and time.monotonic() - started[0] >= r.duration_s:
            jog_ended[0] = True
            events["jog_end"] = time.monotonic()
            axis.end_jog()

    try:
        if source == "recorder":
            from akdctl.drive import scope_recorder as rec

            spec = data["spec"]
            recording = Recording(plan_.target, "recorder", rec.channels_for(spec.signals), trigger=trigger.text,
                                  rate_requested=spec.rate_hz)
            failure = rec.record(data["link"], spec, recording, stopped=stopped, on_armed=start_motion,
                                 on_wait=tick if motion is not None else None, on_chunk=on_sample)
        elif source == "pdo":
            recording, failure = _record_pdo(conn, plan_, stopped, start_motion, tick if motion is not None else None,
                                             on_sample, events, started)
        else:
            from akdctl.drive import scope_poll
            from akdctl.drive.scope_model import Channel

            signals = data["signals"]
            recording = Recording(plan_.target, "poll", [Channel(s.name, s.unit, s.address) for s in signals],
                                  trigger=trigger.text, rate_requested=request.rate_hz)
            sampler = data["sampler"]
            recording.notes.append(f"{sampler.requests_per_sample} request(s) per sample, host monotonic time")
            slot = None
            if trigger.on_status:
                slot = len(signals)
            elif trigger.signal is not None:
                names = [s.name.upper() for s in signals + data["hidden"]]
                slot = names.index(trigger.signal.upper())
            spec = scope_poll.PollSpec(samples=request.samples,
                                       duration_s=request.duration_s if request.samples is None else None,
                                       rate_hz=request.rate_hz, trigger=trigger, pretrigger=request.pretrigger,
                                       timeout_s=request.timeout_s)
            if spec.samples is None and spec.duration_s is None:
                spec.duration_s = 1.0
            recording.events = events  # stamped by the same monotonic clock as the samples, shifted with them
            failure = scope_poll.record(sampler.read, recording, spec, trigger_slot=slot, stopped=stopped,
                                        on_sample=on_sample, on_first=start_motion,
                                        on_tick=tick if motion is not None else None)
        if motion is not None:
            _finish_motion(axis, motion, bool(started), jog_ended[0], failure)
    except BaseException:
        if started:
            axis.safe_stop()
        raise
    return recording, failure


def _record_pdo(conn: Connection, plan_: WritePlan, stopped: Callable[[], bool], start_motion: Callable[[], None],
                tick: Callable[[], None] | None, on_sample: Callable[[Recording], None] | None,
                events: dict[str, float], started: list[float]) -> tuple[Recording, AkdError | None]:
    """The pdo source: the bus in SAFE-OP for the recording (drive/scope_pdo_bus.py), a recorded motion watched
    through the mapped status word (a fault ends the recording: DriveFault, exit 1)."""
    from akdctl.drive import scope_pdo
    from akdctl.drive.scope_pdo_bus import BusInputs
    from akdctl.drive.scope_trigger import FAULT_BIT
    from akdctl.errors import DriveFault

    spec = plan_.data["pdo"]
    trigger: Trigger = plan_.data["trigger"]
    request: ScopeRequest = plan_.data["request"]
    recording = Recording(plan_.target, "pdo", [c.channel for c in spec.columns[:spec.width]], trigger=trigger.text,
                          rate_requested=1.0 / spec.cycle_s)

    def on_row(row: list[float]) -> None:
        if started and spec.status_slot is not None and int(row[spec.status_slot]) & (1 << FAULT_BIT):
            raise DriveFault("drive fault during the recorded motion (status word 0x"
                             f"{int(row[spec.status_slot]):04X} in the TxPDO)")

    with BusInputs(conn.process_data(spec.rx.bytes, spec.tx.bytes), spec.cycle_s,
                   lost_limit_s=conn.options.timeout) as bus:
        failure = scope_pdo.record(bus, spec, recording, trigger, stopped=stopped, timeout_s=request.timeout_s,
                                   on_first=start_motion, on_row=on_row, on_tick=tick, on_sample=on_sample,
                                   events=events)
    if bus.lost:
        recording.notes.append(f"{bus.lost} frame(s) did not come back within the frame timeout: gaps")
    return recording, failure


def _watch(axis: Any) -> None:
    """Read the axis during a recorded motion: a fault ends the recording (DriveFault, exit 1)."""
    from akdctl.errors import DriveFault

    status = axis.read_status()
    if status.fault:
        raise DriveFault(f"drive fault during the recorded motion: {status.fault_summary()}")


def _finish_motion(axis: Any, motion: Any, started: bool, jog_ended: bool, failure: AkdError | None) -> None:
    """The motion the recording watched ends: a jog still running is ended (ramp), a move waited for; the axis is
    stopped when the recording failed."""
    from akdctl.drive.scope_poll import RateNotReached

    if not started:
        return
    if failure is not None and not isinstance(failure, RateNotReached):
        _, outcome = axis.safe_stop()
        if "stop" not in failure.message:
            failure.message = f"{failure.message} ({outcome})"
        return
    r = motion.request
    if r.kind == "jog" and r.duration_s is not None:
        if not jog_ended:
            axis.end_jog()
        axis.wait_for(lambda s: s.standstill, "standstill after the recorded jog", timeout=axis.timeout + 5.0)
        return
    axis.wait_for(lambda s: s.target_reached and s.standstill, "the recorded move to finish",
                  timeout=max(motion.deadline_s, 1.0))


# ====================================================================== bounds (recipes: assert on behaviour)
class Bounds(Record):
    """What a recording must show: ``max_following_error`` (|PL.ERR| at every sample, in its unit),
    ``max_settle_time`` (s from the end of the recorded jog until ``settle_signal`` stays within
    ``settle_band``; the poll source, which stamps that instant on its clock)."""

    __slots__ = ("max_following_error", "max_settle_time", "settle_band", "settle_signal")

    def __init__(self, max_following_error: float | None = None, max_settle_time: float | None = None,
                 settle_band: float | None = None, settle_signal: str = "PL.ERR") -> None:
        self.max_following_error = max_following_error
        self.max_settle_time = max_settle_time
        self.settle_band = settle_band
        self.settle_signal = settle_signal

    @property
    def any(self) -> bool:
        return self.max_following_error is not None or self.max_settle_time is not None

    def check_request(self, request: ScopeRequest) -> None:
        """Usage errors (exit 2) a bound can know before recording: the signals it reads, the jog it times."""
        names = [n.strip().upper() for n in request.signals]
        if self.max_following_error is not None and "PL.ERR" not in names:
            raise UsageError("a following-error bound needs PL.ERR among the recorded signals")
        if self.max_settle_time is not None:
            if self.settle_signal.upper() not in names:
                raise UsageError(f"a settle-time bound needs {self.settle_signal} among the recorded signals")
            if request.move is None or request.move.duration_s is None:
                raise UsageError("a settle-time bound is measured from the end of a recorded jog: give jog and "
                                 "jog_for (--jog, --jog-for)")
            if self.settle_band is None or not self.settle_band > 0:
                raise UsageError("a settle-time bound needs a positive settle band (settle_band, --settle-band)")
            if request.source == "recorder":
                raise UsageError("a settle-time bound needs the poll source (the recorder's clock is the drive's)")


def measure(recording: Recording, bounds: Bounds) -> dict[str, Any]:
    """The measured values a bound compares (``following_error_max``, ``settle_time``)."""
    out: dict[str, Any] = {}
    if bounds.max_following_error is not None:
        column = recording.column("PL.ERR")
        out["following_error_max"] = max((abs(v) for v in column), default=None)
    if bounds.max_settle_time is not None:
        end = recording.events.get("jog_end")
        column = recording.column(bounds.settle_signal)
        band = float(bounds.settle_band or 0.0)
        if end is None:
            out["settle_time"] = None
        else:
            outside = [t for t, v in zip(recording.times, column) if t >= end and abs(v) > band]
            out["settle_time"] = (outside[-1] - end) if outside else 0.0
            if outside and outside[-1] == recording.times[-1]:
                out["settle_time"] = math.inf  # still outside the band at the last sample: not settled
    return out


def check_bounds(recording: Recording, bounds: Bounds) -> dict[str, Any]:
    """Compare: one CheckFailed (exit 5) naming every bound the recording broke; returns the measurements."""
    from akdctl.errors import CheckFailed

    measured = measure(recording, bounds)
    problems = []
    fe = measured.get("following_error_max")
    if bounds.max_following_error is not None:
        if fe is None:
            problems.append("no PL.ERR sample recorded")
        elif fe > bounds.max_following_error:
            problems.append(f"following error reached {fe:.6g} (bound {bounds.max_following_error:g})")
    if bounds.max_settle_time is not None:
        settle = measured.get("settle_time")
        if settle is None:
            problems.append("the end of the jog was not recorded: no settle time")
        elif settle > bounds.max_settle_time:
            shown = "not settled by the last sample" if math.isinf(settle) else f"{settle:.4g} s"
            problems.append(f"settle time {shown} ({bounds.settle_signal} within {bounds.settle_band:g}; bound "
                            f"{bounds.max_settle_time:g} s)")
    if recording.partial:
        problems.append(f"the recording is partial: {recording.partial}")
    if problems:
        raise CheckFailed("scope: " + "; ".join(problems),
                          details={"measured": {k: v for k, v in measured.items() if v is None or math.isfinite(v)}})
    return measured
