"""The poll source: the host reads the signals, one request per sample where the channel batches.

Why on the host: every transport can read parameters or objects, so this is the scope that always works; it is
also the slowest (a real AKD answers a few hundred SDOs per second: foe-alias-recorder.md §C2), so it never
pretends: each sample carries the host's monotonic time of its read, the rate printed is the rate achieved, and a
requested rate the link cannot reach marks the recording partial instead of stretching the time axis.

Pre-trigger: until the trigger fires, the samples of the last ``pretrigger`` share of the recording are kept in a
ring; a trigger is looked for only once that ring is full, so the recording has the requested share before the
trigger (as the drive's recorder does: sim/recorder.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from akdctl.drive.scope_model import Recording, utc_now
from akdctl.drive.scope_trigger import Trigger
from akdctl.errors import AkdError, CommError, Interrupted, TriggerTimeout

#: A requested rate counts as reached when at least this share of it was achieved.
RATE_TOLERANCE = 0.9
#: Below this many seconds between samples the loop does not sleep at all.
MIN_SLEEP_S = 0.0002


class PollSpec:
    """How long and how fast: exactly one of ``samples`` / ``duration_s``; ``rate_hz`` None = as fast as the link
    answers; ``pretrigger`` percent; ``timeout_s`` bounds the wait for the trigger."""

    def __init__(self, *, samples: int | None = None, duration_s: float | None = None, rate_hz: float | None = None,
                 trigger: Trigger | None = None, pretrigger: float = 0.0, timeout_s: float = 10.0) -> None:
        self.samples = samples
        self.duration_s = duration_s
        self.rate_hz = rate_hz
        self.trigger = trigger or Trigger()
        self.pretrigger = pretrigger
        self.timeout_s = timeout_s

    @property
    def pre_samples(self) -> int | None:
        if self.samples is None:
            return None
        return min(self.samples - 1, round(self.samples * self.pretrigger / 100.0))

    @property
    def pre_seconds(self) -> float:
        return (self.duration_s or 0.0) * self.pretrigger / 100.0


def record(read: Callable[[], list[float]], recording: Recording, spec: PollSpec, *, trigger_slot: int | None,
           stopped: Callable[[], bool] = lambda: False, on_sample: Callable[[Recording], None] | None = None,
           clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep,
           on_first: Callable[[], None] | None = None, on_tick: Callable[[], None] | None = None,
           ) -> AkdError | None:
    """Fill ``recording`` from ``read()`` (one row: the recording's channels, then hidden trigger/status values);
    ``trigger_slot`` is the row index the trigger watches; ``on_first`` runs once the trigger is armed: after the
    first sample, or once the pre-trigger share is taken (a recorded move starts there, so the recording shows the
    axis at rest first and the move's edge is looked for). Returns the error that ended it early (the
    recording is then marked partial and keeps what it has), else None. ``on_tick`` runs before each sample
    (a recorded jog ends at its duration there)."""
    width = len(recording.channels)
    trig = spec.trigger
    period = 1.0 / spec.rate_hz if spec.rate_hz else 0.0
    pre: list[tuple[float, list[float]]] = []
    read_times: list[float] = []  # how long each sample's reads took (its values are that far apart at most)
    previous: float | None = None
    fired = trig.kind == "immediate"
    armed = False
    full = False
    start = clock()
    due = start
    post_start = start
    try:
        while True:
            if stopped():
                raise Interrupted("interrupted while recording")
            if on_tick is not None:
                on_tick()
            now = clock()
            if period:
                if due - now > MIN_SLEEP_S:
                    sleep(due - now)
                elif now - due > period:  # behind: never burst to catch up
                    due = now
                due += period
            t = clock()
            row = read()
            read_times.append(clock() - t)
            if not recording.started:
                recording.started = utc_now()
            if not fired:
                pre.append((t, row))
                full = (len(pre) > (spec.pre_samples or 0)) if spec.samples is not None \
                    else (t - pre[0][0] >= spec.pre_seconds)
            if not armed and (fired or full):
                # armed: the pre-trigger ring is full, so a recorded motion starts now, never while the trigger
                # is not yet looked for (its edge would pass unseen)
                armed = True
                if on_first is not None:
                    on_first()
            if not fired:
                value = row[trigger_slot] if trigger_slot is not None else 0.0
                if full and trig.fires(previous, value):
                    fired = True
                    keep = pre[-((spec.pre_samples or 0) + 1):] if spec.samples is not None \
                        else [(ts, r) for ts, r in pre if ts >= t - spec.pre_seconds]
                    for ts, r in keep:
                        recording.add(ts, r[:width])
                    recording.trigger_index = len(recording) - 1
                    post_start = t
                    pre = []
                else:
                    previous = value
                    limit = (spec.pre_samples or 0) + 1 if spec.samples is not None else None
                    if limit is not None and len(pre) > limit:
                        del pre[0]
                    elif limit is None:
                        while len(pre) > 1 and t - pre[1][0] >= spec.pre_seconds:
                            del pre[0]
                    if t - start > spec.timeout_s + spec.pre_seconds:
                        raise TriggerTimeout(f"the trigger ({trig.text}) did not fire within {spec.timeout_s:g} s")
                    continue
            else:
                recording.add(t, row[:width])
                if recording.trigger_index is None:
                    recording.trigger_index = 0
                    post_start = t
            if on_sample is not None:
                on_sample(recording)
            if spec.samples is not None and len(recording) >= spec.samples:
                break
            if spec.duration_s is not None and t - post_start >= spec.duration_s - spec.pre_seconds:
                break
    except AkdError as exc:
        if not fired:  # what was taken while waiting for the trigger is kept (no trigger index)
            for ts, r in pre:
                recording.add(ts, r[:width])
        recording.mark_partial(_why(exc, len(recording)))
        recording.shift_to_trigger()
        _timing_notes(recording, read_times)
        return exc
    recording.shift_to_trigger()
    _timing_notes(recording, read_times)
    return check_rate(recording)


def _timing_notes(recording: Recording, read_times: list[float]) -> None:
    """What a reader of the picture must know about the host's timing: how long one sample's reads took (its
    values were read that far apart; its time is the start of its reads) and the largest gap between samples."""
    if read_times:
        recording.notes.append(f"one sample's reads took {1000 * sum(read_times) / len(read_times):.3g} ms on "
                               f"average, {1000 * max(read_times):.3g} ms at most (t = start of its reads)")
    gaps = [b - a for a, b in zip(recording.times, recording.times[1:])]
    if gaps:
        ordered = sorted(gaps)
        median = ordered[len(ordered) // 2]
        if max(gaps) > 2 * median:
            at = recording.times[gaps.index(max(gaps))]
            recording.notes.append(f"uneven spacing: largest gap {1000 * max(gaps):.3g} ms at t = {at:.4g} s "
                                   f"(median {1000 * median:.3g} ms)")


class RateNotReached(CommError):
    """The link did not sustain the requested rate (exit 3); the samples were taken and the motion, if any, ran
    to its end as planned."""

    kind = "rate-not-reached"


def check_rate(recording: Recording) -> AkdError | None:
    """A requested rate the link did not sustain (the median spacing: a single pause, such as the drive
    accepting a recorded jog's start, is named in the notes, not counted as the link's rate): the recording is
    marked partial and a RateNotReached returned."""
    wanted, got = recording.rate_requested, recording.rate_sustained
    if wanted and got is not None and got < RATE_TOLERANCE * wanted:
        why = (f"requested {wanted:g} samples/s, the link reached {got:.4g}/s "
               f"({recording.notes[0] if recording.notes else 'one request per sample'})")
        recording.mark_partial(why)
        return RateNotReached(f"rate not reached: {why}; the file holds the samples taken, at their real times")
    return None


def _why(exc: AkdError, taken: int) -> str:
    if isinstance(exc, TriggerTimeout):
        return f"{exc.message}; only pre-trigger samples ({taken}), no trigger"
    if isinstance(exc, Interrupted):
        return f"interrupted after {taken} samples"
    return f"stopped after {taken} samples: {exc.message}"


__all__ = ["PollSpec", "RateNotReached", "TriggerTimeout", "check_rate", "record"]