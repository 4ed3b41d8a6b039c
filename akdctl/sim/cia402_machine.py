"""The CiA 402 word machine of the simulated AKD: controlword 0x6040 in, statusword 0x6041 out.

Why a module of its own: the CiA 402 device state machine, its quick stop
option code and its modes of operation (profile position 1, profile velocity 3,
torque 4, homing 6, interpolated position 7, cyclic synchronous position 8;
EtherCAT manual 5.4/5.8, SPEC-NOTES 20-23) are a different standard from
PROFIdrive's STW1/ZSW1 (``stw1_machine``), though both drive the one power
stage (``power_states``) and the one axis (``kinematics``) of the motion
component. SPEC-NOTES 23: while the controlword is mapped in an assigned RxPDO
in OP, an SDO write of it has no effect.

Modes 4, 7 and 8 take set points a master normally streams cyclically; the
simulator acts on every write of them, acyclic ones included, so their effect
shows in ``status`` (docs/fidelity.md F8): torque mode accelerates the load with
0x6071 (0.1 % of peak torque) up to a velocity limit; interpolated position
(controlword bit 4 "enable ip mode") and cyclic synchronous position reach each
new set point (0x60C1:1, 0x607A) within one interpolation period (0x60C2).
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING

from akdctl.profiles import statusword as sw
from akdctl.profiles.units import CIA_COUNTS_PER_REV
from akdctl.sim.component import ABORT_DEVICE_STATE, ABORT_NO_SUBINDEX, ABORT_VALUE_RANGE, FieldState
from akdctl.sim.errors import SdoAccessError
from akdctl.sim.kinematics import DEFAULT_RAMP_RPM_S, EPS, QUICK_STOP_RPM_S, rpm_s
from akdctl.sim.power_states import (
    CIA_WORD,
    ENABLED,
    FAULT,
    FAULT_REACTION,
    QUICK_STOP,
    READY,
    SOD,
    SWITCHED_ON,
)

if TYPE_CHECKING:
    from akdctl.sim.motion import MotionComponent

#: CiA 402 homing methods (0x6098) → the simulator's homing procedure.
CIA_HOMING_PROCEDURES = {
    **{m: "limit-index" for m in (1, 2)},
    **{m: "switch-index" for m in range(3, 15)},
    17: "limit-", 18: "limit+",
    **{m: "switch" for m in range(19, 31)},
    33: "index-", 34: "index", 35: "current", 37: "current",
}

#: Modes of operation (0x6060) the simulator accepts.
MODES = (1, 3, 4, 6, 7, 8)
#: Quick stop option codes (0x605A) the simulator accepts.
QUICK_STOP_CODES = (0, 1, 2, 5, 6)


class Cia402Machine(FieldState):
    """Controlword, mode and target velocity writes, and the statusword they produce."""

    FIELDS = ("controlword", "quick_stop_code")

    def __init__(self, drive: "MotionComponent") -> None:
        super().__init__(drive)
        self.drive = drive
        self.controlword = 0
        self.quick_stop_code = 2

    def _obj_rev(self, index: int, sub: int = 0) -> float:
        """An object in counts (/s, /s²) as rev (/s, /s²)."""
        return self.drive.model.object_value(index, sub) / CIA_COUNTS_PER_REV

    def _ramps(self) -> tuple[float, float]:
        default = rpm_s(DEFAULT_RAMP_RPM_S)
        return self._obj_rev(0x6083) or default, self._obj_rev(0x6084) or default

    # ------------------------------------------------------------------ controlword
    def write_controlword(self, sub: int, data: bytes) -> None:
        d = self.drive
        d.feed()
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        if d.model.pdo.controlword_in_active_rxpdo():
            return  # SPEC-NOTES 23: the cyclic controlword wins; an SDO write has no effect
        d.last_writer = "cia"
        old, new = self.controlword, struct.unpack("<H", data)[0]
        self.controlword = new
        d.enabling_words += new & sw.CW_ENABLE_OPERATION_CMD == sw.CW_ENABLE_OPERATION_CMD  # tests: none without consent
        d.clear_watchdog()
        if new & sw.CW_FAULT_RESET and not old & sw.CW_FAULT_RESET:
            d.acknowledge()
        d.apply_control_word(old, new, self._general, self._mode_bits)

    def _general(self, word: int) -> None:
        d, axis = self.drive, self.drive.axis
        state = d.state
        if not word & sw.CW_ENABLE_VOLTAGE:  # disable voltage
            d.coast_off()
            return
        if not word & sw.CW_QUICK_STOP:  # quick stop
            if state == ENABLED:
                axis.abort_tasks()
                d.state = QUICK_STOP
                d.quick_stop_option = self.quick_stop_code
                if axis.at_rest():
                    d.stop_complete()
                else:
                    axis.ramp_to_zero(QUICK_STOP_RPM_S, "quickstop")
            elif state in (READY, SWITCHED_ON):
                d.state = SOD
            return
        switch_on, enable = bool(word & sw.CW_SWITCH_ON), bool(word & sw.CW_ENABLE_OPERATION)
        if state == QUICK_STOP:
            if axis.at_rest() and switch_on and enable:
                d.enter_enabled()  # transition 16
            return
        if not switch_on:  # shutdown
            if state == ENABLED:
                d.leave_enabled(READY)
            elif state in (SOD, SWITCHED_ON):
                d.state = READY
            return
        if state == SOD:
            return  # switch on needs ready to switch on first
        if not enable:  # switch on / disable operation
            if state == READY:
                d.state = SWITCHED_ON
            elif state == ENABLED:
                d.leave_enabled(SWITCHED_ON)
            return
        if state in (READY, SWITCHED_ON):
            d.enter_enabled()
        elif state == ENABLED and d.stopping_to is not None:
            d.stopping_to = None

    def _mode_bits(self, old: int, new: int) -> None:
        d, axis = self.drive, self.drive.axis
        halt = bool(new & sw.CW_HALT)
        rising4 = bool(new & sw.CW_NEW_SETPOINT and not old & sw.CW_NEW_SETPOINT)
        if d.mode == 6:
            if rising4 and not halt:
                if axis.at_rest():
                    axis.start_homing(CIA_HOMING_PROCEDURES.get(d.model.object_value(0x6098, 0)))
            elif (not new & sw.CW_NEW_SETPOINT or halt) and axis.homing is not None:
                axis.abort_homing()
            return
        if d.mode == 3:
            self.velocity(halt)
            return
        if d.mode == 4:
            self.torque(halt)
            return
        if d.mode in (7, 8):
            if halt or (d.mode == 7 and not new & sw.CW_NEW_SETPOINT):
                if axis.activity == "follow":
                    axis.stop_motion(quick=False, activity="stop")  # halt / ip mode disabled: hold the position
            return
        if d.mode == 1:
            if not new & sw.CW_NEW_SETPOINT:
                axis.task_ack = False
            if halt:
                axis.pause_task()
                return
            axis.resume_task()
            if rising4:
                relative = bool(new & sw.CW_RELATIVE)
                acc, dec = self._ramps()
                task = axis.make_task(self._obj_rev(0x607A), not relative, self._obj_rev(0x6081), acc, dec)
                if task is not None:
                    axis.task_ack = True
                    axis.run_task(task)

    def velocity(self, halt: bool | None = None) -> None:
        """Profile velocity: run at 0x60FF (0 while halt is set)."""
        axis = self.drive.axis
        if halt is None:
            halt = bool(self.controlword & sw.CW_HALT)
        target = 0.0 if halt else self._obj_rev(0x60FF)
        acc, dec = self._ramps()
        if abs(target) < EPS and axis.at_rest():
            axis.idle()
            return
        axis.run_velocity(target, acc, dec, "velocity" if abs(target) > EPS else "stop")

    def torque(self, halt: bool | None = None) -> None:
        """Torque mode: run with 0x6071 (0.1 % of peak; 0x6072 caps it when set; 0 while halt is set)."""
        if halt is None:
            halt = bool(self.controlword & sw.CW_HALT)
        model = self.drive.model
        permille = 0 if halt else model.object_value(0x6071, 0)
        cap = model.object_value(0x6072, 0)
        if cap:
            permille = max(-cap, min(cap, permille))
        self.drive.axis.run_torque(permille / 1000.0)

    def _period_s(self) -> float:
        """The interpolation period 0x60C2 (sub 1 × 10^sub 2 s)."""
        from akdctl.profiles.units import cycle_time_s

        model = self.drive.model
        return float(cycle_time_s(model.object_value(0x60C2, 1), model.object_value(0x60C2, 2)))

    def _follows(self, mode: int) -> bool:
        d = self.drive
        if d.state != ENABLED or d.stopping_to is not None or d.mode != mode or self.controlword & sw.CW_HALT:
            return False
        return mode != 7 or bool(self.controlword & sw.CW_NEW_SETPOINT)  # ip: controlword bit 4 enables ip mode

    # ------------------------------------------------------------------ set point and mode objects
    def write_target_torque(self, sub: int, data: bytes) -> None:
        d = self.drive
        d.feed()
        d.model.set_stored_object(0x6071, sub, data)
        if d.state == ENABLED and d.stopping_to is None and d.mode == 4:
            d.clear_watchdog()
            self.torque()

    def write_ip_setpoint(self, sub: int, data: bytes) -> None:
        d = self.drive
        d.feed()
        d.model.set_stored_object(0x60C1, sub, data)
        if sub == 1 and self._follows(7):
            d.clear_watchdog()
            d.axis.follow(struct.unpack("<i", data)[0] / CIA_COUNTS_PER_REV, self._period_s())

    def write_target_position(self, sub: int, data: bytes) -> None:
        d = self.drive
        d.feed()
        d.model.set_stored_object(0x607A, sub, data)  # profile position reads it on the bit 4 edge
        if self._follows(8):
            d.clear_watchdog()
            d.axis.follow(struct.unpack("<i", data)[0] / CIA_COUNTS_PER_REV, self._period_s())

    def write_target_velocity(self, sub: int, data: bytes) -> None:
        d = self.drive
        d.feed()
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        d.model.set_stored_object(0x60FF, 0, data)
        if d.state == ENABLED and d.stopping_to is None and d.mode == 3:
            d.clear_watchdog()
            self.velocity()

    def write_mode(self, sub: int, data: bytes) -> None:
        d = self.drive
        d.feed()
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        mode = struct.unpack("<b", data)[0]
        if mode not in MODES:
            raise SdoAccessError(ABORT_VALUE_RANGE)
        if mode != d.mode and (not d.axis.at_rest() or d.axis.homing is not None):
            raise SdoAccessError(ABORT_DEVICE_STATE)
        if mode != d.mode:
            d.axis.forget_task()
        d.mode = mode
        d.model.set_stored_pnu(930, [d.opmode])

    def write_opmode_object(self, sub: int, data: bytes) -> None:
        """DRV.OPMODE by its CoE object 35B4h (UDINT): PNU 930's rule (:meth:`MotionComponent.set_opmode`), refused with the
        abort codes a refused 0x6060 write gets."""
        d = self.drive
        d.feed()
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        value = struct.unpack("<I", data)[0]
        if value > 2:
            raise SdoAccessError(ABORT_VALUE_RANGE)
        if not d.set_opmode(value):
            raise SdoAccessError(ABORT_DEVICE_STATE)

    def read_quick_stop_code(self, sub: int) -> bytes:
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        return struct.pack("<h", self.quick_stop_code)

    def write_quick_stop_code(self, sub: int, data: bytes) -> None:
        value = struct.unpack("<h", data)[0]
        if value not in QUICK_STOP_CODES:
            raise SdoAccessError(ABORT_VALUE_RANGE)
        self.quick_stop_code = value

    # ------------------------------------------------------------------ statusword
    def statusword(self) -> int:
        d, axis = self.drive, self.drive.axis
        state = d.state
        word = CIA_WORD[state] | sw.SW_VOLTAGE_ENABLED | sw.SW_REMOTE
        if state in (READY, SWITCHED_ON, ENABLED):
            word |= sw.SW_QUICK_STOP
        if d.fault_present and state not in (FAULT, FAULT_REACTION):
            word = (word & ~0x4F) | 0x08
        if d.warning_present:
            word |= sw.SW_WARNING
        if axis.internal_limit:
            word |= sw.SW_INTERNAL_LIMIT
        if state == ENABLED:
            halt = bool(self.controlword & sw.CW_HALT)
            if d.mode == 1:
                # target reached: at the set point's target (not after an abort), or stopped by halt
                if axis.task is None and axis.at_rest() and axis.at_target or (halt and axis.at_rest()):
                    word |= sw.SW_TARGET_REACHED
                if axis.task_ack:
                    word |= sw.SW_BIT12
                if abs(axis.following_error) > d.fe_window():
                    word |= sw.SW_BIT13
            elif d.mode == 6:
                if axis.homing is None and axis.at_rest():
                    word |= sw.SW_TARGET_REACHED
                if axis.homed and axis.homing is None and axis.homing_done:
                    word |= sw.SW_BIT12
                if axis.homing_error:
                    word |= sw.SW_BIT13
            elif d.mode in (3, 4):
                goal = axis.gen["v"] if axis.gen is not None and axis.gen["kind"] == "velocity" else 0.0
                if abs(axis.vel - goal) < 1e-6:
                    word |= sw.SW_TARGET_REACHED  # pv: target velocity; tq: the torque's end state
            elif d.mode in (7, 8):
                if axis.activity != "follow" and axis.at_rest() and axis.at_target:
                    word |= sw.SW_TARGET_REACHED
                if d.mode == 8 or self.controlword & sw.CW_NEW_SETPOINT:
                    word |= sw.SW_BIT12  # ip: ip mode active; csp: the drive follows the target position
                if abs(axis.following_error) > d.fe_window():
                    word |= sw.SW_BIT13
        return word
