"""The AKD's EtherNet/IP I/O assemblies: the 64-byte command (O->T) and response (T->O) layouts.

Layouts from the AKD EtherNet/IP manual: *AKD EtherNet/IP Communication*, 903-200008-00, December 2014
(rev E); [M-nn] is its page nn (pp. 11-16 here; page 16 is the project's seed 002). Tags: [V] read in
the manual, [I] inferred and unverified on hardware.

* Input (response) assembly instance 102, 64 bytes, no run/idle header [V]; configuration
  assembly 100, 0 bytes [V]; output (command) assembly 101, 64 bytes, run/idle header [I: the
  instance number and size fall on an unreadable part of the manual].
* Byte 2 (and 3): axis in bits 5-7, command (response) type in bits 0-4 [V: derived from the
  worked example 0x21 = axis 1 type 1].
* Command types 0x01 target position, 0x05 torque, 0x06 position move, 0x07 jog move,
  0x08 velocity set point [V]. 0x02-0x04 (ODVA/Moog: velocity, acceleration, deceleration)
  and 0x1B/0x1F are [I] and deliberately not offered here.
* Response type 0x14: byte 4 error code, byte 5 additional code, bytes 6-7 echo command
  bytes 2-3 [V].
* Status word 1: bit 7 Enabled and bit 2 In Position [V, from the example]; the other bit
  positions follow the ODVA/Moog layout [I].

Multi-byte fields are little-endian [V]. Malformed input raises :class:`CodecError` only.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, replace

from akdctl.protocol.errors import CodecError

ASSEMBLY_SIZE = 64
CONFIG_INSTANCE = 100          # [V] 0 bytes
OUTPUT_INSTANCE = 101          # [I] command assembly (O->T)
INPUT_INSTANCE = 102           # [V] response assembly (T->O)
STATIC_MAP_BYTES = 36          # [V] map type 0: only bytes 0..35 carry data

# Command control word (byte 0), bit 7..0: Enable, Reserved, Hard Stop, Smooth Stop, Direction, Relative,
# Start Block, Load/Start [V, M-12]
CTL_LOAD_START = 0x01
CTL_START_BLOCK = 0x02
CTL_RELATIVE = 0x04
CTL_DIRECTION = 0x08
CTL_SMOOTH_STOP = 0x10
CTL_HARD_STOP = 0x20
CTL_ENABLE = 0x80

# Command types [V]
CMD_NONE = 0x00
CMD_TARGET_POSITION = 0x01
CMD_TORQUE = 0x05
CMD_POSITION_MOVE = 0x06
CMD_JOG_MOVE = 0x07
CMD_VELOCITY_SETPOINT = 0x08
COMMAND_TYPES = {CMD_TARGET_POSITION: "target position", CMD_TORQUE: "torque",
                 CMD_POSITION_MOVE: "position move", CMD_JOG_MOVE: "jog move",
                 CMD_VELOCITY_SETPOINT: "velocity set point"}

# Response types
RSP_NONE = 0x00
RSP_TORQUE = 0x05               # [V] actual torque in mA in bytes 4-7
RSP_ERROR = 0x14                # [V] command/response error

# Status word 1 (byte 0)
ST1_ENABLED = 0x80              # [V]
ST1_HOMED = 0x20                # [I]
ST1_DIRECTION = 0x10            # [I] current direction
ST1_GENERAL_FAULT = 0x08        # [I]
ST1_IN_POSITION = 0x04          # [V]
ST1_BLOCK_IN_EXECUTION = 0x02   # [I]
ST1_IN_MOTION = 0x01            # [I]

# Status word 2 (byte 2), bit 7..0: Load Complete, Reserved, Reserved, Neg SW Limit, Pos SW Limit,
# Neg HW Limit, Pos HW Limit, Reserved [V, M-15]
ST2_LOAD_COMPLETE = 0x80
ST2_NEG_SW_LIMIT = 0x10
ST2_POS_SW_LIMIT = 0x08
ST2_NEG_HW_LIMIT = 0x04
ST2_POS_HW_LIMIT = 0x02

ADDITIONAL_CODE = 0xFF          # [V] every listed error carries additional code 0xFF

_CMD = struct.Struct("<BBBBiiiii8sBB2s28s")
_RSP = struct.Struct("<BBBB4siiI4s8sBB2s28s")
assert _CMD.size == ASSEMBLY_SIZE and _RSP.size == ASSEMBLY_SIZE


def axis_type(axis: int, kind: int) -> int:
    """Byte 2/3: axis in bits 5-7, type in bits 0-4."""
    if not 0 <= axis <= 7 or not 0 <= kind <= 0x1F:
        raise CodecError(f"axis {axis} (0..7) or type 0x{kind:X} (0..0x1F) out of range")
    return axis << 5 | kind


def split_axis_type(value: int) -> tuple[int, int]:
    return value >> 5 & 7, value & 0x1F


def _bytes(name: str, value: bytes, size: int) -> bytes:
    if len(value) != size:
        raise CodecError(f"{name} must be {size} bytes, got {len(value)}")
    return bytes(value)


@dataclass(frozen=True)
class Command:
    """The command (output) assembly, bytes 0-63."""

    control: int = 0
    block: int = 0
    command_axis: int = 1
    command_type: int = CMD_NONE
    response_axis: int = 1
    response_type: int = RSP_NONE
    data: int = 0                         # bytes 4-7 (signed)
    position: int = 0                     # 8-11, type 6
    velocity: int = 0                     # 12-15, types 6 and 7
    acceleration: int = 0                 # 16-19
    deceleration: int = 0                 # 20-23
    parameter_data: bytes = bytes(8)      # 24-31
    attribute_to_get: int = 0             # 32
    map_type: int = 0                     # 33
    reserved: bytes = bytes(2)            # 34-35
    dynamic_map: bytes = bytes(28)        # 36-63 (EIP.CMDMAP)

    def encode(self) -> bytes:
        try:
            return _CMD.pack(self.control, self.block, axis_type(self.command_axis, self.command_type),
                             axis_type(self.response_axis, self.response_type), self.data, self.position,
                             self.velocity, self.acceleration, self.deceleration,
                             _bytes("parameter data", self.parameter_data, 8), self.attribute_to_get, self.map_type,
                             _bytes("reserved", self.reserved, 2), _bytes("dynamic map", self.dynamic_map, 28))
        except struct.error as exc:
            raise CodecError(f"command assembly field out of range: {exc}") from None

    @classmethod
    def decode(cls, data: bytes) -> "Command":
        if len(data) != ASSEMBLY_SIZE:
            raise CodecError(f"command assembly must be {ASSEMBLY_SIZE} bytes, got {len(data)}")
        (control, block, cmd, rsp, value, pos, vel, acc, dec, pdata, attr, mtype, res,
         dmap) = _CMD.unpack(data)
        ca, ct = split_axis_type(cmd)
        ra, rt = split_axis_type(rsp)
        return cls(control, block, ca, ct, ra, rt, value, pos, vel, acc, dec, pdata, attr, mtype, res, dmap)

    def flag(self, bit: int) -> bool:
        return bool(self.control & bit)


@dataclass(frozen=True)
class Response:
    """The response (input) assembly, bytes 0-63."""

    status1: int = 0
    executing_block: int = 0
    status2: int = 0
    response_axis: int = 1
    response_type: int = RSP_NONE
    data: bytes = bytes(4)                # 4-7: value, or error code / additional code / echo for 0x14
    actual_position: int = 0              # 8-11
    actual_velocity: int = 0              # 12-15
    motion_status: int = 0                # 16-19 (DRV.MOTIONSTAT)
    reserved: bytes = bytes(4)            # 20-23
    parameter_data: bytes = bytes(8)      # 24-31
    attribute_to_get: int = 0             # 32 (mirror)
    map_type: int = 0                     # 33
    reserved2: bytes = bytes(2)           # 34-35
    dynamic_map: bytes = bytes(28)        # 36-63 (EIP.RSPMAP)

    def encode(self) -> bytes:
        try:
            return _RSP.pack(self.status1, self.executing_block, self.status2,
                             axis_type(self.response_axis, self.response_type), _bytes("data", self.data, 4),
                             self.actual_position, self.actual_velocity, self.motion_status,
                             _bytes("reserved", self.reserved, 4), _bytes("parameter data", self.parameter_data, 8),
                             self.attribute_to_get, self.map_type, _bytes("reserved", self.reserved2, 2),
                             _bytes("dynamic map", self.dynamic_map, 28))
        except struct.error as exc:
            raise CodecError(f"response assembly field out of range: {exc}") from None

    @classmethod
    def decode(cls, data: bytes) -> "Response":
        if len(data) != ASSEMBLY_SIZE:
            raise CodecError(f"response assembly must be {ASSEMBLY_SIZE} bytes, got {len(data)}")
        (st1, block, st2, rsp, value, pos, vel, mstat, res, pdata, attr, mtype, res2, dmap) = _RSP.unpack(data)
        ra, rt = split_axis_type(rsp)
        return cls(st1, block, st2, ra, rt, value, pos, vel, mstat, res, pdata, attr, mtype, res2, dmap)

    @property
    def data_value(self) -> int:
        return struct.unpack("<i", self.data)[0]

    @property
    def load_complete(self) -> bool:
        return bool(self.status2 & ST2_LOAD_COMPLETE)

    @property
    def error(self) -> "CommandError | None":
        """The command error of a response type 0x14, else None."""
        if self.response_type != RSP_ERROR:
            return None
        return CommandError(self.data[0], self.data[1], self.data[2], self.data[3])


@dataclass(frozen=True)
class CommandError:
    """Response type 0x14: error code (a CIP general status), additional code, echoed command bytes 2-3."""

    code: int
    additional: int
    echo_command: int
    echo_response: int

    def data(self) -> bytes:
        return bytes([self.code & 0xFF, self.additional & 0xFF, self.echo_command & 0xFF, self.echo_response & 0xFF])


def error_response(base: Response, command: Command, code: int, additional: int = ADDITIONAL_CODE) -> Response:
    """``base`` turned into a 0x14 error response for ``command`` (echoing its bytes 2-3)."""
    raw = command.encode()
    return replace(base, response_type=RSP_ERROR, data=CommandError(code, additional, raw[2], raw[3]).data())


def value_data(value: int) -> bytes:
    """A signed 32-bit value for the data field."""
    try:
        return struct.pack("<i", value)
    except struct.error:
        raise CodecError(f"{value} does not fit the 32-bit data field") from None
