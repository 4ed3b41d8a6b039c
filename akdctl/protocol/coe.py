"""CoE (CANopen over EtherCAT, ETG.1000.6): CoE header, SDO frames, SDO information.

A CoE mailbox's data is a 2-byte CoE header (bits 0-8 number, bits 12-15
service) followed by the service payload. SDO payloads are the CiA 301 8-byte
frames with two EtherCAT twists that SOEM and the Beckhoff slave stack share:

* a *normal* (non-expedited) initiate carries the complete size (u32) and then
  as much data as the mailbox holds, so most objects move in one round trip;
* segments are not limited to 7 bytes: a segment carries ``1 + len(data)``
  bytes, padded to the CiA 301 minimum of 8 with the unused count in the
  command byte only when it is that short.

The SDO command specifiers overlap between directions (0x60 is a client's
"upload segment, toggle 0" and a server's "download response"), so decoding
needs to know who sent the frame: ``decode_sdo(payload, from_server=...)``.

The SDO information service (CoE service 8) lists the object dictionary and
describes objects and entries; its replies may be fragmented, which
:func:`fragment_info` / :class:`InfoReassembler` handle for both ends.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

from akdctl.protocol.errors import CodecError


class CoeError(CodecError):
    """A CoE header, SDO or SDO-information payload that does not decode or encode."""


class CoeService(IntEnum):
    """CoE header service field (bits 12-15)."""

    EMERGENCY = 1
    SDO_REQUEST = 2
    SDO_RESPONSE = 3
    TXPDO = 4
    RXPDO = 5
    TXPDO_RR = 6
    RXPDO_RR = 7
    SDO_INFO = 8


COE_HEADER_SIZE = 2
SDO_SIZE = 8  # a CiA 301 SDO frame; CoE frames are at least this long
# Mailbox bytes an SDO initiate spends before its data: CoE header 2 + command/index/sub 4 + size 4.
NORMAL_OVERHEAD = COE_HEADER_SIZE + SDO_SIZE
# ... and a segment: CoE header 2 + command 1.
SEGMENT_OVERHEAD = COE_HEADER_SIZE + 1


def encode_coe(service: int, payload: bytes, number: int = 0) -> bytes:
    """CoE header (number | service << 12) + payload."""
    if not isinstance(service, int) or not 0 <= service <= 15:
        raise CoeError(f"CoE service {service!r} out of range 0..15")
    if not isinstance(number, int) or not 0 <= number <= 0x1FF:
        raise CoeError(f"CoE number {number!r} out of range 0..511")
    return struct.pack("<H", number | service << 12) + bytes(payload)


_UPLOAD_REQUEST = struct.Struct("<HBHB4x")
_SDO_REQUEST_HEADER = CoeService.SDO_REQUEST << 12


def upload_request(index: int, subindex: int) -> bytes:
    """CoE data of an SDO upload initiate (CoE header + 8-byte SDO), the client's most frequent request,
    packed in one step (``encode_coe(SDO_REQUEST, encode_sdo(SdoUploadInitiate(index, subindex)))``)."""
    try:
        return _UPLOAD_REQUEST.pack(_SDO_REQUEST_HEADER, 0x40, index, subindex)
    except struct.error:
        raise CoeError(f"SDO index {index!r} / subindex {subindex!r} out of range") from None


def decode_coe(data: bytes) -> tuple[CoeService, int, bytes]:
    """Split a CoE mailbox's data into (service, number, payload); unknown services raise."""
    data = bytes(data)
    if len(data) < COE_HEADER_SIZE:
        raise CoeError(f"CoE data of {len(data)} bytes is shorter than its 2-byte header")
    (header,) = struct.unpack_from("<H", data)
    raw = header >> 12
    try:
        service = CoeService(raw)
    except ValueError:
        raise CoeError(f"unknown CoE service {raw}") from None
    return service, header & 0x1FF, data[COE_HEADER_SIZE:]


# --- SDO abort codes -----------------------------------------------------------------------------

ABORT_TOGGLE = 0x05030000
ABORT_TIMEOUT = 0x05040000
ABORT_UNKNOWN_COMMAND = 0x05040001
ABORT_OUT_OF_MEMORY = 0x05040005
ABORT_UNSUPPORTED_ACCESS = 0x06010000
ABORT_LENGTH_EXCEEDS_MAILBOX = 0x06010005
ABORT_NO_OBJECT = 0x06020000
ABORT_LENGTH_MISMATCH = 0x06070010
ABORT_NO_SUBINDEX = 0x06090011
ABORT_GENERAL = 0x08000000


# --- SDO messages ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class SdoDownloadInitiate:
    """Client: start a write. Expedited carries 1..4 bytes in the frame; normal carries
    the total ``size`` then the first ``data`` bytes (the rest follows in segments)."""

    index: int
    subindex: int
    data: bytes
    size: int | None
    expedited: bool
    complete_access: bool = False


@dataclass(frozen=True)
class SdoDownloadResponse:
    """Server: the initiate download was accepted."""

    index: int
    subindex: int


@dataclass(frozen=True)
class SdoDownloadSegment:
    """Client: the next part of a segmented write."""

    toggle: int
    data: bytes
    last: bool


@dataclass(frozen=True)
class SdoDownloadSegmentResponse:
    """Server: the segment with this toggle was accepted."""

    toggle: int


@dataclass(frozen=True)
class SdoUploadInitiate:
    """Client: start a read."""

    index: int
    subindex: int
    complete_access: bool = False


@dataclass(frozen=True)
class SdoUploadResponse:
    """Server: the value (expedited, ``size`` = 1..4 or None) or its total ``size`` and
    the first ``data`` bytes (normal; segments follow when ``len(data) < size``)."""

    index: int
    subindex: int
    data: bytes
    size: int | None
    expedited: bool


@dataclass(frozen=True)
class SdoUploadSegment:
    """Client: request the next segment of a segmented read."""

    toggle: int


@dataclass(frozen=True)
class SdoUploadSegmentResponse:
    """Server: the next part of a segmented read."""

    toggle: int
    data: bytes
    last: bool


@dataclass(frozen=True)
class SdoAbort:
    """Either side: abort the transfer of ``index:subindex`` with an abort code."""

    index: int
    subindex: int
    code: int


SdoMessage = (
    SdoDownloadInitiate
    | SdoDownloadResponse
    | SdoDownloadSegment
    | SdoDownloadSegmentResponse
    | SdoUploadInitiate
    | SdoUploadResponse
    | SdoUploadSegment
    | SdoUploadSegmentResponse
    | SdoAbort
)

SERVER_MESSAGES = (SdoDownloadResponse, SdoDownloadSegmentResponse, SdoUploadResponse, SdoUploadSegmentResponse)
CLIENT_MESSAGES = (SdoDownloadInitiate, SdoDownloadSegment, SdoUploadInitiate, SdoUploadSegment)

_TOGGLE = 0x10
_COMPLETE_ACCESS = 0x10


def _u(name: str, value: object, bits: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 1 << bits:
        raise CoeError(f"SDO {name} {value!r} out of range 0..{(1 << bits) - 1}")
    return value


def _toggle(value: object) -> int:
    if value not in (0, 1) or not isinstance(value, int):
        raise CoeError(f"SDO toggle {value!r} must be 0 or 1")
    return int(value)


def _addr(msg: SdoDownloadInitiate | SdoDownloadResponse | SdoUploadInitiate | SdoUploadResponse | SdoAbort) -> bytes:
    return struct.pack("<HB", _u("index", msg.index, 16), _u("subindex", msg.subindex, 8))


def _initiate(base: int, msg: SdoDownloadInitiate | SdoUploadResponse, extra: int) -> bytes:
    """Shared layout of initiate download (base 0x20) and initiate upload response (0x40)."""
    data = bytes(msg.data)
    if msg.expedited:
        if msg.size is None:
            if len(data) != 4:
                raise CoeError("an expedited SDO without size indication carries exactly 4 bytes")
            return bytes([base | extra | 0x02]) + _addr(msg) + data
        if not 1 <= msg.size <= 4 or msg.size != len(data):
            raise CoeError(f"expedited SDO size {msg.size} must equal the data length 1..4 ({len(data)})")
        command = base | extra | (4 - msg.size) << 2 | 0x03
        return bytes([command]) + _addr(msg) + data.ljust(4, b"\x00")
    if msg.size is None:
        return bytes([base | extra]) + _addr(msg) + bytes(4) + data
    size = _u("size", msg.size, 32)
    if size < len(data):
        raise CoeError(f"SDO size {size} is smaller than the {len(data)} data bytes carried")
    return bytes([base | extra | 0x01]) + _addr(msg) + struct.pack("<I", size) + data


def _segment(base: int, toggle: object, data: bytes, last: bool) -> bytes:
    data = bytes(data)
    command = base | _toggle(toggle) << 4 | (0x01 if last else 0)
    if len(data) < 7:
        command |= (7 - len(data)) << 1
        return bytes([command]) + data.ljust(7, b"\x00")
    return bytes([command]) + data


def encode_sdo(msg: SdoMessage) -> bytes:
    """The SDO payload (after the CoE header) of any SDO message."""
    if isinstance(msg, SdoDownloadInitiate):
        return _initiate(0x20, msg, _COMPLETE_ACCESS if msg.complete_access else 0)
    if isinstance(msg, SdoUploadResponse):
        return _initiate(0x40, msg, 0)
    if isinstance(msg, SdoDownloadResponse):
        return b"\x60" + _addr(msg) + bytes(4)
    if isinstance(msg, SdoUploadInitiate):
        return bytes([0x40 | (_COMPLETE_ACCESS if msg.complete_access else 0)]) + _addr(msg) + bytes(4)
    if isinstance(msg, SdoDownloadSegment):
        return _segment(0x00, msg.toggle, msg.data, msg.last)
    if isinstance(msg, SdoUploadSegmentResponse):
        return _segment(0x00, msg.toggle, msg.data, msg.last)
    if isinstance(msg, SdoDownloadSegmentResponse):
        return bytes([0x20 | _toggle(msg.toggle) << 4]) + bytes(7)
    if isinstance(msg, SdoUploadSegment):
        return bytes([0x60 | _toggle(msg.toggle) << 4]) + bytes(7)
    if isinstance(msg, SdoAbort):
        return b"\x80" + _addr(msg) + struct.pack("<I", _u("abort code", msg.code, 32))
    raise CoeError(f"not an SDO message: {type(msg).__name__}")


def _decode_initiate(payload: bytes) -> tuple[int, int, bytes, int | None, bool]:
    command = payload[0]
    index, subindex = struct.unpack_from("<HB", payload, 1)
    expedited = bool(command & 0x02)
    size_indicated = bool(command & 0x01)
    if expedited:
        if size_indicated:
            size = 4 - (command >> 2 & 0x03)
            return index, subindex, payload[4 : 4 + size], size, True
        return index, subindex, payload[4:8], None, True
    data = payload[8:]
    if not size_indicated:
        return index, subindex, data, None, False
    (size,) = struct.unpack_from("<I", payload, 4)
    return index, subindex, data[:size], size, False


def _decode_segment(payload: bytes) -> tuple[int, bytes, bool]:
    command = payload[0]
    data = payload[1:]
    if len(payload) == SDO_SIZE:
        data = data[: 7 - (command >> 1 & 0x07)]
    return command >> 4 & 0x01, data, bool(command & 0x01)


def decode_sdo(payload: bytes, *, from_server: bool) -> SdoMessage:
    """Parse an SDO payload; ``from_server`` resolves the overlapping command specifiers."""
    payload = bytes(payload)
    if len(payload) < SDO_SIZE:
        raise CoeError(f"SDO frame of {len(payload)} bytes is shorter than 8")
    command = payload[0]
    spec = command >> 5
    if spec == 4:
        index, subindex, code = struct.unpack_from("<HBI", payload, 1)
        return SdoAbort(index, subindex, code)
    if from_server:
        if spec == 0:
            toggle, data, last = _decode_segment(payload)
            return SdoUploadSegmentResponse(toggle, data, last)
        if spec == 1:
            return SdoDownloadSegmentResponse(command >> 4 & 0x01)
        if spec == 2:
            index, subindex, data, size, expedited = _decode_initiate(payload)
            return SdoUploadResponse(index, subindex, data, size, expedited)
        if spec == 3:
            index, subindex = struct.unpack_from("<HB", payload, 1)
            return SdoDownloadResponse(index, subindex)
        raise CoeError(f"unknown SDO server command specifier in command byte 0x{command:02X}")
    if spec == 0:
        toggle, data, last = _decode_segment(payload)
        return SdoDownloadSegment(toggle, data, last)
    if spec == 1:
        index, subindex, data, size, expedited = _decode_initiate(payload)
        return SdoDownloadInitiate(index, subindex, data, size, expedited, bool(command & _COMPLETE_ACCESS))
    if spec == 2:
        index, subindex = struct.unpack_from("<HB", payload, 1)
        return SdoUploadInitiate(index, subindex, bool(command & _COMPLETE_ACCESS))
    if spec == 3:
        return SdoUploadSegment(command >> 4 & 0x01)
    raise CoeError(f"unknown SDO client command specifier in command byte 0x{command:02X}")


# --- SDO information (CoE service 8) -------------------------------------------------------------


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
