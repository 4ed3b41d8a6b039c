"""The axis over the AKD's own command channel (akd://): status, enable, disable, stop and fault acknowledge
through the drive's keywords, as the reference lists them (akd-ascii-channel.md 3).

* status: ``DRV.ACTIVE`` (1 enabled; 3 dynamic braking counts as not enabled, aakd), ``DRV.FAULTS`` /
  ``DRV.WARNINGS`` (``<number>: <text>.`` lines, or "No faults active"), ``DRV.MOTIONSTAT`` (bit 0 motion task
  active, bits 1+2 homed, bit 9 service motion), ``DRV.OPMODE``, ``VL.FB``;
* enable ``DRV.EN``, disable ``DRV.DIS``, stop ``DRV.STOP`` (ramp and quick stop alike: the channel has no
  separate quick stop [I]), acknowledge ``DRV.CLRFAULTS``.

Motion (jog, home, move) is not offered over this channel in this version: the consent, homed rule and
supervision of those commands are built on the fieldbus profiles; the refusal names them.
"""

from __future__ import annotations

import re
from typing import Any

from akdctl.drive.axis.base import Axis, AxisStatus, JogSpec, MotionScales, MoveSpec, Scale, _fault_entries
from akdctl.errors import AkdError, UsageError

_MODES = {0: "torque", 1: "velocity", 2: "position"}
_NO_MOTION = ("motion commands (jog, home, move) are not offered over the AKD service channel (akd://) in this "
              "version; use a fieldbus target (sim, pn://, ecat-udp://, can://, eip://) or 'akdctl cmd' with consent")
_FAULT_LINE = re.compile(r"^\s*(\d+)\s*:")


def _numbers(text: str) -> list[int]:
    return [int(m.group(1)) for line in text.splitlines() if (m := _FAULT_LINE.match(line))]


class AkdAsciiAxis(Axis):
    """An axis whose every read and command is one line on a :class:`~akdctl.links.CommandLink`."""

    profile = "akd"
    HOMED_SOURCE = "DRV.MOTIONSTAT bits 1 and 2"

    def __init__(self, link: Any, timeout: float = 2.0, target: str = "") -> None:
        super().__init__(timeout, target)
        self.link = link

    def _int(self, name: str) -> int | None:
        try:
            return int(self.link.command(name).split()[0], 0)
        except (AkdError, ValueError, IndexError):
            return None

    def _read_status(self) -> AxisStatus:
        active = self._int("DRV.ACTIVE")
        faults = _fault_entries(_numbers(self.link.command("DRV.FAULTS")))
        try:
            warnings = _fault_entries(_numbers(self.link.command("DRV.WARNINGS")), warning=True)
        except AkdError:
            warnings = []
        motion = self._int("DRV.MOTIONSTAT") or 0
        mode = self._int("DRV.OPMODE")
        velocity = None
        try:
            velocity = float(self.link.command("VL.FB").split()[0])
        except (AkdError, ValueError, IndexError):
            pass
        enabled = active == 1
        state = "fault" if faults else "enabled" if enabled else "disabled"
        moving = bool(motion & 0x201) or (velocity is not None and abs(velocity) >= 0.5)
        return AxisStatus(self.profile, state, {"fault": "fault active", "enabled": "power stage enabled",
                                                "disabled": "power stage disabled"}[state], motion, 0, mode,
                          _MODES.get(mode, "?") if mode is not None else "?", enabled, bool(faults), bool(warnings),
                          faults=faults, warnings=warnings, homed=(motion & 0x6) == 0x6,
                          target_reached=bool(motion & 0x800), standstill=not moving, velocity_rpm=velocity)

    def _enable_steps(self, status: AxisStatus) -> None:
        self.link.command("DRV.EN")

    def _disable_command(self) -> None:
        self.link.command("DRV.DIS")

    def _ramp_stop_command(self) -> None:
        self.link.command("DRV.STOP")

    def _quick_stop_command(self) -> None:
        self.link.command("DRV.STOP")

    def _ack_command(self) -> None:
        self.link.command("DRV.CLRFAULTS")

    def start_jog(self, jog: JogSpec) -> None:
        raise UsageError(_NO_MOTION)

    def end_jog(self) -> None:
        self.link.command("DRV.STOP")

    def start_home(self, mode: int | None) -> None:
        raise UsageError(_NO_MOTION)

    def home_finished(self, status: AxisStatus) -> bool | None:
        return None

    def start_move(self, move: MoveSpec) -> None:
        raise UsageError(_NO_MOTION)

    def ensure_mode(self, kind: str) -> None:
        raise UsageError(_NO_MOTION)

    @classmethod
    def mode_name(cls, kind: str) -> str:
        return kind

    @classmethod
    def motion_scales(cls, kind: str) -> MotionScales:
        raise UsageError(_NO_MOTION)

    def position_scale(self, status: AxisStatus) -> Scale:
        raise UsageError(_NO_MOTION)
