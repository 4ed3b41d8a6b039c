"""The simulated AKD's axis: both state machines, the operating modes and the motion itself.

Why one component for both profiles: an AKD has one power stage. PROFIdrive
(STW1/ZSW1, PNU 1/2) and CiA 402 (0x6040/0x6041) are two views of the same
state, so the simulator keeps one state and renders both words from it. A write
to either control word drives the same machine.

Motion runs in virtual seconds (:meth:`MotionComponent.tick`), integrated in
closed form segment by segment (acceleration, cruise, braking), so a long
gap between two requests costs a few loop turns, not millions of small steps.
Internally the axis works in motor revolutions (rev, rev/s, rev/s²); the
boundary converts to the units each signal uses (SPEC-NOTES 13 for PROFIdrive;
for CiA 402 the simulator uses 65536 counts per revolution, counts/s and
counts/s², i.e. an AKD with FBUS.PARAM05 bit 4 scaling of one count per
encoder increment).

Bounded motion (the drive-side watchdog): every access to a PNU or object this
component owns feeds a watchdog. When no access arrived for ``watchdog_s``
seconds of *wall* time (the virtual equivalent is ``watchdog_s × time scale``),
the drive ramps the axis to standstill on its own, sets a warning
(ZSW1/statusword bit 7) and forgets the level-triggered commands (jog bits,
velocity set point) until the next control word or set point write. A tool
that dies (kill -9) or loses its link therefore never leaves the simulated
axis moving. ``watchdog_s = 0`` disables it.

The watchdog and "target reached": a traversing task it aborts was *not*
completed. ZSW1 bit 10 (position mode) and CiA 402 statusword bit 10 (profile
position) say "target reached" only while the axis stands within
``POSITION_WINDOW_REV`` of the last task's target; after an aborted task they
stay clear, so a ``move --no-wait`` whose tool exited (and stopped feeding the
watchdog) cannot later read as arrived at the wrong position. A move outlives
its tool by at most ``watchdog_s`` of wall time unless something keeps
talking to the drive (docs/simulator.md).
"""

from __future__ import annotations

import math
import struct
from typing import TYPE_CHECKING, Any

from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.sim.errors import PnuAccessError, SdoAccessError
from akdctl.sim.component import (
    ABORT_DEVICE_STATE,
    ABORT_NO_SUBINDEX,
    ABORT_VALUE_RANGE,
    PE_OPERATING_STATE,
    Component,
)

if TYPE_CHECKING:
    from akdctl.sim.model import DriveModel

CIA_COUNTS_PER_REV = 65536
EPS = 1e-9  # rev, rev/s: below this the axis is at its target / at standstill
DEFAULT_RAMP_RPM_S = 1000.0  # a 0 in a CiA 402 ramp object means "use this" in the simulator
QUICK_STOP_RPM_S = 50000.0  # the quick stop / fault reaction ramp
COAST_RPM_S = 2000.0  # an unpowered motor runs down (friction) at this rate
HOMING_FAST_RPM = 60.0
HOMING_SLOW_RPM = 10.0
HOMING_MAX_TRAVEL_REV = 1000.0  # a search that finds nothing within this aborts with a homing error
HOME_SWITCH_REV = 1.25  # physical position of the simulated home switch edge (active above it)
INDEX_OFFSET_REV = 0.3  # the encoder index pulse: once per revolution at k + this
LIMIT_SWITCH_REV = (-5.0, 5.0)  # simulated hardware limit switches (physical)
FOLLOWING_LAG_S = 0.002  # following error = velocity × this (a stiff position loop)
DEFAULT_FE_WINDOW_REV = 0.5  # ZSW1 bit 8 / SW bit 13 window when 0x6065 is 0
SEARCH_STEP_S = 0.001  # homing searches integrate in steps of 1 ms to catch the switch edge
DEFAULT_WATCHDOG_S = 1.0
POSITION_WINDOW_REV = 1.0 / CIA_COUNTS_PER_REV  # "target reached": within one count of the task's target

# internal states (CiA 402 names; PROFIdrive S1..S5 are derived)
SOD, READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION, FAULT = (
    "switch_on_disabled", "ready", "switched_on", "enabled", "quick_stop", "fault_reaction", "fault")
_CIA_WORD = {SOD: 0x40, READY: 0x21, SWITCHED_ON: 0x23, ENABLED: 0x27, QUICK_STOP: 0x07,
             FAULT_REACTION: 0x0F, FAULT: 0x08}
_PD_STATE = {SOD: "S1", READY: "S2", SWITCHED_ON: "S3", ENABLED: "S4", QUICK_STOP: "S5",
             FAULT_REACTION: "S1", FAULT: "S1"}

# AKD HOME.MODE (PNU 1001) → the simulator's procedure; other modes end in a homing error.
HOME_MODE_PROCEDURES = {0: "current", 1: "limit-", 2: "limit-index", 3: "switch", 4: "switch-index", 5: "index"}
# CiA 402 homing methods (0x6098) → procedure.
CIA_HOMING_PROCEDURES = {
    **{m: "limit-index" for m in (1, 2)},
    **{m: "switch-index" for m in range(3, 15)},
    17: "limit-", 18: "limit+",
    **{m: "switch" for m in range(19, 31)},
    33: "index-", 34: "index", 35: "current", 37: "current",
}

# The simulator's motion task table (program mode, SATZANW 1..4): AKD MT.* parameters.
DEFAULT_TASKS = {
    "1": {"position": 1.0, "rpm": 600.0, "acc": 10000.0, "dec": 10000.0, "absolute": False},
    "2": {"position": -1.0, "rpm": 600.0, "acc": 10000.0, "dec": 10000.0, "absolute": False},
    "3": {"position": 0.0, "rpm": 600.0, "acc": 10000.0, "dec": 10000.0, "absolute": True},
    "4": {"position": 5.0, "rpm": 1200.0, "acc": 10000.0, "dec": 10000.0, "absolute": True},
}


def _sign(x: float) -> float:
    return (x > 0) - (x < 0)


def _rpm_s(value: float) -> float:
    """rpm/s → rev/s²."""
    return value / 60.0


class MotionComponent(Component):
    """State machines, modes and motion of the simulated axis (contract: docs/internals.md)."""

    name = "motion"

    def __init__(self, model: "DriveModel") -> None:
        super().__init__(model)
        self.state = SOD
        self.stopping_to: str | None = None  # state to enter when a ramp stop reaches standstill
        self.stw1 = 0
        self.controlword = 0
        self.plc_control_allowed = True  # False simulates a drive that does not honour STW1 bit 10
        self.mode = 3  # 0x6060 (3 profile velocity ↔ PNU 930 = 1, the PNU's documented default)
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
        self.aktsatz = 0
        self.homed = False
        self.homing: dict[str, Any] | None = None
        self.homing_error = False
        self.homing_done = False
        self.internal_limit = False
        self.frozen_vel: float | None = None
        self.watchdog_s = DEFAULT_WATCHDOG_S
        self.since_access = 0.0
        self.watchdog_tripped = False
        self.quick_stop_option = 2
        self.own_faults: list[str] = []  # used only when no fault component exists
        self.tasks = {k: dict(v) for k, v in DEFAULT_TASKS.items()}
        self._bind()

    # ================================================================== contract
    @property
    def standstill(self) -> bool:
        return abs(self.vel) < EPS and (self.gen is None or self.gen.get("hold", False))

    @property
    def position_counts(self) -> int:
        return round((self.pos + self.offset) * self.counts_per_rev)

    @property
    def velocity_rpm(self) -> float:
        return self.vel * 60.0

    def on_fault(self, code: str) -> None:
        """A fault was raised: react at once (fault reaction = quick stop, then power off)."""
        if self._faults() is None and code not in self.own_faults and not code.lower().startswith("n"):
            self.own_faults.append(code)
        if code.lower().startswith("n"):
            return
        self._abort_tasks(error=True)
        self.frozen_vel = None
        if self.state in (ENABLED, QUICK_STOP) and not self._at_rest():
            self.state = FAULT_REACTION
            self._ramp_to_zero(QUICK_STOP_RPM_S, "fault")
        else:
            self.state = FAULT
            if not self._at_rest():
                self._ramp_to_zero(COAST_RPM_S, "coast")
        self.stopping_to = None

    # ================================================================== helpers
    @property
    def counts_per_rev(self) -> int:
        return 1 << self.model.stored_pnu(1002)[0]

    @property
    def opmode(self) -> int:
        """PNU 930 (DRV.OPMODE) derived from the CiA 402 mode."""
        return {4: 0, 3: 1}.get(self.mode, 2)

    def _faults(self) -> Any:
        return self.model.component("faults")

    @property
    def fault_present(self) -> bool:
        faults = self._faults()
        return bool(faults.fault_present) if faults is not None else bool(self.own_faults)

    @property
    def warning_present(self) -> bool:
        faults = self._faults()
        warn = bool(faults.warning_present) if faults is not None else False
        return warn or self.watchdog_tripped

    def _acknowledge(self) -> None:
        faults = self._faults()
        if faults is not None:
            faults.acknowledge()
        else:
            self.own_faults.clear()
        self.watchdog_tripped = False
        if self.state in (FAULT, FAULT_REACTION) and not self.fault_present and self._at_rest():
            self.state = SOD
            self.activity = "idle"

    def _at_rest(self) -> bool:
        return abs(self.vel) < EPS and self.gen is None

    @property
    def at_target(self) -> bool:
        """At the last traversing task's target (True when no task set one since homing/jog/mode change)."""
        return self.last_target is None or abs(self.pos - self.last_target) <= POSITION_WINDOW_REV

    def _pnu(self, pnu: int) -> int:
        return self.model.signed_pnu(pnu)[0]

    def _obj(self, index: int, sub: int = 0) -> int:
        return self.model.object_value(index, sub)

    def _feed(self) -> None:
        self.since_access = 0.0

    def _ramp_to_zero(self, rpm_s: float, activity: str) -> None:
        self.gen = {"kind": "velocity", "v": 0.0, "acc": _rpm_s(rpm_s), "dec": _rpm_s(rpm_s)}
        self.activity = activity

    def _abort_tasks(self, error: bool = False) -> None:
        if self.homing is not None:
            self.homing = None
            self.homing_error = error or self.homing_error
            self.homed = False
        self.task = None
        self.task_paused = False

    def _limits(self) -> tuple[float, float] | None:
        """Software position limits 0x607D (physical rev); None when both are 0 (disabled)."""
        lo, hi = self._obj(0x607D, 1), self._obj(0x607D, 2)
        if lo == 0 and hi == 0:
            return None
        return lo / CIA_COUNTS_PER_REV - self.offset, hi / CIA_COUNTS_PER_REV - self.offset

    def _fe_window(self) -> float:
        window = self._obj(0x6065)
        return window / CIA_COUNTS_PER_REV if window else DEFAULT_FE_WINDOW_REV

    @property
    def following_error(self) -> float:
        return self.vel * FOLLOWING_LAG_S + (self.acc_now * FOLLOWING_LAG_S * FOLLOWING_LAG_S)

    # ================================================================== time
    def tick(self, dt: float) -> None:
        faults = self._faults()
        if faults is not None and faults.fault_present and self.state not in (FAULT, FAULT_REACTION):
            codes = [c for c in faults.active() if not c.lower().startswith("n")]
            self.on_fault(codes[0] if codes else "F0")
        threshold = self.watchdog_s * float(getattr(self.model, "time_scale", 1.0) or 1.0)
        if self._at_rest():
            # The watchdog only guards motion; a resting axis keeps a constant state, so an idle
            # drive's state file need not be rewritten on every read (SimDrive saves on change).
            self.since_access = 0.0
        elif self.watchdog_s > 0 and self.activity not in ("stop", "quickstop", "fault", "coast"):
            remaining = threshold - self.since_access
            if dt > remaining:
                before = max(0.0, remaining)
                self._integrate(before)
                self._watchdog_trip()
                self.since_access += before
                dt -= before
        if not self._at_rest():
            self.since_access += dt
        self._integrate(dt)

    def _watchdog_trip(self) -> None:
        """No request for ``watchdog_s`` wall seconds while moving: ramp to standstill on our own."""
        self.watchdog_tripped = True
        self.frozen_vel = None
        self._abort_tasks(error=True)
        self._stop_motion(quick=False, activity="stop")

    def _stop_motion(self, quick: bool, activity: str) -> None:
        rate = QUICK_STOP_RPM_S if quick else self._ramp_dec_rpm_s()
        if not quick and self.gen is not None and self.gen.get("kind") == "position":
            rate = max(rate, self.gen["dec"] * 60.0)  # brake a traversing task along its own ramp
        if self._at_rest():
            self.gen = None
            self.activity = "idle"
            return
        self._ramp_to_zero(rate, activity)

    def _ramp_dec_rpm_s(self) -> float:
        dec = self._pnu(1007) if self.last_writer == "pd" else self._obj(0x6084) * 60.0 / CIA_COUNTS_PER_REV
        return float(dec) if dec > 0 else DEFAULT_RAMP_RPM_S

    @property
    def last_writer(self) -> str:
        return getattr(self, "_last_writer", "pd")

    def _integrate(self, dt: float) -> None:
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

    # ---------------------------------------------------------------- closed-form stepping
    def _velocity_step(self, dt: float, gen: dict[str, Any]) -> float:
        vt = gen["v"]
        limits = self._limits()
        if limits is not None and abs(vt) > EPS:
            edge = limits[1] if vt > 0 else limits[0]
            if (edge - self.pos) * _sign(vt) <= EPS and abs(self.vel) < EPS:
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
        a = _sign(goal - v) * rate
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
        d = _sign(s) if abs(s) >= EPS else -_sign(v)
        if v * d < 0:  # moving away from the target: brake to 0 first
            t = abs(v) / dec
            h = min(dt, t)
            a = -_sign(v) * dec
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
        if self.activity in ("stop", "quickstop", "coast", "fault"):
            self._stop_complete()
        self.activity = "idle"

    def _stop_complete(self) -> None:
        if self.state == FAULT_REACTION:
            self.state = FAULT
        elif self.state == QUICK_STOP:
            if self.quick_stop_option in (5, 6, 7, 8):
                pass  # stay in quick stop active
            else:
                self.state = SOD
        elif self.stopping_to is not None and self.state == ENABLED:
            self.state = self.stopping_to
        self.stopping_to = None

    # ================================================================== homing
    def _start_homing(self, procedure: str | None) -> None:
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
        fast, slow = self._homing_speeds()
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
        acc = self._homing_acc()
        self.gen = {"kind": "velocity", "v": direction * speed, "acc": acc, "dec": acc}
        self.activity = "homing"

    def _homing_speeds(self) -> tuple[float, float]:
        if self.last_writer == "cia":
            fast = self._obj(0x6099, 1) / CIA_COUNTS_PER_REV
            slow = self._obj(0x6099, 2) / CIA_COUNTS_PER_REV
        else:
            fast = slow = 0.0
        return (fast or HOMING_FAST_RPM / 60.0, slow or HOMING_SLOW_RPM / 60.0)

    def _homing_acc(self) -> float:
        acc = self._obj(0x609A) / CIA_COUNTS_PER_REV if self.last_writer == "cia" else 0.0
        return acc or _rpm_s(DEFAULT_RAMP_RPM_S)

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
            assert self.gen is not None
            self.gen = dict(self.gen, v=homing["dir"] * homing["slow"])
            return
        self._set_reference(edge)
        homing["phase"] = "return"
        acc = self._homing_acc()
        self.gen = {"kind": "position", "target": edge, "v": homing["slow"] * 4, "acc": acc, "dec": acc}

    def _set_reference(self, physical: float) -> None:
        home_offset = self._obj(0x607C) / CIA_COUNTS_PER_REV
        self.offset = home_offset - physical

    def _homing_fail(self) -> None:
        self.homing = None
        self.homing_error = True
        self.homed = False
        self._stop_motion(quick=False, activity="stop")

    # ================================================================== commands: PROFIdrive
    def _write_stw1(self, sub: int, values: list[int]) -> None:
        self._feed()
        self._last_writer = "pd"
        old, new = self.stw1, values[0] & 0xFFFF
        self.stw1 = new
        if not (new & sw.STW1_CONTROL_BY_PLC and self.plc_control_allowed):
            return  # SPEC-NOTES 7: without bit 10 the drive ignores the control word
        self.watchdog_tripped = False
        if new & sw.STW1_FAULT_ACK and not old & sw.STW1_FAULT_ACK:
            self._acknowledge()
            return  # SPEC-NOTES 7: after the acknowledge the drive is in S1; the next word moves on
        if self.state in (FAULT, FAULT_REACTION):
            return
        self._pd_general(new)
        if self.state == ENABLED and self.stopping_to is None:
            self._pd_mode_bits(old, new)

    def _pd_general(self, word: int) -> None:
        on = bool(word & sw.STW1_ON)
        no_coast = bool(word & sw.STW1_NO_COAST_STOP)
        no_quick = bool(word & sw.STW1_NO_QUICK_STOP)
        enable = bool(word & sw.STW1_ENABLE_OPERATION)
        state = self.state
        if not no_coast:  # OFF2: pulses off, the motor coasts, S1
            if state in (ENABLED, QUICK_STOP) and not self._at_rest():
                self._abort_tasks()
                self._ramp_to_zero(COAST_RPM_S, "coast")
            self.state, self.stopping_to = SOD, None
            return
        if not no_quick:  # OFF3: quick stop (S5), then S1
            if state in (ENABLED, QUICK_STOP) and not self._at_rest():
                self._abort_tasks()
                self.state = QUICK_STOP
                self.quick_stop_option = 2
                self._ramp_to_zero(QUICK_STOP_RPM_S, "quickstop")
            elif state != QUICK_STOP:
                self.state, self.stopping_to = SOD, None
            return
        if state == QUICK_STOP:
            return  # S5 runs to standstill, then S1
        if state == SOD:
            if not on:
                self.state = READY
            return
        if state == READY:
            if on:
                self.state = SWITCHED_ON
                if enable:
                    self._enter_enabled()
            return
        if state == SWITCHED_ON:
            if not on:
                self.state = READY
            elif enable:
                self._enter_enabled()
            return
        if state == ENABLED:
            if not on or not enable:
                self._abort_tasks()
                self.frozen_vel = None
                self.stopping_to = READY if not on else SWITCHED_ON
                if self._at_rest():
                    self.state, self.stopping_to = self.stopping_to, None
                else:
                    self._stop_motion(quick=False, activity="stop")
            elif self.stopping_to is not None:
                # ON and enable again while the OFF1 ramp runs: stay in operation
                self.stopping_to = None

    def _enter_enabled(self) -> None:
        self.state = ENABLED
        self.stopping_to = None
        self.internal_limit = False
        self.homing_error = False if self.homing is None else self.homing_error

    def _pd_mode_bits(self, old: int, new: int) -> None:
        jog = new & (sw.STW1_JOG1 | sw.STW1_JOG2)
        old_jog = old & (sw.STW1_JOG1 | sw.STW1_JOG2)
        b456 = new & (sw.STW1_BIT4 | sw.STW1_BIT5 | sw.STW1_BIT6)
        if jog or self.activity == "jog":
            if jog and (self.activity == "jog" or (jog != old_jog and self._at_rest() and not b456)):
                if jog == sw.STW1_JOG1:
                    rpm = units.x_to_rpm(self._pnu(1004), 15)
                elif jog == sw.STW1_JOG2:
                    rpm = units.x_to_rpm(self._pnu(1005), 15)
                else:
                    rpm = 0.0
                acc, dec = self._pnu(1006) or DEFAULT_RAMP_RPM_S, self._pnu(1007) or DEFAULT_RAMP_RPM_S
                self.gen = {"kind": "velocity", "v": rpm / 60.0, "acc": _rpm_s(acc), "dec": _rpm_s(dec)}
                self.activity = "jog"
                self.last_target = None  # jogging replaces any traversing target
                return
            if not jog and self.activity == "jog":
                self._stop_motion(quick=False, activity="stop")
                return
            if jog:
                return  # prerequisites not met (not at standstill, or bits 4/5/6 set): ignored
        if self.opmode == 1:
            self._pd_velocity(new)
        elif self.opmode == 2:
            self._pd_position(old, new)

    def _pd_velocity(self, word: int) -> None:
        """Velocity mode (application class 1): bits 4 ramp generator, 5 unfreeze, 6 set point."""
        acc, dec = self._pnu(1006) or DEFAULT_RAMP_RPM_S, self._pnu(1007) or DEFAULT_RAMP_RPM_S
        if not word & sw.STW1_BIT4 or not word & sw.STW1_BIT6:
            self.frozen_vel = None
            target = 0.0
        elif not word & sw.STW1_BIT5:
            if self.frozen_vel is None:
                self.frozen_vel = self.vel
            target = self.frozen_vel
        else:
            self.frozen_vel = None
            target = units.x_to_rpm(self._pnu(5), 15) / 60.0
        if abs(target) < EPS and self._at_rest():
            self.gen = None
            self.activity = "idle"
            return
        self.gen = {"kind": "velocity", "v": target, "acc": _rpm_s(acc), "dec": _rpm_s(dec)}
        self.activity = "velocity" if abs(target) > EPS else "stop"

    def _pd_position(self, old: int, new: int) -> None:
        """Position mode (application class 3): homing (bit 11), traversing tasks (bits 4/5/6)."""
        start_home = new & sw.STW1_START_HOMING
        if start_home and not old & sw.STW1_START_HOMING:
            if self._at_rest() and self.task is None:
                self._start_homing(HOME_MODE_PROCEDURES.get(self._pnu(1001)))
            return
        if not start_home and self.homing is not None:
            self.homing = None  # aborted: home position set stays clear
            self.homed = False
            self._stop_motion(quick=False, activity="stop")
            return
        if self.homing is not None:
            return
        if not new & sw.STW1_BIT6:
            self.task_ack = False
        if not new & sw.STW1_BIT4:  # reject traversing task: brake with ramp
            if self.task is not None:
                self.task = None
                self.task_paused = False
                self._stop_motion(quick=False, activity="stop")
            return
        if not new & sw.STW1_BIT5:  # intermediate stop: brake, keep the task
            if self.task is not None and not self.task_paused:
                self.task_paused = True
                self._stop_motion(quick=False, activity="stop")
            return
        if self.task is not None and self.task_paused:
            self.task_paused = False
            self._run_task(self.task)
        if new & sw.STW1_BIT6 and not old & sw.STW1_BIT6:
            task = self._pd_load_task()
            if task is not None:
                self.task_ack = True
                self._run_task(task)

    def _pd_load_task(self) -> dict[str, Any] | None:
        """Load SATZANW's task (program mode) or the MDI signals (bit 15); None if it cannot run."""
        if not self.homed or self.activity == "jog":
            return None  # manual 5.10.1/5.10.2: the axis must be homed
        satzanw = self._pnu(32)
        if satzanw & 0x8000:
            self.aktsatz = 0x8000
            rpm = units.x_to_rpm(self.model.stored_pnu(35)[0], 32)
            acc = units.acc_to_rpm_s(self.model.stored_pnu(36)[0])
            dec = units.acc_to_rpm_s(self.model.stored_pnu(37)[0])
            position = self._pnu(34) / self.counts_per_rev
            absolute = bool(self.model.stored_pnu(38)[0] & 1)
        else:
            entry = self.tasks.get(str(satzanw & 0x7FFF))
            if entry is None:
                return None
            self.aktsatz = satzanw & 0x7FFF
            rpm, acc, dec = entry["rpm"], entry["acc"], entry["dec"]
            position, absolute = entry["position"], entry["absolute"]
        return self._make_task(position, absolute, rpm / 60.0, _rpm_s(acc), _rpm_s(dec))

    def _make_task(self, position: float, absolute: bool, v: float, acc: float, dec: float) -> dict[str, Any] | None:
        if v <= 0 or acc <= 0 or dec <= 0:
            return None
        if absolute:
            target = position - self.offset
        else:
            base = self.task["target"] if self.task is not None else self.pos
            target = base + position
        limits = self._limits()
        if limits is not None and not limits[0] - EPS <= target <= limits[1] + EPS:
            self.internal_limit = True
            return None
        self.internal_limit = False
        return {"target": target, "v": v, "acc": acc, "dec": dec}

    def _run_task(self, task: dict[str, Any]) -> None:
        self.task = task
        self.last_target = task["target"]
        self.gen = {"kind": "position", **task}
        self.activity = "task"

    def _write_nsoll(self, sub: int, values: list[int]) -> None:
        self._feed()
        self.model.set_stored_pnu(5, values)
        if self.state == ENABLED and self.stopping_to is None and self.opmode == 1 and self.activity != "jog" \
                and self.stw1 & sw.STW1_CONTROL_BY_PLC and self.plc_control_allowed:
            self.watchdog_tripped = False
            self._pd_velocity(self.stw1)

    def _write_opmode(self, sub: int, values: list[int]) -> None:
        self._feed()
        if not self._at_rest() or self.homing is not None:
            raise PnuAccessError(PE_OPERATING_STATE, None, "operating mode changes only at standstill")
        if {0: 4, 1: 3, 2: 1}[values[0]] != self.mode and self.opmode != values[0]:
            self.task, self.task_paused, self.task_ack, self.last_target = None, False, False, None
            self.mode = {0: 4, 1: 3, 2: 1}[values[0]]
        self.model.set_stored_pnu(930, values)

    def zsw1(self) -> int:
        state = self.state
        word = {SOD: sw.ZSW1_SWITCHING_ON_INHIBITED, READY: 0x01, SWITCHED_ON: 0x03, ENABLED: 0x07,
                QUICK_STOP: 0x07, FAULT_REACTION: sw.ZSW1_FAULT, FAULT: sw.ZSW1_FAULT}[state]
        if self.fault_present:
            word |= sw.ZSW1_FAULT
        honoured = bool(self.stw1 & sw.STW1_CONTROL_BY_PLC) and self.plc_control_allowed
        if self.state != SOD or self.stw1 & sw.STW1_NO_COAST_STOP or not honoured:
            word |= sw.ZSW1_NO_COAST_STOP
        if state not in (QUICK_STOP, FAULT_REACTION) and not (state == SOD and honoured
                                                               and not self.stw1 & sw.STW1_NO_QUICK_STOP):
            word |= sw.ZSW1_NO_QUICK_STOP
        if self.warning_present:
            word |= sw.ZSW1_WARNING
        if honoured:
            word |= sw.ZSW1_CONTROL_REQUESTED
        fe_ok = abs(self.following_error) <= self._fe_window()
        if self.opmode == 2:
            if fe_ok:
                word |= sw.ZSW1_BIT8
            busy = self.homing is not None or (self.task is not None) or not self._at_rest()
            if not busy and state == ENABLED and self.at_target:
                word |= sw.ZSW1_BIT10
            if self.homed and self.homing is None:
                word |= sw.ZSW1_HOME_POSITION_SET
            if self.task_ack:
                word |= sw.ZSW1_TASK_ACK
            if not busy:
                word |= sw.ZSW1_DRIVE_STOPPED
        else:
            if fe_ok:
                word |= sw.ZSW1_BIT8
            goal = self.gen["v"] if self.gen is not None and self.gen["kind"] == "velocity" else 0.0
            if state == ENABLED and abs(self.vel - goal) < 1e-6:
                word |= sw.ZSW1_BIT10
        return word

    # ================================================================== commands: CiA 402
    def _write_controlword(self, sub: int, data: bytes) -> None:
        self._feed()
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        pdo = self.model.component("pdo")
        check = getattr(pdo, "controlword_in_active_rxpdo", None)
        if check is not None and check():
            return  # SPEC-NOTES 23: the cyclic controlword wins; an SDO write has no effect
        self._last_writer = "cia"
        old, new = self.controlword, struct.unpack("<H", data)[0]
        self.controlword = new
        self.watchdog_tripped = False
        if new & sw.CW_FAULT_RESET and not old & sw.CW_FAULT_RESET:
            self._acknowledge()
        if self.state in (FAULT, FAULT_REACTION):
            return
        self._cia_general(new)
        if self.state == ENABLED and self.stopping_to is None:
            self._cia_mode_bits(old, new)

    def _cia_general(self, word: int) -> None:
        state = self.state
        if not word & sw.CW_ENABLE_VOLTAGE:  # disable voltage
            if state in (ENABLED, QUICK_STOP) and not self._at_rest():
                self._abort_tasks()
                self._ramp_to_zero(COAST_RPM_S, "coast")
            self.state, self.stopping_to = SOD, None
            return
        if not word & sw.CW_QUICK_STOP:  # quick stop
            if state == ENABLED:
                self._abort_tasks()
                self.state = QUICK_STOP
                self.quick_stop_option = self._quick_stop_option()
                if self._at_rest():
                    self._stop_complete()
                else:
                    self._ramp_to_zero(QUICK_STOP_RPM_S, "quickstop")
            elif state in (READY, SWITCHED_ON):
                self.state = SOD
            return
        switch_on, enable = bool(word & sw.CW_SWITCH_ON), bool(word & sw.CW_ENABLE_OPERATION)
        if state == QUICK_STOP:
            if self._at_rest() and switch_on and enable:
                self._enter_enabled()  # transition 16
            return
        if not switch_on:  # shutdown
            if state == ENABLED:
                self._abort_tasks()
                self.stopping_to = READY
                if self._at_rest():
                    self.state, self.stopping_to = READY, None
                else:
                    self._stop_motion(quick=False, activity="stop")
            elif state in (SOD, SWITCHED_ON):
                self.state = READY
            return
        if state == SOD:
            return  # switch on needs ready to switch on first
        if not enable:  # switch on / disable operation
            if state == READY:
                self.state = SWITCHED_ON
            elif state == ENABLED:
                self._abort_tasks()
                self.stopping_to = SWITCHED_ON
                if self._at_rest():
                    self.state, self.stopping_to = SWITCHED_ON, None
                else:
                    self._stop_motion(quick=False, activity="stop")
            return
        if state in (READY, SWITCHED_ON):
            self._enter_enabled()
        elif state == ENABLED and self.stopping_to is not None:
            self.stopping_to = None

    def _quick_stop_option(self) -> int:
        return self.quick_stop_code

    def _cia_mode_bits(self, old: int, new: int) -> None:
        halt = bool(new & sw.CW_HALT)
        rising4 = bool(new & sw.CW_NEW_SETPOINT and not old & sw.CW_NEW_SETPOINT)
        if self.mode == 6:
            if rising4 and not halt:
                if self._at_rest():
                    self._start_homing(CIA_HOMING_PROCEDURES.get(self._obj(0x6098)))
            elif (not new & sw.CW_NEW_SETPOINT or halt) and self.homing is not None:
                self.homing = None
                self.homed = False
                self._stop_motion(quick=False, activity="stop")
            return
        if self.mode == 3:
            self._cia_velocity(halt)
            return
        if self.mode == 1:
            if not new & sw.CW_NEW_SETPOINT:
                self.task_ack = False
            if halt:
                if self.task is not None and not self.task_paused:
                    self.task_paused = True
                    self._stop_motion(quick=False, activity="stop")
                return
            if self.task is not None and self.task_paused:
                self.task_paused = False
                self._run_task(self.task)
            if rising4:
                relative = bool(new & sw.CW_RELATIVE)
                task = self._make_task(
                    self._obj(0x607A) / CIA_COUNTS_PER_REV, not relative,
                    self._obj(0x6081) / CIA_COUNTS_PER_REV,
                    (self._obj(0x6083) / CIA_COUNTS_PER_REV) or _rpm_s(DEFAULT_RAMP_RPM_S),
                    (self._obj(0x6084) / CIA_COUNTS_PER_REV) or _rpm_s(DEFAULT_RAMP_RPM_S))
                if task is not None:
                    self.task_ack = True
                    self._run_task(task)

    def _cia_velocity(self, halt: bool | None = None) -> None:
        if halt is None:
            halt = bool(self.controlword & sw.CW_HALT)
        target = 0.0 if halt else self._obj(0x60FF) / CIA_COUNTS_PER_REV
        acc = (self._obj(0x6083) / CIA_COUNTS_PER_REV) or _rpm_s(DEFAULT_RAMP_RPM_S)
        dec = (self._obj(0x6084) / CIA_COUNTS_PER_REV) or _rpm_s(DEFAULT_RAMP_RPM_S)
        if abs(target) < EPS and self._at_rest():
            self.gen, self.activity = None, "idle"
            return
        self.gen = {"kind": "velocity", "v": target, "acc": acc, "dec": dec}
        self.activity = "velocity" if abs(target) > EPS else "stop"

    def _write_target_velocity(self, sub: int, data: bytes) -> None:
        self._feed()
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        self.model.set_stored_object(0x60FF, 0, data)
        if self.state == ENABLED and self.stopping_to is None and self.mode == 3:
            self.watchdog_tripped = False
            self._cia_velocity()

    def _write_mode(self, sub: int, data: bytes) -> None:
        self._feed()
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        mode = struct.unpack("<b", data)[0]
        if mode not in (1, 3, 4, 6, 7, 8):
            raise SdoAccessError(ABORT_VALUE_RANGE)
        if mode != self.mode and (not self._at_rest() or self.homing is not None):
            raise SdoAccessError(ABORT_DEVICE_STATE)
        if mode != self.mode:
            self.task, self.task_paused, self.task_ack, self.last_target = None, False, False, None
        self.mode = mode
        self.model.set_stored_pnu(930, [self.opmode])

    def statusword(self) -> int:
        state = self.state
        word = _CIA_WORD[state] | sw.SW_VOLTAGE_ENABLED | sw.SW_REMOTE
        if state == SOD or state == READY or state == SWITCHED_ON or state == ENABLED:
            word |= sw.SW_QUICK_STOP if state != SOD else 0
        if self.fault_present and state not in (FAULT, FAULT_REACTION):
            word = (word & ~0x4F) | 0x08
        if self.warning_present:
            word |= sw.SW_WARNING
        if self.internal_limit:
            word |= sw.SW_INTERNAL_LIMIT
        if state == ENABLED:
            halt = bool(self.controlword & sw.CW_HALT)
            if self.mode == 1:
                if self.task is None and self._at_rest() and self.at_target or (halt and self._at_rest()):
                    word |= sw.SW_TARGET_REACHED
                if self.task_ack:
                    word |= sw.SW_BIT12
                if abs(self.following_error) > self._fe_window():
                    word |= sw.SW_BIT13
            elif self.mode == 6:
                if self.homing is None and self._at_rest():
                    word |= sw.SW_TARGET_REACHED
                if self.homed and self.homing is None and self.homing_done:
                    word |= sw.SW_BIT12
                if self.homing_error:
                    word |= sw.SW_BIT13
            elif self.mode == 3:
                goal = self.gen["v"] if self.gen is not None and self.gen["kind"] == "velocity" else 0.0
                if abs(self.vel - goal) < 1e-6:
                    word |= sw.SW_TARGET_REACHED
        return word

    # ================================================================== bindings
    def _bind(self) -> None:
        m = self.model

        def pnu_reader(func: Any) -> Any:
            def read(sub: int, count: int) -> list[int]:
                self._feed()
                return [func()]
            return read

        m.bind_pnu(1, read=pnu_reader(lambda: self.stw1), write=self._write_stw1)
        m.bind_pnu(2, read=pnu_reader(self.zsw1))
        m.bind_pnu(5, write=self._write_nsoll)
        m.bind_pnu(6, read=pnu_reader(lambda: units.rpm_to_x(max(-12000.0, min(12000.0, self.velocity_rpm)), 15)))
        m.bind_pnu(33, read=pnu_reader(lambda: self.aktsatz))
        m.bind_pnu(52, read=pnu_reader(lambda: round(self._current_fraction() * (1 << 14))))
        m.bind_pnu(930, read=pnu_reader(lambda: self.opmode), write=self._write_opmode)

        def obj_reader(fmt: str, func: Any) -> Any:
            def read(sub: int) -> bytes:
                if sub != 0:
                    raise SdoAccessError(ABORT_NO_SUBINDEX)
                self._feed()
                return struct.pack(fmt, func())
            return read

        m.bind_object(0x6040, read=obj_reader("<H", lambda: self.controlword), write=self._write_controlword)
        m.bind_object(0x6041, read=obj_reader("<H", self.statusword))
        m.bind_object(0x6060, read=obj_reader("<b", lambda: self.mode), write=self._write_mode)
        m.bind_object(0x6061, read=obj_reader("<b", lambda: self.mode))
        cia_pos = lambda: _clamp32(round((self.pos + self.offset) * CIA_COUNTS_PER_REV))  # noqa: E731
        m.bind_object(0x6063, read=obj_reader("<i", cia_pos))
        m.bind_object(0x6064, read=obj_reader("<i", cia_pos))
        m.bind_object(0x606C, read=obj_reader("<i", lambda: _clamp32(round(self.vel * CIA_COUNTS_PER_REV))))
        m.bind_object(0x6077, read=obj_reader("<h", lambda: round(self._current_fraction() * 1000)))
        m.bind_object(0x60F4, read=obj_reader("<i", lambda: _clamp32(round(self.following_error * CIA_COUNTS_PER_REV))))
        m.bind_object(0x60FC, read=obj_reader("<i", self._demand_counts))
        m.bind_object(0x60FF, write=self._write_target_velocity)

        def read_qs(sub: int) -> bytes:
            if sub != 0:
                raise SdoAccessError(ABORT_NO_SUBINDEX)
            return struct.pack("<h", self.quick_stop_code)

        def write_qs(sub: int, data: bytes) -> None:
            value = struct.unpack("<h", data)[0]
            if value not in (0, 1, 2, 5, 6):
                raise SdoAccessError(ABORT_VALUE_RANGE)
            self.quick_stop_code = value

        self.quick_stop_code = 2
        m.bind_object(0x605A, read=read_qs, write=write_qs)

    def _demand_counts(self) -> int:
        target = self.gen["target"] if self.gen is not None and self.gen["kind"] == "position" else self.pos
        return _clamp32(round((target + self.offset) * CIA_COUNTS_PER_REV))

    def _current_fraction(self) -> float:
        """A plausible current: acceleration torque plus a little friction, as a fraction of peak."""
        if self.state not in (ENABLED, QUICK_STOP, FAULT_REACTION):
            return 0.0
        frac = (self.acc_now * 60.0) / 100000.0 + 0.02 * _sign(self.vel)
        return max(-1.0, min(1.0, frac))

    # ================================================================== persistence
    _FIELDS = ("state", "stopping_to", "stw1", "controlword", "plc_control_allowed", "mode", "pos", "vel",
               "acc_now", "offset", "gen", "activity", "task", "task_paused", "last_target", "task_ack", "aktsatz",
               "homed", "homing", "homing_error", "homing_done", "internal_limit", "frozen_vel", "watchdog_s",
               "since_access", "watchdog_tripped", "quick_stop_option", "quick_stop_code", "own_faults", "tasks")

    def to_state(self) -> dict[str, Any]:
        data = {name: getattr(self, name) for name in self._FIELDS}
        data["last_writer"] = self.last_writer
        data["position_counts"] = self.position_counts  # for `sim show`; ignored on load
        data["velocity_rpm"] = round(self.velocity_rpm, 6)
        return data

    def load_state(self, state: dict[str, Any]) -> None:
        for name in self._FIELDS:
            if name in state:
                setattr(self, name, state[name])
        if state.get("last_writer") in ("pd", "cia"):
            self._last_writer = state["last_writer"]
        if self.state not in _CIA_WORD:
            raise ValueError(f"motion state {self.state!r} is not a drive state")


def _clamp32(value: int) -> int:
    return max(-(1 << 31), min((1 << 31) - 1, value))
