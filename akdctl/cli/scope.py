"""``akdctl scope SIGNAL...``: record signals and show them as a picture.

Thin, like every command: parse, plan (drive/scope.py), ask the one consent when the recording moves the axis,
execute under the stop signals, then render: a terminal plot (plotille), ``--csv``, ``--svg``, ``--png``,
``--json``. A recording that ended early is still written, marked partial in every output, and the command then
exits with the error's code (docs/scope.md).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.errors import CheckFailed, UsageError

#: How often the live terminal plot is redrawn while the poll source records (seconds).
LIVE_REDRAW_S = 0.5


@click.command()
@click.argument("signals", nargs=-1, required=True, metavar="SIGNAL...")
@click.option("--for", "duration", metavar="DURATION", help="How long to record (2s, 500ms; default 1 s).")
@click.option("--samples", type=int, metavar="N", help="How many samples to record (instead of --for).")
@click.option("--rate", type=float, metavar="HZ",
              help="Samples per second (poll: paced, the rate achieved is printed; recorder: 16000/REC.GAP; "
                   "pdo: the bus cycle, 16000/N up to 4000, default the drive's 0x60C2).")
@click.option("--source", type=click.Choice(["auto", "poll", "recorder", "pdo"]), default="auto", show_default=True,
              help="poll: the host reads (every transport); recorder: the AKD's REC.* (akd://, sim); "
                   "pdo: one sample per EtherCAT cycle from the mapped TxPDO (ecat://, this host the master, the "
                   "slave in SAFE-OP). auto: recorder on akd://, else poll.")
@click.option("--trigger", metavar="COND", help="immediate (default), rise:SIG:LEVEL, fall:SIG:LEVEL, "
                                                 "above:SIG:LEVEL, below:SIG:LEVEL, bit:N[=0|1], fault.")
@click.option("--pretrigger", type=float, default=0.0, metavar="PCT", help="Share of the recording before the "
                                                                           "trigger, in percent.")
@click.option("--timeout", "wait_s", type=float, default=10.0, show_default=True, metavar="SECONDS",
              help="How long to wait for the trigger (recorder: for REC.DONE, plus the recording's span).")
@click.option("--csv", "csv_path", metavar="FILE", help="Write CSV (header with names and units; '-' = stdout).")
@click.option("--svg", "svg_path", metavar="FILE", help="Write an SVG plot (no extra needed).")
@click.option("--png", "png_path", metavar="FILE", help="Write a PNG plot (needs the 'plot' extra: matplotlib).")
@click.option("--plot/--no-plot", default=None, help="Terminal plot on stdout (default: on unless --json or --csv -).")
@click.option("--continuous", is_flag=True,
              help="Recorder: stream a continuous recording (REC.STOPTYPE 1) through the drive's ring, so --samples "
                   "may exceed its 10000 points; a host too slow for the rate gets the drive's overflow error.")
@click.option("--ring", type=int, metavar="N", help="Points of the drive's ring for --continuous (default 10000).")
@click.option("--jog", "jog_rpm", type=float, metavar="RPM",
              help="Record during a jog at RPM for --jog-for (as 'jog --for'); asks consent like 'jog'.")
@click.option("--jog-for", "jog_for", metavar="DURATION", help="How long the recorded jog runs (e.g. 1s).")
@click.option("--accel", type=float, metavar="RPM/S", help="Acceleration of the recorded jog (default as 'jog').")
@click.option("--max-following-error", "max_fe", type=float, metavar="X",
              help="Check: |PL.ERR| stays at most X at every sample (exit 5 otherwise).")
@click.option("--max-settle-time", "max_settle", type=float, metavar="S",
              help="Check: after the recorded jog ends, PL.ERR is within --settle-band within S seconds (exit 5).")
@click.option("--settle-band", type=float, metavar="B", help="The band of --max-settle-time (PL.ERR's unit).")
@click.option("--dry-run", is_flag=True, help="Show what would be written and moved; record nothing.")
def scope(signals: tuple[str, ...], duration: str | None, samples: int | None, rate: float | None, source: str,
          trigger: str | None, pretrigger: float, wait_s: float, csv_path: str | None, svg_path: str | None,
          png_path: str | None, plot: bool | None, continuous: bool, ring: int | None,
          jog_rpm: float | None, jog_for: str | None,
          accel: float | None, max_fe: float | None, max_settle: float | None, settle_band: float | None,
          dry_run: bool) -> None:
    """Record SIGNALs (VL.FB, VL.CMD, PL.FB, PL.ERR, IL.FB, 0x606C:0, PNU 6 and more) and plot them.

    A recording that ends early (no answer, a rate the link does not sustain, a trigger that never fires, the
    recorder's overflow, Ctrl-C) is still written, marked PARTIAL in every output, and the command exits with
    the error's code (docs/scope.md).

    \b
    Examples:
      akdctl scope VL.FB PL.ERR --for 2s --rate 200 --svg jog.svg
      akdctl -y scope VL.FB PL.ERR --jog 300 --jog-for 1s --for 2s --csv jog.csv --svg jog.svg
      akdctl scope VL.FB --source recorder --samples 2000 --rate 4000 --trigger rise:VL.FB:100 --pretrigger 10
      akdctl scope IL.FB --trigger fault --pretrigger 50 --for 1s --timeout 60 --json
      akdctl -T ecat://eth0 -y scope VL.FB 0x606C --source pdo --rate 1000 --jog 300 --jog-for 1s --csv jog.csv
    """
    from akdctl.cli.motion import _duration
    from akdctl.drive import scope as op

    app = get_app()
    request = op.build_request(signals, duration_s=_duration(duration) if duration is not None else None,
                               samples=samples, rate_hz=rate, source=source, trigger=trigger, pretrigger=pretrigger,
                               timeout_s=wait_s, jog_rpm=jog_rpm, jog_s=_duration(jog_for) if jog_for else None,
                               accel=accel, ring=(ring if ring is not None else 10000) if continuous else None)
    if ring is not None and not continuous:
        raise UsageError("--ring sizes a continuous recording: give --continuous too")
    if csv_path == "-" and app.json:
        raise UsageError("--csv - and --json both write to stdout: give --csv a file name")
    op.check(request)  # bad input exits 2 before the target is opened
    bounds = op.Bounds(max_fe, max_settle, settle_band)
    bounds.check_request(request)
    for path in (csv_path, svg_path, png_path):
        if path not in (None, "-"):
            _check_writable(path)
    if png_path is not None:
        _check_png_extra()
    conn = app.connection
    plan = op.plan(conn, request)
    if dry_run:
        _render_plan(app, plan)
        return
    motion = op.motion_text(plan)
    if motion is not None:
        from akdctl.cli.consent import require_consent

        require_consent(app, motion)
    from akdctl.cli.signals import stop_signals

    live = _LivePlot() if (not app.json and sys.stderr.isatty() and plot is not False) else None
    with stop_signals() as stop:  # a stop signal ends the recording; the files are still written, then it exits
        recording, failure = op.execute(conn, plan, stopped=stop, on_sample=live.update if live else None)
        if live is not None:
            live.clear()
        written = _write_outputs(recording, csv_path, svg_path, png_path)
        broken: CheckFailed | None = None
        measured: Any = None
        if failure is None and bounds.any:
            try:
                measured = op.check_bounds(recording, bounds)
            except CheckFailed as exc:
                broken, measured = exc, exc.details.get("measured")
        _render(app, recording, written, plot if plot is not None else not app.json and csv_path != "-",
                None if not bounds.any else {"measured": measured, "kept": failure is None and broken is None})
        if failure is not None:
            if written:
                failure.message += f"; partial recording written to {', '.join(written)}"
            failure.reported = app.json
            raise failure
    if broken is not None:
        broken.reported = app.json
        raise broken
    if measured:
        from akdctl.cli.output import message

        message("bounds kept: " + ", ".join(f"{k} {v:.6g}" for k, v in measured.items()))


def _check_writable(path: str) -> None:
    if Path(path).expanduser().is_dir():
        raise UsageError(f"cannot write {path}: it is a directory; give a file name")
    parent = Path(path).expanduser().resolve().parent
    if not parent.is_dir():
        raise UsageError(f"cannot write {path}: directory {parent} does not exist")


def _check_png_extra() -> None:
    try:
        import matplotlib  # noqa: F401 - only asked when --png is given
    except ImportError:
        raise UsageError("--png needs matplotlib: pip install 'akdctl[plot]' (or use --svg, which needs nothing)") \
            from None


def _write_outputs(recording: Any, csv_path: str | None, svg_path: str | None, png_path: str | None) -> list[str]:
    """Write the files asked for; one that cannot be written is a one-line usage error naming it (those written
    before it stay, and are named)."""
    written: list[str] = []
    try:
        _write_files(recording, csv_path, svg_path, png_path, written)
    except OSError as exc:
        done = f" (written: {', '.join(written)})" if written else ""
        raise UsageError(f"cannot write {exc.filename or 'an output file'}: {exc.strerror or exc}{done}") from None
    return written


def _write_files(recording: Any, csv_path: str | None, svg_path: str | None, png_path: str | None,
                 written: list[str]) -> None:
    from akdctl.io.atomic import atomic_open

    if csv_path == "-":
        sys.stdout.write(recording.to_csv())
    elif csv_path is not None:
        with atomic_open(Path(csv_path)) as out:
            out.write(recording.to_csv())
        written.append(csv_path)
    if svg_path is not None:
        from akdctl.drive.scope_svg import render_svg

        with atomic_open(Path(svg_path)) as out:
            out.write(render_svg(recording))
        written.append(svg_path)
    if png_path is not None:
        from akdctl.drive.scope_plot import write_png

        write_png(recording, png_path)
        written.append(png_path)


def _render_plan(app: Any, plan: Any) -> None:
    from akdctl.cli.output import emit_json

    motion = plan.data.get("motion")
    if app.json:
        data = plan.to_json()
        data["source"] = plan.data["source"]
        if motion is not None:
            data["motion"] = motion.to_json()
        emit_json({"dry_run": True, "plan": data})
        return
    lines = [f"source: {plan.data['source']}", *plan.lines()]
    sys.stdout.write("\n".join(lines) + "\n")


def _render(app: Any, recording: Any, written: list[str], plot: bool, bounds: dict[str, Any] | None) -> None:
    from akdctl.cli.output import Doc, emit_json, message, render

    if app.json:
        data = recording.to_json()
        data["files"] = written
        document: dict[str, Any] = {"recording": data}
        if bounds is not None:
            document["bounds"] = bounds
        emit_json(document)
        return
    message(recording.summary() + (f"; PARTIAL: {recording.partial}" if recording.partial else ""))
    if plot:
        from akdctl.drive.scope_plot import terminal_plot

        width = max(40, min(160, _columns() - 14))
        sys.stdout.write(terminal_plot(recording, width=width, height=12, colours=sys.stdout.isatty()))
        return
    if written:
        doc = Doc("scope", recording.target)
        doc.kv("source", recording.source)
        doc.kv("samples", len(recording))
        doc.kv("files", ", ".join(written))
        render(doc)


def _columns() -> int:
    import shutil

    return shutil.get_terminal_size((100, 24)).columns


class _LivePlot:
    """The plot redrawn in place on stderr while recording (a terminal only), at most every LIVE_REDRAW_S."""

    def __init__(self) -> None:
        self._next = 0.0
        self._lines = 0

    def update(self, recording: Any) -> None:
        now = time.monotonic()
        if now < self._next or len(recording) < 2:
            return
        from akdctl.drive.scope_plot import terminal_plot

        text = terminal_plot(recording, width=max(40, min(120, _columns() - 14)), height=8, colours=True)
        self.clear()
        sys.stderr.write(text)
        sys.stderr.flush()
        self._lines = text.count("\n")
        # the drawing costs the recording's time: at most a tenth of it, however long the recording grows
        self._next = time.monotonic() + max(LIVE_REDRAW_S, 10 * (time.monotonic() - now))

    def clear(self) -> None:
        if self._lines:
            sys.stderr.write(f"\x1b[{self._lines}F\x1b[J")
            sys.stderr.flush()
            self._lines = 0
