"""A recording as an SVG picture, with the standard library only (no extra to install).

Why stacked panels, one per unit: a technician compares VL.CMD with VL.FB (both rpm) on one axis, and reads the
following error (rev) or the current (A) on its own scale beside them, as on WorkBench's scope with one y-axis per
unit. Every panel shares the time axis (seconds from the trigger), carries its unit on the y-axis, a legend naming
each trace, grid lines at round values, and the trigger as a dashed vertical line labelled "trigger". A partial
recording says so in red in the title, so a picture of a short recording is never mistaken for a whole one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from xml.sax.saxutils import escape

from akdctl.drive.scope_model import Recording

#: Trace colours (colour-blind-friendly Okabe-Ito order).
COLOURS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
WIDTH = 960
PANEL_H = 230
LEFT, RIGHT, GAP, BOTTOM = 86, 24, 34, 52


def nice_ticks(low: float, high: float, count: int = 6) -> list[float]:
    """Round tick values covering [low, high] (1-2-5 steps)."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return [0.0]
    if high <= low:
        pad = abs(low) * 0.1 or 1.0
        low, high = low - pad, high + pad
    raw = (high - low) / max(1, count - 1)
    power = 10 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1, 2, 2.5, 5, 10) if m * power >= raw)
    first = math.floor(low / step) * step
    ticks = []
    value = first
    while value <= high + step * 1e-9:
        ticks.append(round(value, 12))
        value += step
    if ticks[-1] < high:
        ticks.append(round(value, 12))
    return ticks


def tick_text(value: float, ticks: Sequence[float]) -> str:
    step = abs(ticks[1] - ticks[0]) if len(ticks) > 1 else 1.0
    decimals = max(0, -math.floor(math.log10(step)) + (1 if step / 10 ** math.floor(math.log10(step)) == 2.5 else 0))
    return f"{value:.{min(decimals, 9)}f}"


#: Above this many samples a trace is drawn as its min/max envelope (each of MAX_DRAWN/2 buckets keeps its lowest
#: and highest sample, in time order): a spike survives, a million-sample file stays small.
MAX_DRAWN = 4000


def envelope(times: list[float], values: list[float], max_points: int = MAX_DRAWN) -> tuple[list[float], list[float]]:
    """The points to draw for one trace: all of them, or the min/max envelope when there are more than
    ``max_points``."""
    if len(times) <= max_points:
        return times, values
    buckets = max(1, max_points // 2)
    size = len(times) / buckets
    out_t: list[float] = []
    out_v: list[float] = []
    for b in range(buckets):
        lo = int(b * size)
        segment = values[lo:max(lo + 1, int((b + 1) * size))]  # finite: Recording refuses anything else
        low, high = lo + segment.index(min(segment)), lo + segment.index(max(segment))
        for i in ((low, high) if low < high else (high, low) if high < low else (low,)):
            out_t.append(times[i])
            out_v.append(values[i])
    return out_t, out_v


def unit_groups(recording: Recording) -> list[tuple[str, list[int]]]:
    """(unit, channel indexes) in the order the units first appear."""
    groups: dict[str, list[int]] = {}
    for i, channel in enumerate(recording.channels):
        groups.setdefault(channel.unit, []).append(i)
    return list(groups.items())


def title_of(recording: Recording) -> str:
    return f"akdctl scope — {recording.target} — source {recording.source} — trigger {recording.trigger}"


def subtitle_of(recording: Recording) -> str:
    thinned = f" (drawn as a min/max envelope of {MAX_DRAWN} points)" if len(recording) > MAX_DRAWN else ""
    return recording.summary() + thinned + (f" — {'; '.join(recording.notes)}" if recording.notes else "")


def wrapped(text: str, width: int = 130) -> list[str]:
    import textwrap

    return textwrap.wrap(text, width) or [""]


def render_svg(recording: Recording) -> str:
    """The whole picture as SVG text."""
    groups = unit_groups(recording)
    head = [(line, "#333", "12", "normal") for line in wrapped(subtitle_of(recording))]
    if recording.partial:
        head += [(line, "#C00000", "13", "bold") for line in wrapped(f"PARTIAL: {recording.partial}", 110)]
    top_of_panels = 34 + 18 * len(head)
    height = top_of_panels + len(groups) * PANEL_H + (len(groups) - 1) * GAP + BOTTOM
    plot_w = WIDTH - LEFT - RIGHT
    times = recording.times
    t0, t1 = (times[0], times[-1]) if times else (0.0, 1.0)
    if t1 <= t0:
        t1 = t0 + 1e-3
    xlo, xhi = t0, t1
    xticks = [t for t in nice_ticks(t0, t1, 10) if xlo - 1e-12 <= t <= xhi + 1e-12]

    def x_of(t: float) -> float:
        return LEFT + (t - xlo) / (xhi - xlo) * plot_w

    out = [(f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" '
            f'viewBox="0 0 {WIDTH} {height}" font-family="DejaVu Sans, Arial, sans-serif" font-size="12">'),
           f'<rect width="{WIDTH}" height="{height}" fill="white"/>',
           f'<text x="{LEFT}" y="20" font-size="14" font-weight="bold">{escape(title_of(recording))}</text>']
    for number, (line, colour, size, weight) in enumerate(head):
        out.append(f'<text x="{LEFT}" y="{38 + 18 * number}" font-size="{size}" fill="{colour}" '
                   f'font-weight="{weight}">{escape(line)}</text>')
    trigger_t = recording.trigger_time
    for number, (unit, indexes) in enumerate(groups):
        top = top_of_panels + number * (PANEL_H + GAP)
        bottom = top + PANEL_H
        columns = [recording.values[i] for i in indexes if recording.values[i]]
        lo, hi = (min(min(c) for c in columns), max(max(c) for c in columns)) if columns else (0.0, 1.0)
        yticks = nice_ticks(lo, hi, 6)
        ylo, yhi = yticks[0], yticks[-1]

        def y_of(v: float, ylo: float = ylo, yhi: float = yhi, top: float = top) -> float:
            return top + PANEL_H - (v - ylo) / (yhi - ylo) * PANEL_H

        out.append(f'<rect x="{LEFT}" y="{top}" width="{plot_w}" height="{PANEL_H}" fill="none" stroke="#444"/>')
        for tick in yticks:
            y = y_of(tick)
            out.append(f'<line x1="{LEFT}" y1="{y:.1f}" x2="{LEFT + plot_w}" y2="{y:.1f}" stroke="#ddd"/>')
            out.append(f'<text x="{LEFT - 6}" y="{y + 4:.1f}" text-anchor="end">{tick_text(tick, yticks)}</text>')
        for tick in xticks:
            x = x_of(tick)
            out.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{bottom}" stroke="#eee"/>')
            if number == len(groups) - 1:
                out.append(f'<text x="{x:.1f}" y="{bottom + 16}" text-anchor="middle">{tick_text(tick, xticks)}</text>')
        label = unit or "value"
        out.append(f'<text transform="translate(18,{top + PANEL_H / 2:.0f}) rotate(-90)" text-anchor="middle" '
                   f'font-weight="bold">{escape(label)}</text>')
        for i in indexes:
            colour = COLOURS[i % len(COLOURS)]
            drawn_t, drawn_v = envelope(times, recording.values[i])
            points = " ".join(f"{x_of(t):.2f},{y_of(v):.2f}" for t, v in zip(drawn_t, drawn_v) if math.isfinite(v))
            if points:
                out.append(f'<polyline fill="none" stroke="{colour}" stroke-width="1.6" points="{points}"/>')
        legend_x = LEFT + 8
        for i in indexes:
            colour = COLOURS[i % len(COLOURS)]
            text = recording.channels[i].legend
            out.append(f'<rect x="{legend_x}" y="{top + 8}" width="14" height="4" fill="{colour}"/>')
            out.append(f'<text x="{legend_x + 18}" y="{top + 14}">{escape(text)}</text>')
            legend_x += 26 + 7 * len(text)
        if trigger_t is not None and xlo <= trigger_t <= xhi:
            x = x_of(trigger_t)
            out.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{bottom}" stroke="#C00000" '
                       f'stroke-dasharray="6,4" stroke-width="1.4"/>')
            out.append(f'<text x="{x + 4:.1f}" y="{bottom - 6}" fill="#C00000">trigger</text>')
    axis_y = height - 14
    out.append(f'<text x="{LEFT + plot_w / 2:.0f}" y="{axis_y}" text-anchor="middle" font-weight="bold">'
               f'time [s] (0 = {recording.time_origin})</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"
