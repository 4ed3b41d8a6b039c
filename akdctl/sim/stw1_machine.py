"""The PROFIdrive word machine of the simulated AKD: STW1 (PNU 1) in, ZSW1 (PNU 2) out.

Why a module of its own: STW1/ZSW1 follow the PROFIdrive general state machine
and the AKD's application classes (PROFINET manual 5.4/5.5, SPEC-NOTES 6-12):
velocity mode (bits 4/5/6 ramp generator, NSOLL_A), position mode (traversing
tasks from SATZANW or MDI, homing on bit 11) and jog (bits 8/9). None of that
is CiA 402; keeping it here lets ``cia402_machine`` stay a plain CiA 402 device
while both drive the one power stage (``power_states``) and the one axis
(``kinematics``) of the motion component.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.sim.component import PE_OPERATING_STATE, FieldState
from akdctl.sim.errors import PnuAccessError
from akdctl.sim.kinematics import DEFAULT_RAMP_RPM_S, EPS, QUICK_STOP_RPM_S, rpm_s
from akdctl.sim.power_states import (
    ENABLED,
    FAULT,
    FAULT_REACTION,
    QUICK_STOP,
    READY,
    SOD,
    SWITCHED_ON,
    ZSW1_STATE_BITS,
    profidrive_state,
)

if TYPE_CHECKING:
    from akdctl.sim.motion import MotionComponent

#: AKD HOME.MODE (PNU 1001) → the simulator's homing procedure; other modes end in a homing error.
HOME_MODE_PROCEDURES = {0: "current", 1: "limit-", 2: "limit-index", 3: "switch", 4: "switch-index", 5: "index"}


class Stw1Machine(FieldState):
    """STW1 writes, NSOLL_A and PNU 930 writes, and the ZSW1 they produce."""

    FIELDS = ("stw1", "plc_control_allowed", "aktsatz", "frozen_vel")

    def __init__(self, drive: "MotionComponent") -> None:
        super().__init__(drive)
        self.drive = drive
        self.stw1 = 0
        self.plc_control_allowed = True  # False simulates a drive that does not honour STW1 bit 10
        self.aktsatz = 0
        self.frozen_vel: float | None = None

    @property
    def honoured(self) -> bool:
        """SPEC-NOTES 7: the drive obeys STW1 only with bit 10 (control by PLC) set."""
        return bool(self.stw1 & sw.STW1_CONTROL_BY_PLC) and self.plc_control_allowed

    def _pnu(self, pnu: int) -> int:
        return self.drive.model.signed_pnu(pnu)[0]

    # ------------------------------------------------------------------ STW1
    def write_stw1(self, sub: int, values: list[int]) -> None:
        d = self.drive
        d.feed("pd")
        old, new = self.stw1, values[0] & 0xFFFF
        self.stw1 = new
        enabling = sw.STW1_ON | sw.STW1_ENABLE_OPERATION
        d.enabling_words += new & enabling == enabling  # tests: no enabling word reaches the drive without consent
        if not self.honoured:
            return  # SPEC-NOTES 7: without bit 10 the drive ignores the control word
        d.clear_watchdog()
        if new & sw.STW1_FAULT_ACK and not old & sw.STW1_FAULT_ACK:
            d.acknowledge()
            return  # SPEC-NOTES 7: after the acknowledge the drive is in S1; the next word moves on
        d.apply_control_word(old, new, self._general, self._mode_bits)

    def _general(self, word: int) -> None:
        d, axis = self.drive, self.drive.axis
        on = bool(word & sw.STW1_ON)
        no_coast = bool(word & sw.STW1_NO_COAST_STOP)
        no_quick = bool(word & sw.STW1_NO_QUICK_STOP)
        enable = bool(word & sw.STW1_ENABLE_OPERATION)
        state = d.state
        if not no_coast:  # OFF2: pulses off, the motor coasts, S1
            d.coast_off()
            return
        if not no_quick:  # OFF3: quick stop (S5), then S1
            if state in (ENABLED, QUICK_STOP) and not axis.at_rest():
                axis.abort_tasks()
                d.state = QUICK_STOP
                d.quick_stop_option = 2
                axis.ramp_to_zero(QUICK_STOP_RPM_S, "quickstop")
            elif state != QUICK_STOP:
                d.state, d.stopping_to = SOD, None
            return
        if state == QUICK_STOP:
            return  # S5 runs to standstill, then S1
        if state == SOD:
            if not on:
                d.state = READY
            return
        if state == READY:
            if on:
                d.state = SWITCHED_ON
                if enable:
                    d.enter_enabled()
            return
        if state == SWITCHED_ON:
            if not on:
                d.state = READY
            elif enable:
                d.enter_enabled()
            return
        if state == ENABLED:
            if not on or not enable:
                self.frozen_vel = None
                d.leave_enabled(READY if not on else SWITCHED_ON)
            elif d.stopping_to is not None:
                # ON and enable again while the OFF1 ramp runs: stay in operation
                d.stopping_to = None

    def _mode_bits(self, old: int, new: int) -> None:
        axis = self.drive.axis
        jog = new & (sw.STW1_JOG1 | sw.STW1_JOG2)
        old_jog = old & (sw.STW1_JOG1 | sw.STW1_JOG2)
        b456 = new & (sw.STW1_BIT4 | sw.STW1_BIT5 | sw.STW1_BIT6)
        if jog or axis.activity == "jog":
            if jog and (axis.activity == "jog" or (jog != old_jog and axis.at_rest() and not b456)):
                if jog == sw.STW1_JOG1:
                    rpm = units.x_to_rpm(self._pnu(1004), 15)
                elif jog == sw.STW1_JOG2:
                    rpm = units.x_to_rpm(self._pnu(1005), 15)
                else:
                    rpm = 0.0
                acc, dec = self._pnu(1006) or DEFAULT_RAMP_RPM_S, self._pnu(1007) or DEFAULT_RAMP_RPM_S
                axis.run_velocity(rpm / 60.0, rpm_s(acc), rpm_s(dec), "jog")
                axis.last_target = None  # jogging replaces any traversing target
                return
            if not jog and axis.activity == "jog":
                axis.stop_motion(quick=False, activity="stop")
                return
            if jog:
                return  # prerequisites not met (not at standstill, or bits 4/5/6 set): ignored
        if self.drive.opmode == 1:
            self.velocity(new)
        elif self.drive.opmode == 2:
            self._position(old, new)

    def velocity(self, word: int) -> None:
        """Velocity mode (application class 1): bits 4 ramp generator, 5 unfreeze, 6 set point."""
        axis = self.drive.axis
        acc, dec = self._pnu(1006) or DEFAULT_RAMP_RPM_S, self._pnu(1007) or DEFAULT_RAMP_RPM_S
        if not word & sw.STW1_BIT4 or not word & sw.STW1_BIT6:
            self.frozen_vel = None
            target = 0.0
        elif not word & sw.STW1_BIT5:
            if self.frozen_vel is None:
                self.frozen_vel = axis.vel
            target = self.frozen_vel
        else:
            self.frozen_vel = None
            target = units.x_to_rpm(self._pnu(5), 15) / 60.0
        if abs(target) < EPS and axis.at_rest():
            axis.idle()
            return
        axis.run_velocity(target, rpm_s(acc), rpm_s(dec), "velocity" if abs(target) > EPS else "stop")

    def _position(self, old: int, new: int) -> None:
        """Position mode (application class 3): homing (bit 11), traversing tasks (bits 4/5/6)."""
        axis = self.drive.axis
        start_home = new & sw.STW1_START_HOMING
        if start_home and not old & sw.STW1_START_HOMING:
            if axis.at_rest() and axis.task is None:
                axis.start_homing(HOME_MODE_PROCEDURES.get(self._pnu(1001)))
            return
        if not start_home and axis.homing is not None:
            axis.abort_homing()
            return
        if axis.homing is not None:
            return
        if not new & sw.STW1_BIT6:
            axis.task_ack = False
        if not new & sw.STW1_BIT4:  # reject traversing task: brake with ramp
            axis.reject_task()
            return
        if not new & sw.STW1_BIT5:  # intermediate stop: brake, keep the task
            axis.pause_task()
            return
        axis.resume_task()
        if new & sw.STW1_BIT6 and not old & sw.STW1_BIT6:
            task = self._load_task()
            if task is not None:
                axis.task_ack = True
                axis.run_task(task)

    def _load_task(self) -> dict[str, Any] | None:
        """Load SATZANW's task (program mode) or the MDI signals (bit 15); None if it cannot run: not homed, or
        the selected telegram does not carry the submode's signals (telegram 7 / 9, or 0 mapping them; manual
        5.10.1/5.10.2 "Standard telegram 7 (9) needs to be configured", docs/fidelity.md F9). ZSW1 bit 12 then
        stays clear, as 5.10.2 says for a task that cannot be executed."""
        axis, model = self.drive.axis, self.drive.model
        if not axis.homed or axis.activity == "jog":
            return None  # manual 5.10.1/5.10.2: the axis must be homed
        from akdctl.catalog import telegrams as tc  # here: only a traversing task reads the telegram table

        satzanw = self._pnu(32)
        setpoint, _ = model.pdo.telegram_signals()
        if tc.missing_for_submode("mdi" if satzanw & 0x8000 else "program", setpoint):
            return None  # docs/fidelity.md F9: the selected telegram must carry the submode's signals
        if satzanw & 0x8000:
            self.aktsatz = 0x8000
            rpm = units.x_to_rpm(model.stored_pnu(35)[0], 32)
            acc = units.acc_to_rpm_s(model.stored_pnu(36)[0])
            dec = units.acc_to_rpm_s(model.stored_pnu(37)[0])
            position = self._pnu(34) / self.drive.counts_per_rev
            absolute = bool(model.stored_pnu(38)[0] & 1)
        else:
            entry = self.drive.tasks.get(satzanw & 0x7FFF)  # the task table (sim/task_table.py)
            if entry is None:
                return None
            self.aktsatz = satzanw & 0x7FFF
            rpm, acc, dec = entry["rpm"], entry["acc"], entry["dec"]
            position, absolute = entry["position"], entry["absolute"]
        return axis.make_task(position, absolute, rpm / 60.0, rpm_s(acc), rpm_s(dec))

    # ------------------------------------------------------------------ set point and mode PNUs
    def write_nsoll(self, sub: int, values: list[int]) -> None:
        d = self.drive
        d.feed()
        d.model.set_stored_pnu(5, values)
        if d.state == ENABLED and d.stopping_to is None and d.opmode == 1 and d.axis.activity != "jog" \
                and self.honoured:
            d.clear_watchdog()
            self.velocity(self.stw1)

    def write_opmode(self, sub: int, values: list[int]) -> None:
        d = self.drive
        d.feed()
        if not d.set_opmode(values[0]):
            raise PnuAccessError(PE_OPERATING_STATE, None, "operating mode changes only at standstill")

    # ------------------------------------------------------------------ ZSW1
    def zsw1(self) -> int:
        d, axis = self.drive, self.drive.axis
        state = d.state
        if state in (FAULT_REACTION, FAULT):
            word = sw.ZSW1_FAULT
        else:  # S5 (OFF1 ramp, OFF3 quick stop) shows bits 0 and 1 without bit 2 (docs/fidelity.md F2)
            word = ZSW1_STATE_BITS[profidrive_state(state, d.stopping_to)]
        if d.fault_present:
            word |= sw.ZSW1_FAULT
        honoured = self.honoured
        if state != SOD or self.stw1 & sw.STW1_NO_COAST_STOP or not honoured:
            word |= sw.ZSW1_NO_COAST_STOP
        if state not in (QUICK_STOP, FAULT_REACTION) and not (state == SOD and honoured
                                                               and not self.stw1 & sw.STW1_NO_QUICK_STOP):
            word |= sw.ZSW1_NO_QUICK_STOP
        if d.warning_present:
            word |= sw.ZSW1_WARNING
        if honoured:
            word |= sw.ZSW1_CONTROL_REQUESTED
        if abs(axis.following_error) <= d.fe_window():
            word |= sw.ZSW1_BIT8
        if d.opmode == 2:
            busy = axis.homing is not None or axis.task is not None or not axis.at_rest()
            if not busy and state == ENABLED and axis.at_target:
                word |= sw.ZSW1_BIT10  # target position reached: only at the target (not after an abort)
            if axis.homed and axis.homing is None:
                word |= sw.ZSW1_HOME_POSITION_SET
            if axis.task_ack:
                word |= sw.ZSW1_TASK_ACK
            if not busy:
                word |= sw.ZSW1_DRIVE_STOPPED
        else:
            goal = axis.gen["v"] if axis.gen is not None and axis.gen["kind"] == "velocity" else 0.0
            if state == ENABLED and abs(axis.vel - goal) < 1e-6:
                word |= sw.ZSW1_BIT10  # set point reached
        return word
