"""The third axis profile: the AKD's CIP Position Controller object 0x25 over explicit messaging.

Attributes used (AKD EtherNet/IP manual appendix A [M-37]; reference/ethernetip.md 1.8):
3 mode (0 position, 1 velocity, 2 torque), 4/5 position/profile units, 6 target position,
7 target velocity, 10 incremental flag, 11 load data/profile handshake, 17 enable, 58 load data
complete, 100 home mode, 101 home move [V]. Read only where available, because they are
*inferred* from the ODVA position-controller profile and not in the AKD's list [I]: 12 on target
position, 13 actual position, 14 actual velocity, and the Supervisor 0x24 attribute 5 general fault.
A drive that answers "attribute not supported" for them leaves those fields unknown.

Units: positions are 32-bit integers in EIP.POSUNIT units and velocities 32-bit integers in
EIP.PROFUNIT units [V: M-25]; akdctl takes POSUNIT counts as one revolution and PROFUNIT counts/s
as one rev/s [I], which is the simulator's scaling and the drive's default of 65536 for both.

What explicit messaging cannot do on an AKD (no attribute for it in appendix A): a ramp stop of a
position move (the stop disables the drive, which ramps down and then switches the power stage
off), reading the homed state, and acknowledging faults (DRV.CLRFAULTS has no cited instance).
"""

from __future__ import annotations

import struct
from typing import Any

from akdctl.drive.axis.base import Axis, AxisStatus, JogSpec, MotionScales, MoveSpec, Scale
from akdctl.errors import CipRefused, DriveError, MalformedReply, UsageError
from akdctl.profiles import statusword as sw
from akdctl.protocol import cip

PC = cip.POSITION_CONTROLLER
MODES = {0: "position (0x25 attribute 3 = 0)", 1: "velocity (0x25 attribute 3 = 1)", 2: "torque (0x25 attribute 3 = 2)"}
STATUS_BITS = {0: "enabled (0x25/1/17)", 1: "on target position (0x25/1/12, inferred)",
               2: "load data complete (0x25/1/58)", 3: "general fault (0x24/1/5, inferred)",
               4: "load data handshake (0x25/1/11)", 5: "incremental position (0x25/1/10)"}
NOT_AVAILABLE = (cip.ATTRIBUTE_NOT_SUPPORTED, cip.PATH_DESTINATION_UNKNOWN, cip.OBJECT_DOES_NOT_EXIST,
                 cip.SERVICE_NOT_SUPPORTED)
INT32 = (-(1 << 31), (1 << 31) - 1)
#: EIP.POSUNIT / EIP.PROFUNIT default (the drive's and the simulator's): the grid before the drive is asked.
DEFAULT_UNITS = 65536


class CipAxis(Axis):
    profile = "cip"

    def __init__(self, channel: Any, timeout: float = 2.0, target: str = "") -> None:
        super().__init__(timeout, target)
        self.channel = channel

    # ---------------------------------------------------------------- access
    def _get(self, attribute: int, fmt: str, class_id: int = PC) -> int:
        data = self.channel.get(class_id, 1, attribute)
        try:
            return struct.unpack(fmt, data)[0]
        except struct.error:
            raise MalformedReply(f"attribute 0x{class_id:02X}/1/{attribute} answered {len(data)} bytes "
                                 f"({data.hex(' ') or 'empty'})") from None

    def _optional(self, attribute: int, fmt: str, class_id: int = PC) -> int | None:
        try:
            return self._get(attribute, fmt, class_id)
        except CipRefused as exc:
            if exc.code in NOT_AVAILABLE:
                return None
            raise

    def _set(self, attribute: int, fmt: str, value: int) -> None:
        try:
            data = struct.pack(fmt, value)
        except struct.error:
            raise UsageError(f"value {value} does not fit attribute 0x25/1/{attribute} ({fmt[1:]})") from None
        self._forget()
        self.channel.set(PC, 1, attribute, data)

    def units(self) -> tuple[int, int]:
        """(EIP.POSUNIT, EIP.PROFUNIT) as the Position Controller reports them (attributes 4 and 5)."""
        posunit, profunit = self._get(4, "<i"), self._get(5, "<i")
        if posunit <= 0 or profunit <= 0:
            raise DriveError(f"the drive reports position/profile units {posunit}/{profunit}; akdctl needs both > 0")
        return posunit, profunit

    # ---------------------------------------------------------------- planner contract (quantisation, ranges)
    # Explicit messaging has no homed attribute: an absolute position cannot be trusted, so absolute
    # moves are refused (confirm_homed is False); relative moves and jogs need no home.
    RELATIVE_MOVES_NEED_HOME = False
    HOMED_SOURCE = "no Position Controller attribute reports it over explicit messaging"
    NO_ABSOLUTE_MOVES = ("explicit messaging has no attribute that reports the homed state, so akdctl cannot know "
                         "that an absolute position means anything, even right after 'akdctl home'; move with "
                         "--relative, or use 'akdctl eip io position|move' (the drive itself checks homing there)")
    HOME_MODE_RANGE = (-32768, 32767)
    HOME_MODE_FIELD = "the home mode 0x25/1/100 (INT)"

    @classmethod
    def _scales(cls, kind: str, profunit: int) -> MotionScales:
        step = 60.0 / profunit
        # Attributes 8/9 (acceleration/deceleration) are "not used yet" [M-37]: the drive runs its own
        # DRV.ACC/DRV.DEC. The planner still checks a requested ramp against the profile's limits; nothing
        # of it is sent.
        ramp = Scale("the drive's own ramp (0x25/1/8-9 are not used by the AKD; nothing is sent)", "rpm/s",
                     step, 1, INT32[1])
        velocity = Scale(f"target velocity 0x25/1/7 (DINT, EIP.PROFUNIT = {profunit} per rev/s)", "rpm", step,
                         1 if kind == "position" else 1, INT32[1])
        return MotionScales(velocity, ramp, ramp)

    @classmethod
    def motion_scales(cls, kind: str) -> MotionScales:
        return cls._scales(kind, DEFAULT_UNITS)

    def drive_motion_scales(self, kind: str) -> MotionScales:
        return self._scales(kind, self.units()[1])

    def position_scale(self, status: AxisStatus) -> Scale:
        return Scale("target position 0x25/1/6 (DINT, EIP.POSUNIT counts per rev)", "counts", 1.0, *INT32)

    def homed_reading(self, status: AxisStatus) -> bool | None:
        return None

    def confirm_homed(self) -> bool:
        return False

    # ---------------------------------------------------------------- status
    def _read_status(self) -> AxisStatus:
        mode = self._get(3, "<B")
        enabled = bool(self._get(17, "<B"))
        load_complete = bool(self._get(58, "<B"))
        handshake = bool(self._get(11, "<B"))
        incremental = bool(self._get(10, "<B"))
        posunit, profunit = self.units()
        on_target = self._optional(12, "<B")
        position = self._optional(13, "<i")
        velocity = self._optional(14, "<i")
        fault = bool(self._optional(5, "<B", cip.POSITION_CONTROLLER_SUPERVISOR) or 0)
        word = (enabled | (bool(on_target) << 1) | (load_complete << 2) | (fault << 3) | (handshake << 4)
                | (incremental << 5))
        standstill = velocity == 0 if velocity is not None else bool(on_target)
        state = "fault" if fault else ("enabled" if enabled else "disabled")
        return AxisStatus(
            profile=self.profile, state=state, state_text=state, word=word, control=0, mode=mode,
            mode_text=MODES.get(mode, f"mode {mode}"), enabled=enabled and not fault, fault=fault, warning=False,
            faults=[], homed=None, target_reached=bool(on_target), standstill=standstill, task_ack=load_complete,
            position_rev=None if position is None else position / posunit, counts_per_rev=posunit,
            velocity_rpm=None if velocity is None else velocity * 60.0 / profunit, current_pct=None,
            bits=[sw.Bit(n, name, bool(word >> n & 1)) for n, name in STATUS_BITS.items()],
        )

    # ---------------------------------------------------------------- state
    def _enable_steps(self, status: AxisStatus) -> None:
        self._set(17, "<B", 1)

    def _disable_command(self) -> None:
        self._set(17, "<B", 0)

    def _ramp_stop_command(self) -> None:
        if self._get(3, "<B") == 1:
            self._load_velocity(0)
        else:
            self._disable_command()     # no stop attribute for a position move: the drive ramps down, then disables

    def _quick_stop_command(self) -> None:
        self._disable_command()

    def _ack_command(self) -> None:
        raise UsageError("acknowledging faults over eip:// needs DRV.CLRFAULTS, and akdctl has no cited Parameter "
                         "object instance for it; acknowledge through WorkBench or another target")

    # ---------------------------------------------------------------- modes and motion
    @classmethod
    def mode_name(cls, kind: str) -> str:
        return {"velocity": MODES[1], "position": MODES[0], "homing": MODES[0] + ", home move 0x25/1/101"}[kind]

    def ensure_mode(self, kind: str) -> None:
        wanted = 1 if kind == "velocity" else 0
        if self._get(3, "<B") != wanted:
            self._set(3, "<B", wanted)

    def _handshake(self) -> None:
        """Load Data: 0 -> 1 on attribute 11, check Load Data Complete (58), then back to 0."""
        self._set(11, "<B", 0)
        self._set(11, "<B", 1)
        try:
            if not self._get(58, "<B"):
                raise DriveError("the drive did not confirm the loaded data (0x25/1/58 Load Data Complete stayed 0)")
        finally:
            self._set(11, "<B", 0)

    def _load_velocity(self, raw: int) -> None:
        self._set(7, "<i", raw)
        self._handshake()

    def start_jog(self, jog: JogSpec) -> None:
        self._load_velocity(jog.velocity_raw)     # 8/9 (ramps) are "not used yet" [M-37]: the drive's own apply

    def end_jog(self) -> None:
        self._load_velocity(0)

    def start_home(self, mode: int | None) -> None:
        if mode is not None:
            self._set(100, "<h", mode)
        self._set(101, "<B", 1)

    def home_finished(self, status: AxisStatus) -> bool | None:
        # Only "on target" [I] tells that the homing move ended; a homing error is not observable here.
        return True if status.target_reached and status.standstill else None

    def start_move(self, move: MoveSpec) -> None:
        self._set(10, "<B", 1 if move.relative else 0)
        self._set(6, "<i", move.target_raw)
        self._set(7, "<i", abs(move.velocity_raw))
        try:
            self._handshake()
        except CipRefused as exc:
            if exc.code != cip.DEVICE_STATE_CONFLICT:
                raise
            # [V] "The amplifier must be homed before motion is begun in position mode" [M-11]; explicit
            # messaging cannot read the homed state beforehand, so the drive's refusal is where it shows.
            raise DriveError(f"the drive refused the position move ({exc.message.split(': ', 1)[-1]}): an AKD "
                             "positions only once homed (EtherNet/IP manual); run 'akdctl home' first",
                             code=exc.code) from None
