"""File access over EtherCAT (FoE, ETG.1000.6 5.9): the mailbox protocol the AKD names for firmware downloads.

Why a codec of its own: the AKD EtherCAT manual (4.6.3) says a new firmware "must be performed using File over
EtherCAT (FoE)", and the AKD's SII advertises FoE (mailbox protocols 0x0E); the simulated drive answers FoE
requests with these frames. Bytes in, objects out, no I/O.

Layout (mailbox type 4; little-endian)::

    0  u8   opcode: 1 read request, 2 write request, 3 data, 4 ack, 5 error, 6 busy
    1  u8   reserved (0)
    2  u32  password (read/write request), packet number (data, ack), error code (error),
            done u16 + entire u16 (busy)
    6  ...  file name (requests, no terminator), data (data), error text (error)

A transfer ends with a data packet shorter than the largest one the mailbox carries (an empty one when the
file fills the last packet exactly). Packet numbers count from 1; the ack of a write request is packet 0.
"""

from __future__ import annotations

import struct

from akdctl.protocol.errors import CodecError
from akdctl.protocol.record import Record

HEADER_SIZE = 6


class FoeError(CodecError):
    """A FoE frame that does not decode or cannot be encoded."""


class FoeOpcode:
    """The opcodes, as plain integer constants (an enum costs more to create at every start than it gives)."""

    READ = 1
    WRITE = 2
    DATA = 3
    ACK = 4
    ERROR = 5
    BUSY = 6


#: Every opcode a frame may carry.
OPCODES = frozenset((FoeOpcode.READ, FoeOpcode.WRITE, FoeOpcode.DATA, FoeOpcode.ACK, FoeOpcode.ERROR, FoeOpcode.BUSY))


#: FoE error codes (ETG.1000.6 table "FoE error codes"); their words are ``catalog.texts.FOE_ERROR_TEXTS``.
ERR_NOT_DEFINED = 0x8000
ERR_NOT_FOUND = 0x8001
ERR_ACCESS_DENIED = 0x8002
ERR_DISK_FULL = 0x8003
ERR_ILLEGAL = 0x8004
ERR_PACKET_NUMBER = 0x8005
ERR_EXISTS = 0x8006
ERR_NO_USER = 0x8007
ERR_BOOTSTRAP_ONLY = 0x8008
ERR_NOT_BOOTSTRAP = 0x8009
ERR_NO_RIGHTS = 0x800A
ERR_PROGRAM = 0x800B


class FoeFrame(Record):
    """One FoE frame: ``value`` is the password, packet number or error code; ``data`` the name, data or text."""

    __slots__ = ("opcode", "value", "data")

    def __init__(self, opcode: int, value: int = 0, data: bytes = b"") -> None:
        self.opcode = opcode
        self.value = value
        self.data = data

    @property
    def name(self) -> str:
        """The file name of a read/write request (latin-1, as the names travel as bytes)."""
        return self.data.decode("latin-1")


def encode_foe(frame: FoeFrame) -> bytes:
    if frame.opcode not in OPCODES:
        raise FoeError(f"FoE opcode {frame.opcode!r} is not 1..6")
    if not isinstance(frame.value, int) or not 0 <= frame.value <= 0xFFFFFFFF:
        raise FoeError(f"FoE value {frame.value!r} out of range 0..0xFFFFFFFF")
    return struct.pack("<BBI", frame.opcode, 0, frame.value) + bytes(frame.data)


def decode_foe(data: bytes) -> FoeFrame:
    data = bytes(data)
    if len(data) < HEADER_SIZE:
        raise FoeError(f"FoE frame of {len(data)} bytes is shorter than its {HEADER_SIZE}-byte header")
    opcode, _reserved, value = struct.unpack_from("<BBI", data, 0)
    if opcode not in OPCODES:
        raise FoeError(f"FoE opcode {opcode} is not 1..6")
    return FoeFrame(opcode, value, data[HEADER_SIZE:])


def read_request(name: str, password: int = 0) -> FoeFrame:
    return FoeFrame(FoeOpcode.READ, password, name.encode("latin-1"))


def write_request(name: str, password: int = 0) -> FoeFrame:
    return FoeFrame(FoeOpcode.WRITE, password, name.encode("latin-1"))


def data_packet(number: int, data: bytes) -> FoeFrame:
    return FoeFrame(FoeOpcode.DATA, number, bytes(data))


def ack(number: int) -> FoeFrame:
    return FoeFrame(FoeOpcode.ACK, number)


def error(code: int, text: str = "") -> FoeFrame:
    return FoeFrame(FoeOpcode.ERROR, code, text.encode("latin-1", "replace"))


def busy_progress(frame: FoeFrame) -> tuple[int, int]:
    """(done, entire) of a BUSY frame: the u32 holds ``u16 Done, u16 Entire`` (ETG.1000.6; reference A1)."""
    return frame.value & 0xFFFF, frame.value >> 16


def busy(done: int, entire: int, text: str = "") -> FoeFrame:
    return FoeFrame(FoeOpcode.BUSY, (done & 0xFFFF) | (entire & 0xFFFF) << 16, text.encode("latin-1", "replace"))


def packet_data_size(mailbox_size: int) -> int:
    """File bytes one DATA packet carries: the mailbox minus the 6-byte mailbox and 6-byte FoE headers (a
    shorter packet ends the file; reference A1: SOEM, IgH and SOES agree)."""
    return mailbox_size - 6 - HEADER_SIZE
