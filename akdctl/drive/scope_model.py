"""One sample model for every scope source: a time axis, named channels with units, and the trigger's index.

Why one model: the poll, recorder and PDO sources differ in how samples reach the host (one request per sample,
the drive's recorder buffer, one bus cycle each), but a technician reads the same picture from each, and the CSV,
SVG, PNG, JSON, the terminal plot, a support bundle and a recipe's bounds all read this one record. So a source
only fills a :class:`Recording`; nothing below it knows about files or plots.

Time: seconds relative to the trigger sample (negative before it), as WorkBench's scope shows it. The poll source
stamps samples with the host's monotonic clock; the recorder has no time column and the axis comes from REC.GAP
(shared/reference/foe-alias-recorder.md §C3).

A recording that ended early (a timeout, a refusal, an overflow) keeps what was taken and says why in
``partial``; every output marks it (CSV comment ``# PARTIAL: ...``, JSON ``"partial"``, a title in the plots),
so a short file is never mistaken for a whole one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from akdctl.protocol.record import Record

FORMAT_VERSION = 1


class Channel(Record):
    """One recorded signal: ``name`` as the user gave it (``VL.FB``, ``0x606C:0``, ``PNU 6``), its ``unit``
    (``""`` when it has none) and where it came from (``address``: ``0x606C:0``, ``PNU 6``, ``REC.CH1``)."""

    __slots__ = ("address", "name", "unit")

    def __init__(self, name: str, unit: str = "", address: str = "") -> None:
        self.name = name
        self.unit = unit
        self.address = address

    @property
    def label(self) -> str:
        return f"{self.name} [{self.unit}]" if self.unit else self.name

    @property
    def legend(self) -> str:
        """The label plus where it was read, when that is not the name itself (``VL.FB [rpm] (PNU 6)``)."""
        if self.address and self.address.upper() != self.name.upper() and not self.address.startswith("REC."):
            return f"{self.label} ({self.address})"
        return self.label

    def to_json(self) -> dict[str, str]:
        return {"name": self.name, "unit": self.unit, "address": self.address}


class Recording:
    """Samples of ``channels`` at ``times`` (s, 0 = trigger); ``values[i]`` is channel i's column."""

    def __init__(self, target: str, source: str, channels: Sequence[Channel], *, trigger: str = "immediate",
                 rate_requested: float | None = None) -> None:
        self.target = target
        self.source = source
        self.channels = list(channels)
        self.times: list[float] = []
        self.values: list[list[float]] = [[] for _ in self.channels]
        self.trigger = trigger
        self.trigger_index: int | None = None
        self.rate_requested = rate_requested
        self.partial: str | None = None
        self.notes: list[str] = []
        self.started: str = ""  # wall-clock time of the first sample, ISO 8601 UTC (for the reader, not the axis)
        #: named instants on the time axis (``motion_start``, ``jog_end``), stamped by the source's clock
        self.events: dict[str, float] = {}

    # ------------------------------------------------------------------ filling
    def add(self, t: float, row: Sequence[float]) -> None:
        """One sample; every value finite (a source's parser refuses anything else: MalformedReply)."""
        self.times.append(float(t))
        for column, value in zip(self.values, row):
            column.append(float(value))

    def __len__(self) -> int:
        return len(self.times)

    def mark_partial(self, why: str) -> None:
        """Keep what was recorded and say why it is not the whole recording."""
        if self.partial is None:
            self.partial = why

    def shift_to_trigger(self) -> None:
        """Make the trigger sample t = 0 (a source stamps from its own start); without a trigger (it never
        fired) the first sample is t = 0 (:attr:`time_origin` says which)."""
        if self.trigger_index is not None and 0 <= self.trigger_index < len(self.times):
            zero = self.times[self.trigger_index]
        elif self.times:
            zero = self.times[0]
        else:
            return
        self.times = [t - zero for t in self.times]
        self.events = {name: t - zero for name, t in self.events.items()}

    @property
    def time_origin(self) -> str:
        """What t = 0 is, for axis labels."""
        return "trigger" if self.trigger_time is not None else "first sample, no trigger"

    # ------------------------------------------------------------------ facts
    @property
    def rate_achieved(self) -> float | None:
        """Samples per second actually taken (mean spacing); None with fewer than two samples."""
        if len(self.times) < 2 or self.times[-1] <= self.times[0]:
            return None
        return (len(self.times) - 1) / (self.times[-1] - self.times[0])

    @property
    def rate_sustained(self) -> float | None:
        """Samples per second at the median spacing (what the link sustains, pauses aside); None with fewer
        than two samples."""
        cached = self.__dict__.get("_median")
        if cached is not None and cached[0] == len(self.times):
            return cached[1]  # type: ignore[no-any-return]
        gaps = sorted(b - a for a, b in zip(self.times, self.times[1:]))
        rate = None if not gaps or gaps[len(gaps) // 2] <= 0 else 1.0 / gaps[len(gaps) // 2]
        self.__dict__["_median"] = (len(self.times), rate)
        return rate

    @property
    def trigger_time(self) -> float | None:
        if self.trigger_index is None or not 0 <= self.trigger_index < len(self.times):
            return None
        return self.times[self.trigger_index]

    def column(self, name: str) -> list[float]:
        for channel, column in zip(self.channels, self.values):
            if channel.name.upper() == name.upper():
                return column
        raise KeyError(name)

    def summary(self) -> str:
        """One line: samples, span, the achieved rate against the requested one."""
        span = (self.times[-1] - self.times[0]) if len(self.times) > 1 else 0.0
        rate = self.rate_achieved
        text = f"{len(self)} samples over {span:.4g} s"
        if rate is not None:
            text += f", {rate:.4g} samples/s achieved"
            sustained = self.rate_sustained
            if sustained is not None and abs(sustained - rate) > 0.1 * rate:
                text += f" ({sustained:.4g}/s at the median spacing)"
        if self.rate_requested:
            text += f" ({self.rate_requested:.6g} requested)"
        return text

    # ------------------------------------------------------------------ outputs
    def comment_line(self) -> str:
        rate = self.rate_achieved
        parts = [f"target={self.target}", f"source={self.source}",
                 f"rate={rate:.6g}Hz" if rate is not None else "rate=n/a"]
        sustained = self.rate_sustained
        if sustained is not None and rate is not None and abs(sustained - rate) > 0.1 * rate:
            parts.append(f"median_rate={sustained:.6g}Hz")
        if self.rate_requested:
            parts.append(f"requested={self.rate_requested:.6g}Hz")
        parts += [f"trigger={self.trigger}", f"trigger_index={self.trigger_index if self.trigger_index is not None else ''}",
                  f"samples={len(self)}"]
        if self.started:
            parts.append(f"started={self.started}")
        return "# akdctl scope: " + " ".join(parts)

    def to_csv(self) -> str:
        """CSV: a comment line (target, source, rate, trigger), ``# PARTIAL: ...`` when partial, ``# note: ...``,
        a header naming each column with its unit, then one row per sample."""
        lines = [self.comment_line()]
        if self.partial:
            lines.append(f"# PARTIAL: {self.partial}")
        lines += [f"# note: {note}" for note in self.notes]
        lines.append(",".join(["t [s]"] + [_csv_field(c.label) for c in self.channels]))
        for i, t in enumerate(self.times):
            lines.append(",".join([f"{t:.6f}"] + [_number(column[i]) for column in self.values]))
        return "\n".join(lines) + "\n"

    def to_json(self) -> dict[str, Any]:
        return {"format": "akdctl-scope", "version": FORMAT_VERSION, "target": self.target, "source": self.source,
                "started": self.started, "trigger": {"condition": self.trigger, "index": self.trigger_index},
                "rate_hz": {"requested": self.rate_requested, "achieved": self.rate_achieved,
                            "median": self.rate_sustained},
                "samples": len(self), "partial": self.partial, "notes": list(self.notes), "events": dict(self.events),
                "channels": [c.to_json() for c in self.channels], "t": list(self.times),
                "values": [list(column) for column in self.values]}

    @classmethod
    def from_json(cls, data: Any) -> Recording:
        """A recording back from :meth:`to_json` (a bundle member, a file); ValueError when it is not one."""
        if not isinstance(data, dict) or data.get("format") != "akdctl-scope":
            raise ValueError("not an akdctl scope recording")
        try:
            channels = [Channel(str(c["name"]), str(c.get("unit", "")), str(c.get("address", "")))
                        for c in data["channels"]]
            trigger = data.get("trigger") or {}
            rate = data.get("rate_hz") or {}
            rec = cls(str(data.get("target", "")), str(data.get("source", "")), channels,
                      trigger=str(trigger.get("condition", "immediate")), rate_requested=rate.get("requested"))
            times = [float(t) for t in data["t"]]
            columns = [[float(v) for v in column] for column in data["values"]]
            if not all(math.isfinite(v) for v in times) or not all(math.isfinite(v) for c in columns for v in c):
                raise ValueError("a time or value is not a finite number")
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ValueError(f"damaged scope recording: {exc}") from None
        if len(columns) != len(channels) or any(len(column) != len(times) for column in columns):
            raise ValueError("damaged scope recording: columns and time axis differ in length")
        rec.times, rec.values = times, columns
        index = trigger.get("index")
        rec.trigger_index = int(index) if isinstance(index, int) else None
        rec.partial = data.get("partial") or None
        rec.notes = [str(n) for n in data.get("notes") or []]
        rec.started = str(data.get("started") or "")
        events = data.get("events") or {}
        rec.events = {str(k): float(v) for k, v in events.items()} if isinstance(events, dict) else {}
        return rec


def _number(value: float) -> str:
    if math.isnan(value):
        return ""
    return f"{value:.6g}" if not float(value).is_integer() else str(int(value))


def _csv_field(text: str) -> str:
    return f'"{text}"' if any(ch in text for ch in ',"\n') else text


def utc_now() -> str:
    import datetime

    return datetime.datetime.now(datetime.UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


#: The largest recording file ``support bundle --scope`` reads (10000 points x 6 channels as JSON is ~2 MiB).
MAX_RECORDING_BYTES = 16 * 1024 * 1024


def load_recording(path: str) -> Recording:
    """A recording from a file ``scope --json`` wrote (``{"recording": ...}``) or its bare recording object;
    UsageError (exit 2) in one line for a missing, oversized, foreign or damaged file."""
    import json

    from akdctl.errors import UsageError
    from akdctl.io.safe_read import FileRefused, read_bounded

    try:
        raw = read_bounded(path, MAX_RECORDING_BYTES)
    except FileRefused as exc:
        raise UsageError(f"{path}: not read as a scope recording: {exc}") from None
    except OSError as exc:
        raise UsageError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        data = json.loads(raw.decode("utf-8"))
        if isinstance(data, dict) and "recording" in data:
            data = data["recording"]
        return Recording.from_json(data)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError, ValueError) as exc:
        raise UsageError(f"{path}: not an akdctl scope recording ({type(exc).__name__}: {str(exc)[:80]})") from None
