"""``status``, ``enable``, ``disable``, ``stop``, ``jog``, ``home``, ``move``: the axis from the shell, safely.

The safety model (README "Safety model"): every command that powers or moves the
axis runs :func:`_plan_and_run` — the one planner (:mod:`akdctl.drive.motion_plan`:
input, the drive's quantisation, limits as executed, travel, homed, the drive's
state; reads only), then the one consent (:mod:`akdctl.cli.consent`), then the
execution under the stop signals (:mod:`akdctl.cli.signals`):

* SIGINT / SIGTERM / SIGHUP / any error while the axis moves: the axis is stopped
  (ramp, then quick stop if the ramp is not obeyed) before the tool exits (128 + signal);
* bounded motion: jog needs ``--for`` or ``--distance``; moves are finite; the
  simulated drive's watchdog stops the axis when the tool stops talking.

Velocities are rpm, accelerations rpm/s; positions take ``--units``.
"""

from __future__ import annotations

import contextlib
import functools
import time
from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc, LiveView, message
from akdctl.cli.parsing import Duration
from akdctl.drive.motion_plan import DEFAULT_ACC_RPM_S, DEFAULT_RPM, MAX_JOG_S, UNITS
from akdctl.errors import Interrupted, UsageError


# ---------------------------------------------------------------------- helpers
def _axis(app: Any) -> Any:
    return app.connection.axis()


def _status_doc(app: Any, status: Any, title: str, extra: dict[str, Any] | None = None) -> Doc:
    doc = Doc(title, app.target.display)
    for key, value in (extra or {}).items():
        if key == "homed" and status.homed is not None:
            continue  # the status below says it, read from the drive
        doc.kv(key, ("yes" if value else "no") if isinstance(value, bool) else value)  # one rendering of a yes/no
    doc.kv("profile", status.profile)
    doc.kv("state", f"{status.state} ({status.state_text})" if status.state != status.state_text else status.state)
    doc.kv("mode", f"{status.mode} ({status.mode_text})")
    word_name = "ZSW1" if status.profile == "profidrive" else "statusword"
    doc.kv(word_name, f"0x{status.word:04X}")
    if status.position_rev is not None:
        doc.kv("position", f"{status.position_counts} counts ({status.position_rev:.4f} rev)")
    if status.velocity_rpm is not None:
        doc.kv("velocity", f"{status.velocity_rpm:.2f} rpm")
    if status.current_pct is not None:
        doc.kv("current" if status.profile == "profidrive" else "torque",
               f"{status.current_pct:.1f} % of {'DRV.IPEAK' if status.profile == 'profidrive' else 'rated'}")
    if status.homed is not None:
        doc.kv("homed", "yes" if status.homed else "no")
    doc.kv("standstill", "yes" if status.standstill else "no")
    doc.kv("warning", status.warning_summary())
    doc.kv("fault", status.fault_summary() if status.fault else "none")
    return doc


def _emit_status(app: Any, status: Any, title: str, extra: dict[str, Any] | None = None, bits: bool = False,
                 plan: dict[str, Any] | None = None) -> None:
    data = {"target": app.target.display, **(extra or {}), **({"plan": plan} if plan else {}),
            "status": status.to_json()}

    def human() -> Doc:
        doc = _status_doc(app, status, title, extra)
        if bits:
            word_name = "ZSW1" if status.profile == "profidrive" else "statusword"
            doc.table(["bit", "meaning", "set"], [[b.number, b.name, "1" if b.set else "0"] for b in status.bits],
                      title=f"{word_name} bits")
        return doc

    app.emit(data, human)


def _duration(text: str) -> float:
    """Seconds from ``2``, ``2s``, ``500ms`` (the one parser, :func:`akdctl.cli.parsing.parse_duration`; this
    name stays for its callers, e.g. ``scope --jog-for``)."""
    from akdctl.cli.parsing import parse_duration

    return parse_duration(text)


def _plan_and_run(app: Any, request: Any, title: str, extra: dict[str, Any] | None = None,
                  wait: bool = True, dry_run: bool = False) -> None:
    """The one path of every command that powers or moves the axis: plan (checks, reads only),
    consent, then execute under the stop signals; prints the final state. ``dry_run``: the plan in words, then
    stop (nothing asked, owned or written)."""
    from akdctl.cli.consent import own_axis, refuse_unaskable, render_dry_run, require_consent, show_notes
    from akdctl.cli.progress import MotionProgress
    from akdctl.cli.signals import stop_signals
    from akdctl.drive import motion_plan
    from akdctl.drive.axis.choice import axis_class

    conn = app.connection
    motion_plan.check_request(conn, request, axis_class(conn))  # no drive needed: bad input exits 2 first
    if dry_run:
        return render_dry_run(app, motion_plan.plan(conn, conn.axis(), request))
    if app.yes:
        # Consent is given: own the axis before the plan reads it, so the preparation may share the plan's
        # status read (Axis.recent_status) - no other command can have moved the axis in between.
        own_axis(app)
    axis = conn.axis()
    plan = motion_plan.plan(conn, axis, request)
    action = f"{plan.what} (mode: {plan.mode_text})"
    refuse_unaskable(app, action)
    show_notes(plan)
    require_consent(app, action)
    if not app.yes:
        axis.forget_status()  # the owner lock came with the answer: the preparation reads the drive again
    with stop_signals() as stop, MotionProgress(plan, quiet=app.json or not wait) as progress:
        result = motion_plan.execute(axis, plan, stop, progress.update, wait=wait)
    extra = dict(extra or {})
    if not wait:
        extra["note"] = motion_plan.wait_hint(conn)
        message(f"akdctl: {extra['note']}")
    _emit_status(app, result, title, extra, plan=plan.to_json())


# ---------------------------------------------------------------------- commands
@click.command()
@click.option("--watch", is_flag=True, help="Refresh until Ctrl-C (or --count / --for).")
@click.option("--interval", type=click.FloatRange(min=0.05), default=0.5, show_default=True,
              help="Seconds between refreshes with --watch.")
@click.option("--count", type=click.IntRange(min=1), metavar="N",
              help="With --watch: stop after N readings (a script watches for a while and goes on).")
@click.option("--for", "duration", type=Duration(low=0.001, high=86400), metavar="DURATION",
              help="With --watch: stop after this long (2, 2s, 500ms, 1.5min).")
def status(watch: bool, interval: float, count: int | None, duration: float | None) -> None:
    """Show state, mode, every status-word bit in words, position, velocity, current, warnings, faults.

    \b
    Examples:
      akdctl status
      akdctl status --watch --interval 0.2
      akdctl status --watch --json > status.jsonl
      akdctl status --watch --count 10 --json
      akdctl status --watch --for 30s
    """
    app = get_app()
    if (count is not None or duration is not None) and not watch:
        raise UsageError("--count and --for need --watch")
    axis = _axis(app)
    if not watch:
        _emit_status(app, axis.read_status(), "axis status", bits=True)
        return
    from akdctl.cli.signals import stop_signals
    from akdctl.drive.polling import pause_unless_stopped

    ends = time.monotonic() + duration if duration is not None else None
    shown = 0
    with contextlib.suppress(Interrupted), stop_signals() as stop, LiveView(app.json) as view:
        while not stop():
            status, now = axis.read_status(), time.localtime()
            view.show({"time": time.strftime("%Y-%m-%dT%H:%M:%S", now), "target": app.target.display,
                       "status": status.to_json()},
                      functools.partial(_watch_doc, app, status, time.strftime("%H:%M:%S", now)))
            shown += 1
            if count is not None and shown >= count:
                break
            pause = interval
            if ends is not None:
                left = ends - time.monotonic()
                if left <= 0:
                    break
                pause = min(interval, left)
            pause_unless_stopped(pause, stop)
            if ends is not None and time.monotonic() >= ends:
                break


def _watch_doc(app: Any, status: Any, stamp: str) -> Doc:
    """The status document, compact enough to redraw in place: the set bits on one line, not the bit table."""
    from akdctl.profiles.statusword import set_names

    doc = _status_doc(app, status, f"axis status {stamp} (Ctrl-C ends)")
    doc.kv("bits set", ", ".join(set_names(status.bits)) or "none")
    return doc


@click.command()
@click.option("--dry-run", is_flag=True, help="Show the plan (the motion as executed, mode, travel); move nothing.")
def enable(dry_run: bool) -> None:
    """Bring the drive to operation enabled (S4 / operation enabled); no motion is commanded.

    \b
    Examples:
      akdctl -y enable
      akdctl -T 'sim?drive=cia402' enable --yes
    """
    from akdctl.drive.motion_plan import MotionRequest

    _plan_and_run(get_app(), MotionRequest("enable"), "drive enabled", dry_run=dry_run)


@click.command()
def disable() -> None:
    """Disable the power stage; a moving axis is brought to standstill along its ramp first.

    \b
    Examples:
      akdctl disable
    """
    app = get_app()
    _emit_status(app, _axis(app).disable(), "drive disabled")


@click.command()
@click.option("--quick", is_flag=True, help="Quick stop (steep ramp; leaves the drive disabled).")
def stop(quick: bool) -> None:
    """Stop the axis: ramp to standstill (a quick stop if the ramp is not obeyed).

    \b
    Examples:
      akdctl stop
      akdctl stop --quick
    """
    app = get_app()
    status = _axis(app).stop(quick=quick)
    _emit_status(app, status, "axis stopped (quick stop)" if quick else "axis stopped")


@click.command()
@click.argument("velocity", type=float)
@click.option("--for", "duration", metavar="DURATION",
              help=f"Jog for this long (e.g. 2s, 500ms; at most {MAX_JOG_S:g} s), then stop.")
@click.option("--distance", type=float, help="Jog this far (in --units), a finite move; sign gives the direction.")
@click.option("--accel", type=float, help=f"rpm/s (default {DEFAULT_ACC_RPM_S:g}, capped by the profile).")
@click.option("--units", "unit", type=click.Choice(UNITS), help="Units of --distance (default: rev, or user).")
@click.option("--dry-run", is_flag=True, help="Show the plan (the motion as executed, mode, travel); move nothing.")
def jog(velocity: float, duration: str | None, distance: float | None, accel: float | None, unit: str | None,
        dry_run: bool) -> None:
    """Jog at VELOCITY rpm for a bounded time (--for) or distance (--distance).

    \b
    Examples:
      akdctl -y jog 100 --for 2s
      akdctl -y jog -50 --distance 0.25
      akdctl jog 100 --for 2s --dry-run
    """
    from akdctl.drive.motion_plan import MotionRequest

    if duration is not None and distance is not None:
        raise UsageError("jog needs exactly one of --for DURATION or --distance D, so the motion is bounded")
    if distance is not None:
        request = MotionRequest("jog", velocity=abs(velocity), distance=distance, accel=accel, unit=unit)
        _plan_and_run(get_app(), request, "jog finished", {"distance": distance}, dry_run=dry_run)
        return
    from akdctl.cli.parsing import parse_duration

    seconds = parse_duration(duration, "jog --for") if duration is not None else None
    request = MotionRequest("jog", velocity=velocity, duration_s=seconds, accel=accel)
    _plan_and_run(get_app(), request, "jog finished", {"velocity_rpm": velocity, "duration_s": seconds},
                  dry_run=dry_run)


@click.command()
@click.option("--mode", "home_mode", type=int, help="Homing mode: PNU 1001 (HOME.MODE) or 0x6098 method.")
@click.option("--max-time", "--timeout", "home_timeout", type=Duration(0.0, 3600.0), default=60.0, metavar="DURATION",
              help="How long the whole homing may take before the axis is stopped (default 60 s; 30, 30s, 2m). "
                   "'home --timeout' is this option too; the wait for each request is the global "
                   "'akdctl --timeout' before the command.")
@click.option("--dry-run", is_flag=True, help="Show the plan (the motion as executed, mode, travel); move nothing.")
def home(home_mode: int | None, home_timeout: float, dry_run: bool) -> None:
    """Run the drive's homing procedure and wait until the home position is set.

    \b
    Examples:
      akdctl -y home
      akdctl -y home --mode 3 --max-time 30s
    """
    from akdctl.drive.motion_plan import MotionRequest

    _plan_and_run(get_app(), MotionRequest("home", home_mode=home_mode, timeout_s=home_timeout), "homing finished",
                  {"homed": True}, dry_run=dry_run)


@click.command()
@click.argument("target", type=float)
@click.option("--relative/--absolute", default=False, help="Relative to the current position (default absolute).")
@click.option("--velocity", type=float, help=f"rpm (default {DEFAULT_RPM:g}, capped by the profile).")
@click.option("--accel", type=float, help=f"rpm/s (default {DEFAULT_ACC_RPM_S:g}, capped by the profile).")
@click.option("--decel", type=float, help="rpm/s (default: --accel).")
@click.option("--units", "unit", type=click.Choice(UNITS), help="Units of TARGET (default: rev, or user).")
@click.option("--no-wait", is_flag=True,
              help="Return once the drive accepted the move; the simulator's watchdog then stops it within about "
                   "1 s unless something keeps polling (a real AKD finishes the task).")
@click.option("--dry-run", is_flag=True, help="Show the plan (the motion as executed, mode, travel); move nothing.")
def move(target: float, relative: bool, velocity: float | None, accel: float | None, decel: float | None,
         unit: str | None, no_wait: bool, dry_run: bool) -> None:
    """Move to TARGET and wait for target reached (a finite, acknowledged point-to-point move).

    \b
    Examples:
      akdctl -y move 10
      akdctl -y move --relative -0.5 --velocity 60
      akdctl -y move 90 --units deg --json
      akdctl move 10 --dry-run
    """
    from akdctl.drive.motion_plan import MotionRequest

    request = MotionRequest("move", target=target, relative=relative, velocity=velocity, accel=accel, decel=decel,
                            unit=unit)
    title = "move started (not waiting)" if no_wait else "target reached"
    _plan_and_run(get_app(), request, title, {"position_target": target, "units": unit}, wait=not no_wait,
                  dry_run=dry_run)
