"""The axis: one interface for enable/disable/stop/acknowledge/jog/home/move/status on both profiles.

Why one implementation: every command that moves or powers the axis (``enable``,
``move``, ``fault ack``, recipes) goes through :func:`open_axis`, so the safety
checks (fault present, control not honoured, controlword overridden by process
data, not homed) and the stop-on-error behaviour exist exactly once.

* :class:`ProfidriveAxis` speaks PNUs: STW1/ZSW1 (PNU 1/2) and the general state
  machine S1..S5 (SPEC-NOTES 6/7), jog with STW1 bits 8/9 and PNU 1004..1007
  (note 8), homing with STW1 bit 11 (note 9), MDI positioning with SATZANW bit 15,
  MDI_* PNU 34..38 and the ZSW1 bit 12 handshake (note 12), units per note 13.
* :class:`Cia402Axis` speaks objects: controlword/statusword (EtherCAT manual 5.4),
  profile position (1) with the bit 4 / bit 12 handshake, profile velocity (3) for
  jog, homing (6, 0x6098, statusword bits 10/12/13). Modes 7/8 need a cyclic set
  point stream and are refused acyclically. Scaling assumed: 65536 counts per
  revolution, counts/s, counts/s² (the simulator's; set a real drive alike).

Every wait polls with a deadline (how often: :mod:`akdctl.drive.polling`); nothing here sleeps unbounded.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akdctl.drive.polling import Poll
from akdctl.drive.values import read_object, read_pnu_map, write_object, write_pnu_map
from akdctl.errors import (
    AkdError,
    CommError,
    DriveError,
    DriveFault,
    Interrupted,
    ParameterRefused,
    SafetyRefusal,
    UsageError,
)
from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.profiles.units import CIA_COUNTS_PER_REV
from akdctl.protocol.record import Record


class AxisStatus(Record):
    """What the drive reports, decoded. ``word`` is ZSW1 or the statusword; ``warnings``: the active warnings (number,
    code, text) when the drive names them (0x2000), empty when it only sets the bit. Mutable, unhashable."""

    __slots__ = ("profile", "state", "state_text", "word", "control", "mode", "mode_text", "enabled", "fault", "warning",
                 "faults", "warnings", "homed", "target_reached", "standstill", "task_ack", "homing_error",
                 "control_honoured", "position_rev", "counts_per_rev", "velocity_rpm", "current_pct", "bits")
    __hash__ = None  # type: ignore[assignment]

    def __init__(self, profile: str, state: str, state_text: str, word: int, control: int, mode: int | None,
                 mode_text: str, enabled: bool, fault: bool, warning: bool,
                 faults: list[dict[str, Any]] | None = None, warnings: list[dict[str, Any]] | None = None,
                 homed: bool | None = None, target_reached: bool = False, standstill: bool = True,
                 task_ack: bool = False, homing_error: bool = False, control_honoured: bool | None = None,
                 position_rev: float | None = None, counts_per_rev: int = 65536, velocity_rpm: float | None = None,
                 current_pct: float | None = None, bits: list[sw.Bit] | None = None) -> None:
        self.profile = profile
        self.state = state
        self.state_text = state_text
        self.word = word
        self.control = control
        self.mode = mode
        self.mode_text = mode_text
        self.enabled = enabled
        self.fault = fault
        self.warning = warning
        self.faults = [] if faults is None else faults
        self.warnings = [] if warnings is None else warnings
        self.homed = homed
        self.target_reached = target_reached
        self.standstill = standstill
        self.task_ack = task_ack
        self.homing_error = homing_error
        self.control_honoured = control_honoured
        self.position_rev = position_rev
        self.counts_per_rev = counts_per_rev
        self.velocity_rpm = velocity_rpm
        self.current_pct = current_pct
        self.bits = [] if bits is None else bits

    @property
    def position_counts(self) -> int | None:
        return None if self.position_rev is None else round(self.position_rev * self.counts_per_rev)

    def fault_summary(self) -> str:
        if not self.faults:
            return "a fault is present (the drive did not report its number)"
        return "; ".join(f"{f['code']} {f['text']}".strip() for f in self.faults)

    def warning_summary(self) -> str:
        """'n503 ...; n179 ...', 'none', or the bit alone when the drive does not say which warning."""
        if self.warnings:
            return "; ".join(f"{w['code']} {w['text']}".strip() for w in self.warnings)
        return "a warning is present (the drive did not report its number)" if self.warning else "none"

    def to_json(self) -> dict[str, Any]:
        return {
            "profile": self.profile,
            "state": self.state,
            "state_text": self.state_text,
            "word": self.word,
            "word_hex": f"0x{self.word:04X}",
            "control": self.control,
            "mode": self.mode,
            "mode_text": self.mode_text,
            "enabled": self.enabled,
            "fault": self.fault,
            "warning": self.warning,
            "faults": self.faults,
            "warnings": self.warnings,
            "homed": self.homed,
            "target_reached": self.target_reached,
            "standstill": self.standstill,
            "control_honoured": self.control_honoured,
            "position_counts": self.position_counts,
            "position_rev": None if self.position_rev is None else round(self.position_rev, 6),
            "counts_per_rev": self.counts_per_rev,
            "velocity_rpm": None if self.velocity_rpm is None else round(self.velocity_rpm, 3),
            "current_pct": None if self.current_pct is None else round(self.current_pct, 2),
            "bits": [b.to_json() for b in self.bits],
        }


class Scale(Record):
    """How the drive represents one quantity: ``raw`` integers ``raw_min..raw_max``, each ``step`` ``unit``.

    The planner (:mod:`akdctl.drive.motion_plan`) quantises every request on these
    grids and compares the limits with the executed values; the Axis writes the raw
    integers it is handed and converts nothing itself.
    """

    __slots__ = ("name", "unit", "step", "raw_min", "raw_max")

    def __init__(self, name: str, unit: str, step: float, raw_min: int, raw_max: int) -> None:
        self.name = name
        self.unit = unit
        self.step = step
        self.raw_min = raw_min
        self.raw_max = raw_max


class MotionScales(Record):
    """The scales of the set points one motion kind writes (velocity, accelerations)."""

    __slots__ = ("velocity", "accel", "decel")

    def __init__(self, velocity: Scale, accel: Scale, decel: Scale) -> None:
        self.velocity = velocity
        self.accel = accel
        self.decel = decel


class MoveSpec(Record):
    """A planned point-to-point move in raw drive units (position counts, the profile's velocity/ramp raw values)."""

    __slots__ = ("target_raw", "relative", "velocity_raw", "acc_raw", "dec_raw")

    def __init__(self, target_raw: int, relative: bool, velocity_raw: int, acc_raw: int, dec_raw: int) -> None:
        self.target_raw = target_raw
        self.relative = relative
        self.velocity_raw = velocity_raw
        self.acc_raw = acc_raw
        self.dec_raw = dec_raw


class JogSpec(Record):
    """A planned timed jog in raw drive units (signed velocity raw, ramp raws)."""

    __slots__ = ("velocity_raw", "acc_raw", "dec_raw")

    def __init__(self, velocity_raw: int, acc_raw: int, dec_raw: int) -> None:
        self.velocity_raw = velocity_raw
        self.acc_raw = acc_raw
        self.dec_raw = dec_raw


def _fault_entries(numbers: list[int], *, warning: bool = False) -> list[dict[str, Any]]:
    from akdctl.catalog import faults as catalog

    out = []
    for number in numbers:
        fault = catalog.by_number(number, warning=warning)
        out.append({"number": number, "code": fault.code if fault else f"{'n' if warning else 'F'}{number}",
                    "text": fault.name if fault else f"unknown {'warning' if warning else 'fault'}"})
    return out


#: The AKD's current warnings (DRV.WARNING1..3, UDINT; reference/cia402_and_canopen_reference.md).
OBJ_WARNINGS, WARNING_SLOTS = 0x2000, 3


def _warning_entries(objects: Any) -> list[dict[str, Any]]:
    """The warnings the drive names in 0x2000 sub 1..3 (zeros are empty slots); [] when it cannot tell."""
    numbers = []
    try:
        for sub in range(1, WARNING_SLOTS + 1):
            number = read_object(objects, OBJ_WARNINGS, sub)
            if number:
                numbers.append(number)
    except CommError:
        raise
    except AkdError:
        return []
    return _fault_entries(numbers, warning=True)


class Axis(ABC):
    """One axis over one profile. ``timeout`` bounds each wait for a state change.

    The contract a profile implements (PROFIdrive and CiA 402 here; a new profile, e.g.
    EtherNet/IP, implements the same):

    * state: :meth:`read_status` (reads only), the state-machine primitives
      (``_enable_steps``, ``_disable_command``, ``_ramp_stop_command``, ``_quick_stop_command``,
      ``_ack_command``), :meth:`ensure_mode`;
    * what the drive can represent, for the planner: :meth:`motion_scales` (classmethod, no
      drive needed: velocity and ramp grids of a motion kind), :meth:`position_scale` and
      :meth:`counts_per_rev` (may depend on the drive's configuration, from a status),
      ``HOME_MODE_RANGE`` / ``HOME_MODE_FIELD``;
    * the facts behind the homed rule: ``RELATIVE_MOVES_NEED_HOME``, ``HOMED_SOURCE``,
      :meth:`homed_reading` (from a status, no write; None = not visible in this mode) and
      :meth:`confirm_homed` (after consent; may switch the mode, restores it when not homed);
      :meth:`check_home` (reads only: a homing the drive could not run);
    * :meth:`refuse_if_not_commandable`: a read-only check that this link's commands will be
      obeyed (PROFIdrive: STW1 bit 10; CiA 402: the controlword not owned by process data in OP);
    * motion: ``start_jog(JogSpec)``, ``end_jog``, ``start_home``, ``home_finished``,
      ``start_move(MoveSpec)`` write the raw values they are handed, nothing else;
      ``start_task(number)`` starts a stored motion task where ``TASKS`` (else ``NO_TASKS`` says why).
    """

    profile = "?"
    #: True when the drive positions (even relatively) only once homed (AKD MDI, PROFINET manual 5.10.2).
    RELATIVE_MOVES_NEED_HOME = False
    #: Where the homed state comes from, for refusals.
    HOMED_SOURCE = ""
    #: The homing modes/methods the drive accepts, and where they go.
    HOME_MODE_RANGE: tuple[int, int] = (-128, 127)
    HOME_MODE_FIELD = ""
    #: Whether ``start_task`` can start a stored motion task, and why not (``task start``, docs/fidelity.md F11).
    TASKS = False
    NO_TASKS = ("the drive's manual documents no way to start a stored motion task over this profile; "
                "use a PROFIdrive target (program mode) or 'akdctl move'")

    #: Seconds of the drive's time per wall second, asked when a wait starts (open_axis: the transport's
    #: ``time_scale``, which only the simulator has); None: a real drive's 1.
    time_scale_source: Callable[[], float] | None = None

    def __init__(self, timeout: float = 2.0, target: str = "") -> None:
        self.timeout = timeout
        self.target = target

    def poll(self, deadline: float | None = None) -> Poll:
        """The pauses of one wait (drive/polling.py: fast after a command or a change, then steady)."""
        return Poll(self.time_scale_source() if self.time_scale_source is not None else 1.0, deadline)

    # ---------------------------------------------------------------- primitives per profile
    @abstractmethod
    def read_status(self) -> AxisStatus: ...

    @abstractmethod
    def _enable_steps(self, status: AxisStatus) -> None: ...

    @abstractmethod
    def _disable_command(self) -> None: ...

    @abstractmethod
    def _ramp_stop_command(self) -> None: ...

    @abstractmethod
    def _quick_stop_command(self) -> None: ...

    @abstractmethod
    def _ack_command(self) -> None: ...

    @abstractmethod
    def start_jog(self, jog: JogSpec) -> None: ...

    @abstractmethod
    def end_jog(self) -> None: ...

    @abstractmethod
    def start_home(self, mode: int | None) -> None: ...

    @abstractmethod
    def home_finished(self, status: AxisStatus) -> bool | None:
        """True done, False failed, None still running."""

    @abstractmethod
    def start_move(self, move: MoveSpec) -> None: ...

    @abstractmethod
    def ensure_mode(self, kind: str) -> None:
        """Switch to the mode a motion needs ('velocity', 'position', 'homing') at standstill."""

    @classmethod
    @abstractmethod
    def mode_name(cls, kind: str) -> str:
        """The operating mode a motion kind uses, in words (for the consent prompt)."""

    @classmethod
    @abstractmethod
    def motion_scales(cls, kind: str) -> MotionScales:
        """The grids of velocity and ramps for motion ``kind`` ('velocity' = timed jog, 'position')."""

    def drive_motion_scales(self, kind: str) -> MotionScales:
        """The scales as this drive is configured (the planner's second look, after connecting).

        Default: :meth:`motion_scales`. A profile whose grid the drive configures reads it here.
        """
        return self.motion_scales(kind)

    @abstractmethod
    def position_scale(self, status: AxisStatus) -> Scale:
        """The grid of the position set point (counts; range of the target object/PNU)."""

    def counts_per_rev(self, status: AxisStatus) -> int:
        return status.counts_per_rev

    def homed_reading(self, status: AxisStatus) -> bool | None:
        """Homed as far as ``status`` shows it without any write; None when this mode does not show it."""
        return status.homed

    def confirm_homed(self) -> bool:
        """Homed? After consent only: may switch to the mode in which the drive shows it."""
        self.ensure_mode("position")
        return bool(self.read_status().homed)

    def check_home(self, mode: int | None) -> None:
        """Refuse (reads only) a homing the drive could not run, e.g. no method configured."""

    def refuse_if_not_commandable(self, status: AxisStatus) -> None:
        """SafetyRefusal when it is already visible that this link's commands would be ignored (reads only)."""

    # ---------------------------------------------------------------- shared behaviour
    def wait_for(self, predicate: Callable[[AxisStatus], bool], what: str, timeout: float | None = None,
                 allow_fault: bool = False) -> AxisStatus:
        """Poll the status until ``predicate`` holds; DriveFault on a fault, DriveError on timeout."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        poll = self.poll(deadline)
        while True:
            status = poll.read(self.read_status)
            poll.observe(status.word)
            if predicate(status):
                return status
            if status.fault and not allow_fault:
                raise DriveFault(f"drive fault while waiting for {what}: {status.fault_summary()}",
                                 details={"faults": status.faults})
            if time.monotonic() > deadline:
                raise DriveError(f"the drive did not reach {what} within {self.timeout if timeout is None else timeout:g} s "
                                 f"(state {status.state} {status.state_text}, word 0x{status.word:04X})")
            poll.pause()

    def refuse_if_fault(self, status: AxisStatus) -> None:
        if status.fault:
            raise SafetyRefusal(f"refusing: the drive reports a fault: {status.fault_summary()}; "
                                "acknowledge it with 'akdctl fault ack' once the cause is removed",
                                details={"faults": status.faults})

    def enable(self) -> AxisStatus:
        status = self.read_status()
        self.refuse_if_fault(status)
        if status.enabled:
            return status
        self._enable_steps(status)
        return self.wait_for(lambda s: s.enabled, "operation enabled")

    def disable(self) -> AxisStatus:
        status = self.read_status()
        if status.enabled and not status.standstill:
            self.stop()
        self._disable_command()
        return self.wait_for(lambda s: not s.enabled, "power stage disabled", timeout=self.timeout + 5.0,
                             allow_fault=True)

    def stop(self, quick: bool = False, timeout: float | None = None) -> AxisStatus:
        """Ramp to standstill (quick stop with ``quick`` or when the ramp is not acknowledged)."""
        wait = max(self.timeout, 5.0) if timeout is None else timeout
        if not quick:
            self._ramp_stop_command()
            try:
                return self.wait_for(lambda s: s.standstill, "standstill", timeout=wait, allow_fault=True)
            except DriveError:
                pass  # the ramp was not obeyed in time: quick stop
        self._quick_stop_command()
        return self.wait_for(lambda s: s.standstill, "standstill after quick stop", timeout=wait, allow_fault=True)

    def acknowledge_faults(self) -> AxisStatus:
        self._ack_command()
        status = self.read_status()
        if status.fault:
            raise DriveFault(f"fault still present after acknowledge (cause not removed?): {status.fault_summary()}",
                             details={"faults": status.faults})
        return status

    def safe_stop(self) -> tuple[AxisStatus | None, str]:
        """Best-effort stop used when something went wrong: never raises; says what happened."""
        try:
            status = self.stop()
            return status, "axis stopped" if status.standstill else "axis did not confirm standstill"
        except CommError as exc:
            return None, f"could not stop the axis, the drive does not answer ({exc.message}); " \
                         "the motion is bounded by the drive's own limits (see 'Safety model')"
        except AkdError as exc:
            return None, f"stop failed: {exc.message}"


# ====================================================================== PROFIdrive
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
    def read_status(self) -> AxisStatus:
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
class Cia402Axis(Axis):
    profile = "cia402"

    def __init__(self, objects: Any, transport: Any = None, timeout: float = 2.0, target: str = "") -> None:
        super().__init__(timeout, target)
        self.objects = objects
        self.transport = transport

    def _up(self, index: int, sub: int) -> int:
        return read_object(self.objects, index, sub)  # type: ignore[no-any-return]

    def _down(self, index: int, sub: int, value: int) -> None:
        write_object(self.objects, index, sub, value)

    def controlword(self, word: int) -> None:
        self._down(0x6040, 0, word)

    def read_status(self) -> AxisStatus:
        word = self._up(0x6041, 0)
        control = self._up(0x6040, 0)
        mode = self._up(0x6061, 0)
        position = self._up(0x6064, 0) / CIA_COUNTS_PER_REV
        velocity = self._up(0x606C, 0) * 60.0 / CIA_COUNTS_PER_REV
        torque = self._up(0x6077, 0) / 10.0
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
            position_rev=position, counts_per_rev=CIA_COUNTS_PER_REV, velocity_rpm=velocity, current_pct=torque,
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
        probe = getattr(self.transport, "al_state", None)
        if probe is None:
            return None
        try:
            state = probe()
        except AkdError:
            return None
        return None if state is None else str(state).upper()

    def _refuse_pdo_override(self, observed: bool) -> None:
        try:
            mapped = self.controlword_mapping()
        except AkdError:
            mapped = []
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
                    self.wait_for(lambda s: s.state in ("ready to switch on", "switched on"), "ready to switch on")
                except DriveError:
                    if self.read_status().word == before:
                        self._refuse_pdo_override(observed=True)
                    raise
            self.controlword(sw.CW_SWITCH_ON_CMD)
            self.wait_for(lambda s: s.state in ("switched on", "operation enabled"), "switched on")
        # With halt (bit 8): "enable" commands no motion, even if a set point (0x60FF in profile velocity) was
        # loaded before; the motion commands clear halt when they start.
        self.controlword(sw.CW_ENABLE_OPERATION_CMD | sw.CW_HALT)

    def _disable_command(self) -> None:
        self.controlword(sw.CW_SHUTDOWN)

    def _ramp_stop_command(self) -> None:
        status = self.read_status()
        if status.state == "operation enabled":
            self.controlword(sw.CW_ENABLE_OPERATION_CMD | sw.CW_HALT)  # halt: brake along the profile ramp
        elif status.state not in ("quick stop active",):
            self.controlword(sw.CW_SHUTDOWN)

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
        if self._up(0x6061, 0) != wanted:
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


# ====================================================================== choosing
def target_channels(conn: Any) -> set[str] | None:
    """The channels ('parameters', 'objects') the target offers, known without connecting; None if unknown."""
    from akdctl.transport.registry import BUILTIN

    spec = BUILTIN.get(conn.target.scheme)
    if spec is None:
        return None
    return {part.strip() for part in spec.channels.split(",")}


def profile_name(conn: Any) -> str:
    """The axis profile of this invocation: ``conn.drive_profile`` if set, else the CIP Position
    Controller on an EtherNet/IP target, PROFIdrive when the target has a parameter channel, else
    CiA 402 (decided without connecting when the registry knows)."""
    chosen = conn.drive_profile
    if chosen is not None:
        return str(chosen)
    channels = target_channels(conn)
    if channels is None:
        return "profidrive" if conn.has_parameters else "cia402"
    if "attributes" in channels:
        return "cip"
    return "profidrive" if "parameters" in channels else "cia402"


def axis_class(conn: Any) -> type[Axis]:
    """The Axis subclass of this invocation's profile (the planner reads its scales before connecting)."""
    chosen = profile_name(conn)
    if chosen == "cip":
        from akdctl.drive.cip_axis import CipAxis

        return CipAxis
    classes: dict[str, type[Axis]] = {"profidrive": ProfidriveAxis, "cia402": Cia402Axis}
    if chosen not in classes:
        raise UsageError(f"unknown drive profile {chosen!r}: use 'profidrive', 'cia402' or 'cip'")
    return classes[chosen]


if TYPE_CHECKING:  # beside its one user, so this hunk stays apart from the module's import block
    from akdctl.connection import Connection


def open_axis(conn: "Connection") -> Axis:
    """The axis of this connection (:func:`profile_name` chooses the profile)."""
    chosen = profile_name(conn)
    timeout = conn.options.timeout
    target = conn.target.display
    axis: Axis
    if chosen == "cip":
        from akdctl.drive.cip_axis import CipAxis

        axis = CipAxis(conn.cip(), timeout=timeout, target=target)
    elif chosen == "profidrive":
        axis = ProfidriveAxis(conn.parameters(), conn.objects() if conn.has_objects else None,
                              timeout=timeout, target=target)
    elif chosen == "cia402":
        axis = Cia402Axis(conn.objects(), conn.transport(), timeout=timeout, target=target)
    else:
        raise UsageError(f"unknown drive profile {chosen!r}: use 'profidrive', 'cia402' or 'cip'")
    transport = conn.transport()
    axis.time_scale_source = lambda: float(getattr(transport, "time_scale", 1.0))
    return axis


# ====================================================================== running a motion safely
class MotionRun:
    """Run one motion to its end, stopping the axis on Ctrl-C, on any error, and at the deadline.

    ``interrupted`` is a callable the CLI's signal handler flips; it is checked between polls
    so a Ctrl-C never lands in the middle of a request.
    """

    def __init__(self, axis: Axis, interrupted: Callable[[], bool],
                 progress: Callable[[AxisStatus], None] | None = None) -> None:
        self.axis = axis
        self.interrupted = interrupted
        self.progress = progress

    def _stop_and_raise(self, exc: AkdError) -> None:
        _, outcome = self.axis.safe_stop()
        exc.details.setdefault("stop", outcome)
        if "stop" not in exc.message:
            exc.message = f"{exc.message} ({outcome})"
        raise exc

    def run(self, start: Callable[[], None], finished: Callable[[AxisStatus], bool | None], *,
            deadline_s: float, what: str, on_deadline: str = "error") -> AxisStatus:
        """``start`` then poll ``finished`` (True done / False failed / None running) until ``deadline_s``.

        ``on_deadline='stop'`` ends the motion at the deadline as a success (jog --for).
        """
        try:
            start()
        except AkdError as exc:
            self._stop_and_raise(exc)
        end = time.monotonic() + deadline_s
        poll = self.axis.poll()
        while True:
            if self.interrupted():
                _, outcome = self.axis.safe_stop()
                raise Interrupted(f"interrupted during {what}; {outcome}", details={"stop": outcome})
            try:
                status = poll.read(self.axis.read_status)
            except AkdError as exc:
                self._stop_and_raise(exc)
            poll.observe(status.word)
            if self.progress is not None:
                self.progress(status)
            if status.fault:
                self.axis.safe_stop()
                raise DriveFault(f"drive fault during {what}: {status.fault_summary()}",
                                 details={"faults": status.faults})
            try:
                result = finished(status)
            except AkdError as exc:
                self._stop_and_raise(exc)
            if result is True:
                return status
            if result is False:
                self._stop_and_raise(DriveError(f"{what} failed: the drive ended it without success "
                                                f"(state {status.state}, word 0x{status.word:04X})"))
            if time.monotonic() > end:
                if on_deadline == "stop":
                    return status
                self._stop_and_raise(DriveError(f"{what} did not finish within {deadline_s:.1f} s"))
            poll.pause()
