"""The simulated AKD's axis as a model component: one power stage, two word machines, one axis.

Why this module: an AKD has one power stage and one axis. PROFIdrive
(STW1/ZSW1, PNU 1/2) and CiA 402 (0x6040/0x6041) are two views of the same
state, so the component keeps the one state (``power_states``), lets either
word machine drive it (``stw1_machine``, ``cia402_machine``), moves the one
axis (``kinematics``) and binds all of it to the drive model's PNUs and
objects. Everything about *how* the words are read or the axis moves lives in
those modules; this one holds what they share: the power stage transitions,
the fault reaction, the drive parameters the axis asks for, and the watchdog.

Bounded motion (the drive-side watchdog): every access to a PNU or object this
component owns feeds a watchdog. When no access arrived for ``watchdog_s``
seconds of *wall* time (the virtual equivalent is ``watchdog_s × time scale``),
the drive ramps the axis to standstill on its own, raises the simulator's
warning n990 (ZSW1/statusword bit 7, 0x2000, an emergency), aborts the running traversing task and forgets the
level-triggered commands (jog bits, velocity set point) until the next control
word or set point write. A tool that dies (kill -9) or loses its link therefore
never leaves the simulated axis moving. ``watchdog_s = 0`` disables it.

The watchdog and "target reached": the aborted task was *not* completed, so
ZSW1 bit 10 (position mode) and CiA 402 statusword bit 10 (profile position)
stay clear short of its target (:attr:`Kinematics.at_target`). A
``move --no-wait`` therefore outlives its tool by at most ``watchdog_s`` of
wall time unless something keeps talking to the drive, and never reads as
arrived at the wrong position afterwards (docs/simulator.md).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.profiles.units import CIA_COUNTS_PER_REV
from akdctl.sim.cia402_machine import MODES, Cia402Machine
from akdctl.sim.component import ABORT_NO_SUBINDEX, Component, FieldState
from akdctl.sim.errors import SdoAccessError
from akdctl.sim.kinematics import (
    COAST_RPM_S,
    DEFAULT_RAMP_RPM_S,
    HOMING_FAST_RPM,
    HOMING_SLOW_RPM,
    QUICK_STOP_RPM_S,
    STOPPING,
    Kinematics,
    rpm_s,
)
from akdctl.sim.power_states import CIA_WORD, ENABLED, FAULT, FAULT_REACTION, POWERED, QUICK_STOP, SOD
from akdctl.sim.stw1_machine import Stw1Machine
from akdctl.sim.task_table import TaskTable

if TYPE_CHECKING:
    from akdctl.sim.model import DriveModel

DEFAULT_FE_WINDOW_REV = 0.5  # ZSW1 bit 8 / SW bit 13 window when 0x6065 is 0
DEFAULT_WATCHDOG_S = 1.0
#: The warning the watchdog raises: a simulator-only number (catalog/data/faults.csv marks it so); a real AKD has
#: no watchdog on acyclic access, hence no warning for it (docs/fidelity.md F4).
WATCHDOG_WARNING = "n990"


class MotionComponent(Component):
    """Power stage, word machines and axis of the simulated drive (contract: docs/internals.md)."""

    name = "motion"
    FIELDS = ("state", "stopping_to", "mode", "watchdog_s", "since_access", "watchdog_tripped", "quick_stop_option",
              "enabling_words")
    PERSISTED = ("last_writer",)

    def __init__(self, model: "DriveModel") -> None:
        super().__init__(model)
        self.state = SOD
        self.stopping_to: str | None = None  # state to enter when a ramp stop reaches standstill
        self.mode = 3  # 0x6060 (3 profile velocity ↔ PNU 930 = 1, the PNU's documented default)
        self.watchdog_s = DEFAULT_WATCHDOG_S
        self.since_access = 0.0
        self.watchdog_tripped = False
        self.quick_stop_option = 2  # the option code of the quick stop in progress (0x605A when CiA 402 began it)
        self.enabling_words = 0  # control words with "enable operation" received (tests: none without consent)
        self.last_writer = "pd"  # "pd" or "cia": whose ramps and homing speeds apply
        self.axis = Kinematics(self)
        self.pd = Stw1Machine(self)
        self.cia = Cia402Machine(self)
        self.tasks = TaskTable(self)
        self._bind()
        self.tasks.bind()

    # ================================================================== contract
    @property
    def standstill(self) -> bool:
        return self.axis.standstill

    @property
    def position_counts(self) -> int:
        return round((self.axis.pos + self.axis.offset) * self.counts_per_rev)

    @property
    def velocity_rpm(self) -> float:
        return self.axis.vel * 60.0

    def on_fault(self, code: str) -> None:
        """A fault was raised: react at once (fault reaction = quick stop, then power off)."""
        if code.lower().startswith("n"):
            return
        axis = self.axis
        axis.abort_tasks(error=True)
        self.pd.frozen_vel = None
        if self.state in (ENABLED, QUICK_STOP) and not axis.at_rest():
            self.state = FAULT_REACTION
            axis.ramp_to_zero(QUICK_STOP_RPM_S, "fault")
        else:
            self.state = FAULT
            if not axis.at_rest():
                axis.ramp_to_zero(COAST_RPM_S, "coast")
        self.stopping_to = None

    # ================================================================== shared by both word machines
    @property
    def counts_per_rev(self) -> int:
        return 1 << self.model.stored_pnu(1002)[0]

    @property
    def opmode(self) -> int:
        """PNU 930 (DRV.OPMODE) derived from the CiA 402 mode."""
        return {4: 0, 3: 1}.get(self.mode, 2)

    @property
    def fault_present(self) -> bool:
        return bool(self.model.faults.fault_present)

    @property
    def warning_present(self) -> bool:
        return bool(self.model.faults.warning_present) or self.watchdog_tripped

    def clear_watchdog(self) -> None:
        """A new command (control word, set point, acknowledge): the watchdog's stop and its warning end."""
        if self.watchdog_tripped:
            self.watchdog_tripped = False
            self.model.faults.clear_warning(WATCHDOG_WARNING)

    def feed(self, writer: str | None = None) -> None:
        """An access to the axis: feed the watchdog; a control word write also says whose ramps apply."""
        if self.since_access:
            self.since_access = 0.0
        if writer is not None:
            self.last_writer = writer

    def acknowledge(self) -> None:
        self.model.faults.acknowledge()
        self.clear_watchdog()
        if self.state in (FAULT, FAULT_REACTION) and not self.fault_present and self.axis.at_rest():
            self.state = SOD
            self.axis.activity = "idle"

    def apply_control_word(self, old: int, new: int, general: Callable[[int], None],
                           mode_bits: Callable[[int, int], None]) -> None:
        """The order both word machines share once a word is honoured (and acknowledge handled): no transition
        in fault; the general state transitions; then, in operation, the mode-specific bits."""
        if self.state in (FAULT, FAULT_REACTION):
            return
        general(new)
        if self.state == ENABLED and self.stopping_to is None:
            mode_bits(old, new)

    def coast_off(self) -> None:
        """OFF2 / disable voltage: pulses off, a moving motor coasts down, switch on disabled."""
        if self.state in (ENABLED, QUICK_STOP) and not self.axis.at_rest():
            self.axis.abort_tasks()
            self.axis.ramp_to_zero(COAST_RPM_S, "coast")
        self.state, self.stopping_to = SOD, None

    def enter_enabled(self) -> None:
        self.state = ENABLED
        self.stopping_to = None
        self.axis.internal_limit = False
        self.axis.homing_error = False if self.axis.homing is None else self.axis.homing_error

    def leave_enabled(self, to: str) -> None:
        """Disable operation / shut down from ENABLED: brake along the ramp, then enter ``to``."""
        self.axis.abort_tasks()
        self.stopping_to = to
        if self.axis.at_rest():
            self.state, self.stopping_to = to, None
        else:
            self.axis.stop_motion(quick=False, activity="stop")

    def stop_complete(self) -> None:
        """A stop ramp reached standstill (:class:`KinematicsHost`): the power stage takes its next state."""
        if self.state == FAULT_REACTION:
            self.state = FAULT
        elif self.state == QUICK_STOP:
            if self.quick_stop_option not in (5, 6, 7, 8):
                self.state = SOD  # options 5..8 stay in quick stop active
        elif self.stopping_to is not None and self.state == ENABLED:
            self.state = self.stopping_to
        self.stopping_to = None

    # ================================================================== drive parameters (KinematicsHost)
    def _obj(self, index: int, sub: int = 0) -> int:
        return self.model.object_value(index, sub)

    def soft_limits(self) -> tuple[float, float] | None:
        """Software position limits 0x607D (physical rev); None when both are 0 (disabled)."""
        lo, hi = self._obj(0x607D, 1), self._obj(0x607D, 2)
        if lo == 0 and hi == 0:
            return None
        return lo / CIA_COUNTS_PER_REV - self.axis.offset, hi / CIA_COUNTS_PER_REV - self.axis.offset

    def fe_window(self) -> float:
        window = self._obj(0x6065)
        return window / CIA_COUNTS_PER_REV if window else DEFAULT_FE_WINDOW_REV

    def ramp_dec_rpm_s(self) -> float:
        dec = self.model.signed_pnu(1007)[0] if self.last_writer == "pd" \
            else self._obj(0x6084) * 60.0 / CIA_COUNTS_PER_REV
        return float(dec) if dec > 0 else DEFAULT_RAMP_RPM_S

    def homing_profile(self) -> tuple[float, float, float]:
        if self.last_writer == "cia":
            fast, slow = self._obj(0x6099, 1) / CIA_COUNTS_PER_REV, self._obj(0x6099, 2) / CIA_COUNTS_PER_REV
            acc = self._obj(0x609A) / CIA_COUNTS_PER_REV
        else:
            fast = slow = acc = 0.0
        return fast or HOMING_FAST_RPM / 60.0, slow or HOMING_SLOW_RPM / 60.0, acc or rpm_s(DEFAULT_RAMP_RPM_S)

    def home_offset_rev(self) -> float:
        return self._obj(0x607C) / CIA_COUNTS_PER_REV

    # ================================================================== time
    def tick(self, dt: float) -> None:
        faults = self.model.faults
        if faults.fault_present and self.state not in (FAULT, FAULT_REACTION):
            codes = [c for c in faults.active() if not c.lower().startswith("n")]
            self.on_fault(codes[0] if codes else "F0")
        axis = self.axis
        if axis.at_rest():
            # The watchdog only guards motion; a resting axis keeps a constant state, so an idle
            # drive's state file need not be rewritten on every read (SimDrive saves on change).
            if self.since_access:
                self.since_access = 0.0
            if not (axis.vel or axis.acc_now):
                return  # nothing moves, nothing to integrate
        elif self.watchdog_s > 0 and axis.activity not in STOPPING:
            threshold = self.watchdog_s * float(self.model.time_scale or 1.0)
            remaining = threshold - self.since_access
            if dt > remaining:
                before = max(0.0, remaining)
                axis.integrate(before)
                self._watchdog_trip()
                self.since_access += before
                dt -= before
        if not axis.at_rest():
            self.since_access += dt
        axis.integrate(dt)

    def _watchdog_trip(self) -> None:
        """No request for ``watchdog_s`` wall seconds while moving: ramp to standstill on our own, and say why
        with the simulator's own warning (ZSW1/statusword bit 7, 0x2000, an EMCY; docs/fidelity.md F4)."""
        self.watchdog_tripped = True
        self.model.faults.raise_fault(WATCHDOG_WARNING)
        self.pd.frozen_vel = None
        self.axis.abort_tasks(error=True)
        self.axis.stop_motion(quick=False, activity="stop")

    # ================================================================== bindings
    def _bind(self) -> None:
        m, pd, cia, axis = self.model, self.pd, self.cia, self.axis

        def pnu_reader(func: Any) -> Any:
            def read(sub: int, count: int) -> list[int]:
                self.feed()
                return [func()]
            return read

        m.bind_pnu(1, read=pnu_reader(lambda: pd.stw1), write=pd.write_stw1)
        m.bind_pnu(2, read=pnu_reader(pd.zsw1))
        m.bind_pnu(5, write=pd.write_nsoll)
        m.bind_pnu(6, read=pnu_reader(lambda: units.rpm_to_x(max(-12000.0, min(12000.0, self.velocity_rpm)), 15)))
        m.bind_pnu(4, read=pnu_reader(lambda: 0))  # ZSW2: no clock synchronism, so no slave sign of life
        m.bind_pnu(28, read=pnu_reader(lambda: _clamp32(self.position_counts)))  # XIST_A, 2^PNU1002 per rev
        m.bind_pnu(33, read=pnu_reader(lambda: pd.aktsatz))
        m.bind_pnu(52, read=pnu_reader(lambda: round(self._current_fraction() * (1 << 14))))
        m.bind_pnu(930, read=pnu_reader(lambda: self.opmode), write=pd.write_opmode)

        def obj_reader(fmt: str, func: Any) -> Any:
            def read(sub: int) -> bytes:
                if sub != 0:
                    raise SdoAccessError(ABORT_NO_SUBINDEX)
                self.feed()
                return struct.pack(fmt, func())
            return read

        def counts(rev: float) -> int:
            return _clamp32(round(rev * CIA_COUNTS_PER_REV))

        m.bind_object(0x6040, read=obj_reader("<H", lambda: cia.controlword), write=cia.write_controlword)
        m.bind_object(0x6041, read=obj_reader("<H", cia.statusword))
        m.bind_object(0x6060, read=obj_reader("<b", lambda: self.mode), write=cia.write_mode)
        m.bind_object(0x6061, read=obj_reader("<b", lambda: self.mode))
        m.bind_object(0x6063, read=obj_reader("<i", lambda: counts(axis.pos + axis.offset)))
        m.bind_object(0x6064, read=obj_reader("<i", lambda: counts(axis.pos + axis.offset)))
        m.bind_object(0x606C, read=obj_reader("<i", lambda: counts(axis.vel)))
        m.bind_object(0x606B, read=obj_reader("<i", lambda: counts(axis.vel)))  # velocity demand (VL.CMD): the ramp
        m.bind_object(0x6077, read=obj_reader("<h", lambda: round(self._current_fraction() * 1000)))
        m.bind_object(0x60F4, read=obj_reader("<i", lambda: counts(axis.following_error)))
        m.bind_object(0x60FC, read=obj_reader("<i", lambda: counts(axis.demand + axis.offset)))
        m.bind_object(0x60FF, write=cia.write_target_velocity)
        m.bind_object(0x6071, write=cia.write_target_torque)          # torque mode (4)
        m.bind_object(0x60C1, write=cia.write_ip_setpoint)            # interpolated position (7)
        m.bind_object(0x607A, write=cia.write_target_position)        # profile position (1) and CSP (8)
        m.bind_object(0x605A, read=cia.read_quick_stop_code, write=cia.write_quick_stop_code)
        # 0x6502 lists the modes 0x6060 accepts (EtherCAT manual 5.8 table: 1, 3, 4, 6, 7, 8)
        m.bind_object(0x6502, read=obj_reader("<I", lambda: sw.drive_modes_word(MODES)))

    def _current_fraction(self) -> float:
        """A plausible current: acceleration torque plus a little friction, as a fraction of peak."""
        if self.state not in POWERED:
            return 0.0
        return self.axis.torque_fraction()

    # ================================================================== persistence
    def to_state(self) -> dict[str, Any]:
        """One flat dict (the keys of the state files written before the split, so old files load)."""
        data = FieldState.to_state(self)
        data.update(self.pd.to_state())
        data.update(self.cia.to_state())
        data.update(self.tasks.to_state())
        data.update(self.axis.to_state())
        data["last_writer"] = self.last_writer
        data["position_counts"] = self.position_counts  # for `sim show`; ignored on load
        data["velocity_rpm"] = round(self.velocity_rpm, 6)
        return data

    def load_state(self, state: dict[str, Any]) -> None:
        FieldState.load_state(self, state)
        self.pd.load_state(state)
        self.cia.load_state(state)
        self.tasks.load_state(state)
        self.axis.load_state(state)
        if state.get("last_writer") in ("pd", "cia"):
            self.last_writer = state["last_writer"]
        if self.state not in CIA_WORD:
            raise ValueError(f"motion state {self.state!r} is not a drive state")


def _clamp32(value: int) -> int:
    return max(-(1 << 31), min((1 << 31) - 1, value))
