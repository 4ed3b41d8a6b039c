"""The recorder source: the AKD's own REC.* recorder, programmed and read over its ASCII command channel.

Why the drive's recorder: it samples on the drive's 16 kHz base (REC.GAP ticks of 62.5 us), up to 6 channels,
with the drive's own trigger, far beyond what host polling reaches (a few hundred SDOs/s: foe-alias-recorder.md
§C2). It is reachable only through the ASCII channel (Telnet, CoE 0x2026): no REC.* parameter is a fieldbus object
(§C1). This module speaks to a :class:`CommandLink` (``command(line) -> reply text``; the ``akd://`` transport's
``conn.commands()`` offers one) and nothing else, so it is tested against the simulated recorder in process.

The sequence (aakd's and WorkBench's, §C1): ``REC.OFF``; gap, points, channels (unused ones cleared), trigger,
pre-trigger (``REC.TRIGPOS``), ``REC.STOPTYPE 0`` (one-shot), retrieval format and chunk size; ``REC.TRIG`` arms;
``REC.DONE`` is polled until 1 within the timeout; ``REC.RETRIEVEHDR`` gives the points, gap and channel names;
``REC.RETRIEVEDATA`` chunks follow until every point arrived. The drive sends no time column: t = (k - trigger
index) x gap x 62.5 us, with the trigger index = round(points x TRIGPOS / 100) [I: the drive's rounding is not
documented; the simulator uses the same rule].
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Sequence
from typing import Protocol

from akdctl.drive.scope_model import Channel, Recording, utc_now
from akdctl.drive.scope_trigger import Trigger
from akdctl.errors import (
    AkdError,
    Interrupted,
    MalformedReply,
    TriggerTimeout,
    UsageError,
)

BASE_HZ = 16000
MAX_CHANNELS = 6
MAX_POINTS = 10000  # aakd: "max buffer size" [I]
MAX_GAP = 65535
#: The most points a continuous recording streams (a look, not a logger).
MAX_STREAM_POINTS = 1_000_000
DEFAULT_POINTS = 1000
RETRIEVE_SIZE = 500
#: How often REC.DONE is asked while the recorder runs.
DONE_POLL_S = 0.05

#: Units of the recorder's signals as the AKD reports them with UNIT.* at their defaults where known; the simulator
#: reports its own units (sim/recorder.py); a real drive's UNIT.* may differ [I].
UNITS = {"VL.FB": "rpm", "VL.CMD": "rpm", "PL.FB": "rev", "PL.CMD": "rev", "PL.ERR": "rev", "IL.FB": "A",
         "IL.CMD": "A", "DS402.STATUSWORD": "", "DRV.ACTIVE": ""}


class CommandLink(Protocol):
    """The AKD's ASCII channel as the ``akd://`` transport offers it: one command line in, the reply text out
    (no echo, no prompt); an ``Error:`` reply raises a DriveError subclass."""

    def command(self, line: str) -> str: ...


class RecorderSpec:
    """What to record: signal names, points, gap (ticks of 62.5 us), trigger, pre-trigger percent, timeout."""

    def __init__(self, signals: Sequence[str], points: int, gap: int, trigger: Trigger, pretrigger: float,
                 timeout_s: float, ring: int | None = None) -> None:
        self.signals = [s.strip().upper() for s in signals]
        self.points = points
        self.gap = gap
        self.trigger = trigger
        self.pretrigger = pretrigger
        self.timeout_s = timeout_s
        #: continuous recording (REC.STOPTYPE 1) into a ring of this many points, streamed with REC.RETRIEVEDATA;
        #: None: one-shot (REC.STOPTYPE 0) of ``points``
        self.ring = ring

    @property
    def buffer_points(self) -> int:
        return self.ring if self.ring is not None else self.points

    @property
    def rate_hz(self) -> float:
        return BASE_HZ / self.gap

    @property
    def span_s(self) -> float:
        return self.points * self.gap / BASE_HZ

    @property
    def trigger_index(self) -> int:
        if self.trigger.kind == "immediate":
            return 0
        return min(self.buffer_points - 1, round(self.buffer_points * self.pretrigger / 100.0))

    def writes(self) -> list[tuple[str, str]]:
        """The REC.* writes in order, before ``REC.TRIG`` (which arms)."""
        out = [("REC.GAP", str(self.gap)), ("REC.NUMPOINTS", str(self.buffer_points))]
        for slot in range(MAX_CHANNELS):
            out.append((f"REC.CH{slot + 1}", self.signals[slot] if slot < len(self.signals) else "CLR"))
        out += self.trigger.recorder_settings()
        if self.trigger.kind != "immediate":
            out.append(("REC.TRIGPOS", str(max(1, round(self.pretrigger)))))
        out += [("REC.STOPTYPE", "0" if self.ring is None else "1"), ("REC.RETRIEVEFRMT", "1"),
                ("REC.RETRIEVESIZE", str(RETRIEVE_SIZE))]
        return out


def timing(samples: int | None, duration_s: float | None, rate_hz: float | None, *,
           continuous: bool = False) -> tuple[int, int, list[str]]:
    """(points, gap, notes) for the request; UsageError (exit 2) for what the recorder cannot do.

    The recorder's rate is 16000/gap exactly: a requested rate between two gaps is recorded at the nearest one,
    and the note says which (never pretended)."""
    notes: list[str] = []
    if rate_hz is not None:
        if not math.isfinite(rate_hz) or rate_hz <= 0:
            raise UsageError(f"--rate {rate_hz:g}: a rate must be a positive number of samples per second")
        if rate_hz > BASE_HZ:
            raise UsageError(f"--rate {rate_hz:g}: the AKD's recorder samples at most {BASE_HZ} times a second "
                             "(REC.GAP 1 = 62.5 us)")
        gap = max(1, round(BASE_HZ / rate_hz))
        if gap > MAX_GAP:
            raise UsageError(f"--rate {rate_hz:g}: the slowest recorder rate is {BASE_HZ / MAX_GAP:.4g}/s "
                             f"(REC.GAP {MAX_GAP})")
        if abs(BASE_HZ / gap - rate_hz) > 1e-6 * rate_hz:
            notes.append(f"recorder rate {BASE_HZ / gap:.6g}/s (REC.GAP {gap}), the nearest to {rate_hz:g}/s")
        points = samples if samples is not None else round((duration_s or 1.0) * BASE_HZ / gap)
    else:
        points = samples if samples is not None else DEFAULT_POINTS
        span = duration_s if duration_s is not None else points / 1000.0
        gap = max(1, math.ceil(span * BASE_HZ / points))
        if gap > MAX_GAP:
            raise UsageError(f"--for {span:g} s: the recorder spans at most {points * MAX_GAP / BASE_HZ:.4g} s "
                             f"with {points} points")
    if continuous and 2 <= points <= MAX_STREAM_POINTS:
        return points, gap, notes
    if continuous:
        raise UsageError(f"{points} samples: a continuous recording streams 2..{MAX_STREAM_POINTS} points")
    if not 2 <= points <= MAX_POINTS:
        raise UsageError(f"{points} samples: the AKD's recorder holds 2..{MAX_POINTS} points (REC.NUMPOINTS); "
                         "lower --rate or --for")
    return points, gap, notes


def check_signals(signals: Sequence[str]) -> None:
    if not signals:
        raise UsageError("scope needs at least one SIGNAL")
    if len(signals) > MAX_CHANNELS:
        raise UsageError(f"{len(signals)} signals: the AKD's recorder has {MAX_CHANNELS} channels (REC.CH1..6)")
    for name in signals:
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9]*\.[A-Za-z0-9.]+", name.strip()):
            raise UsageError(f"signal {name!r}: the recorder records AKD parameters by name (VL.FB, PL.ERR, ...)")


def record(link: CommandLink, spec: RecorderSpec, recording: Recording, *, stopped: Callable[[], bool],
           clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep,
           on_chunk: Callable[[Recording], None] | None = None, on_armed: Callable[[], None] | None = None,
           on_wait: Callable[[], None] | None = None) -> AkdError | None:
    """Program, arm, wait, retrieve into ``recording``; returns the error that ended it early (recording marked
    partial), else None. A refusal while programming raises (nothing was recorded). ``on_armed`` runs once the
    recorder is armed (a recorded move starts there), ``on_wait`` at each REC.DONE poll (watching that move)."""
    link.command("REC.OFF")
    for name, value in spec.writes():
        link.command(f"{name} {value}")
    link.command("REC.TRIG")
    recording.started = utc_now()
    deadline = clock() + spec.timeout_s + spec.span_s
    if spec.ring is not None:
        return _stream(link, spec, recording, stopped=stopped, clock=clock, sleep=sleep, on_chunk=on_chunk,
                       on_armed=on_armed, on_wait=on_wait)
    try:
        if on_armed is not None:
            on_armed()
        while link.command("REC.DONE").strip() != "1":
            if on_wait is not None:
                on_wait()
            if stopped():
                raise Interrupted("interrupted while the recorder ran")
            if clock() > deadline:
                raise TriggerTimeout(f"the recorder did not finish within {spec.timeout_s + spec.span_s:.3g} s "
                                     f"(trigger {spec.trigger.text}; REC.DONE stayed 0)")
            sleep(DONE_POLL_S)
    except AkdError as exc:
        _quiet_off(link)
        recording.mark_partial(f"{exc.message}; nothing retrieved")
        return exc
    try:
        points, gap, names = parse_header(link.command("REC.RETRIEVEHDR"))
        if names != spec.signals[:len(names)] or len(names) != len(spec.signals):
            raise MalformedReply(f"REC.RETRIEVEHDR names {','.join(names)}, expected {','.join(spec.signals)}")
        recording.trigger_index = spec.trigger_index
        step = gap / BASE_HZ
        reply = link.command("REC.RETRIEVEDATA 0")
        while True:
            rows = parse_rows(reply, len(names), skip_first=True)
            if not rows:
                raise MalformedReply(f"REC.RETRIEVEDATA returned no rows after {len(recording)} of {points}")
            for row in rows:
                if len(recording) >= points:
                    break
                recording.add((len(recording) - recording.trigger_index) * step, row)
            if on_chunk is not None:
                on_chunk(recording)
            if len(recording) >= points:
                break
            if stopped():
                raise Interrupted("interrupted while retrieving the recording")
            reply = link.command("REC.RETRIEVEDATA")
    except AkdError as exc:
        recording.mark_partial(f"retrieval stopped after {len(recording)} samples: {exc.message}")
        return exc
    if points != spec.points or gap != spec.gap:
        recording.notes.append(f"the drive recorded {points} points at REC.GAP {gap} "
                               f"(asked {spec.points} at {spec.gap})")
    return None


def _stream(link: CommandLink, spec: RecorderSpec, recording: Recording, *, stopped: Callable[[], bool],
            clock: Callable[[], float], sleep: Callable[[float], None],
            on_chunk: Callable[[Recording], None] | None, on_armed: Callable[[], None] | None,
            on_wait: Callable[[], None] | None) -> AkdError | None:
    """A continuous recording (REC.STOPTYPE 1): chunks of REC.RETRIEVEDATA as the ring fills, until ``points``
    arrived. The drive's overflow error (the ring overwrote rows not yet fetched) ends it, partial."""
    width = len(spec.signals)
    step = spec.gap / BASE_HZ
    recording.trigger_index = spec.trigger_index
    # half the ring's time between fetches at most, so a host that keeps up never overflows
    pause = min(DONE_POLL_S, spec.buffer_points * step / 2)
    deadline = clock() + spec.timeout_s
    try:
        if on_armed is not None:
            on_armed()
        reply = link.command("REC.RETRIEVEDATA 0")
        while True:
            rows = parse_rows(reply, width, skip_first=True)
            first = _chunk_start(reply)
            if rows and first is not None and first != len(recording):
                raise MalformedReply(f"REC.RETRIEVEDATA sent rows from {first}, expected {len(recording)}")
            for row in rows[: spec.points - len(recording)]:
                recording.add((len(recording) - recording.trigger_index) * step, row)
            if rows and on_chunk is not None:
                on_chunk(recording)
            if len(recording) >= spec.points:
                break
            if stopped():
                raise Interrupted("interrupted while the recorder streamed")
            if not recording and clock() > deadline:
                raise TriggerTimeout(f"the recorder sent no rows within {spec.timeout_s:.3g} s "
                                     f"(trigger {spec.trigger.text})")
            if on_wait is not None:
                on_wait()
            if not rows:
                sleep(pause)
            reply = link.command("REC.RETRIEVEDATA")
    except AkdError as exc:
        _quiet_off(link)
        recording.mark_partial(f"streaming stopped after {len(recording)} samples: {exc.message}")
        if not recording:
            recording.trigger_index = None
        return exc
    _quiet_off(link)
    return None


def _chunk_start(reply: str) -> int | None:
    """The first row's index from the first line of a REC.RETRIEVEDATA reply, read as ``<first index>,<rows>``
    as the simulator writes it [I: the drive's first line is not documented]; None when it is not that shape
    (then rows are taken in order, unchecked)."""
    head = reply.replace("\r", "\n").split("\n", 1)[0].strip()
    try:
        return int(head.split(",")[0])
    except ValueError:
        return None


def _quiet_off(link: CommandLink) -> None:
    try:
        link.command("REC.OFF")
    except AkdError:
        pass


def parse_header(text: str) -> tuple[int, int, list[str]]:
    """``Recording`` / ``<points>,<gap>`` / names (akd-ascii-channel.md §2.3); MalformedReply otherwise."""
    lines = [line.strip() for line in text.replace("\r", "\n").split("\n") if line.strip()]
    try:
        start = [line.lower() for line in lines].index("recording")
        points_text, gap_text = lines[start + 1].split(",")[:2]
        names = [n.strip().upper() for n in lines[start + 2].split(",") if n.strip()]
        return int(points_text), int(gap_text), names
    except (ValueError, IndexError):
        raise MalformedReply(f"REC.RETRIEVEHDR: not a recorder header: {text[:80]!r}") from None


_INTERNAL = re.compile(r"F(\d+)(-?)0x([0-9A-Fa-f]+)")


def parse_value(text: str) -> float:
    """One value in either retrieval format: standard ``-0.086`` or internal ``F3-0x56`` (10^-3 x -0x56)."""
    text = text.strip()
    match = _INTERNAL.fullmatch(text)
    if match:
        value = int(match.group(3), 16) / 10 ** int(match.group(1))
        return -value if match.group(2) else value
    try:
        value = float(text)
    except ValueError:
        raise MalformedReply(f"recorder value {text!r} is in neither retrieval format") from None
    if not math.isfinite(value):
        raise MalformedReply(f"recorder value {text!r} is not finite")
    return value


def parse_rows(text: str, width: int, *, skip_first: bool) -> list[list[float]]:
    """Rows of ``width`` values; ``skip_first`` drops REC.RETRIEVEDATA's first line (aakd skips it too)."""
    lines = [line.strip() for line in text.replace("\r", "\n").split("\n") if line.strip()]
    if skip_first:
        lines = lines[1:]
    rows = []
    for line in lines:
        fields = line.split(",")
        if len(fields) != width:
            raise MalformedReply(f"recorder row {line[:60]!r} has {len(fields)} values, expected {width}")
        rows.append([parse_value(f) for f in fields])
    return rows


def parse_retrieve(text: str) -> tuple[int, int, list[str], list[list[float]]]:
    """A whole ``REC.RETRIEVE`` reply: (points, gap, names, rows)."""
    points, gap, names = parse_header(text)
    lines = [line for line in text.replace("\r", "\n").split("\n") if line.strip()]
    start = [line.strip().lower() for line in lines].index("recording")
    rows = parse_rows("\n".join(lines[start + 3:]), len(names), skip_first=False)
    return points, gap, names, rows


def channels_for(signals: Sequence[str]) -> list[Channel]:
    return [Channel(name.upper(), UNITS.get(name.upper(), ""), f"REC.CH{i + 1}") for i, name in enumerate(signals)]
