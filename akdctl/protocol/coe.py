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
describes objects and entries: :mod:`akdctl.protocol.coe_info`, which its users import
themselves where they need it (so an upload never loads it); no name of it is re-exported here.
"""

from __future__ import annotations

import struct

from akdctl.protocol.errors import CodecError
from akdctl.protocol.record import Record


class CoeError(CodecError):
    """A CoE header, SDO or SDO-information payload that does not decode or encode."""


class CoeService:
    """CoE header service field (bits 12-15), as plain integer constants (an enum costs more to create at every
    start than it gives)."""

    EMERGENCY = 1
    SDO_REQUEST = 2
    SDO_RESPONSE = 3
    TXPDO = 4
    RXPDO = 5
    TXPDO_RR = 6
    RXPDO_RR = 7
    SDO_INFO = 8


#: Every service a CoE header may name.
SERVICES = frozenset(value for name, value in vars(CoeService).items() if name.isupper())

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


def decode_coe(data: bytes) -> tuple[int, int, bytes]:
    """Split a CoE mailbox's data into (service, number, payload); unknown services raise."""
    data = bytes(data)
    if len(data) < COE_HEADER_SIZE:
        raise CoeError(f"CoE data of {len(data)} bytes is shorter than its 2-byte header")
    (header,) = struct.unpack_from("<H", data)
    service = header >> 12
    if service not in SERVICES:
        raise CoeError(f"unknown CoE service {service}")
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


class SdoDownloadInitiate(Record):
    """Client: start a write. Expedited carries 1..4 bytes in the frame; normal carries
    the total ``size`` then the first ``data`` bytes (the rest follows in segments)."""

    __slots__ = ("index", "subindex", "data", "size", "expedited", "complete_access")

    def __init__(self, index: int, subindex: int, data: bytes, size: int | None, expedited: bool,
                 complete_access: bool = False) -> None:
        self.index = index
        self.subindex = subindex
        self.data = data
        self.size = size
        self.expedited = expedited
        self.complete_access = complete_access


class SdoDownloadResponse(Record):
    """Server: the initiate download was accepted."""

    __slots__ = ("index", "subindex")

    def __init__(self, index: int, subindex: int) -> None:
        self.index = index
        self.subindex = subindex


class SdoDownloadSegment(Record):
    """Client: the next part of a segmented write."""

    __slots__ = ("toggle", "data", "last")

    def __init__(self, toggle: int, data: bytes, last: bool) -> None:
        self.toggle = toggle
        self.data = data
        self.last = last


class SdoDownloadSegmentResponse(Record):
    """Server: the segment with this toggle was accepted."""

    __slots__ = ("toggle",)

    def __init__(self, toggle: int) -> None:
        self.toggle = toggle


class SdoUploadInitiate(Record):
    """Client: start a read."""

    __slots__ = ("index", "subindex", "complete_access")

    def __init__(self, index: int, subindex: int, complete_access: bool = False) -> None:
        self.index = index
        self.subindex = subindex
        self.complete_access = complete_access


class SdoUploadResponse(Record):
    """Server: the value (expedited, ``size`` = 1..4 or None) or its total ``size`` and
    the first ``data`` bytes (normal; segments follow when ``len(data) < size``)."""

    __slots__ = ("index", "subindex", "data", "size", "expedited")

    def __init__(self, index: int, subindex: int, data: bytes, size: int | None, expedited: bool) -> None:
        self.index = index
        self.subindex = subindex
        self.data = data
        self.size = size
        self.expedited = expedited


class SdoUploadSegment(Record):
    """Client: request the next segment of a segmented read."""

    __slots__ = ("toggle",)

    def __init__(self, toggle: int) -> None:
        self.toggle = toggle


class SdoUploadSegmentResponse(Record):
    """Server: the next part of a segmented read."""

    __slots__ = ("toggle", "data", "last")

    def __init__(self, toggle: int, data: bytes, last: bool) -> None:
        self.toggle = toggle
        self.data = data
        self.last = last


class SdoAbort(Record):
    """Either side: abort the transfer of ``index:subindex`` with an abort code."""

    __slots__ = ("index", "subindex", "code")

    def __init__(self, index: int, subindex: int, code: int) -> None:
        self.index = index
        self.subindex = subindex
        self.code = code


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


# --- the server's fast path, both layouts -----------------------------------------------------------------------
# An upload initiate is the request every poll makes; the simulated drive's SDO server answers it without message
# objects. The layouts it packs live here, beside decode_sdo/encode_sdo which they must equal
# (tests/test_sdo_server.py holds both paths byte-equal).

#: The command byte of an upload initiate request without complete access.
UPLOAD_INITIATE_COMMAND = 0x40
_INDEX = struct.Struct("<HB")
_EXPEDITED_UPLOAD = struct.Struct("<BHB4s")  # command, index, subindex, 4 data bytes (struct pads a shorter value)
_COE_HEADER = struct.Struct("<H")


def coe_header(service: int) -> bytes:
    """The 2-byte CoE header of a reply (number 0), without :func:`encode_coe`'s checks: ``service`` is a
    :class:`CoeService` member."""
    return _COE_HEADER.pack(service << 12)


def sdo_address(payload: bytes) -> tuple[int, int]:
    """(index, subindex) of an initiate SDO (bytes 1..3; the caller checked the length)."""
    index, subindex = _INDEX.unpack_from(payload, 1)
    return index, subindex


def pack_expedited_upload_response(index: int, subindex: int, value: bytes) -> bytes:
    """The SDO of an expedited upload response carrying 1..4 bytes: what
    ``encode_sdo(SdoUploadResponse(index, subindex, value, expedited=True))`` writes."""
    return _EXPEDITED_UPLOAD.pack(0x43 | (4 - len(value)) << 2, index, subindex, value)



# --- a client's fast path, both layouts -------------------------------------------------------------------------
# The same poll from the client's side: a CANopen client sends the 8-byte upload initiate and, for an object of up to
# four bytes, gets the value back in one expedited response. These pack and read those two layouts without message
# objects; tests/test_trace_off.py holds them equal to encode_sdo/decode_sdo.

_UPLOAD_INITIATE = struct.Struct("<BHB4x")
_UPLOAD_REPLY_HEAD = struct.Struct("<BHB")


def pack_upload_initiate(index: int, subindex: int) -> bytes:
    """The 8-byte SDO of an upload initiate: ``encode_sdo(SdoUploadInitiate(index, subindex))``."""
    try:
        return _UPLOAD_INITIATE.pack(UPLOAD_INITIATE_COMMAND, index, subindex)
    except struct.error:
        raise CoeError(f"SDO index {index!r} / subindex {subindex!r} out of range") from None


def expedited_upload_value(payload: bytes, index: int, subindex: int) -> bytes | None:
    """The value of ``payload`` if it is an expedited upload response for ``index:subindex`` -- what
    ``decode_sdo(payload, from_server=True).data`` gives for it -- else None (the caller then takes the general
    decoder, which also reads every other reply)."""
    if len(payload) < SDO_SIZE:
        return None
    command, got_index, got_subindex = _UPLOAD_REPLY_HEAD.unpack_from(payload)
    if command & 0xE2 != 0x42 or got_index != index or got_subindex != subindex:
        return None
    if command & 0x01:
        return bytes(payload[4:8 - (command >> 2 & 0x03)])
    return bytes(payload[4:8])


# --- the whole upload mailbox in one step (the simulated drive's SDO server, issue 29) --------------------------
# The poll's upload initiate reaches the server as one 16-byte mailbox: mailbox header (6), CoE header (2), SDO (8).
# One unpack reads what the general path (mailbox.split, decode_coe, sdo_address) reads of it and one pack writes
# the expedited answer mailbox (mailbox.pack of coe_header + pack_expedited_upload_response): the layouts are the
# codecs' (this module's and mailbox.py's header), held equal to the general encoders by tests/test_fast_paths.py.

_MAILBOX_TYPE_COE = 3  # mailbox.MailboxType.COE (coe does not import mailbox; the test holds them equal)
_UPLOAD_MAILBOX_SIZE = 16
_UPLOAD_MAILBOX = struct.Struct("<HHBBHBHB")  # length, address, channel|priority, type|counter, CoE, command, index, sub
_EXPEDITED_MAILBOX = struct.Struct("<HHBBHBHB4s")


def plain_upload_initiate(mailbox: bytes) -> tuple[int, int, int, int] | None:
    """(address, counter, index, subindex) when ``mailbox`` is exactly an SDO upload initiate request of CoE on
    channel 0 (16 bytes, length 10, no complete access); None for anything else, which the general path decodes."""
    if len(mailbox) != _UPLOAD_MAILBOX_SIZE:
        return None
    length, address, channel, type_counter, header, command, index, subindex = _UPLOAD_MAILBOX.unpack_from(mailbox)
    if (length != _UPLOAD_MAILBOX_SIZE - 6 or channel & 0x3F or type_counter & 0x0F != _MAILBOX_TYPE_COE
            or header >> 12 != CoeService.SDO_REQUEST or command != UPLOAD_INITIATE_COMMAND):
        return None
    return address, (type_counter >> 4) & 0x07, index, subindex


def pack_expedited_upload_mailbox(address: int, counter: int, index: int, subindex: int, value: bytes) -> bytes:
    """The whole answer mailbox of an expedited upload (1..4 bytes, channel 0, CoE number 0): what
    ``mailbox.pack(COE, coe_header(SDO_RESPONSE) + pack_expedited_upload_response(...), address, counter)`` writes."""
    return _EXPEDITED_MAILBOX.pack(_UPLOAD_MAILBOX_SIZE - 6, address, 0, _MAILBOX_TYPE_COE | counter << 4,
                                   CoeService.SDO_RESPONSE << 12, 0x43 | (4 - len(value)) << 2, index, subindex, value)


def expedited_upload_templates(address: int, counter: int, index: int, subindex: int
                               ) -> dict[int, tuple[bytes, bytes]]:
    """The answer mailbox of an expedited upload cut around its value, by the value's length: ``n`` (1..4) gives
    ``(head, tail)`` with ``head + value + tail == pack_expedited_upload_mailbox(address, counter, index,
    subindex, value)`` for every ``value`` of ``n`` bytes (no other length is expedited). Why: a server that
    answers the same request again (a poll) joins the value between two byte strings it made once, instead of a
    pack per answer; the layout stays this module's (the cuts are made from its pack)."""
    out = {}
    for size in range(1, 5):
        whole = pack_expedited_upload_mailbox(address, counter, index, subindex, bytes(size))
        out[size] = (whole[:_UPLOAD_MAILBOX_SIZE - 4], whole[_UPLOAD_MAILBOX_SIZE - 4 + size:])
    return out


def is_upload_request(coe_data: bytes) -> bool:
    """Whether CoE data (header + SDO) is a client's SDO upload request, initiate or segment: a read the
    simulated slave answers from memory on the frame thread (:mod:`akdctl.sim.face_ethercat_raw`)."""
    return (len(coe_data) >= COE_HEADER_SIZE + 1 and coe_data[1] >> 4 == CoeService.SDO_REQUEST
            and coe_data[COE_HEADER_SIZE] >> 5 in (2, 3))  # ccs 2 upload initiate, 3 upload segment (CiA 301)


# --- the client's upload in one step (the CoE SDO channel's fast path, issue 29) -----------------------------------
# The answer to a poll is one 16-byte mailbox: mailbox header (6), CoE header (2), the expedited SDO (8). One unpack
# reads what mailbox.split + the CoE header + expedited_upload_value read of it; anything else (another length, a
# normal or segmented answer, an abort, an emergency, CoE service 2) is left to the general path
# (tests/test_sdo_fast_path_parity.py holds both equal).

_EXPEDITED_REPLY = struct.Struct("<HHBBHBHB")  # length, address, channel|priority, type|counter, CoE, command, index, sub


def expedited_upload_reply(mailbox: bytes, index: int, subindex: int) -> tuple[int, bytes] | None:
    """(mailbox counter, value) when ``mailbox`` is exactly a CoE SDO response (service 3) carrying the expedited
    upload of ``index:subindex``; None for anything else (the caller's general path decodes it)."""
    if len(mailbox) < _UPLOAD_MAILBOX_SIZE:
        return None
    length, _address, _channel, type_counter, header, command, got_index, got_subindex = \
        _EXPEDITED_REPLY.unpack_from(mailbox)
    if (length != _UPLOAD_MAILBOX_SIZE - 6 or type_counter & 0x0F != _MAILBOX_TYPE_COE
            or header >> 12 != CoeService.SDO_RESPONSE or command & 0xE2 != 0x42
            or got_index != index or got_subindex != subindex):
        return None
    value = mailbox[12:_UPLOAD_MAILBOX_SIZE - (command >> 2 & 0x03) if command & 0x01 else _UPLOAD_MAILBOX_SIZE]
    return (type_counter >> 4) & 0x07, value if value.__class__ is bytes else bytes(value)


def expedited_upload_pattern(address: int, index: int, subindex: int) -> tuple[bytes, bytes, int]:
    """What :func:`expedited_upload_reply` checks of a reply from ``address``, as (bytes, mask, value offset): the
    first 14 bytes of an accepted mailbox, ANDed with ``mask``, equal ``bytes`` (length 10, CoE, service 3, an
    expedited upload command, the index and subindex, and the address); the counter, the channel, the reserved bit,
    the CoE number, the size bits and the value are masked out. For a client that checks a whole frame in one step
    (:mod:`akdctl.protocol.gateway_sdo`): the layout stays this module's."""
    return (_EXPEDITED_REPLY.pack(_UPLOAD_MAILBOX_SIZE - 6, address, 0, _MAILBOX_TYPE_COE,
                                  CoeService.SDO_RESPONSE << 12, 0x42, index, subindex),
            _EXPEDITED_REPLY.pack(0xFFFF, 0xFFFF, 0, 0x0F, 0xF000, 0xE2, 0xFFFF, 0xFF),
            _EXPEDITED_REPLY.size)
