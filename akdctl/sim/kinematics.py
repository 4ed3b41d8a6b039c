"""Kinematics of the simulated axis: set point generators, traversing tasks and homing, in motor revolutions.

Why a module of its own: how the axis moves does not depend on which control
word asked for it. The PROFIdrive word machine (``stw1_machine``) and the CiA 402
word machine (``cia402_machine``) both start the same generators here; the
motion component (``motion``) supplies the drive's parameters through
:class:`KinematicsHost` and renders the result.

Motion runs in virtual seconds (:meth:`Kinematics.integrate`), integrated in
closed form segment by segment (acceleration, cruise, braking), so a long gap
between two requests costs a few loop turns, not millions of small steps.
Internally the axis works in motor revolutions (rev, rev/s, rev/s²); the word
machines convert at their boundary (SPEC-NOTES 13 for PROFIdrive; 65536 counts
per revolution for CiA 402).

"Target reached" (ZSW1 bit 10 in position mode, CiA 402 statusword bit 10 in
profile position) is :attr:`Kinematics.at_target`: the axis stands within
``POSITION_WINDOW_REV`` of the last traversing task's target. A task that was
aborted (by the drive-side watchdog, a reject, a stop) keeps its target, so the
bit stays clear short of it; homing, jogging and a mode change forget it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Protocol

from akdctl.profiles.units import CIA_COUNTS_PER_REV
from akdctl.sim.component import FieldState, Tracked

EPS = 1e-9  # rev, rev/s: below this the axis is at its target / at standstill
POSITION_WINDOW_REV = 1.0 / CIA_COUNTS_PER_REV  # "target reached": within one count of the task's target
DEFAULT_RAMP_RPM_S = 1000.0  # a 0 in a ramp parameter means "use this" in the simulator
QUICK_STOP_RPM_S = 50000.0  # the quick stop / fault reaction ramp
COAST_RPM_S = 2000.0  # an unpowered motor runs down (friction) at this rate
HOMING_FAST_RPM = 60.0
HOMING_SLOW_RPM = 10.0
HOMING_MAX_TRAVEL_REV = 1000.0  # a search that finds nothing within this aborts with a homing error
HOME_SWITCH_REV = 1.25  # physical position of the simulated home switch edge (active above it)
INDEX_OFFSET_REV = 0.3  # the encoder index pulse: once per revolution at k + this
LIMIT_SWITCH_REV = (-5.0, 5.0)  # simulated hardware limit switches (physical)
FOLLOWING_LAG_S = 0.002  # following error = velocity × this (a stiff position loop)
SEARCH_STEP_S = 0.001  # homing searches integrate in steps of 1 ms to catch the switch edge

# The load model behind torque mode and the current estimate: at 100 % of peak torque the unloaded motor
# accelerates at ACC_AT_PEAK_RPM_S; FRICTION_FRACTION of peak is lost to friction while it turns; in torque mode
# the drive's velocity limit (VL.LIMITP on an AKD; the simulator's value) caps the speed.
ACC_AT_PEAK_RPM_S = 100000.0
FRICTION_FRACTION = 0.02
TORQUE_MODE_LIMIT_RPM = 3000.0
# Interpolated / cyclic synchronous position: the drive reaches a set point within one interpolation period
# (0x60C2), at most at the AKD's top speed and the quick stop rate.
FOLLOW_MAX_RPM = 12000.0

#: Activities in which the axis is already being brought to standstill (the watchdog leaves them alone).
STOPPING = ("stop", "quickstop", "fault", "coast")


def sign(x: float) -> float:
    return (x > 0) - (x < 0)


def rpm_s(value: float) -> float:
    """rpm/s → rev/s²."""
    return value / 60.0


if TYPE_CHECKING:  # a typing-only contract: a Protocol class costs a cold start more than the rest of the module
    class KinematicsHost(Protocol):
        """What the axis needs from the drive around it (the motion component implements it)."""

        def soft_limits(self) -> tuple[float, float] | None:
            """Software position limits in physical rev, or None when disabled."""

        def ramp_dec_rpm_s(self) -> float:
            """The deceleration of a normal (ramp) stop."""

        def homing_profile(self) -> tuple[float, float, float]:
            """Homing (fast rev/s, slow rev/s, acceleration rev/s²) of the profile that started homing."""

        def home_offset_rev(self) -> float:
            """The position the reference point reports after homing (0x607C)."""

        def stop_complete(self) -> None:
            """A stop ramp reached standstill: the power stage takes its next state."""


class Kinematics(FieldState):
    """Position, velocity and the active set point generator of one axis, plus its task and homing state."""

    FIELDS = ("pos", "vel", "acc_now", "offset", "gen", "activity", "task", "task_paused", "last_target",
              "task_ack", "homed", "homing", "homing_error", "homing_done", "internal_limit")

    def __init__(self, host: "KinematicsHost") -> None:
        super().__init__(host if isinstance(host, Tracked) else None)  # the motion component owns the axis
        self.host = host
        self.pos = 0.0  # physical position, rev
        self.vel = 0.0  # rev/s
        self.acc_now = 0.0  # rev/s² of the last segment (for the current estimate)
        self.offset = 0.0  # reported position = physical + offset (homing sets it)
        self.gen: dict[str, Any] | None = None  # the active set point generator
        self.activity = "idle"  # idle, velocity, jog, task, homing, stop, quickstop, coast, fault
        self.task: dict[str, Any] | None = None  # the running traversing task / pp set point
        self.task_paused = False
        self.last_target: float | None = None  # physical target of the last traversing task (kept if aborted)
        self.task_ack = False  # ZSW1 bit 12 / SW bit 12 (pp)
        self.homed = False
        self.homing: dict[str, Any] | None = None
        self.homing_error = False
        self.homing_done = False
        self.internal_limit = False

    # ------------------------------------------------------------------ state questions
    @property
    def standstill(self) -> bool:
        return abs(self.vel) < EPS and (self.gen is None or self.gen.get("hold", False))

    def at_rest(self) -> bool:
        return abs(self.vel) < EPS and self.gen is None

    @property
    def at_target(self) -> bool:
        """At the last traversing task's target (True when no task set one since homing/jog/mode change)."""
        return self.last_target is None or abs(self.pos - self.last_target) <= POSITION_WINDOW_REV

    @property
    def following_error(self) -> float:
        return self.vel * FOLLOWING_LAG_S + (self.acc_now * FOLLOWING_LAG_S * FOLLOWING_LAG_S)

    @property
    def demand(self) -> float:
        """The position demand (physical rev): the target of a position generator, else where the axis is."""
        return self.gen["target"] if self.gen is not None and self.gen["kind"] == "position" else self.pos

    # ------------------------------------------------------------------ generators
    def run_velocity(self, v: float, acc: float, dec: float, activity: str) -> None:
        """Ramp to velocity ``v`` (rev/s) with ``acc``/``dec`` (rev/s²)."""
        self.gen = {"kind": "velocity", "v": v, "acc": acc, "dec": dec}
        self.activity = activity

    def idle(self) -> None:
        self.gen = None
        self.activity = "idle"

    def ramp_to_zero(self, rate_rpm_s: float, activity: str) -> None:
        self.run_velocity(0.0, rpm_s(rate_rpm_s), rpm_s(rate_rpm_s), activity)

    def abort_tasks(self, error: bool = False) -> None:
        if self.homing is not None:
            self.homing = None
            self.homing_error = error or self.homing_error
            self.homed = False
        self.task = None
        self.task_paused = False

    def forget_task(self) -> None:
        """A mode change: no task, no handshake, no target to be reached."""
        self.task, self.task_paused, self.task_ack, self.last_target = None, False, False, None

    def stop_motion(self, quick: bool, activity: str) -> None:
        rate = QUICK_STOP_RPM_S if quick else self.host.ramp_dec_rpm_s()
        if not quick and self.gen is not None and self.gen.get("kind") == "position":
            rate = max(rate, self.gen["dec"] * 60.0)  # brake a traversing task along its own ramp
        if self.at_rest():
            self.idle()
            return
        self.ramp_to_zero(rate, activity)

    def make_task(self, position: float, absolute: bool, v: float, acc: float, dec: float) -> dict[str, Any] | None:
        """A traversing task to ``position`` (reported rev; relative to the running task's target), or None."""
        if v <= 0 or acc <= 0 or dec <= 0:
            return None
        if absolute:
            target = position - self.offset
        else:
            base = self.task["target"] if self.task is not None else self.pos
            target = base + position
        limits = self.host.soft_limits()
        if limits is not None and not limits[0] - EPS <= target <= limits[1] + EPS:
            self.internal_limit = True
            return None
        self.internal_limit = False
        return {"target": target, "v": v, "acc": acc, "dec": dec}

    def run_torque(self, fraction: float) -> None:
        """Torque mode: ``fraction`` of peak torque accelerates the load (less friction) up to the mode's
        velocity limit; below the friction the axis coasts down. :meth:`torque_fraction` reads it back."""
        rate = max(0.0, abs(fraction) - FRICTION_FRACTION) * ACC_AT_PEAK_RPM_S
        if rate > 0:
            self.run_velocity(sign(fraction) * TORQUE_MODE_LIMIT_RPM / 60.0, rpm_s(rate), rpm_s(rate), "torque")
        elif self.at_rest():
            self.idle()
        else:
            self.run_velocity(0.0, rpm_s(FRICTION_FRACTION * ACC_AT_PEAK_RPM_S),
                              rpm_s(FRICTION_FRACTION * ACC_AT_PEAK_RPM_S), "torque")

    def torque_fraction(self) -> float:
        """The torque (fraction of peak) the motion takes: acceleration plus friction while turning."""
        frac = self.acc_now * 60.0 / ACC_AT_PEAK_RPM_S + FRICTION_FRACTION * sign(self.vel)
        return max(-1.0, min(1.0, frac))

    def follow(self, position: float, period_s: float) -> None:
        """Interpolated / cyclic synchronous position: reach ``position`` (reported rev) within ``period_s``,
        limited to the top speed and the quick stop rate; the set point becomes the target to be reached."""
        target = position - self.offset
        speed = min(FOLLOW_MAX_RPM / 60.0, max(abs(target - self.pos) / max(period_s, 1e-6), EPS))
        rate = rpm_s(QUICK_STOP_RPM_S)
        self.last_target = target
        self.gen = {"kind": "position", "target": target, "v": speed, "acc": rate, "dec": rate}
        self.activity = "follow"

    def pause_task(self) -> None:
        """Intermediate stop (STW1 bit 5 = 0, CiA 402 halt): brake along the ramp, keep the task."""
        if self.task is not None and not self.task_paused:
            self.task_paused = True
            self.stop_motion(quick=False, activity="stop")

    def resume_task(self) -> None:
        """The intermediate stop was lifted: continue the kept task."""
        if self.task is not None and self.task_paused:
            self.task_paused = False
            self.run_task(self.task)

    def reject_task(self) -> None:
        """Reject the traversing task (STW1 bit 4 = 0): brake along the ramp, drop the task."""
        if self.task is not None:
            self.task = None
            self.task_paused = False
            self.stop_motion(quick=False, activity="stop")

    def run_task(self, task: dict[str, Any]) -> None:
        self.task = task
        self.last_target = task["target"]
        self.gen = {"kind": "position", **task}
        self.activity = "task"

    # ------------------------------------------------------------------ time
    def integrate(self, dt: float) -> None:
        guard = 0
        while dt > 1e-12 and guard < 100000:
            guard += 1
            gen = self.gen
            if gen is None:
                self.vel = 0.0
                self.acc_now = 0.0
                return
            if self.homing is not None and self.homing.get("phase") in ("search", "index"):
                used = self._search_step(dt)
            elif gen["kind"] == "velocity":
                used = self._velocity_step(dt, gen)
            else:
                used = self._position_step(dt, gen)
            if used <= 0:
                break
            dt -= used
        if self.gen is None:
            self.vel = 0.0

    def _velocity_step(self, dt: float, gen: dict[str, Any]) -> float:
        vt = gen["v"]
        limits = self.host.soft_limits()
        if limits is not None and abs(vt) > EPS:
            edge = limits[1] if vt > 0 else limits[0]
            if (edge - self.pos) * sign(vt) <= EPS and abs(self.vel) < EPS:
                self.internal_limit = True
                self.vel = 0.0
                return dt
            return self._position_step(dt, {"target": edge, "v": abs(vt), "acc": gen["acc"], "dec": gen["dec"]},
                                       limit_move=True)
        v = self.vel
        if abs(v - vt) < EPS:
            self.vel = vt
            self.acc_now = 0.0
            if abs(vt) < EPS:
                self._generator_done()
                return dt
            self.pos += vt * dt
            return dt
        if v * vt < 0 or abs(vt) < abs(v):
            rate, goal = gen["dec"], (0.0 if v * vt < 0 else vt)
        else:
            rate, goal = gen["acc"], vt
        rate = max(rate, 1e-9)
        t = abs(goal - v) / rate
        h = min(dt, t)
        a = sign(goal - v) * rate
        self.pos += v * h + 0.5 * a * h * h
        self.vel = goal if h >= t else v + a * h
        self.acc_now = a
        return h if h > 0 else dt

    def _position_step(self, dt: float, gen: dict[str, Any], limit_move: bool = False) -> float:
        target, vmax, acc, dec = gen["target"], max(gen["v"], 1e-9), max(gen["acc"], 1e-9), max(gen["dec"], 1e-9)
        s = target - self.pos
        v = self.vel
        if abs(s) < EPS and abs(v) < EPS:
            self.pos, self.vel, self.acc_now = target, 0.0, 0.0
            if limit_move:
                self.internal_limit = True
                return dt
            self._generator_done()
            return dt
        d = sign(s) if abs(s) >= EPS else -sign(v)
        if v * d < 0:  # moving away from the target: brake to 0 first
            t = abs(v) / dec
            h = min(dt, t)
            a = -sign(v) * dec
            self.pos += v * h + 0.5 * a * h * h
            self.vel = 0.0 if h >= t else v + a * h
            self.acc_now = a
            return h if h > 0 else dt
        vabs, dist = abs(v), abs(s)
        if vabs * vabs / (2 * dec) >= dist - EPS or dist < EPS:
            if vabs < EPS:
                self.pos, self.vel = target, 0.0
                return 1e-12 if dt > 1e-12 else dt
            d_eff = vabs * vabs / (2 * dist) if dist > EPS else dec
            t = vabs / d_eff
            h = min(dt, t)
            self.pos += d * (vabs * h - 0.5 * d_eff * h * h)
            vabs -= d_eff * h
            self.acc_now = -d * d_eff
            if h >= t - 1e-12:
                self.pos, self.vel = target, 0.0
            else:
                self.vel = d * vabs
            return h if h > 0 else dt
        if vabs > vmax + EPS:
            t = (vabs - vmax) / dec
            h = min(dt, t)
            self.pos += d * (vabs * h - 0.5 * dec * h * h)
            self.vel = d * (vmax if h >= t else vabs - dec * h)
            self.acc_now = -d * dec
            return h if h > 0 else dt
        if vabs < vmax - EPS:
            vp = min(vmax, math.sqrt((2 * dist * acc * dec + vabs * vabs * dec) / (acc + dec)))
            if vp <= vabs + EPS:  # cannot accelerate any further: cruise into the braking point
                vp = vabs
            else:
                t = (vp - vabs) / acc
                h = min(dt, t)
                self.pos += d * (vabs * h + 0.5 * acc * h * h)
                self.vel = d * (vp if h >= t else vabs + acc * h)
                self.acc_now = d * acc
                return h if h > 0 else dt
        cruise = max(vabs, EPS)
        t = (dist - cruise * cruise / (2 * dec)) / cruise
        if t <= 1e-12:
            # numerically at the braking point: brake now
            d_eff = cruise * cruise / (2 * dist)
            t = cruise / d_eff
            h = min(dt, t)
            self.pos += d * (cruise * h - 0.5 * d_eff * h * h)
            self.acc_now = -d * d_eff
            if h >= t - 1e-12:
                self.pos, self.vel = target, 0.0
            else:
                self.vel = d * (cruise - d_eff * h)
            return h if h > 0 else dt
        h = min(dt, t)
        self.pos += d * cruise * h
        self.vel = d * cruise
        self.acc_now = 0.0
        return h

    def _search_step(self, dt: float) -> float:
        """One step of a homing search; captures the switch edge / index pulse when crossed.

        While accelerating the step is at most 1 ms; at search speed it goes straight to the
        edge (or to the travel bound), so a long search costs a few turns.
        """
        homing = self.homing
        assert homing is not None and self.gen is not None
        before = self.pos
        h = min(dt, SEARCH_STEP_S)
        if abs(self.vel - self.gen["v"]) < EPS and abs(self.vel) > EPS:
            to_edge = (homing["edge"] - self.pos) / self.vel
            to_bound = (HOMING_MAX_TRAVEL_REV - abs(self.pos - homing["start"])) / abs(self.vel)
            ahead = [t for t in (to_edge, to_bound) if t > 0]
            h = min(dt, (min(ahead) if ahead else 0.0) + 1e-6)
        self._velocity_step(h, self.gen)
        edge = homing["edge"]
        if (before - edge) * (self.pos - edge) <= 0 and before != self.pos:
            self._homing_reference_found(edge)
        elif abs(self.pos - homing["start"]) > HOMING_MAX_TRAVEL_REV:
            self._homing_fail()
        return h

    def _generator_done(self) -> None:
        """The active generator reached its goal (standstill at a velocity 0 or at a target)."""
        gen = self.gen
        self.gen = None
        self.vel = 0.0
        self.acc_now = 0.0
        if self.homing is not None and self.homing.get("phase") == "return":
            self.homing = None
            self.homed = True
            self.homing_done = True
            self.activity = "idle"
            return
        if self.task is not None and gen is not None and gen.get("kind") == "position":
            self.task = None
        if self.activity in STOPPING:
            self.host.stop_complete()
        self.activity = "idle"

    # ------------------------------------------------------------------ homing
    def start_homing(self, procedure: str | None) -> None:
        """Start a homing procedure ("current", "limit-", "switch-index", ...; None: unknown → homing error)."""
        self.last_target = None  # homing replaces any traversing target
        self.homing_error = False
        self.homing_done = False
        self.internal_limit = False
        self.homed = False
        if procedure is None:
            self._homing_fail()
            return
        if procedure == "current":
            self._set_reference(self.pos)
            self.homed = True
            self.homing_done = True
            self.homing = None
            self.activity = "idle"
            return
        fast, slow, acc = self.host.homing_profile()
        if procedure.startswith("limit"):
            direction = 1.0 if procedure.endswith("+") else -1.0
            edge = LIMIT_SWITCH_REV[1] if direction > 0 else LIMIT_SWITCH_REV[0]
        elif procedure.startswith("switch"):
            direction = -1.0 if self.pos >= HOME_SWITCH_REV else 1.0
            edge = HOME_SWITCH_REV
        else:  # index
            direction = -1.0 if procedure == "index-" else 1.0
            edge = self._next_index(self.pos, direction)
        then_index = procedure.endswith("index") and not procedure.startswith("index")
        self.homing = {"phase": "search" if not procedure.startswith("index") else "index", "edge": edge,
                       "dir": direction, "then_index": then_index, "start": self.pos, "slow": slow}
        speed = fast if self.homing["phase"] == "search" else slow
        self.run_velocity(direction * speed, acc, acc, "homing")

    def abort_homing(self) -> None:
        """The controller withdrew its homing request: brake; the home position stays unset."""
        self.homing = None
        self.homed = False
        self.stop_motion(quick=False, activity="stop")

    @staticmethod
    def _next_index(pos: float, direction: float) -> float:
        k = (pos - INDEX_OFFSET_REV)
        n = math.floor(k) + 1 if direction > 0 else math.ceil(k) - 1
        return n + INDEX_OFFSET_REV

    def _homing_reference_found(self, edge: float) -> None:
        homing = self.homing
        assert homing is not None
        if homing["phase"] == "search" and homing["then_index"]:
            homing["phase"] = "index"
            homing["edge"] = self._next_index(edge, homing["dir"])
            self.changed()
            assert self.gen is not None
            self.gen = dict(self.gen, v=homing["dir"] * homing["slow"])
            return
        self._set_reference(edge)
        homing["phase"] = "return"
        self.changed()
        acc = self.host.homing_profile()[2]
        self.gen = {"kind": "position", "target": edge, "v": homing["slow"] * 4, "acc": acc, "dec": acc}

    def _set_reference(self, physical: float) -> None:
        self.offset = self.host.home_offset_rev() - physical

    def _homing_fail(self) -> None:
        self.homing = None
        self.homing_error = True
        self.homed = False
        self.stop_motion(quick=False, activity="stop")
