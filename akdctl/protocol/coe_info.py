"""CoE SDO information service (CoE service 8, ETG.1000.6): list the object dictionary, describe objects and entries.

Its replies may be fragmented, which :func:`fragment_info` / :class:`InfoReassembler` handle for both ends.

Why a module of its own: an SDO upload or download never needs it, and its eight message records cost a cold
start about 3 ms to create; :mod:`akdctl.protocol.coe` hands these names out on first use (``coe.SdoInfo`` and
``from akdctl.protocol.coe import SdoInfo`` keep working).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

from akdctl.protocol.coe import CoeError, _u

class SdoInfoOpcode(IntEnum):
    """SDO information header opcode (bits 0-6; bit 7 = "incomplete", more fragments follow)."""

    LIST_REQUEST = 1
    LIST_RESPONSE = 2
    OBJECT_REQUEST = 3
    OBJECT_RESPONSE = 4
    ENTRY_REQUEST = 5
    ENTRY_RESPONSE = 6
    ERROR = 7


SDO_INFO_HEADER_SIZE = 4
LIST_ALL = 1  # OD list type "all objects" (0 = list lengths, 2 RxPDO, 3 TxPDO, 4 backup, 5 settings)


@dataclass(frozen=True)
class SdoInfo:
    """One SDO information frame: opcode, its (fragment of) service data, fragment flags."""

    opcode: int
    data: bytes
    incomplete: bool = False
    fragments_left: int = 0


def encode_sdo_info(frame: SdoInfo) -> bytes:
    """The payload after the CoE header: opcode|incomplete, reserved, fragments left u16, data."""
    opcode = _u("SDO info opcode", frame.opcode, 7)
    left = _u("SDO info fragments left", frame.fragments_left, 16)
    return struct.pack("<BBH", opcode | (0x80 if frame.incomplete else 0), 0, left) + bytes(frame.data)


def decode_sdo_info(payload: bytes) -> SdoInfo:
    payload = bytes(payload)
    if len(payload) < SDO_INFO_HEADER_SIZE:
        raise CoeError(f"SDO information frame of {len(payload)} bytes is shorter than its 4-byte header")
    head, _reserved, left = struct.unpack_from("<BBH", payload)
    return SdoInfo(head & 0x7F, payload[SDO_INFO_HEADER_SIZE:], bool(head & 0x80), left)


def fragment_info(frame: SdoInfo, max_data: int) -> list[SdoInfo]:
    """Split a complete reply into fragments of at most ``max_data`` service-data bytes.

    The standard fragments the service data as a byte stream; fragments other
    than the last carry the "incomplete" flag and count the fragments still to come.
    """
    if max_data < 2:
        raise CoeError(f"SDO information fragments need room for at least 2 data bytes (got {max_data})")
    max_data -= max_data % 2  # keep 16-bit list entries whole, as slave stacks do
    data = bytes(frame.data)
    chunks = [data[i : i + max_data] for i in range(0, len(data), max_data)] or [b""]
    if len(chunks) - 1 > 0xFFFF:
        raise CoeError("SDO information reply needs more than 65535 fragments")
    return [
        SdoInfo(frame.opcode, chunk, incomplete=i < len(chunks) - 1, fragments_left=len(chunks) - 1 - i)
        for i, chunk in enumerate(chunks)
    ]


class InfoReassembler:
    """Collects fragments of one SDO information reply until the last one arrives."""

    def __init__(self) -> None:
        self.opcode: int | None = None
        self._parts: list[bytes] = []
        self._expect_left: int | None = None

    def add(self, frame: SdoInfo) -> SdoInfo | None:
        """Add a fragment; return the complete reply once the final fragment arrived."""
        if self.opcode is None:
            self.opcode = frame.opcode
        elif frame.opcode != self.opcode:
            raise CoeError(f"SDO information fragment with opcode {frame.opcode} inside a reply of {self.opcode}")
        if self._expect_left is not None and frame.fragments_left != self._expect_left:
            raise CoeError(
                f"SDO information fragment out of order: {frame.fragments_left} left, expected {self._expect_left}"
            )
        self._parts.append(bytes(frame.data))
        if frame.incomplete and frame.fragments_left > 0:
            self._expect_left = frame.fragments_left - 1
            return None
        return SdoInfo(self.opcode, b"".join(self._parts))


@dataclass(frozen=True)
class OdListRequest:
    list_type: int = LIST_ALL


@dataclass(frozen=True)
class OdListResponse:
    list_type: int
    indices: tuple[int, ...]


@dataclass(frozen=True)
class ObjectDescriptionRequest:
    index: int


@dataclass(frozen=True)
class ObjectDescription:
    """Object code 7 VAR, 8 ARRAY, 9 RECORD; ``data_type`` is a CANopen type code."""

    index: int
    data_type: int
    max_subindex: int
    object_code: int
    name: str


@dataclass(frozen=True)
class EntryDescriptionRequest:
    index: int
    subindex: int
    value_info: int = 0


@dataclass(frozen=True)
class EntryDescription:
    """``access`` bits: 0-2 read in PREOP/SAFEOP/OP, 3-5 write, 6 RxPDO, 7 TxPDO mappable.
    ``values`` holds the optional unit/default/min/max block that ``value_info`` bits 3-6 announce."""

    index: int
    subindex: int
    value_info: int
    data_type: int
    bit_length: int
    access: int
    name: str
    values: bytes = b""


@dataclass(frozen=True)
class SdoInfoError:
    """The slave refused an SDO information request (an SDO abort code)."""

    code: int


SdoInfoMessage = (
    OdListRequest
    | OdListResponse
    | ObjectDescriptionRequest
    | ObjectDescription
    | EntryDescriptionRequest
    | EntryDescription
    | SdoInfoError
)

VALUE_INFO_UNIT = 0x08
VALUE_INFO_DEFAULT = 0x10
VALUE_INFO_MIN = 0x20
VALUE_INFO_MAX = 0x40


def _values_size(value_info: int, bit_length: int) -> int:
    """Size of the optional value block: unit type (u32, as ETG.1000.6 defines it) and one
    value of the entry's size for each of default, minimum and maximum."""
    size = 4 if value_info & VALUE_INFO_UNIT else 0
    each = (bit_length + 7) // 8
    for bit in (VALUE_INFO_DEFAULT, VALUE_INFO_MIN, VALUE_INFO_MAX):
        if value_info & bit:
            size += each
    return size


def _name(data: bytes) -> str:
    """Names fill the rest of the frame; some stacks NUL-terminate or pad them."""
    return data.split(b"\x00", 1)[0].decode("utf-8", errors="replace")


def _encode_name(name: str) -> bytes:
    if "\x00" in name:
        raise CoeError("SDO information names cannot contain NUL")
    try:
        return name.encode("utf-8")
    except (UnicodeEncodeError, AttributeError) as exc:
        raise CoeError(f"SDO information name {name!r} cannot be encoded: {exc}") from None


def pack_info(msg: SdoInfoMessage) -> SdoInfo:
    """A complete (unfragmented) SDO information frame for a message."""
    if isinstance(msg, OdListRequest):
        return SdoInfo(SdoInfoOpcode.LIST_REQUEST, struct.pack("<H", _u("list type", msg.list_type, 16)))
    if isinstance(msg, OdListResponse):
        body = struct.pack("<H", _u("list type", msg.list_type, 16))
        body += b"".join(struct.pack("<H", _u("index", i, 16)) for i in msg.indices)
        return SdoInfo(SdoInfoOpcode.LIST_RESPONSE, body)
    if isinstance(msg, ObjectDescriptionRequest):
        return SdoInfo(SdoInfoOpcode.OBJECT_REQUEST, struct.pack("<H", _u("index", msg.index, 16)))
    if isinstance(msg, ObjectDescription):
        body = struct.pack(
            "<HHBB",
            _u("index", msg.index, 16),
            _u("data type", msg.data_type, 16),
            _u("max subindex", msg.max_subindex, 8),
            _u("object code", msg.object_code, 8),
        )
        return SdoInfo(SdoInfoOpcode.OBJECT_RESPONSE, body + _encode_name(msg.name))
    if isinstance(msg, EntryDescriptionRequest):
        body = struct.pack(
            "<HBB", _u("index", msg.index, 16), _u("subindex", msg.subindex, 8), _u("value info", msg.value_info, 8)
        )
        return SdoInfo(SdoInfoOpcode.ENTRY_REQUEST, body)
    if isinstance(msg, EntryDescription):
        values = bytes(msg.values)
        expected = _values_size(_u("value info", msg.value_info, 8), _u("bit length", msg.bit_length, 16))
        if len(values) != expected:
            raise CoeError(f"entry description value block of {len(values)} bytes, value info needs {expected}")
        body = struct.pack(
            "<HBBHHH",
            _u("index", msg.index, 16),
            _u("subindex", msg.subindex, 8),
            msg.value_info,
            _u("data type", msg.data_type, 16),
            msg.bit_length,
            _u("access", msg.access, 16),
        )
        return SdoInfo(SdoInfoOpcode.ENTRY_RESPONSE, body + values + _encode_name(msg.name))
    if isinstance(msg, SdoInfoError):
        return SdoInfo(SdoInfoOpcode.ERROR, struct.pack("<I", _u("abort code", msg.code, 32)))
    raise CoeError(f"not an SDO information message: {type(msg).__name__}")


def unpack_info(frame: SdoInfo) -> SdoInfoMessage:
    """Parse a complete (reassembled) SDO information frame."""
    data = bytes(frame.data)
    op = frame.opcode

    def need(n: int, what: str) -> None:
        if len(data) < n:
            raise CoeError(f"SDO information {what} of {len(data)} bytes is shorter than {n}")

    if op == SdoInfoOpcode.LIST_REQUEST:
        need(2, "list request")
        return OdListRequest(struct.unpack_from("<H", data)[0])
    if op == SdoInfoOpcode.LIST_RESPONSE:
        need(2, "list response")
        if len(data) % 2:
            raise CoeError(f"SDO information list response of odd length {len(data)}")
        words = struct.unpack(f"<{len(data) // 2}H", data)
        return OdListResponse(words[0], tuple(words[1:]))
    if op == SdoInfoOpcode.OBJECT_REQUEST:
        need(2, "object description request")
        return ObjectDescriptionRequest(struct.unpack_from("<H", data)[0])
    if op == SdoInfoOpcode.OBJECT_RESPONSE:
        need(6, "object description")
        index, data_type, max_sub, code = struct.unpack_from("<HHBB", data)
        return ObjectDescription(index, data_type, max_sub, code, _name(data[6:]))
    if op == SdoInfoOpcode.ENTRY_REQUEST:
        need(4, "entry description request")
        index, subindex, value_info = struct.unpack_from("<HBB", data)
        return EntryDescriptionRequest(index, subindex, value_info)
    if op == SdoInfoOpcode.ENTRY_RESPONSE:
        need(10, "entry description")
        index, subindex, value_info, data_type, bit_length, access = struct.unpack_from("<HBBHHH", data)
        size = _values_size(value_info, bit_length)
        need(10 + size, "entry description with values")
        return EntryDescription(
            index, subindex, value_info, data_type, bit_length, access, _name(data[10 + size :]), data[10 : 10 + size]
        )
    if op == SdoInfoOpcode.ERROR:
        need(4, "error")
        return SdoInfoError(struct.unpack_from("<I", data)[0])
    raise CoeError(f"unknown SDO information opcode {op}")
