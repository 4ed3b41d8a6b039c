"""PROFIdrive axis: STW1/ZSW1 (PNU 1/2), jog with PNU 1004..1007, homing with STW1 bit 11, MDI positioning.

See akdctl.drive.axis for the SPEC-NOTES each part follows.
"""


from __future__ import annotations

from typing import Any

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
from akdctl.drive.values import read_object, read_pnu_map, write_pnu_map
from akdctl.errors import (
    AkdError,
    DriveError,
    DriveFault,
    ParameterRefused,
    SafetyRefusal,
)
from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.profiles.units import CIA_COUNTS_PER_REV


class ProfidriveAxis(Axis):
    profile = "profidrive"

    BASE = sw.STW1_CONTROL_BY_PLC | sw.STW1_NO_COAST_STOP | sw.STW1_NO_QUICK_STOP  # 0x0406

    def __init__(self, params: Any, objects: Any = None, timeout: float = 2.0, target: str = "") -> None:
        super().__init__(timeout, target)
        self.params = params
        self.objects = objects

    # ---------------------------------------------------------------- access
    def _read(self, *pnus: int) -> dict[int, list[int]]:
        return read_pnu_map(self.params, pnus)

    def _write(self, *pairs: tuple[int, int]) -> None:
        self._forget()
        write_pnu_map(self.params, pairs)

    def stw1(self, word: int) -> None:
        self._write((1, word))

    def _read_with_position(self, *pnus: int) -> dict[int, list[int]]:
        """``pnus`` (a refusal raises) plus XIST_A (PNU 28) in the same request, left out when refused: the
        manual's PNU table does not list it, so a drive may not offer it (docs/fidelity.md F7)."""
        from akdctl.drive.values import pnu_spec, read_pnus

        out: dict[int, list[int]] = {}
        for reading in read_pnus(self.params, [pnu_spec(p) for p in (*pnus, 28)]):
            if reading.ok:
                out[reading.spec.pnu] = list(reading.values or [])
            elif reading.spec.pnu != 28:
                raise ParameterRefused(f"drive refused to read PNU {reading.spec.label}: {reading.error_text}",
                                       code=reading.error)
        return out

    # ---------------------------------------------------------------- status
    def _read_status(self) -> AxisStatus:
        values = self._read_with_position(2, 1, 930, 6, 52, 1002)
        zsw1, stw1, opmode = values[2][0], values[1][0], values[930][0]
        nist, itist, bits = values[6][0], values[52][0], values[1002][0]
        state = sw.profidrive_state(zsw1, stw1)
        fault = bool(zsw1 & sw.ZSW1_FAULT)
        faults: list[dict[str, Any]] = []
        if fault:
            try:
                buffer = self._read(947)[947][:8]
                faults = _fault_entries([n for n in buffer if n])
            except AkdError:
                faults = []
        position = None
        warning = bool(zsw1 & sw.ZSW1_WARNING)
        warnings = _warning_entries(self.objects) if warning and self.objects is not None else []
        if 28 in values:  # XIST_A, 2^PNU1002 counts per revolution (docs/fidelity.md F7)
            position = units.counts_to_rev(values[28][0], bits)
        elif self.objects is not None:
            try:
                position = read_object(self.objects, 0x6064, 0) / CIA_COUNTS_PER_REV
            except AkdError:
                position = None
        velocity = units.x_to_rpm(nist, 15)
        if opmode == 2:
            standstill = bool(zsw1 & sw.ZSW1_DRIVE_STOPPED) and nist == 0
            homed: bool | None = bool(zsw1 & sw.ZSW1_HOME_POSITION_SET)
        else:
            standstill = nist == 0
            homed = bool(zsw1 & sw.ZSW1_HOME_POSITION_SET) if opmode == 2 else None
        return AxisStatus(
            profile=self.profile, state=state, state_text=sw.PD_STATES[state], word=zsw1, control=stw1,
            mode=opmode, mode_text=sw.PROFIDRIVE_MODES.get(opmode, f"mode {opmode}"),
            enabled=state in ("S4", "S5") and not fault, fault=fault, warning=warning,
            faults=faults, warnings=warnings, homed=homed, target_reached=bool(zsw1 & sw.ZSW1_BIT10), standstill=standstill,
            task_ack=bool(zsw1 & sw.ZSW1_TASK_ACK), control_honoured=bool(zsw1 & sw.ZSW1_CONTROL_REQUESTED),
            position_rev=position, counts_per_rev=1 << bits, velocity_rpm=velocity,
            current_pct=itist * 100.0 / (1 << 14), bits=sw.zsw1_bits(zsw1, opmode),
        )

    def _refuse_if_not_honoured(self) -> None:
        status = self.read_status()
        if not status.control_honoured:
            raise SafetyRefusal(
                "refusing: the drive does not honour STW1 bit 10 (control by PLC): ZSW1 bit 9 'control requested' "
                "stays clear, so it would ignore every control word (SPEC-NOTES 7); check the drive's command source"
            )

    # ---------------------------------------------------------------- state machine
    def _enable_steps(self, status: AxisStatus) -> None:
        # The S7 sample's sequence (SPEC-NOTES 6): OFF with bits 1/2/10 → S2, then ON+enable → S3 → S4.
        if status.state in ("S1", "S2", "S3"):
            self.stw1(self.BASE)  # 0x0406
            self._refuse_if_not_honoured()
            self.wait_for(lambda s: s.state in ("S2", "S3"), "S2 (ready for switching on)")
        self.stw1(self.BASE | sw.STW1_ON | sw.STW1_ENABLE_OPERATION)  # 0x040F

    def _disable_command(self) -> None:
        self.stw1(self.BASE)  # OFF1: ramp down, then S2

    def _ramp_stop_command(self) -> None:
        # Stay in S4; bit 4 = 0 rejects a traversing task / zeroes the ramp generator, bits 8/9/11 = 0
        # end jog and homing: every mode brakes along its ramp.
        status = self.read_status()
        if status.state in ("S4",):
            self.stw1(self.BASE | sw.STW1_ON | sw.STW1_ENABLE_OPERATION | sw.STW1_BIT5)
        elif status.state not in ("S5",):
            self.stw1(self.BASE)

    def _quick_stop_command(self) -> None:
        self.stw1(sw.STW1_CONTROL_BY_PLC | sw.STW1_NO_COAST_STOP | sw.STW1_ON | sw.STW1_ENABLE_OPERATION)  # OFF3

    def _ack_command(self) -> None:
        current = self._read(1)[1][0] & ~sw.STW1_FAULT_ACK & 0xFFFF
        base = (current | sw.STW1_CONTROL_BY_PLC) & ~(sw.STW1_ON | sw.STW1_ENABLE_OPERATION)
        self.stw1(base)
        self.stw1(base | sw.STW1_FAULT_ACK)  # rising edge of bit 7 (SPEC-NOTES 7)
        self.stw1(base)

    # ---------------------------------------------------------------- modes
    @classmethod
    def mode_name(cls, kind: str) -> str:
        return {"velocity": "velocity (PNU 930 = 1), jog via STW1 bit 8",
                "position": "position (PNU 930 = 2), MDI via SATZANW bit 15 (telegram 9)",
                "homing": "position (PNU 930 = 2), homing via STW1 bit 11",
                "task": "position (PNU 930 = 2), program mode via SATZANW (telegram 7)"}[kind]

    def _ensure_opmode(self, wanted: int) -> None:
        if self._read(930)[930][0] != wanted:
            self._write((930, wanted))

    def ensure_mode(self, kind: str) -> None:
        self._ensure_opmode(1 if kind == "velocity" else 2)
        if kind in ("position", "task"):  # MDI / program mode read their telegram's signals (docs/fidelity.md F9)
            from akdctl.drive.telegram import ensure_submode

            self._forget()  # the telegram may change below, by writes outside _write

            ensure_submode(self.params, "mdi" if kind == "position" else "program")

    def _operating_word(self) -> int:
        return self.BASE | sw.STW1_ON | sw.STW1_ENABLE_OPERATION  # 0x040F

    # SPEC-NOTES 13: jog velocity PNU 1004 is N2 (x = 15, 2^15 = 12000 rpm), MDI_VELOCITY X4 (x = 32),
    # MDI_ACC/MDI_DEC X2 (x = 16, 2^16 = 50,000,000 rpm/s: one step is ~763 rpm/s); jog ramps PNU 1006/1007 rpm/s.
    _JOG_VELOCITY = Scale("the jog velocity PNU 1004 (N2: 2^15 = 12000 rpm)", "rpm", units.MAX_RPM / (1 << 15),
                          1, 32767)
    _JOG_ACC = Scale("the jog ramp PNU 1006", "rpm/s", 1.0, 1, 65535)
    _JOG_DEC = Scale("the jog ramp PNU 1007", "rpm/s", 1.0, 1, 65535)
    _MDI_VELOCITY = Scale("MDI_VELOCITY (PNU 35, X4: 2^32 = 12000 rpm)", "rpm", units.MAX_RPM / (1 << 32), 1,
                          (1 << 32) - 1)
    _MDI_ACC = Scale("MDI_ACC (PNU 36, X2: 2^16 = 50,000,000 rpm/s)", "rpm/s", units.MAX_ACC_RPM_S / (1 << 16),
                     1, 65535)
    _MDI_DEC = Scale("MDI_DEC (PNU 37, X2: 2^16 = 50,000,000 rpm/s)", "rpm/s", units.MAX_ACC_RPM_S / (1 << 16),
                     1, 65535)
    RELATIVE_MOVES_NEED_HOME = True
    TASKS = True
    HOMED_SOURCE = "ZSW1 bit 11; PROFINET manual 5.10.2"
    HOME_MODE_RANGE = (0, 20)
    HOME_MODE_FIELD = "HOME.MODE (PNU 1001)"

    @classmethod
    def motion_scales(cls, kind: str) -> MotionScales:
        if kind == "velocity":
            return MotionScales(cls._JOG_VELOCITY, cls._JOG_ACC, cls._JOG_DEC)
        return MotionScales(cls._MDI_VELOCITY, cls._MDI_ACC, cls._MDI_DEC)

    def position_scale(self, status: AxisStatus) -> Scale:
        return Scale(f"MDI_TARPOS (PNU 34, {status.counts_per_rev} counts/rev)", "counts", 1.0, -(1 << 31),
                     (1 << 31) - 1)

    def homed_reading(self, status: AxisStatus) -> bool | None:
        return status.homed if status.mode == 2 else None  # ZSW1 bit 11 means "home position set" in mode 2

    def confirm_homed(self) -> bool:
        before = self._read(930)[930][0]
        self._ensure_opmode(2)  # ZSW1 bit 11 reads "home position set" in position mode only
        homed = bool(self.read_status().homed)
        if not homed and before != 2:
            self._write((930, before))  # leave the mode as it was: the refusal changes nothing
        return homed

    def refuse_if_not_commandable(self, status: AxisStatus) -> None:
        # ZSW1 bit 9 is only meaningful once STW1 bit 10 was written; before that, enable checks it.
        if status.control & sw.STW1_CONTROL_BY_PLC and not status.control_honoured:
            self._refuse_if_not_honoured()

    def start_jog(self, jog: JogSpec) -> None:
        self._write((1004, jog.velocity_raw), (1006, jog.acc_raw), (1007, jog.dec_raw))
        self.stw1(self._operating_word())  # bits 4/5/6 = 0: the jog prerequisite
        self.stw1(self._operating_word() | sw.STW1_JOG1)

    def end_jog(self) -> None:
        self.stw1(self._operating_word())

    def start_home(self, mode: int | None) -> None:
        if mode is not None:
            self._write((1001, mode))
        self.stw1(self._operating_word())
        self.stw1(self._operating_word() | sw.STW1_START_HOMING)

    def home_finished(self, status: AxisStatus) -> bool | None:
        # SPEC-NOTES 9: bits 10/11/13 clear while homing runs, all set when it finished.
        if status.word & sw.ZSW1_HOME_POSITION_SET and status.word & sw.ZSW1_DRIVE_STOPPED:
            self.stw1(self._operating_word())
            return True
        if status.word & sw.ZSW1_DRIVE_STOPPED and status.standstill:
            self.stw1(self._operating_word())
            return False
        return None

    def start_move(self, move: MoveSpec) -> None:
        self._write((32, 0x8000), (34, move.target_raw), (35, move.velocity_raw), (36, move.acc_raw),
                    (37, move.dec_raw), (38, 0 if move.relative else 1))
        self._activate_task("the MDI traversing task", "target outside the software limits, or the drive not in "
                                                       "position mode/S4, or not in telegram 9")

    def start_task(self, number: int) -> None:
        """Program mode (PROFINET manual 5.10.1): SATZANW = the stored task, then the bit 6 handshake."""
        self._write((32, number & 0x7FFF))
        self._activate_task(f"motion task {number}", "the task is not configured or its target is outside the "
                                                     "software limits, or the drive not in position mode/S4, or "
                                                     "not in telegram 7/9")

    def _activate_task(self, what: str, reasons: str) -> None:
        """STW1 bits 4/5, a rising edge of bit 6, wait for ZSW1 bit 12, drop bit 6 (5.10.1/5.10.2 handshake)."""
        ready = self._operating_word() | sw.STW1_BIT4 | sw.STW1_BIT5
        self.stw1(ready)
        self.stw1(ready | sw.STW1_BIT6)  # rising edge loads the task
        try:
            self.wait_for(lambda s: s.task_ack, "traversing task acknowledged (ZSW1 bit 12)")
        except DriveError as exc:
            if isinstance(exc, DriveFault):
                raise
            self.stw1(ready)
            raise DriveError(f"the drive did not accept {what} (ZSW1 bit 12 stayed clear): {reasons}") from None
        self.stw1(ready)  # handshake: drop bit 6 once bit 12 is seen; the task keeps running

    def issued_target(self) -> int | None:
        """The MDI target the drive holds (PNU 34), to tell our task from another's (motion_plan)."""
        return int(self._read(34)[34][0])


# ====================================================================== CiA 402
