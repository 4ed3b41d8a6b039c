"""The one axis behind the simulated AKD's CIP objects: CIP requests turned into CiA 402 object accesses.

Why apart from the objects (sim/cip_objects.py): the Parameter object, the Position Controller and the I/O
handshake all act on the same axis the same way -- units, mode, enable, homing, a loaded move -- and an AKD has
one power stage, which the simulator keeps once (``sim/motion.py``). This bridge writes controlword 0x6040, mode
0x6060, targets 0x607A/0x60FF/0x6081 and homing 0x6098 of that one model inside a ``SimDrive`` transaction, so
``akdctl status`` over any other face sees what an EtherNet/IP client did. Scaling ([I], reference/ethernetip.md):
EIP.POSUNIT counts make one revolution, EIP.PROFUNIT counts/s one rev/s.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

from akdctl.protocol import akd_assembly as asm
from akdctl.protocol import cip
from akdctl.sim.errors import SdoAccessError

CIA_COUNTS = 65536
DEFAULT_UNIT = 65536
HOMING_METHODS = {0: 35, 1: 17, 2: 1, 3: 19, 4: 3, 5: 34}   # AKD HOME.MODE -> a CiA 402 method of the same procedure
PC_MODES = {0: 1, 1: 3, 2: 4}            # Position Controller mode -> 0x6060

# simulated-model refusals (CiA 301 aborts) in CIP words
_ABORT_TO_CIP = {0x08000022: cip.DEVICE_STATE_CONFLICT, 0x06090030: cip.INVALID_ATTRIBUTE_VALUE,
                 0x06090031: cip.INVALID_ATTRIBUTE_VALUE, 0x06090032: cip.INVALID_ATTRIBUTE_VALUE}


class CipRefusal(Exception):
    """A request the device refuses with a CIP general status (and extended status words)."""

    def __init__(self, status: int, extended: tuple[int, ...] = ()) -> None:
        super().__init__(f"CIP status 0x{status:02X}")
        self.status = status
        self.extended = extended


@dataclass
class PcState:
    """Position Controller attributes that live in the EtherNet/IP interface (volatile, per face)."""

    target_position: int = 0
    target_velocity: int = 0
    acceleration: int = 0
    deceleration: int = 0
    incremental: bool = False
    handshake: bool = False
    load_complete: bool = False
    torque: int = 0
    home_mode: int = 0
    posunit: int = DEFAULT_UNIT
    profunit: int = DEFAULT_UNIT


#: The Parameter object's unit parameters, by their PcState attribute: kept in the drive model by AKD name.
UNIT_PARAMETERS = {"posunit": "EIP.POSUNIT", "profunit": "EIP.PROFUNIT"}


class AxisBridge:
    """The axis as the CIP objects see it, on the simulated drive's CiA 402 objects."""

    def __init__(self, drive: Any, pc: PcState) -> None:
        self.drive = drive
        self.pc = pc
        self._units_loaded = False

    def load_units(self) -> None:
        """EIP.POSUNIT/EIP.PROFUNIT as the drive keeps them (once per face: only this face writes them)."""
        if self._units_loaded:
            return
        with self.model() as model:
            for key, name in UNIT_PARAMETERS.items():
                setattr(self.pc, key, model.named_value(name, DEFAULT_UNIT))
        self._units_loaded = True

    def save_unit(self, key: str, value: int) -> None:
        """A unit parameter written over the Parameter object: kept with the drive's state, saved before the reply
        (a drive that cannot keep it refuses: issue 23.11)."""
        with self.model() as model:
            model.set_named_value(UNIT_PARAMETERS[key], value)
        setattr(self.pc, key, value)

    # ---------------------------------------------------------------- model access
    def model(self) -> Any:
        return self.drive.transaction()

    def fault(self) -> bool:
        with self.model() as model:
            return bool(model.object_value(0x6041, 0) & 0x08)

    @staticmethod
    def write(model: Any, index: int, fmt: str, value: int) -> None:
        try:
            model.object_write(index, 0, struct.pack(fmt, value))
        except SdoAccessError as exc:
            raise CipRefusal(_ABORT_TO_CIP.get(exc.code, cip.OBJECT_STATE_CONFLICT)) from None

    @staticmethod
    def enabled(model: Any) -> bool:
        return bool(model.object_value(0x6041, 0) & 0x6F == 0x27)

    def snapshot(self) -> dict[str, Any]:
        """What the objects report, read in one transaction."""
        with self.model() as model:
            word = model.object_value(0x6041, 0)
            mode = model.object_value(0x6061, 0)
            axis = model.motion.axis
            return {"word": word, "mode": mode, "enabled": word & 0x6F == 0x27, "fault": bool(word & 0x08),
                    "position": model.object_value(0x6064, 0), "velocity": model.object_value(0x606C, 0),
                    "homed": axis.homed, "homing": axis.homing is not None, "activity": axis.activity,
                    "task": axis.task is not None, "at_rest": axis.standstill,
                    "current": model.object_value(0x6077, 0), "current_ma": model.object_value(0x2077, 0)}

    @staticmethod
    def pc_mode(cia_mode: int) -> int:
        """The Position Controller's mode (0 position, 1 velocity, 2 torque) of a CiA 402 mode."""
        return {1: 0, 3: 1, 4: 2, 6: 0}.get(cia_mode, 0)

    # ---------------------------------------------------------------- scaling [I]
    def cia_pos(self, eip: int) -> int:
        return round(eip * CIA_COUNTS / self.pc.posunit)

    def cia_vel(self, eip: int) -> int:
        return round(eip * CIA_COUNTS / self.pc.profunit)

    def eip_pos(self, cia: int) -> int:
        return clamp32(round(cia * self.pc.posunit / CIA_COUNTS))

    def eip_vel(self, cia: int) -> int:
        return clamp32(round(cia * self.pc.profunit / CIA_COUNTS))

    # ---------------------------------------------------------------- what the objects command
    def ensure_mode(self, model: Any, cia_mode: int) -> None:
        if model.object_value(0x6061, 0) != cia_mode:
            self.write(model, 0x6060, "<b", cia_mode)

    def set_mode(self, pc_mode: int) -> None:
        if pc_mode not in PC_MODES:
            raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
        with self.model() as model:
            self.ensure_mode(model, PC_MODES[pc_mode])

    def enable(self, on: bool) -> None:
        with self.model() as model:
            state = model.object_value(0x6041, 0) & 0x6F
            if on:
                if model.object_value(0x6041, 0) & 0x08:
                    raise CipRefusal(cip.DEVICE_STATE_CONFLICT)
                if state != 0x27:
                    for word in (0x06, 0x07, 0x0F):
                        self.write(model, 0x6040, "<H", word)
            else:
                self.write(model, 0x6040, "<H", 0x06)

    def start_homing(self) -> None:
        with self.model() as model:
            if not self.enabled(model):
                raise CipRefusal(cip.DEVICE_STATE_CONFLICT)
            method = HOMING_METHODS.get(self.pc.home_mode)
            if method is None:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
            self.ensure_mode(model, 6)
            self.write(model, 0x6098, "<b", method)
            self.write(model, 0x6040, "<H", 0x0F)
            self.write(model, 0x6040, "<H", 0x1F)

    def load(self, kind: int, *, target: int | None = None, velocity: int | None = None,
             acceleration: int = 0, deceleration: int = 0, relative: bool = False) -> None:
        """Load (and start) one command on the one axis: a position move, a velocity or a torque."""
        pc = self.pc
        with self.model() as model:
            if not self.enabled(model):
                raise CipRefusal(cip.DEVICE_STATE_CONFLICT)
            axis = model.motion.axis
            if kind == asm.CMD_TORQUE:
                pc.torque = 0 if target is None else target
                return
            if kind in (asm.CMD_VELOCITY_SETPOINT, asm.CMD_JOG_MOVE):
                self.ensure_mode(model, 3)
                if acceleration:
                    self.write(model, 0x6083, "<I", abs(self.cia_vel(acceleration)))
                    self.write(model, 0x6084, "<I", abs(self.cia_vel(deceleration or acceleration)))
                self.write(model, 0x60FF, "<i", clamp32(self.cia_vel(velocity or 0)))
                self.write(model, 0x6040, "<H", 0x0F)
                return
            if not axis.homed:
                raise CipRefusal(cip.DEVICE_STATE_CONFLICT)   # must be homed before position moves [M-11]
            self.ensure_mode(model, 1)
            # type 1 carries no velocity: the attribute-7 target velocity, else the simulator's 1 rev/s
            speed = velocity or pc.target_velocity or pc.profunit
            self.write(model, 0x607A, "<i", clamp32(self.cia_pos(target or 0)))
            self.write(model, 0x6081, "<I", min(0xFFFFFFFF, abs(self.cia_vel(speed))))
            self.write(model, 0x6083, "<I", abs(self.cia_vel(acceleration or pc.acceleration)))
            self.write(model, 0x6084, "<I", abs(self.cia_vel(deceleration or pc.deceleration)))
            base = 0x0F | 0x20 | (0x40 if relative else 0)
            self.write(model, 0x6040, "<H", base)
            self.write(model, 0x6040, "<H", base | 0x10)
            if not model.object_value(0x6041, 0) & 0x1000:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)      # outside the software limits
            self.write(model, 0x6040, "<H", base)


def clamp32(value: int) -> int:
    return max(-(1 << 31), min((1 << 31) - 1, int(value)))
