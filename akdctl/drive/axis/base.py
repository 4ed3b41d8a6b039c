"""The profile-neutral axis: what every profile reports (AxisStatus), how it scales motion (Scale,
MotionScales) and the Axis interface with the safety behaviour written once.
"""


from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akdctl.drive.polling import Poll
from akdctl.drive.values import read_object
from akdctl.errors import (
    AkdError,
    CommError,
    DriveError,
    DriveFault,
    SafetyRefusal,
    UsageError,
)
from akdctl.profiles import statusword as sw
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel


#: The homing phase a finished homing reports (:meth:`AxisStatus.homing_phase`; the progress line drops its deadline).
HOMING_COMPLETED = "homing completed"


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

    def homing_phase(self) -> str | None:
        """Where a running homing stands, in words, as far as the drive's status word tells (issue 28 item 7);
        None when the profile's word says nothing about homing in this mode.

        CiA 402 homing mode (0x6061 = 6), statusword bits 13/12/10 (CiA 402 homing mode table): 000 in progress,
        001 interrupted or not started, 010 attained but target not reached, 011 completed, 1x0 error while
        moving, 1x1 error at standstill. PROFIdrive position mode (SPEC-NOTES 9): ZSW1 bits 10/11/13 are clear
        while homing runs and all set when it finished; bit 11 alone is the home position set."""
        if self.profile == "cia402" and self.mode == 6:
            bits = (bool(self.word & sw.SW_BIT13), bool(self.word & sw.SW_BIT12), bool(self.word & sw.SW_TARGET_REACHED))
            return {(False, False, False): "homing in progress",
                    (False, False, True): "homing interrupted or not started",
                    (False, True, False): "home found, still moving to it",
                    (False, True, True): HOMING_COMPLETED}.get(
                bits, "homing error" + (" at standstill" if bits[2] else ", still moving"))
        if self.profile == "profidrive" and self.mode == 2:
            if self.word & sw.ZSW1_HOME_POSITION_SET and self.word & sw.ZSW1_DRIVE_STOPPED:
                return HOMING_COMPLETED
            if self.word & sw.ZSW1_HOME_POSITION_SET:
                return "home position set, still moving"
            return "searching for the reference" if not self.standstill else "homing not running"
        return None

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


def _warning_entries(objects: "ObjectChannel") -> list[dict[str, Any]]:
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
    #: Why absolute moves are not possible over this profile at all ("" when they are once homed): the planner
    #: refuses them with this reason before reading the drive, instead of a "not homed" a 'home' cannot cure.
    NO_ABSOLUTE_MOVES = ""
    #: The homing modes/methods the drive accepts, and where they go.
    HOME_MODE_RANGE: tuple[int, int] = (-128, 127)
    HOME_MODE_FIELD = ""
    #: Whether ``start_task`` can start a stored motion task, and why not (``task start``, docs/fidelity.md F11).
    TASKS = False
    NO_TASKS = ("the drive's manual documents no way to start a stored motion task over this profile; "
                "use a PROFIdrive target (program mode) or 'akdctl move'")

    #: Seconds of the drive's time per wall second, asked when a wait starts (open_axis: the Connection's
    #: declared ``time_scale``, above 1 only for the simulator); None: a real drive's 1.
    time_scale_source: Callable[[], float] | None = None

    def __init__(self, timeout: float = 2.0, target: str = "") -> None:
        self.timeout = timeout
        self.target = target

    def poll(self, deadline: float | None = None) -> Poll:
        """The pauses of one wait (drive/polling.py: fast after a command or a change, then steady)."""
        return Poll(self.time_scale_source() if self.time_scale_source is not None else 1.0, deadline)

    def start_task(self, number: int) -> None:
        """Start stored motion task ``number`` where the profile can (``TASKS``); refused otherwise
        (the planner refuses first: declared here so no caller probes for it)."""
        raise UsageError(f"task start: {self.NO_TASKS}")

    def issued_target(self) -> int | None:
        """The set point the drive holds, raw, to tell our target from another master's (motion_plan);
        None where the profile cannot read it back (declared here, not probed)."""
        return None

    # ---------------------------------------------------------------- primitives per profile
    #: How old a status may be to stand in for a new read (:meth:`recent_status`): no human prompt fits in it,
    #: and every write of the axis forgets the status (:meth:`_forget`), so it never hides a change we made.
    RECENT_S = 0.25
    _last: tuple[float, AxisStatus] | None = None

    def read_status(self) -> AxisStatus:
        """The drive's status, read now (and remembered for :meth:`recent_status`)."""
        status = self._read_status()
        self._last = (time.monotonic(), status)
        return status

    def recent_status(self) -> AxisStatus:
        """The status read within :data:`RECENT_S` with no write of ours since, else a new read: the one read the
        planner and the preparation of a motion share (issue 22 item 6), instead of two back to back. Callers
        share it only under the owner lock (cli/motion._plan_and_run takes it before the plan with --yes, and
        calls :meth:`forget_status` after a prompt; a recipe holds it for its whole run)."""
        if self._last is not None and time.monotonic() - self._last[0] <= self.RECENT_S:
            return self._last[1]
        return self.read_status()

    def read_motion_status(self) -> AxisStatus:
        """The status a poll of a running motion needs; a profile whose full status costs extra requests for what
        a poll does not use (CiA 402: the torque) reads less here."""
        return self.read_status()

    def _forget(self) -> None:
        """A write of ours: the remembered status is no longer the drive's."""
        self._last = None

    def forget_status(self) -> None:
        """The remembered status may not stand for a new read (e.g. it was read before the owner lock was
        taken: another command may have moved the axis since)."""
        self._forget()

    @abstractmethod
    def _read_status(self) -> AxisStatus: ...

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
        status = self.recent_status()
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
                status = self.wait_for(lambda s: s.standstill, "standstill", timeout=wait, allow_fault=True)
            except DriveError:
                pass  # the ramp was not obeyed in time: quick stop
            else:
                return self._drop_held_motion(status)
        self._quick_stop_command()
        return self.wait_for(lambda s: s.standstill, "standstill after quick stop", timeout=wait, allow_fault=True)

    def _drop_held_motion(self, status: AxisStatus) -> AxisStatus:
        """After a ramp stop at standstill: a profile that only *holds* the interrupted motion (CiA 402 halt keeps
        the positioning task) drops it here, so nothing resumes it later. Default: nothing is held."""
        return status

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
