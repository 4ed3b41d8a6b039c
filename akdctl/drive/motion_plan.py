"""The one motion planner: every path that powers or moves the axis asks it first.

Why one planner: the CLI commands (``enable``, ``jog``, ``home``, ``move``) and the
recipe steps (``enable``, ``home``, ``move``) must refuse the same requests for the
same reasons, and the drive must execute exactly what was checked. So a request
(target or distance, velocity, accelerations, units, duration) becomes a
:class:`MotionPlan` in *drive units after the drive's own quantisation and ranges*
(the :class:`~akdctl.drive.axis.Scale` each Axis profile declares), and the limits
of the config profile are compared with those executed values — not with what the
user typed.

Two stages, both here:

* :func:`check_request` needs no drive: NaN/inf, signs, the jog duration bound,
  units, quantisation of velocity and accelerations for the axis profile, the
  profile limits as executed, an absolute target against the travel window.
  Recipes run it at validation time; commands before opening the transport.
* :func:`plan` reads (never writes) the drive: fault, standstill, whether the
  drive will obey this link (STW1 bit 10, controlword owned by process data in
  OP), the homed rule, the current position for relative moves and jogs against
  the travel window, and the position quantisation (counts per revolution).

Only after the plan is accepted and consent given does :func:`execute` change
anything on the drive (mode, enable, set points), always through the Axis.

Representability: a value is executed as the largest representable value at or
below the request when that is within :data:`REL_TOL` of it; otherwise the request
is refused (exit 2) naming the nearest representable values. Values are never
rounded up. Defaults (no value given) take the largest representable value at or
below the default, capped by the profile's limit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akdctl.errors import Interrupted, SafetyRefusal, UsageError
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.drive.axis.base import Axis
    from akdctl.connection import Connection

#: A request within this fraction above a representable value is executed as that value.
REL_TOL = 0.02
DEFAULT_RPM = 100.0
DEFAULT_ACC_RPM_S = 1000.0
#: ``jog --for`` longer than this is refused: the tool, not the drive, ends such a jog (README "Safety model").
MAX_JOG_S = 60.0
#: Homing, moves and waits are bounded by this many seconds at most.
MAX_WAIT_S = 3600.0
UNITS = ("counts", "rev", "deg", "user")
KINDS = ("enable", "home", "move", "jog", "task")


class MotionRequest(Record):
    """What a command line or a recipe step asks for, in the user's words and units.

    ``kind``: enable, home, move (``target``, ``relative``) or jog (``velocity`` signed,
    and exactly one of ``duration_s`` / ``distance``). ``unit`` None means the profile's
    default (user units when ``[units] per_rev`` is set, else rev). ``velocity`` /
    ``accel`` / ``decel`` None mean the defaults.
    """

    __slots__ = ("kind", "target", "relative", "velocity", "accel", "decel", "unit", "duration_s", "distance",
                 "home_mode", "timeout_s", "task")

    def __init__(self, kind: str, target: float | None = None, relative: bool = False, velocity: float | None = None,
                 accel: float | None = None, decel: float | None = None, unit: str | None = None,
                 duration_s: float | None = None, distance: float | None = None, home_mode: int | None = None,
                 timeout_s: float | None = None, task: int | None = None) -> None:
        self.kind = kind
        self.target = target
        self.relative = relative
        self.velocity = velocity
        self.accel = accel
        self.decel = decel
        self.unit = unit
        self.duration_s = duration_s
        self.distance = distance
        self.home_mode = home_mode
        self.timeout_s = timeout_s
        self.task = task  # kind "task": the stored motion task to start (program mode)


class Quantity(Record):
    """One value as requested and as the drive will execute it (``raw`` is what is written)."""

    __slots__ = ("what", "requested", "executed", "raw", "unit", "field_name")

    def __init__(self, what: str, requested: float, executed: float, raw: int, unit: str, field_name: str) -> None:
        self.what = what
        self.requested = requested
        self.executed = executed
        self.raw = raw
        self.unit = unit
        self.field_name = field_name


    def to_json(self) -> dict[str, Any]:
        return {"requested": self.requested, "executed": round(self.executed, 6), "raw": self.raw,
                "unit": self.unit, "field": self.field_name}


class MotionPlan(Record):
    """An accepted request: the mode it needs, the raw values to write, the consent text.

    ``mode_kind``: 'velocity', 'position', 'homing' or '' (enable); ``target_raw``: position counts written
    (absolute target or relative distance), ``move_rev`` the same in revolutions; ``homed`` as read before consent
    (None: only visible after the mode switch); ``limits`` the profile's, for the re-check under the owner lock;
    ``after_consent``: checks that can only read by writing (a stored task is read through MT.LOAD), run after
    consent, before anything is enabled or moved; they refuse like the planner (kind "task").
    Mutable, compared by value, unhashable.
    """

    __slots__ = ("request", "profile", "mode_kind", "unit", "velocity", "accel", "decel", "target_raw", "move_rev",
                 "start_rev", "end_rev", "duration_s", "deadline_s", "needs_homed", "homed", "mode_text", "notes",
                 "limits", "after_consent", "task_text", "target")
    __hash__ = None  # type: ignore[assignment]

    def __init__(self, request: MotionRequest, profile: str, mode_kind: str, unit: str = "rev",
                 velocity: Quantity | None = None, accel: Quantity | None = None, decel: Quantity | None = None,
                 target_raw: int | None = None, move_rev: float | None = None, start_rev: float | None = None,
                 end_rev: float | None = None, duration_s: float | None = None, deadline_s: float = 0.0,
                 needs_homed: bool = False, homed: bool | None = None, mode_text: str = "",
                 notes: list[str] | None = None, limits: dict[str, Any] | None = None,
                 after_consent: Callable[[], None] | None = None) -> None:
        self.request = request
        self.profile = profile
        self.mode_kind = mode_kind
        self.unit = unit
        self.velocity = velocity
        self.accel = accel
        self.decel = decel
        self.target_raw = target_raw
        self.move_rev = move_rev
        self.start_rev = start_rev
        self.end_rev = end_rev
        self.duration_s = duration_s
        self.deadline_s = deadline_s
        self.needs_homed = needs_homed
        self.homed = homed
        self.mode_text = mode_text
        self.notes: list[str] = [] if notes is None else notes
        self.limits: dict[str, Any] = {} if limits is None else limits
        self.after_consent = after_consent
        self.task_text = ""  # kind "task": the stored task in words (target, speed), read while planning
        self.target = ""  # the target's display name (plan() sets it): the dry run names it

    def __repr__(self) -> str:
        shown = (n for n in self.__slots__ if n not in ("after_consent", "task_text"))
        return f"MotionPlan({', '.join(f'{n}={getattr(self, n)!r}' for n in shown)})"

    @property
    def what(self) -> str:
        """The motion in words, for the consent prompt and the reports."""
        r = self.request
        if r.kind == "enable":
            return "enable the power stage (no motion commanded)"
        if r.kind == "home":
            return "run the homing procedure (the axis searches for its reference)" + (
                f", homing mode {r.home_mode}" if r.home_mode is not None else "")
        if r.kind == "task":
            return f"start motion task {r.task} as stored in the drive (program mode)" + (
                f": {self.task_text}" if self.task_text else "")
        assert self.velocity is not None and self.accel is not None
        v, a = self.velocity.executed, self.accel.executed
        if r.kind == "jog" and r.duration_s is not None:
            return f"jog at {v:g} rpm for {r.duration_s:g} s (accel {a:.6g} rpm/s)"
        if r.kind == "jog":
            return f"jog {r.distance:g} {self.unit} at {abs(v):g} rpm (accel {a:.6g} rpm/s)"
        assert self.decel is not None
        how = "by" if r.relative else "to"
        return (f"move {how} {r.target:g} {self.unit} at {v:.6g} rpm "
                f"(accel {a:.6g}, decel {self.decel.executed:.6g} rpm/s)")

    def lines(self) -> list[str]:
        """The plan in words, one line each (``--dry-run``): the motion as the drive will execute it."""
        out = [f"{self.request.kind} on {self.target}: {self.what}", f"  mode: {self.mode_text}"]
        for q in (self.velocity, self.accel, self.decel):
            if q is not None:
                out.append(f"  {q.what}: {q.executed:.6g} {q.unit} as executed, {q.field_name} = {q.raw} "
                           f"(requested {q.requested:g})")
        if self.end_rev is not None:
            start = "?" if self.start_rev is None else f"{self.start_rev:.4f}"
            out.append(f"  travel: from {start} to {self.end_rev:.4f} rev")
        if self.needs_homed:
            out.append("  homed: " + ("yes" if self.homed else "read after consent, in the motion's mode"
                                      if self.homed is None else "no"))
        if self.after_consent is not None:
            out.append("  checked after consent, before anything moves: the stored task as the drive holds it")
        out += [f"  note: {text}" for text in self.notes]
        return out

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {"kind": self.request.kind, "profile": self.profile, "mode": self.mode_text,
                                "what": self.what}
        if self.notes:
            data["notes"] = list(self.notes)
        for name in ("velocity", "accel", "decel"):
            q = getattr(self, name)
            if q is not None:
                data[name] = q.to_json()
        for name in ("target_raw", "start_rev", "end_rev", "duration_s"):
            value = getattr(self, name)
            if value is not None:
                data[name] = round(value, 6) if isinstance(value, float) else value
        return data


# ====================================================================== helpers
def finite(value: Any, what: str) -> float:
    """A finite number or exit 2 (NaN, inf and non-numbers never reach a drive)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise UsageError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def limits_of(conn: "Connection") -> dict[str, Any]:
    profile = conn.profile
    return dict(profile.limits) if profile is not None else {}


def per_rev_of(conn: "Connection") -> float | None:
    profile = conn.profile
    value = profile.units.get("per_rev") if profile is not None else None
    return float(value) if value else None


def default_unit(conn: "Connection") -> str:
    return "user" if per_rev_of(conn) else "rev"


def to_rev(conn: "Connection", value: float, unit: str, counts_per_rev: int | None) -> float:
    """A position or distance in ``unit`` → motor revolutions (the one conversion)."""
    if unit == "rev":
        return value
    if unit == "deg":
        return value / 360.0
    if unit == "counts":
        if counts_per_rev is None:
            raise UsageError("positions in counts need the drive's counts per revolution")
        return value / counts_per_rev
    if unit == "user":
        per_rev = per_rev_of(conn)
        if not per_rev:
            raise UsageError("--units user needs [units] per_rev in the config profile")
        return value / per_rev
    raise UsageError(f"unknown unit {unit!r}: expected one of {', '.join(UNITS)}")


def quantise(scale: Any, value: float, what: str, *, explicit: bool = True) -> Quantity:
    """``value`` (sign kept) on the drive's grid ``scale``; never rounded up (module docstring)."""
    sign = -1 if value < 0 else 1
    mag = abs(value)
    unit = scale.unit
    largest = scale.raw_max * scale.step
    if mag / scale.step > scale.raw_max * (1 + 1e-12):
        raise UsageError(f"{what} {mag:g} {unit} is outside the range of {scale.name}: the largest representable "
                         f"value is {largest:.12g} {unit}")
    raw = math.floor(mag / scale.step * (1 + 1e-12))
    if raw < scale.raw_min:
        smallest = scale.raw_min * scale.step
        raise UsageError(f"{what} {mag:g} {unit} cannot be represented by {scale.name} (steps of "
                         f"{scale.step:.6g} {unit}); the nearest representable value is {smallest:.6g} {unit}")
    executed = raw * scale.step
    if explicit and mag - executed > REL_TOL * mag:
        above = min(raw + 1, scale.raw_max) * scale.step
        raise UsageError(f"{what} {mag:g} {unit} cannot be represented by {scale.name} (steps of "
                         f"{scale.step:.6g} {unit}); the nearest representable values are {executed:.6g} and "
                         f"{above:.6g} {unit}")
    return Quantity(what, mag, executed, sign * raw, unit, scale.name)


def _limit(limits: dict[str, Any], key: str) -> float | None:
    value = limits.get(key)
    return None if value is None else float(value)


def _refuse_over_limit(what: str, value: float | None, limit: float | None, key: str, unit: str,
                       executed_by: str = "") -> None:
    if value is not None and limit is not None and value > limit:
        how = f" (as {executed_by} executes it)" if executed_by else ""
        raise SafetyRefusal(f"refusing: {what} {value:.6g} {unit}{how} exceeds the profile's {key} {limit:g} {unit}")


def _check_travel(limits: dict[str, Any], end_rev: float, how: str = "would end at") -> None:
    travel = limits.get("travel")
    if travel is None:
        return
    lo, hi = float(travel[0]), float(travel[1])
    if not lo <= end_rev <= hi:
        raise SafetyRefusal(f"refusing: the axis {how} {end_rev:.4f} rev, outside the profile's travel "
                            f"[{lo:g}, {hi:g}] rev")


def check_travel(limits: dict[str, Any], end_rev: float, how: str = "would end at") -> None:
    """The travel window's rule for a caller outside the planner (a stored task's relative end)."""
    _check_travel(limits, end_rev, how)


def check_executed_limits(conn: "Connection", *, rpm: float | None = None, acc_rpm_s: float | None = None,
                          end_rev: float | None = None, executed_by: str = "") -> None:
    """The profile's limits for a motion whose raw values a caller built itself (``eip io``): the
    same rules and words as a planned motion, applied to what the drive will execute."""
    limits = limits_of(conn)
    _refuse_over_limit("velocity", None if rpm is None else abs(rpm), _limit(limits, "max_velocity"),
                       "max_velocity", "rpm", executed_by)
    _refuse_over_limit("acceleration", None if acc_rpm_s is None else abs(acc_rpm_s),
                       _limit(limits, "max_acceleration"), "max_acceleration", "rpm/s", executed_by)
    if end_rev is not None:
        _check_travel(limits, end_rev)


def check_duration(limits: dict[str, Any], duration_s: Any, what: str = "jog --for",
                   hint: str = "use --distance for a move the drive ends itself") -> float:
    """A motion the tool ends after ``duration_s``: at most :data:`MAX_JOG_S` and the profile's
    ``max_jog_duration`` (every timed motion: ``jog --for``, ``eip io jog|velocity|torque --for``)."""
    seconds = finite(duration_s, f"{what} duration")
    if not 0 < seconds <= MAX_JOG_S:
        raise UsageError(f"{what} must be more than 0 and at most {MAX_JOG_S:g} s (the tool ends a timed "
                         f"motion; {hint}), got {seconds:g} s")
    profile_bound = _limit(limits, "max_jog_duration")
    if profile_bound is not None and seconds > profile_bound:  # a profile limit, like velocity: exit 4
        raise SafetyRefusal(f"refusing: {what} {seconds:g} s exceeds the profile's max_jog_duration "
                            f"{profile_bound:g} s; nothing was sent")
    return seconds


def _move_time(distance_rev: float, rpm: float, acc: float, dec: float) -> float:
    """Trapezoid time (s) of a move; an upper bound, so the wait for it is finite but sufficient."""
    v = max(abs(rpm) / 60.0, 1e-6)
    return abs(distance_rev) / v + v / max(acc / 60.0, 1e-6) + v / max(dec / 60.0, 1e-6)


# ====================================================================== stage 1: no drive needed
def check_request(conn: "Connection", request: MotionRequest, axis_cls: Any,
                  scales_of: Callable[[str], Any] | None = None) -> MotionPlan:
    """Everything that can be decided without the drive (module docstring); exit 2 / 4 on a problem.

    ``axis_cls`` is the Axis subclass of the target's profile (:func:`akdctl.drive.axis.choice.axis_class`):
    its scales say what the drive can represent. ``scales_of`` replaces ``axis_cls.motion_scales``
    once the drive's own configuration is known (a profile whose grid the drive configures, such as
    the CIP Position Controller's EIP.PROFUNIT).
    """
    r = request
    if r.kind not in KINDS:
        raise UsageError(f"unknown motion {r.kind!r}")
    limits = limits_of(conn)
    plan = MotionPlan(request=r, profile=axis_cls.profile, mode_kind="", limits=limits)
    if r.timeout_s is not None:
        timeout = finite(r.timeout_s, "timeout")
        if not 0 < timeout <= MAX_WAIT_S:
            raise UsageError(f"timeout must be in (0, {MAX_WAIT_S:g}] s, got {timeout:g}")
    if r.kind == "enable":
        plan.mode_text = "current mode"
        return plan
    if r.kind == "home":
        plan.mode_kind = "homing"
        plan.mode_text = axis_cls.mode_name("homing")
        if r.home_mode is not None:
            lo, hi = axis_cls.HOME_MODE_RANGE
            if isinstance(r.home_mode, bool) or not isinstance(r.home_mode, int) or not lo <= r.home_mode <= hi:
                raise UsageError(f"homing mode {r.home_mode!r} is out of range for {axis_cls.HOME_MODE_FIELD}: "
                                 f"expected {lo}..{hi}")
        plan.deadline_s = r.timeout_s if r.timeout_s is not None else 60.0
        return plan
    if r.kind == "task":
        from akdctl.drive.tasks import check_number

        if not axis_cls.TASKS:  # declared on Axis (False)
            raise UsageError(f"task start: {axis_cls.NO_TASKS}")
        check_number(r.task)  # type: ignore[arg-type]
        plan.mode_kind = "task"
        plan.mode_text = axis_cls.mode_name("task")
        plan.needs_homed = True  # PROFINET manual 5.10.1: "Axis needs to be homed"
        plan.deadline_s = r.timeout_s if r.timeout_s is not None else 60.0
        return plan
    kind = "velocity" if r.kind == "jog" and r.duration_s is not None else "position"
    plan.mode_kind = kind
    plan.mode_text = axis_cls.mode_name(kind)
    scales = (scales_of or axis_cls.motion_scales)(kind)
    vmax, amax = _limit(limits, "max_velocity"), _limit(limits, "max_acceleration")
    velocity: float | None
    if r.kind == "jog":
        if (r.duration_s is None) == (r.distance is None):
            raise UsageError("jog needs exactly one of --for DURATION or --distance D, so the motion is bounded")
        velocity = finite(r.velocity, "jog velocity")
        if velocity == 0:
            raise UsageError("jog velocity must not be 0")
        if r.duration_s is not None:
            plan.duration_s = check_duration(limits, r.duration_s)
        else:
            finite(r.distance, "jog distance")
    else:
        finite(r.target, "move target")
        velocity = finite(r.velocity, "velocity") if r.velocity is not None else None
    # ---- velocity and accelerations as the drive will execute them
    if velocity is not None and r.kind == "move" and velocity <= 0:
        raise UsageError(f"velocity must be greater than 0, got {velocity:g} rpm")
    _refuse_over_limit("velocity", None if velocity is None else abs(velocity), vmax, "max_velocity", "rpm")
    for name, value in (("acceleration", r.accel), ("deceleration", r.decel)):
        if value is not None:
            _refuse_over_limit(name, abs(finite(value, name)), amax, "max_acceleration", "rpm/s")
    if velocity is None:
        wanted = min(DEFAULT_RPM, vmax) if vmax is not None else DEFAULT_RPM
        plan.velocity = quantise(scales.velocity, wanted, "velocity", explicit=False)
    else:
        signed = velocity if r.kind == "jog" and r.duration_s is not None else abs(velocity)
        plan.velocity = quantise(scales.velocity, signed, "velocity")
    accels = []
    for name, value, scale in (("acceleration", r.accel, scales.accel), ("deceleration", r.decel, scales.decel)):
        if value is None and name == "deceleration" and r.accel is not None:
            value = r.accel  # decel defaults to accel
        if value is not None:
            value = finite(value, name)
            if value <= 0:
                raise UsageError(f"{name} must be greater than 0, got {value:g} rpm/s")
            accels.append(quantise(scale, value, name))
        else:
            wanted = min(DEFAULT_ACC_RPM_S, amax) if amax is not None else DEFAULT_ACC_RPM_S
            accels.append(quantise(scale, wanted, name, explicit=False))
    plan.accel, plan.decel = accels
    # The limits hold for what the drive executes (a default or a quantised value), not only for the request.
    _refuse_over_limit("velocity", abs(plan.velocity.executed), vmax, "max_velocity", "rpm", plan.velocity.field_name)
    for q in accels:
        _refuse_over_limit(q.what, q.executed, amax, "max_acceleration", "rpm/s", q.field_name)
    # ---- positions that need no drive
    plan.unit = r.unit or default_unit(conn)
    if plan.unit not in UNITS:
        raise UsageError(f"'unit' {plan.unit!r} is not a unit: expected one of {', '.join(UNITS)}")
    if plan.unit == "user" and not per_rev_of(conn):
        raise UsageError("--units user needs [units] per_rev in the config profile")
    if r.kind == "move" and not r.relative and axis_cls.NO_ABSOLUTE_MOVES:
        raise SafetyRefusal(f"refusing: absolute moves are not possible over this link: {axis_cls.NO_ABSOLUTE_MOVES}")
    if r.kind == "move" and not r.relative and plan.unit != "counts":
        _check_travel(limits, to_rev(conn, float(r.target), plan.unit, None))  # type: ignore[arg-type]
    positioning = r.kind == "move" or r.distance is not None
    plan.needs_homed = (r.kind == "move" and not r.relative) or (positioning and axis_cls.RELATIVE_MOVES_NEED_HOME)
    return plan


# ====================================================================== stage 2: the drive's state (reads only)
def plan(conn: "Connection", axis: "Axis", request: MotionRequest) -> MotionPlan:
    """:func:`check_request`, then the drive's state (module docstring); nothing is written."""
    accepted = check_request(conn, request, type(axis), axis.drive_motion_scales)
    accepted.target = conn.target.display
    r = request
    status = axis.read_status()
    axis.refuse_if_fault(status)
    accepted.mode_text = axis.mode_name(accepted.mode_kind) if accepted.mode_kind else status.mode_text
    if r.kind != "enable" and not status.standstill:
        raise SafetyRefusal("refusing: the axis is moving; stop it first ('akdctl stop')")
    axis.refuse_if_not_commandable(status)
    if r.kind == "home":
        axis.check_home(r.home_mode)
    if r.kind in ("enable", "home"):
        return accepted
    limits = limits_of(conn)
    cpr = axis.counts_per_rev(status)
    if accepted.needs_homed:
        accepted.homed = axis.homed_reading(status)
        if accepted.homed is False:
            raise SafetyRefusal(_not_homed_text(axis, r))
    if r.kind == "task":
        return _plan_task(conn, accepted, status.position_rev, limits)
    pos = status.position_rev
    if r.kind == "jog" and r.duration_s is not None:
        assert accepted.velocity is not None and accepted.accel is not None
        rps = accepted.velocity.executed / 60.0
        braking = rps * abs(rps) / (2 * accepted.accel.executed / 60.0)
        accepted.start_rev = pos
        if pos is not None:
            accepted.end_rev = pos + rps * r.duration_s + braking
            _check_travel(limits, accepted.end_rev, "would reach")
        elif limits.get("travel") is not None:
            raise SafetyRefusal("refusing: the profile limits travel but this link cannot read the position")
        accepted.deadline_s = r.duration_s
        return accepted
    value = r.distance if r.kind == "jog" else r.target
    rev = to_rev(conn, float(value), accepted.unit, cpr)  # type: ignore[arg-type]
    relative = r.kind == "jog" or r.relative
    scale = axis.position_scale(status)
    counts = round(rev * cpr)
    if not scale.raw_min <= counts <= scale.raw_max:
        raise UsageError(f"{'distance' if relative else 'target'} {value:g} {accepted.unit} is outside the range of "
                         f"{scale.name} ({scale.raw_min}..{scale.raw_max} counts)")
    accepted.target_raw = counts
    accepted.move_rev = counts / cpr
    accepted.start_rev = pos
    if relative:
        if pos is not None:
            accepted.end_rev = pos + accepted.move_rev
        elif limits.get("travel") is not None:
            raise SafetyRefusal("refusing: the profile limits travel but this link cannot read the position")
    else:
        accepted.end_rev = accepted.move_rev
    if accepted.end_rev is not None:
        _check_travel(limits, accepted.end_rev)
    assert accepted.velocity and accepted.accel and accepted.decel
    distance = accepted.move_rev if relative else (accepted.move_rev - (pos or 0.0))
    estimate = _move_time(distance, accepted.velocity.executed, accepted.accel.executed, accepted.decel.executed)
    accepted.deadline_s = r.timeout_s if r.timeout_s is not None else estimate + 2 * axis.timeout + 1.0
    return accepted


def _plan_task(conn: "Connection", accepted: MotionPlan, pos: float | None, limits: dict[str, Any]) -> MotionPlan:
    """A stored task: read (MT.LOAD, the working parameters restored) and held to the rules ``task set`` applied
    (:func:`akdctl.drive.tasks.check_values`) before consent, so the consent names its target and speed; a link
    that cannot read the table refuses when the profile sets limits, because they could not be checked
    (docs/fidelity.md F11)."""
    from akdctl.drive import tasks

    number = accepted.request.task
    limited = [k for k in ("max_velocity", "max_acceleration", "travel") if limits.get(k) is not None]
    if not conn.has_objects:
        if limited:
            raise SafetyRefusal(f"refusing: the profile limits {', '.join(limited)} but motion task {number} cannot "
                                f"be read over this link to check it ({tasks.NO_TABLE})")
        accepted.notes.append(f"motion task {number} cannot be read over this link; it runs as stored")
        return accepted

    # Read before consent, so the consent names where and how fast: the read saves and restores the working
    # parameters it overwrites (drive/tasks.read_tasks) and the plan already refused a moving axis.
    task = tasks.read_task(conn.objects(), number)  # type: ignore[arg-type]
    if not task.configured:
        raise SafetyRefusal(f"refusing: motion task {number} is not configured (MT.V/MT.ACC/MT.DEC are 0); "
                            f"set it with 'akdctl task set {number} ...'")
    if task.relative and pos is None and limits.get("travel") is not None:
        raise SafetyRefusal("refusing: the profile limits travel but this link cannot read the position")
    tasks.check_values(conn, int(number or 0), task.position_rev, task.velocity_rpm, task.acc_rpm_s, task.dec_rpm_s,
                       task.relative, start_rev=pos)
    end = (pos or 0.0) + task.position_rev if task.relative else task.position_rev
    accepted.start_rev, accepted.end_rev = pos, end
    accepted.task_text = (f"{'by' if task.relative else 'to'} {task.position_rev:g} rev (ends at {end:.4f} rev) at "
                          f"{task.velocity_rpm:.6g} rpm, accel {task.acc_rpm_s:.6g} / decel {task.dec_rpm_s:.6g} "
                          "rpm/s")
    accepted.notes.append(tasks.RESTORED_NOTE)
    if accepted.request.timeout_s is None:
        distance = task.position_rev if task.relative else end - (pos or 0.0)
        accepted.deadline_s = _move_time(distance, task.velocity_rpm, task.acc_rpm_s, task.dec_rpm_s) + 5.0
    return accepted


def _not_homed_text(axis: "Axis", request: MotionRequest) -> str:
    if axis.RELATIVE_MOVES_NEED_HOME:
        return ("refusing: the axis is not homed; the drive runs positioning tasks (absolute and relative) only on a "
                f"homed axis ({axis.HOMED_SOURCE}); run 'akdctl home' first")
    return ("refusing: the axis is not homed, so an absolute position means nothing yet; run 'akdctl home' first "
            "(or move with --relative)")


# ====================================================================== running an accepted plan
def execute(axis: "Axis", accepted: MotionPlan, interrupted: Callable[[], bool],
            progress: Callable[[Any], None] | None = None, wait: bool = True) -> Any:
    """Carry out an accepted plan (after consent): mode, enable, set points, wait; stops the axis on errors.

    ``wait=False`` (``move --no-wait``) returns once the drive acknowledged the move.
    """
    from akdctl.drive.axis.base import JogSpec, MoveSpec
    from akdctl.drive.motion_run import MotionRun

    r = accepted.request
    if r.kind == "enable":
        return axis.enable()
    if accepted.after_consent is not None:
        accepted.after_consent()
    _prepare(axis, accepted, interrupted)
    run = MotionRun(axis, interrupted, progress)
    if r.kind == "home":
        return run.run(lambda: axis.start_home(r.home_mode), axis.home_finished, deadline_s=accepted.deadline_s,
                       what="homing")
    if r.kind == "task":
        number = r.task
        if number is None:  # check_request refuses it first; never start "task 0" by accident
            raise UsageError("task start needs a task number")
        return run.run(lambda: axis.start_task(number), lambda s: True if s.target_reached and s.standstill else None,
                       deadline_s=accepted.deadline_s, what=f"motion task {r.task}")
    assert accepted.velocity and accepted.accel and accepted.decel
    if r.kind == "jog" and r.duration_s is not None:
        spec = JogSpec(accepted.velocity.raw, accepted.accel.raw, accepted.decel.raw)
        run.run(lambda: axis.start_jog(spec), lambda s: None, deadline_s=accepted.deadline_s, what="jog",
                on_deadline="stop")
        axis.end_jog()
        return axis.wait_for(lambda s: s.standstill, "standstill after jog", timeout=axis.timeout + 5.0)
    assert accepted.target_raw is not None
    move = MoveSpec(accepted.target_raw, r.kind == "jog" or r.relative, accepted.velocity.raw, accepted.accel.raw,
                    accepted.decel.raw)
    if not wait:
        try:
            axis.start_move(move)
        except BaseException:
            axis.safe_stop()
            raise
        return axis.read_status()
    what = "jog" if r.kind == "jog" else "move"
    status = run.run(lambda: axis.start_move(move), lambda s: True if s.target_reached and s.standstill else None,
                     deadline_s=accepted.deadline_s, what=what)
    return confirm_own_target(axis, accepted, status, what)


#: How far from the position this command aimed at the axis may stand when the drive says "target
#: reached" (revolutions). The drive's own position window is not known here; one hundredth of a
#: revolution is far inside any move another command could have run instead, and far outside the
#: following error of a settled axis.
TARGET_TOLERANCE_REV = 0.01


def confirm_own_target(axis: "Axis", accepted: MotionPlan, status: Any, what: str) -> Any:
    """"Target reached" only for the set point this command issued (issue 17.7).

    The drive's target-reached bit says that *a* positioning task ended, not that it was ours: a task
    loaded by someone else (another master, a command that did not pass the owner lock) reports the
    same bit. So the axis must stand where this command's set point puts it (the start position read
    after the owner lock was taken, plus the distance; or the absolute target), and where the
    position cannot be read, the drive's set point must still be the one written here. Otherwise
    DriveError (exit 1) in words; the axis is at standstill already.
    """
    from akdctl.errors import DriveError

    expected = accepted.end_rev
    if expected is not None and status.position_rev is not None:
        if abs(status.position_rev - expected) > TARGET_TOLERANCE_REV:
            raise DriveError(f"the drive reports target reached, but the axis stands at {status.position_rev:.4f} rev, "
                             f"not at {expected:.4f} rev where this {what} was going: another command or master "
                             "moved the axis meanwhile; check the position before moving again",
                             details={"expected_rev": round(expected, 6),
                                      "position_rev": round(status.position_rev, 6)})
        return status
    drive_target = axis.issued_target()
    if drive_target is not None and drive_target != accepted.target_raw:
        raise DriveError(f"the drive reports target reached for set point {drive_target}, not for {accepted.target_raw} "
                         f"which this {what} wrote: another command or master loaded a task meanwhile",
                         details={"expected_raw": accepted.target_raw, "drive_raw": drive_target})
    return status


def _prepare(axis: "Axis", accepted: MotionPlan, interrupted: Callable[[], bool]) -> None:
    """Re-check under the owner lock (the drive may have changed since the plan), confirm homed,
    switch the mode, enable. A relative move is measured from the position read here. With no prompt between
    (``--yes``) the plan's own read is recent enough to stand for this one (Axis.recent_status)."""
    status = axis.recent_status()
    axis.refuse_if_fault(status)
    if not status.standstill:
        raise SafetyRefusal("refusing: the axis is moving; stop it first ('akdctl stop')")
    relative = accepted.request.kind == "jog" or accepted.request.relative
    if relative and accepted.move_rev is not None and status.position_rev is not None:
        accepted.start_rev = status.position_rev
        accepted.end_rev = status.position_rev + accepted.move_rev
        _check_travel(accepted.limits, accepted.end_rev)
    if accepted.needs_homed and accepted.homed is None and not axis.confirm_homed():
        raise SafetyRefusal(_not_homed_text(axis, accepted.request))
    axis.ensure_mode(accepted.mode_kind)
    if interrupted():
        raise Interrupted("interrupted before the motion started; nothing moved")
    axis.enable()
    if interrupted():
        _, outcome = axis.safe_stop()
        raise Interrupted(f"interrupted before the motion started; {outcome}")


def wait_hint(conn: "Connection") -> str:
    """What happens to a move the tool does not wait for (``move --no-wait``), in words."""
    if conn.target.scheme == "sim":
        return ("not waiting: the simulated drive's watchdog stops the axis about 'sim speed --watchdog' seconds "
                "(default 1 s) of wall time after the last access, so keep polling ('akdctl status --watch') if "
                "the move must finish")
    return ("not waiting: the drive runs the finite positioning task to its end on its own (acyclic access has no "
            "watchdog on the AKD); check the result with 'akdctl status'")


def start(axis: Any, accepted: MotionPlan, interrupted: Callable[[], bool]) -> None:
    """Start an accepted motion without waiting for it, for a caller that watches it itself (``scope`` records
    during it): the same re-checks, mode and enable as :func:`execute`; a move is started as ``move --no-wait``;
    a timed jog is started and left running: the caller ends it (``axis.end_jog()``) at its duration and stops
    the axis (``axis.safe_stop()``) on any error or interrupt."""
    from akdctl.drive.axis.base import JogSpec

    r = accepted.request
    if r.kind != "jog" or r.duration_s is None:
        execute(axis, accepted, interrupted, wait=False)
        return
    if accepted.after_consent is not None:
        accepted.after_consent()
    _prepare(axis, accepted, interrupted)
    assert accepted.velocity and accepted.accel and accepted.decel
    try:
        axis.start_jog(JogSpec(accepted.velocity.raw, accepted.accel.raw, accepted.decel.raw))
    except BaseException:
        axis.safe_stop()
        raise
