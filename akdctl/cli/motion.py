"""``status``, ``enable``, ``disable``, ``stop``, ``jog``, ``home``, ``move``: the axis from the shell, safely.

The safety model (README "Safety model", docs/motion.md):

* consent: anything that powers or moves the axis asks on the terminal, naming the
  target, the mode and the motion; without a terminal it needs ``--yes`` (exit 4);
* limits: velocity, acceleration and travel from the config profile's ``[limits]``
  are checked before anything is sent (exit 4);
* Ctrl-C / SIGTERM / any error while the axis moves: the axis is stopped (ramp,
  then quick stop if the ramp is not obeyed) before the tool exits (130 on Ctrl-C);
* bounded motion: jog needs ``--for`` or ``--distance``; moves are finite; the
  simulated drive's watchdog stops the axis when the tool stops talking.

Velocities are rpm, accelerations rpm/s; positions take ``--units``.
"""

from __future__ import annotations

import contextlib
import re
import signal
import sys
import time
from collections.abc import Iterator
from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import SafetyRefusal, UsageError

UNIT_CHOICES = ("counts", "rev", "deg", "user")
DEFAULT_RPM = 100.0
DEFAULT_ACC = 1000.0


# ---------------------------------------------------------------------- helpers
def _axis(app: Any) -> Any:
    return app.connection.axis()


def _status_doc(app: Any, status: Any, title: str, extra: dict[str, Any] | None = None) -> Doc:
    doc = Doc(title, app.target.display)
    for key, value in (extra or {}).items():
        doc.kv(key, value)
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
    doc.kv("warning", "yes" if status.warning else "no")
    doc.kv("fault", status.fault_summary() if status.fault else "none")
    return doc


def _emit_status(app: Any, status: Any, title: str, extra: dict[str, Any] | None = None, bits: bool = False) -> None:
    data = {"target": app.target.display, **(extra or {}), "status": status.to_json()}

    def human() -> Doc:
        doc = _status_doc(app, status, title, extra)
        if bits:
            word_name = "ZSW1" if status.profile == "profidrive" else "statusword"
            doc.table(["bit", "meaning", "set"], [[b.number, b.name, "1" if b.set else "0"] for b in status.bits],
                      title=f"{word_name} bits")
        return doc

    app.emit(data, human)


def _consent(app: Any, what: str, mode: str) -> None:
    """Ask before powering or moving the axis; --yes answers for scripts."""
    text = f"{what} on {app.target.display} (mode: {mode})"
    if app.yes:
        return
    if not sys.stdin.isatty():
        raise SafetyRefusal(f"refusing to {text}: no terminal to ask for consent and --yes was not given")
    if not click.confirm(f"About to {text}. Proceed?", default=False, err=True):
        raise SafetyRefusal(f"not confirmed: {text}")


def _limits(app: Any) -> dict[str, Any]:
    profile = app.profile
    return dict(profile.limits) if profile is not None else {}


def _check_limits(app: Any, rpm: float | None = None, acc: float | None = None,
                  final_rev: float | None = None) -> None:
    """Refuse (exit 4) before anything is sent when a profile limit would be exceeded."""
    limits = _limits(app)
    max_v, max_a, travel = limits.get("max_velocity"), limits.get("max_acceleration"), limits.get("travel")
    if rpm is not None and max_v is not None and abs(rpm) > float(max_v):
        raise SafetyRefusal(f"refusing: velocity {abs(rpm):g} rpm exceeds the profile limit max_velocity = {max_v} rpm")
    if acc is not None and max_a is not None and abs(acc) > float(max_a):
        raise SafetyRefusal(f"refusing: acceleration {abs(acc):g} rpm/s exceeds the profile limit "
                            f"max_acceleration = {max_a} rpm/s")
    if travel is not None and final_rev is not None:
        try:
            lo, hi = float(travel[0]), float(travel[1])
        except (TypeError, ValueError, IndexError):
            raise UsageError("config: limits.travel must be [min, max] in revolutions") from None
        if not lo <= final_rev <= hi:
            raise SafetyRefusal(f"refusing: the axis would end at {final_rev:.4f} rev, outside the profile's travel "
                                f"[{lo:g}, {hi:g}] rev")


def _travel_needs_position(app: Any, status: Any) -> None:
    if _limits(app).get("travel") is not None and status.position_rev is None:
        raise SafetyRefusal("refusing: the profile limits travel but this link cannot read the position")


def _default_units(app: Any) -> str:
    profile = app.profile
    return "user" if profile is not None and profile.units.get("per_rev") else "rev"


def _to_rev(app: Any, value: float, unit: str, counts_per_rev: int) -> float:
    if unit == "rev":
        return value
    if unit == "deg":
        return value / 360.0
    if unit == "counts":
        return value / counts_per_rev
    per_rev = (app.profile.units.get("per_rev") if app.profile is not None else None)
    if not per_rev:
        raise UsageError("--units user needs [units] per_rev in the config profile")
    return value / float(per_rev)


_DURATION = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(ms|s|m|min)?\s*$")


def _duration(text: str) -> float:
    match = _DURATION.match(text)
    if not match:
        raise UsageError(f"bad duration {text!r}: use e.g. 2s, 500ms, 1.5")
    value = float(match.group(1))
    unit = match.group(2) or "s"
    return value / 1000.0 if unit == "ms" else value * 60.0 if unit in ("m", "min") else value


@contextlib.contextmanager
def _interrupt_guard() -> Iterator[list[bool]]:
    """Turn SIGINT/SIGTERM into a flag checked between requests, so the axis is stopped cleanly."""
    flag = [False]

    def handler(signum: int, frame: Any) -> None:
        flag[0] = True

    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            previous[sig] = signal.signal(sig, handler)
        except ValueError:  # not the main thread (tests calling commands in a thread)
            pass
    try:
        yield flag
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _progress(app: Any) -> Any:
    if app.json or not sys.stderr.isatty():
        return None

    def show(status: Any) -> None:
        pos = f"{status.position_rev:10.4f} rev" if status.position_rev is not None else "position n/a"
        vel = f"{status.velocity_rpm:9.2f} rpm" if status.velocity_rpm is not None else ""
        sys.stderr.write(f"\r  {pos}  {vel}  {status.state}  ")
        sys.stderr.flush()

    return show


def _end_progress(app: Any) -> None:
    if not app.json and sys.stderr.isatty():
        sys.stderr.write("\n")


def _prepare(axis: Any, kind: str, check: Any = None) -> Any:
    from akdctl.drive.axis import prepare_motion

    return prepare_motion(axis, kind, check)


def _run(app: Any, axis: Any, start: Any, finished: Any, deadline: float, what: str,
         on_deadline: str = "error") -> Any:
    from akdctl.drive.axis import MotionRun

    with _interrupt_guard() as flag:
        runner = MotionRun(axis, lambda: flag[0], _progress(app))
        try:
            return runner.run(start, finished, deadline_s=deadline, what=what, on_deadline=on_deadline)
        finally:
            _end_progress(app)


def _move_time(distance_rev: float, rpm: float, acc: float, dec: float) -> float:
    v = max(abs(rpm) / 60.0, 1e-6)
    return abs(distance_rev) / v + v / max(acc / 60.0, 1e-6) + v / max(dec / 60.0, 1e-6)


def _common(func: Any) -> Any:
    """``--json`` and ``--yes`` after the command name too (``akdctl move 3 --json --yes``)."""
    import functools

    @click.option("--json", "json_output", is_flag=True, help="Machine-readable JSON on stdout.")
    @click.option("-y", "--yes", "yes_flag", is_flag=True, help="Consent to motion without a prompt.")
    @functools.wraps(func)
    def wrapper(*args: Any, json_output: bool = False, yes_flag: bool = False, **kwargs: Any) -> Any:
        app = get_app()
        app.json = app.json or json_output
        app.yes = app.yes or yes_flag
        return func(*args, **kwargs)

    return wrapper


# ---------------------------------------------------------------------- commands
@click.command()
@click.option("--watch", is_flag=True, help="Refresh until Ctrl-C.")
@click.option("--interval", type=click.FloatRange(min=0.05), default=0.5, show_default=True,
              help="Seconds between refreshes with --watch.")
@_common
def status(watch: bool, interval: float) -> None:
    """Show state, mode, every status-word bit in words, position, velocity, current, warnings, faults."""
    app = get_app()
    axis = _axis(app)
    if not watch:
        _emit_status(app, axis.read_status(), "axis status", bits=True)
        return
    with _interrupt_guard() as flag:
        while not flag[0]:
            _emit_status(app, axis.read_status(), f"axis status {time.strftime('%H:%M:%S')}", bits=not app.json)
            sys.stdout.flush()
            end = time.monotonic() + interval
            while time.monotonic() < end and not flag[0]:
                time.sleep(0.05)


@click.command()
@_common
def enable() -> None:
    """Bring the drive to operation enabled (S4 / operation enabled); no motion is commanded."""
    app = get_app()
    axis = _axis(app)
    status = axis.read_status()
    axis.refuse_if_fault(status)
    _consent(app, "enable the power stage (no motion commanded)", status.mode_text)
    _emit_status(app, axis.enable(), "drive enabled")


@click.command()
@_common
def disable() -> None:
    """Disable the power stage; a moving axis is brought to standstill along its ramp first."""
    app = get_app()
    _emit_status(app, _axis(app).disable(), "drive disabled")


@click.command()
@click.option("--quick", is_flag=True, help="Quick stop (steep ramp; leaves the drive disabled).")
@_common
def stop(quick: bool) -> None:
    """Stop the axis: ramp to standstill (a quick stop if the ramp is not obeyed)."""
    app = get_app()
    status = _axis(app).stop(quick=quick)
    _emit_status(app, status, "axis stopped (quick stop)" if quick else "axis stopped")


@click.command(context_settings={"ignore_unknown_options": True})
@click.argument("velocity", type=float)
@click.option("--for", "duration", metavar="DURATION", help="Jog for this long (e.g. 2s, 500ms), then stop.")
@click.option("--distance", type=float, help="Jog this far (in --units), a finite move; sign gives the direction.")
@click.option("--accel", type=click.FloatRange(min=1), default=DEFAULT_ACC, show_default=True, help="rpm/s.")
@click.option("--units", "unit", type=click.Choice(UNIT_CHOICES), help="Units of --distance (default: rev, or user).")
@_common
def jog(velocity: float, duration: str | None, distance: float | None, accel: float, unit: str | None) -> None:
    """Jog at VELOCITY rpm for a bounded time (--for) or distance (--distance)."""
    from akdctl.drive.axis import MoveSpec

    app = get_app()
    if (duration is None) == (distance is None):
        raise UsageError("jog needs exactly one of --for DURATION or --distance D, so the motion is bounded")
    if velocity == 0:
        raise UsageError("jog velocity must not be 0")
    _check_limits(app, rpm=velocity, acc=accel)
    axis = _axis(app)
    status = axis.read_status()
    axis.refuse_if_fault(status)
    if duration is not None:
        seconds = _duration(duration)
        if seconds <= 0:
            raise UsageError("--for must be positive")
        if status.position_rev is not None:
            _check_limits(app, final_rev=status.position_rev + velocity / 60.0 * seconds
                          + (velocity / 60.0) ** 2 / (2 * accel / 60.0) * (1 if velocity > 0 else -1))
        else:
            _travel_needs_position(app, status)
        _consent(app, f"jog at {velocity:g} rpm for {seconds:g} s", axis.mode_name("velocity"))
        _prepare(axis, "velocity")
        result = _run(app, axis, lambda: axis.start_jog(velocity, accel), lambda s: None, seconds,
                      "jog", on_deadline="stop")
        axis.end_jog()
        result = axis.wait_for(lambda s: s.standstill, "standstill after jog", timeout=axis.timeout + 5.0)
        _emit_status(app, result, "jog finished", {"velocity_rpm": velocity, "duration_s": seconds})
        return
    assert distance is not None
    unit = unit or _default_units(app)
    rev = _to_rev(app, distance, unit, status.counts_per_rev)
    if status.position_rev is not None:
        _check_limits(app, final_rev=status.position_rev + rev)
    else:
        _travel_needs_position(app, status)
    _consent(app, f"jog {distance:g} {unit} at {abs(velocity):g} rpm", axis.mode_name("position"))
    _prepare(axis, "position", lambda: _require_homed(axis, True))
    move = MoveSpec(rev, True, abs(velocity), accel, accel)
    result = _run(app, axis, lambda: axis.start_move(move), lambda s: s.target_reached and s.standstill or None,
                  _move_time(rev, velocity, accel, accel) + 2 * axis.timeout + 1.0, "jog")
    _emit_status(app, result, "jog finished", {"distance": distance, "units": unit})


@click.command()
@click.option("--mode", "home_mode", type=int, help="Homing mode: PNU 1001 (HOME.MODE) or 0x6098 method.")
@click.option("--timeout", "home_timeout", type=click.FloatRange(min=0.1), default=60.0, show_default=True,
              help="Seconds the whole homing may take before the axis is stopped.")
@_common
def home(home_mode: int | None, home_timeout: float) -> None:
    """Run the drive's homing procedure and wait until the home position is set."""
    app = get_app()
    axis = _axis(app)
    status = axis.read_status()
    axis.refuse_if_fault(status)
    mode_text = axis.mode_name("homing") + (f", homing mode {home_mode}" if home_mode is not None else "")
    _consent(app, "run the homing procedure (the axis searches for its reference)", mode_text)
    _prepare(axis, "homing")
    result = _run(app, axis, lambda: axis.start_home(home_mode), axis.home_finished, home_timeout, "homing")
    _emit_status(app, result, "homing finished", {"homed": True})


@click.command(context_settings={"ignore_unknown_options": True})
@click.argument("target", type=float)
@click.option("--relative/--absolute", default=False, help="Relative to the current position (default absolute).")
@click.option("--velocity", type=click.FloatRange(min=0.001), help=f"rpm (default {DEFAULT_RPM:g}, capped by the profile).")
@click.option("--accel", type=click.FloatRange(min=1), help=f"rpm/s (default {DEFAULT_ACC:g}, capped by the profile).")
@click.option("--decel", type=click.FloatRange(min=1), help="rpm/s (default: --accel).")
@click.option("--units", "unit", type=click.Choice(UNIT_CHOICES), help="Units of TARGET (default: rev, or user).")
@click.option("--no-wait", is_flag=True, help="Return once the drive accepted the move (it is finite).")
@_common
def move(target: float, relative: bool, velocity: float | None, accel: float | None, decel: float | None,
         unit: str | None, no_wait: bool) -> None:
    """Move to TARGET and wait for target reached (a finite, acknowledged point-to-point move)."""
    from akdctl.drive.axis import MoveSpec

    app = get_app()
    limits = _limits(app)
    rpm = velocity if velocity is not None else min(DEFAULT_RPM, float(limits.get("max_velocity", DEFAULT_RPM)))
    acc = accel if accel is not None else min(DEFAULT_ACC, float(limits.get("max_acceleration", DEFAULT_ACC)))
    dec = decel if decel is not None else acc
    _check_limits(app, rpm=rpm, acc=max(acc, dec))
    axis = _axis(app)
    status = axis.read_status()
    axis.refuse_if_fault(status)
    unit = unit or _default_units(app)
    rev = _to_rev(app, target, unit, status.counts_per_rev)
    if relative:
        if status.position_rev is not None:
            _check_limits(app, final_rev=status.position_rev + rev)
        else:
            _travel_needs_position(app, status)
    else:
        _check_limits(app, final_rev=rev)
    distance = rev if relative else (rev - status.position_rev if status.position_rev is not None else rev)
    how = "by" if relative else "to"
    _consent(app, f"move {how} {target:g} {unit} at {rpm:g} rpm (accel {acc:g}, decel {dec:g} rpm/s)",
             axis.mode_name("position"))
    _prepare(axis, "position", lambda: _require_homed(axis, relative))
    spec = MoveSpec(rev, relative, rpm, acc, dec)
    if no_wait:
        with _interrupt_guard():
            axis.start_move(spec)
        _emit_status(app, axis.read_status(), "move started (not waiting)", {"target": target, "units": unit})
        return
    result = _run(app, axis, lambda: axis.start_move(spec), lambda s: s.target_reached and s.standstill or None,
                  _move_time(distance, rpm, acc, dec) + 2 * axis.timeout + 1.0, "move")
    _emit_status(app, result, "target reached", {"target": target, "units": unit})


def _is_homed(axis: Any) -> bool:
    """Homed? ZSW1 bit 11 in position mode; CiA 402 shows 'homing attained' only in homing mode."""
    status = axis.read_status()
    if not status.standstill:
        return bool(status.homed)
    if status.profile == "profidrive":
        axis.ensure_mode("position")
    else:
        axis.ensure_mode("homing")
    return bool(axis.read_status().homed)


def _require_homed(axis: Any, relative: bool) -> None:
    """Absolute moves need a homed axis; PROFIdrive MDI needs one even for relative moves."""
    if not relative:
        if not _is_homed(axis):
            raise SafetyRefusal("refusing: the axis is not homed, so an absolute position means nothing yet; "
                                "run 'akdctl home' first (or use --relative)")
    elif axis.profile == "profidrive" and not _is_homed(axis):
        raise SafetyRefusal("refusing: the axis is not homed (ZSW1 bit 11 clear); the AKD runs MDI traversing "
                            "tasks only on a homed axis (PROFINET manual 5.10.2); run 'akdctl home' first")
