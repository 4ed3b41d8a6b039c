"""CiA 402 axis: controlword/statusword, profile position/velocity, homing, over the object channel.

See akdctl.drive.axis for the modes and scaling it assumes.
"""


from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akdctl.drive.axis.base import (
    Axis,
    AxisStatus,
    JogSpec,
    MotionScales,
    MoveSpec,
    Scale,
    _fault_entries,
    _warning_entries,
)
from akdctl.drive.values import read_object, write_object
from akdctl.errors import (
    AkdError,
    DriveError,
    DriveFault,
    SafetyRefusal,
    UsageError,
)
from akdctl.profiles import statusword as sw
from akdctl.profiles.units import CIA_COUNTS_PER_REV

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel


class Cia402Axis(Axis):
    profile = "cia402"

    def __init__(self, objects: "ObjectChannel", al_state: "Callable[[], str | None] | None" = None,
                 timeout: float = 2.0, target: str = "") -> None:
        """``al_state`` is the Connection's declared AL state (:meth:`akdctl.connection.Connection.al_state`,
        None where the target has none): whether process data owns the controlword (SPEC-NOTES 23)."""
        super().__init__(timeout, target)
        self.objects = objects
        self.al_state_source = al_state
        self._mapping: list[int] | None = None  # RxPDOs holding 0x6040, read once (_refuse_pdo_override)

    def _up(self, index: int, sub: int) -> int:
        return read_object(self.objects, index, sub)  # type: ignore[no-any-return]

    def _down(self, index: int, sub: int, value: int) -> None:
        self._forget()
        write_object(self.objects, index, sub, value)

    def controlword(self, word: int) -> None:
        self._down(0x6040, 0, word)

    def read_motion_status(self) -> AxisStatus:
        """A poll's status: five objects, not six (no torque 0x6077: nothing a poll decides needs it)."""
        status = self._read_status(torque=False)
        self._last = (time.monotonic(), status)
        return status

    def _read_status(self, torque: bool = True) -> AxisStatus:
        word = self._up(0x6041, 0)
        control = self._up(0x6040, 0)
        mode = self._up(0x6061, 0)
        position = self._up(0x6064, 0) / CIA_COUNTS_PER_REV
        velocity = self._up(0x606C, 0) * 60.0 / CIA_COUNTS_PER_REV
        current = self._up(0x6077, 0) / 10.0 if torque else None
        state = sw.cia402_state(word)
        fault = bool(word & sw.SW_FAULT)
        faults: list[dict[str, Any]] = []
        if fault:
            numbers = []
            try:
                for sub in range(1, 11):
                    number = self._up(0x2001, sub)
                    if not number:
                        break
                    numbers.append(number)
            except AkdError:
                pass
            faults = _fault_entries(numbers)
        warnings = _warning_entries(self.objects) if word & sw.SW_WARNING else []
        homed = None
        if mode == 6:
            homed = bool(word & sw.SW_BIT12)
        return AxisStatus(
            profile=self.profile, state=state, state_text=state, word=word, control=control, mode=mode,
            mode_text=sw.CIA402_MODES.get(mode, f"mode {mode}"),
            enabled=state in ("operation enabled", "quick stop active"), fault=fault,
            warning=bool(word & sw.SW_WARNING), faults=faults, warnings=warnings, homed=homed,
            target_reached=bool(word & sw.SW_TARGET_REACHED), standstill=velocity == 0.0,
            task_ack=bool(word & sw.SW_BIT12) and mode == 1, homing_error=bool(word & sw.SW_BIT13) and mode == 6,
            position_rev=position, counts_per_rev=CIA_COUNTS_PER_REV, velocity_rpm=velocity, current_pct=current,
            bits=sw.statusword_bits(word, mode),
        )

    # ---------------------------------------------------------------- SPEC-NOTES 23
    def controlword_mapping(self) -> list[int]:
        """The assigned RxPDOs (read back by SDO from 0x1C12) whose mapping holds 0x6040."""
        found = []
        count = self._up(0x1C12, 0)
        for sub in range(1, count + 1):
            pdo = self._up(0x1C12, sub)
            entries = self._up(pdo, 0)
            for esub in range(1, entries + 1):
                if self._up(pdo, esub) >> 16 == 0x6040:
                    found.append(pdo)
                    break
        return found

    def _al_state(self) -> str | None:
        if self.al_state_source is None:
            return None
        try:
            return self.al_state_source()
        except AkdError:
            return None

    def _refuse_pdo_override(self, observed: bool) -> None:
        # The mapping is read once per command (five SDOs; plan and enable both ask): only an SDO write or the
        # master changes it, and the AL state that decides is read each time.
        if self._mapping is None:
            try:
                self._mapping = self.controlword_mapping()
            except AkdError:
                self._mapping = []
        mapped = self._mapping
        if not mapped:
            return
        al = self._al_state()
        if al == "OP" or (observed and al is None):
            pdos = ", ".join(f"0x{p:04X}" for p in mapped)
            raise SafetyRefusal(
                f"refusing: the controlword 0x6040 is mapped in the active RxPDO {pdos} and the drive is in "
                f"{al or 'an AL state that makes process data win'}; controlword writes by SDO have no effect "
                "(SPEC-NOTES 23): let the EtherCAT master enable the axis, or drop to SAFE-OP/PRE-OP")

    def _enable_steps(self, status: AxisStatus) -> None:
        self._refuse_pdo_override(observed=False)
        before = status.word
        if status.state in ("switch on disabled", "not ready to switch on", "ready to switch on", "switched on"):
            if status.state != "switched on":
                self.controlword(sw.CW_SHUTDOWN)
                try:
                    self._wait_state(("ready to switch on", "switched on"), "ready to switch on")
                except DriveError:
                    if self.read_status().word == before:
                        self._refuse_pdo_override(observed=True)
                    raise
            self.controlword(sw.CW_SWITCH_ON_CMD)
            self._wait_state(("switched on", "operation enabled"), "switched on")
        # With halt (bit 8): "enable" commands no motion, even if a set point (0x60FF in profile velocity) was
        # loaded before; the motion commands clear halt when they start.
        self.controlword(sw.CW_ENABLE_OPERATION_CMD | sw.CW_HALT)

    def _wait_state(self, states: tuple[str, ...], what: str) -> None:
        """Wait for a state of the state machine reading the statusword alone (one SDO per poll, not the six of a
        full status: issue 22 item 6); a fault ends the wait as in :meth:`wait_for`."""
        deadline = time.monotonic() + self.timeout
        poll = self.poll(deadline)
        while True:
            word = poll.read(lambda: self._up(0x6041, 0))
            poll.observe(word)
            if sw.cia402_state(word) in states:
                return
            if word & sw.SW_FAULT:
                status = self.read_status()
                raise DriveFault(f"drive fault while waiting for {what}: {status.fault_summary()}",
                                 details={"faults": status.faults})
            if time.monotonic() > deadline:
                raise DriveError(f"the drive did not reach {what} within {self.timeout:g} s "
                                 f"(state {sw.cia402_state(word)}, word 0x{word:04X})")
            poll.pause()

    def _disable_command(self) -> None:
        self.controlword(sw.CW_SHUTDOWN)

    def _ramp_stop_command(self) -> None:
        status = self.read_status()
        if status.state == "operation enabled":
            self.controlword(sw.CW_ENABLE_OPERATION_CMD | sw.CW_HALT)  # halt: brake along the profile ramp
        elif status.state not in ("quick stop active",):
            self.controlword(sw.CW_SHUTDOWN)

    def _drop_held_motion(self, status: AxisStatus) -> AxisStatus:
        """Halt only pauses a profile-position task (CiA 402: clearing halt resumes it), so an interrupted move
        would continue on the next controlword without halt, and the PROFIdrive view of the same drive shows no
        "drive stopped" (ZSW1 bit 13) while the task is held. Replace it by a set point at the standstill
        position (change immediately, absolute), which ends at once; then the axis holds where it stopped."""
        if status.state != "operation enabled" or status.mode != 1 or not status.control & sw.CW_HALT:
            return status
        here = self._up(0x6064, 0)
        self._down(0x607A, 0, here)
        base = sw.CW_ENABLE_OPERATION_CMD | sw.CW_CHANGE_IMMEDIATELY
        self.controlword(base | sw.CW_NEW_SETPOINT)
        try:
            self.wait_for(lambda s: s.task_ack, "set-point acknowledge (statusword bit 12)")
        except DriveError:
            self.controlword(base | sw.CW_HALT)  # not taken: keep holding with halt
            return self.read_status()
        # Handshake without bit 5 as well (it counts only on the rising edge of bit 4, CiA 402 pp): 0x000F is a word
        # no absolute move leaves (start_move keeps 0x002F), so a move polled from another process that missed the
        # halt still sees its control word changed ("ended by something else"), not a "target reached" elsewhere.
        self.controlword(sw.CW_ENABLE_OPERATION_CMD)
        return self.wait_for(lambda s: s.standstill, "standstill at the stop position", allow_fault=True)

    def _quick_stop_command(self) -> None:
        self.controlword(sw.CW_QUICK_STOP_CMD | sw.CW_SWITCH_ON | sw.CW_ENABLE_OPERATION)  # 0x000B

    def _ack_command(self) -> None:
        self.controlword(0x0000)
        self.controlword(sw.CW_FAULT_RESET)  # rising edge of bit 7
        self.controlword(0x0000)

    @classmethod
    def mode_name(cls, kind: str) -> str:
        return {"velocity": "profile velocity (0x6060 = 3)", "position": "profile position (0x6060 = 1)",
                "homing": "homing (0x6060 = 6)"}[kind]

    def ensure_mode(self, kind: str) -> None:
        wanted = {"velocity": 3, "position": 1, "homing": 6}[kind]
        if self.recent_status().mode != wanted:
            self._down(0x6060, 0, wanted)
            deadline = time.monotonic() + self.timeout
            poll = self.poll(deadline)
            while poll.read(lambda: self._up(0x6061, 0)) != wanted:
                if time.monotonic() > deadline:
                    raise DriveError(f"the drive did not switch to mode {wanted} (0x6061) within {self.timeout:g} s")
                poll.pause()

    # Object ranges (EtherCAT manual, CiA 402): 0x60FF i32, 0x6081/0x6083/0x6084 u32, 0x607A i32; the
    # simulator's scaling of 65536 counts/rev, counts/s, counts/s² (module docstring).
    _STEP_RPM = 60.0 / CIA_COUNTS_PER_REV
    RELATIVE_MOVES_NEED_HOME = False
    HOMED_SOURCE = "statusword bit 12 in homing mode"
    HOME_MODE_RANGE = (-128, 127)
    HOME_MODE_FIELD = "the homing method 0x6098"

    @classmethod
    def motion_scales(cls, kind: str) -> MotionScales:
        acc = Scale("profile acceleration 0x6083 (counts/s², 65536 counts/rev)", "rpm/s", cls._STEP_RPM, 1,
                    (1 << 32) - 1)
        dec = Scale("profile deceleration 0x6084 (counts/s², 65536 counts/rev)", "rpm/s", cls._STEP_RPM, 1,
                    (1 << 32) - 1)
        if kind == "velocity":
            return MotionScales(Scale("target velocity 0x60FF (counts/s, 65536 counts/rev)", "rpm", cls._STEP_RPM,
                                      1, (1 << 31) - 1), acc, dec)
        return MotionScales(Scale("profile velocity 0x6081 (counts/s, 65536 counts/rev)", "rpm", cls._STEP_RPM,
                                  1, (1 << 32) - 1), acc, dec)

    def position_scale(self, status: AxisStatus) -> Scale:
        return Scale("target position 0x607A (65536 counts/rev)", "counts", 1.0, -(1 << 31), (1 << 31) - 1)

    def homed_reading(self, status: AxisStatus) -> bool | None:
        # Bit 12 means "homing attained" only in homing mode and with the drive enabled.
        return status.homed if status.mode == 6 and status.enabled else None

    def confirm_homed(self) -> bool:
        self.ensure_mode("homing")
        status = self.read_status()
        if status.enabled:
            return bool(status.homed)
        status = self.enable()
        homed = bool(status.homed)
        if not homed:
            self.disable()  # it was disabled before the check: leave it so
        return homed

    def refuse_if_not_commandable(self, status: AxisStatus) -> None:
        self._refuse_pdo_override(observed=False)

    def start_jog(self, jog: JogSpec) -> None:
        self._down(0x6083, 0, jog.acc_raw)
        self._down(0x6084, 0, jog.dec_raw)
        self._down(0x60FF, 0, jog.velocity_raw)
        self.controlword(sw.CW_ENABLE_OPERATION_CMD)  # halt clear: follow 0x60FF

    def end_jog(self) -> None:
        self.controlword(sw.CW_ENABLE_OPERATION_CMD | sw.CW_HALT)
        self._down(0x60FF, 0, 0)

    def check_home(self, mode: int | None) -> None:
        if mode is None and self._up(0x6098, 0) == 0:
            # Method 0 means "no homing method": the drive would only report a homing error.
            raise UsageError("homing method 0x6098 is 0 (none configured); choose one with --mode, "
                             "e.g. 35 = current position, 19..30 = home switch, 1/2 = limit switch and index")

    def start_home(self, mode: int | None) -> None:
        if mode is not None:
            self._down(0x6098, 0, mode)
        self.controlword(sw.CW_ENABLE_OPERATION_CMD)
        self.controlword(sw.CW_ENABLE_OPERATION_CMD | sw.CW_NEW_SETPOINT)  # homing operation start

    def home_finished(self, status: AxisStatus) -> bool | None:
        if status.homing_error:
            self.controlword(sw.CW_ENABLE_OPERATION_CMD)
            return False
        if status.word & sw.SW_BIT12 and status.word & sw.SW_TARGET_REACHED:
            self.controlword(sw.CW_ENABLE_OPERATION_CMD)
            return True
        return None

    def start_move(self, move: MoveSpec) -> None:
        self._down(0x607A, 0, move.target_raw)
        self._down(0x6081, 0, move.velocity_raw)
        self._down(0x6083, 0, move.acc_raw)
        self._down(0x6084, 0, move.dec_raw)
        base = sw.CW_ENABLE_OPERATION_CMD | (sw.CW_RELATIVE if move.relative else 0) | sw.CW_CHANGE_IMMEDIATELY
        self.controlword(base)
        self.controlword(base | sw.CW_NEW_SETPOINT)
        try:
            self.wait_for(lambda s: s.task_ack, "set-point acknowledge (statusword bit 12)")
        except DriveError as exc:
            if isinstance(exc, DriveFault):
                raise
            self.controlword(base)
            raise DriveError("the drive did not acknowledge the new set-point (statusword bit 12 stayed clear): "
                             "target outside the software limits 0x607D, or the drive not in profile position") from None
        self.controlword(base)  # handshake: drop bit 4 once bit 12 is seen

    def issued_target(self) -> int | None:
        """The target position the drive holds (0x607A), to tell our set point from another's (motion_plan)."""
        return int(self._up(0x607A, 0))


