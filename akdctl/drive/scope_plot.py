"""A recording as a terminal plot (plotille) or a PNG (matplotlib, the optional ``plot`` extra).

Why these two: a technician at a shell wants to *see* the ramp while it records, without a window (plotille: pure
Python, no dependencies, 17 ms import, foe-alias-recorder.md §D), and support wants an image file; the SVG writer
(:mod:`akdctl.drive.scope_svg`) needs nothing installed, the PNG needs matplotlib, so it is an extra and a missing
extra is one clear line. Both are imported here, lazily, so no other command pays for them.

Both show what the SVG shows: one panel per unit, time in seconds from the trigger, legends, the trigger as a
vertical line, and PARTIAL in the title of a recording that ended early.
"""

from __future__ import annotations

from akdctl.drive.scope_model import Recording
from akdctl.drive.scope_svg import COLOURS, envelope, subtitle_of, title_of, unit_groups
from akdctl.errors import UsageError

TERMINAL_COLOURS = ("blue", "red", "green", "magenta", "yellow", "cyan")


def terminal_plot(recording: Recording, width: int = 72, height: int = 12, colours: bool = False) -> str:
    """The plot as text: one plotille figure per unit (axis labels carry the units), legend, the trigger marked
    by a vertical line and named under the figure."""
    import plotille

    lines = [title_of(recording), subtitle_of(recording)]
    if recording.partial:
        lines.append(f"PARTIAL: {recording.partial}")
    times = recording.times
    if len(times) < 2:
        lines.append("(fewer than two samples: nothing to plot)")
        return "\n".join(lines) + "\n"
    t0, t1 = times[0], times[-1]
    trigger_t = recording.trigger_time
    for unit, indexes in unit_groups(recording):
        fig = plotille.Figure()
        fig.width, fig.height = max(20, width), max(4, height)
        fig.with_colors = colours
        fig.register_label_formatter(float, _label)
        fig.x_label, fig.y_label = "t [s]", unit or "value"  # t = 0: recording.time_origin, named below
        fig.set_x_limits(min_=t0, max_=t1 if t1 > t0 else t0 + 1e-3)
        columns = [recording.values[i] for i in indexes if recording.values[i]]
        lo, hi = (min(min(c) for c in columns), max(max(c) for c in columns)) if columns else (0.0, 1.0)
        if hi <= lo:
            lo, hi = lo - (abs(lo) * 0.1 or 1.0), hi + (abs(hi) * 0.1 or 1.0)
        fig.set_y_limits(min_=lo, max_=hi)
        for i in indexes:
            drawn_t, drawn_v = envelope(times, recording.values[i], max(200, 4 * width))
            fig.plot(drawn_t, drawn_v, label=recording.channels[i].legend,
                     lc=TERMINAL_COLOURS[i % len(TERMINAL_COLOURS)] if colours else None)
        if trigger_t is not None and t0 < trigger_t <= t1:
            fig.axvline((trigger_t - t0) / (t1 - t0), lc="red" if colours else None)
        lines.append(fig.show(legend=True))
        if trigger_t is not None:
            lines.append(f"trigger ({recording.trigger}) at t = {trigger_t:g} s"
                         + (" (vertical line)" if t0 < trigger_t <= t1 else " (first sample)"))
        else:
            lines.append("no trigger: t = 0 is the first sample")
    return "\n".join(lines) + "\n"


def _label(value: float, chars: int, delta: float, left: bool = False) -> str:
    """Axis labels with 4 significant digits (plotille's default prints 7: ``0.2939038``)."""
    text = f"{value:.4g}"
    return text.ljust(chars) if left else text.rjust(chars)


def write_png(recording: Recording, path: str) -> None:
    """The picture as PNG via matplotlib (Agg, no display); UsageError naming the extra when it is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        from matplotlib.figure import Figure
    except ImportError:
        raise UsageError("--png needs matplotlib: pip install 'akdctl[plot]' (or use --svg, which needs nothing)") \
            from None
    groups = unit_groups(recording)
    fig = Figure(figsize=(11, 1.2 + 2.6 * len(groups)), dpi=100)
    axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
    import textwrap

    title = f"{title_of(recording)}\n" + "\n".join(textwrap.wrap(subtitle_of(recording), 150))
    if recording.partial:
        title += f"\nPARTIAL: {recording.partial}"
    fig.suptitle(title, fontsize=9, color="#C00000" if recording.partial else "black")
    trigger_t = recording.trigger_time
    for ax, (unit, indexes) in zip(axes, groups):
        for i in indexes:
            drawn_t, drawn_v = envelope(recording.times, recording.values[i])
            ax.plot(drawn_t, drawn_v, color=COLOURS[i % len(COLOURS)], linewidth=1.2,
                    label=recording.channels[i].legend)
        ax.set_ylabel(unit or "value")
        ax.grid(True, color="#ddd")
        if trigger_t is not None:
            ax.axvline(trigger_t, color="#C00000", linestyle="--", linewidth=1.2, label="trigger")
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel(f"time [s] (0 = {recording.time_origin})")
    fig.tight_layout()
    import io
    from pathlib import Path

    from akdctl.io.atomic import atomic_open

    image = io.BytesIO()
    fig.savefig(image, format="png")
    with atomic_open(Path(path), "wb") as out:  # as every file akdctl writes: whole or not at all
        out.write(image.getvalue())
