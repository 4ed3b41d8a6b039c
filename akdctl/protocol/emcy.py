"""CiA 301 emergency (EMCY) frame: 8 bytes, shared by CANopen and CoE.

CANopen sends it as a CAN frame on COB-ID 0x80 + node; CoE carries the same
8 bytes as CoE service 1 in a mailbox. The AKD has no 0x603F, so emergencies
are how a fieldbus client learns about faults (SPEC-NOTES 21); keeping one
codec means both transports report a fault identically.

Layout: u16 error code (LE), u8 error register (0x1001), 5 manufacturer bytes.
"""

from __future__ import annotations

import struct

from akdctl.protocol.errors import CodecError
from akdctl.protocol.record import Record

EMCY_SIZE = 8


class EmcyError(CodecError):
    """An emergency frame that does not decode or cannot be encoded."""


class Emergency(Record):
    """One emergency: CiA 301 error code, error register bits, manufacturer data."""

    __slots__ = ("error_code", "error_register", "data")

    def __init__(self, error_code: int, error_register: int, data: bytes = bytes(5)) -> None:
        self.error_code = error_code
        self.error_register = error_register
        self.data = data

    @property
    def is_reset(self) -> bool:
        """Error code 0x0000 announces "error reset / no error" (the fault was cleared)."""
        return self.error_code == 0


def encode_emcy(emcy: Emergency) -> bytes:
    """The 8 wire bytes; manufacturer data shorter than 5 bytes is zero-padded."""
    if not isinstance(emcy.error_code, int) or not 0 <= emcy.error_code <= 0xFFFF:
        raise EmcyError(f"EMCY error code {emcy.error_code!r} out of range 0..0xFFFF")
    if not isinstance(emcy.error_register, int) or not 0 <= emcy.error_register <= 0xFF:
        raise EmcyError(f"EMCY error register {emcy.error_register!r} out of range 0..0xFF")
    data = bytes(emcy.data)
    if len(data) > 5:
        raise EmcyError(f"EMCY manufacturer data of {len(data)} bytes exceeds 5")
    return struct.pack("<HB", emcy.error_code, emcy.error_register) + data.ljust(5, b"\x00")


def decode_emcy(data: bytes) -> Emergency:
    """Parse exactly 8 bytes (CAN DLC 8 / CoE service-1 payload)."""
    data = bytes(data)
    if len(data) != EMCY_SIZE:
        raise EmcyError(f"EMCY frame of {len(data)} bytes (expected 8)")
    code, register = struct.unpack_from("<HB", data)
    return Emergency(code, register, data[3:8])
