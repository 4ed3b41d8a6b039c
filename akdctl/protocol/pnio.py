"""PROFINET IO context management (CM) bodies carried by DCE/RPC: NDR arguments,
the blocks a Device Access AR needs, PNIOStatus in words, and the I&M0 record.

akdctl only ever needs a small part of PNIO: connect a Device Access AR, write
and read record 47 (the PROFIdrive parameter channel), read I&M0 implicitly,
and release. Each block here is a frozen dataclass with ``encode()`` and a
``decode(data)`` classmethod. Block contents are always big-endian; only the
NDR array header around them follows the DCE/RPC data representation.

Pure codec: only :class:`PnioError` escapes.
"""

from __future__ import annotations

import struct
import uuid
from dataclasses import dataclass

from akdctl.protocol.errors import CodecError

PNIO_PORT = 34964

OP_CONNECT = 0
OP_RELEASE = 1
OP_READ = 2
OP_WRITE = 3
OP_CONTROL = 4
OP_READ_IMPLICIT = 5
OPNUM_NAMES = {OP_CONNECT: "Connect", OP_RELEASE: "Release", OP_READ: "Read", OP_WRITE: "Write",
               OP_CONTROL: "Control", OP_READ_IMPLICIT: "ReadImplicit"}

DEVICE_INTERFACE = uuid.UUID("dea00001-6c97-11d1-8271-00a02442df7d")
CONTROLLER_INTERFACE = uuid.UUID("dea00002-6c97-11d1-8271-00a02442df7d")
SUPERVISOR_INTERFACE = uuid.UUID("dea00003-6c97-11d1-8271-00a02442df7d")
PARAMETER_SERVER_INTERFACE = uuid.UUID("dea00004-6c97-11d1-8271-00a02442df7d")
NIL_UUID = uuid.UUID(int=0)

BT_WRITE_REQ = 0x0008
BT_READ_REQ = 0x0009
BT_IM0 = 0x0020
BT_AR_REQ = 0x0101
BT_RELEASE_REQ = 0x0114
BT_WRITE_RES = 0x8008
BT_READ_RES = 0x8009
BT_AR_RES = 0x8101
BT_RELEASE_RES = 0x8114

AR_TYPE_IOCAR = 0x0001
AR_TYPE_IOSAR = 0x0006          # supervisor AR; with DeviceAccess set: "Device Access AR"
AR_TYPE_NAMES = {0x0001: "IOCARSingle", 0x0006: "IOSAR (supervisor / device access)",
                 0x0010: "IOCARSingle RT_CLASS_3", 0x0020: "IOCARSR"}
AR_PROP_STATE_ACTIVE = 0x00000001
AR_PROP_PRM_SERVER_CM_INITIATOR = 0x00000010
AR_PROP_DEVICE_ACCESS = 0x00000100
DEVICE_ACCESS_PROPERTIES = AR_PROP_STATE_ACTIVE | AR_PROP_PRM_SERVER_CM_INITIATOR | AR_PROP_DEVICE_ACCESS

CONTROL_RELEASE = 0x0004
CONTROL_DONE = 0x0008

INDEX_PROFIDRIVE = 0x002F        # record 47, the AKD's documented parameter channel
INDEX_PROFIDRIVE_ALT = 0xB02E    # same channel through the profile-specific index
INDEX_IM0 = 0xAFF0
INDEX_KEEPALIVE = 0xFBFF
API_PROFIDRIVE = 0x3A00

BLOCK_HEADER = struct.Struct(">HHBB")
NDR_REQUEST = struct.Struct("IIIII")     # byte order prefix added per drep
NDR_RESPONSE = struct.Struct("IIII")


class PnioError(CodecError):
    """Bytes that are not a valid PNIO CM body or block."""


def object_uuid(vendor_id: int, device_id: int, instance: int = 1) -> uuid.UUID:
    """The PNIO object UUID a device answers to: DEA00000-6C97-11D1-8271-{inst}{dev}{vendor}."""
    for name, value in (("vendor", vendor_id), ("device", device_id), ("instance", instance)):
        if not 0 <= value <= 0xFFFF:
            raise PnioError(f"{name} id {value} does not fit 16 bits")
    return uuid.UUID(f"dea00000-6c97-11d1-8271-{instance:04x}{device_id:04x}{vendor_id:04x}")


# ---------------------------------------------------------------- PNIOStatus

#: ``DB 81 01 04``: the device does not accept this AR type.
AR_TYPE_REFUSED = (0xDB, 0x81, 0x01, 0x04)
AR_PROPERTIES_REFUSED = (0xDB, 0x81, 0x01, 0x09)
#: ``DB 81 40 04``: Connect refused, CMRPC "out of AR resources" (every AR the device offers is held).
OUT_OF_AR_RESOURCES = (0xDB, 0x81, 0x40, 0x04)


@dataclass(frozen=True)
class PnioStatus:
    """PNIOStatus: ErrorCode, ErrorDecode, ErrorCode1, ErrorCode2 (a byte sequence, no byte order).

    Codes only: the words are :func:`akdctl.catalog.texts.pnio_status_text` (``*status.encode()``)."""

    code: int = 0
    decode: int = 0
    code1: int = 0
    code2: int = 0

    @property
    def ok(self) -> bool:
        return self.code == 0 and self.decode == 0 and self.code1 == 0 and self.code2 == 0

    @property
    def busy(self) -> bool:
        """The device asks us to come back later (0xB5 state conflict, 0xC2/0xA7 busy)."""
        return self.decode == 0x80 and self.code1 in (0xB5, 0xC2, 0xA7)

    def encode(self) -> bytes:
        return bytes((self.code, self.decode, self.code1, self.code2))

    @classmethod
    def decode_bytes(cls, data: bytes) -> "PnioStatus":
        if len(data) != 4:
            raise PnioError(f"PNIOStatus needs 4 bytes, got {len(data)}")
        if data == b"\0\0\0\0" and cls is PnioStatus:
            return OK  # the usual answer: one shared object
        return cls(*data)

    @property
    def value(self) -> int:
        return int.from_bytes(self.encode(), "big")

    def hex(self) -> str:
        return self.encode().hex(" ").upper()


OK = PnioStatus()


def rw_error(write: bool, code1: int, code2: int = 0) -> PnioStatus:
    """A record-layer (PNIORW) refusal for a read or write."""
    return PnioStatus(0xDF if write else 0xDE, 0x80, code1, code2)


# ---------------------------------------------------------------- NDR arguments

def _order(little: bool) -> str:
    return "<" if little else ">"


_NDR_REQ = {False: struct.Struct(">IIIII"), True: struct.Struct("<IIIII")}
_NDR_RES = {False: struct.Struct(">IIII"), True: struct.Struct("<IIII")}


def encode_request_args(blocks: bytes, args_maximum: int = 1024, little: bool = False) -> bytes:
    """NDR request: ArgsMaximum, ArgsLength, MaximumCount, Offset, ActualCount, blocks."""
    n = len(blocks)
    top = args_maximum if args_maximum > n else n
    return _NDR_REQ[little].pack(top, n, top, 0, n) + blocks


def decode_request_args(body: bytes, little: bool = False) -> tuple[int, bytes]:
    """(ArgsMaximum, block bytes) of a request body."""
    if len(body) < 20:
        raise PnioError(f"request body of {len(body)} bytes is shorter than the 20-byte NDR header")
    args_max, length, maximum, offset, actual = struct.unpack_from(_order(little) + "IIIII", body, 0)
    if offset != 0 or actual > maximum or length > len(body) - 20 or actual > len(body) - 20:
        raise PnioError(f"inconsistent NDR header (length {length}, max {maximum}, offset {offset}, "
                        f"actual {actual}, {len(body) - 20} bytes present)")
    return args_max, body[20:20 + length]


def encode_response_args(status: PnioStatus, blocks: bytes, args_maximum: int | None = None,
                         little: bool = False) -> bytes:
    """NDR response: PNIOStatus, ArgsLength, MaximumCount, Offset, ActualCount, blocks."""
    n = len(blocks)
    maximum = n if args_maximum is None else max(args_maximum, n)
    return status.encode() + struct.pack(_order(little) + "IIII", n, maximum, 0, n) + blocks


def decode_response_args(body: bytes, little: bool = False) -> tuple[PnioStatus, bytes]:
    """(PNIOStatus, block bytes) of a response body."""
    if len(body) < 20:
        raise PnioError(f"response body of {len(body)} bytes is shorter than the 20-byte NDR header")
    status = PnioStatus.decode_bytes(body[:4])
    length, maximum, offset, actual = _NDR_RES[bool(little)].unpack_from(body, 4)
    if offset != 0 or actual > maximum or length > len(body) - 20:
        raise PnioError(f"inconsistent NDR header (length {length}, max {maximum}, offset {offset}, "
                        f"actual {actual}, {len(body) - 20} bytes present)")
    return status, body[20:20 + length]


# ---------------------------------------------------------------- blocks

def block_header(block_type: int, length_after: int, version: tuple[int, int] = (1, 0)) -> bytes:
    """BlockHeader; ``length_after`` counts bytes after the version bytes."""
    if not 0 <= length_after + 2 <= 0xFFFF:
        raise PnioError(f"block of {length_after} bytes is too long")
    return BLOCK_HEADER.pack(block_type, length_after + 2, *version)


@dataclass(frozen=True)
class RawBlock:
    """One block as found in a body: type, version, content after the header, trailing data.

    ``data`` holds what follows a read/write header block (the record bytes),
    which the block length does not count.
    """

    type: int
    version: tuple[int, int]
    content: bytes


def split_blocks(data: bytes) -> list[RawBlock]:
    """Cut a body into blocks. Record data after a read/write header is returned as
    part of that block's content (see :func:`_record_tail`)."""
    blocks: list[RawBlock] = []
    pos = 0
    while pos < len(data):
        if len(data) - pos < 6:
            raise PnioError(f"{len(data) - pos} stray bytes after the last block")
        btype, length, vhi, vlo = BLOCK_HEADER.unpack_from(data, pos)
        if length < 2 or pos + 4 + length > len(data):
            raise PnioError(f"block 0x{btype:04X} announces {length} bytes, {len(data) - pos - 4} present")
        end = pos + 4 + length
        if btype in (BT_WRITE_REQ, BT_READ_RES):
            # the record data follows the header block, outside its length
            if length != 60:
                raise PnioError(f"block 0x{btype:04X} must be 60 bytes long, not {length}")
            record_length = struct.unpack_from(">I", data, pos + 36)[0]
            if end + record_length > len(data):
                raise PnioError(f"record data of {record_length} bytes announced, {len(data) - end} present")
            end += record_length
        blocks.append(RawBlock(btype, (vhi, vlo), data[pos + 6:end]))
        pos = end
    return blocks


def _expect(block: RawBlock, btype: int, minimum: int) -> None:
    if block.type != btype:
        raise PnioError(f"expected block 0x{btype:04X}, found 0x{block.type:04X}")
    if len(block.content) < minimum:
        raise PnioError(f"block 0x{btype:04X} has {len(block.content)} bytes, needs {minimum}")


def _mac(value: bytes) -> bytes:
    if len(value) != 6:
        raise PnioError(f"MAC address needs 6 bytes, got {len(value)}")
    return bytes(value)


def _one_block(data: bytes, btype: int) -> RawBlock:
    blocks = split_blocks(data)
    if not blocks:
        raise PnioError(f"no block found where 0x{btype:04X} was expected")
    for block in blocks:
        if block.type == btype:
            return block
    raise PnioError(f"block 0x{btype:04X} missing (found {', '.join(f'0x{b.type:04X}' for b in blocks)})")


@dataclass(frozen=True)
class ARBlockReq:
    ar_type: int
    ar_uuid: uuid.UUID
    session_key: int
    initiator_mac: bytes
    initiator_object_uuid: uuid.UUID
    properties: int
    timeout_factor: int
    station_name: bytes
    udp_rt_port: int = 0x8892

    _FMT = struct.Struct(">H16sH6s16sIHHH")

    @property
    def device_access(self) -> bool:
        return bool(self.properties & AR_PROP_DEVICE_ACCESS)

    def encode(self) -> bytes:
        try:
            body = self._FMT.pack(self.ar_type, self.ar_uuid.bytes, self.session_key, _mac(self.initiator_mac),
                                  self.initiator_object_uuid.bytes, self.properties, self.timeout_factor,
                                  self.udp_rt_port, len(self.station_name)) + self.station_name
        except struct.error as exc:
            raise PnioError(f"ARBlockReq field out of range: {exc}") from None
        return block_header(BT_AR_REQ, len(body)) + body

    @classmethod
    def from_block(cls, block: RawBlock) -> "ARBlockReq":
        _expect(block, BT_AR_REQ, cls._FMT.size)
        ar_type, ar_uuid, key, mac, obj, props, factor, port, nlen = cls._FMT.unpack_from(block.content, 0)
        name = block.content[cls._FMT.size:]
        if len(name) != nlen:
            raise PnioError(f"station name length {nlen} but {len(name)} bytes present")
        return cls(ar_type, uuid.UUID(bytes=ar_uuid), key, mac, uuid.UUID(bytes=obj), props, factor, name, port)

    @classmethod
    def decode(cls, data: bytes) -> "ARBlockReq":
        return cls.from_block(_one_block(data, BT_AR_REQ))


@dataclass(frozen=True)
class ARBlockRes:
    ar_type: int
    ar_uuid: uuid.UUID
    session_key: int
    responder_mac: bytes
    udp_rt_port: int = 0x8892

    _FMT = struct.Struct(">H16sH6sH")

    def encode(self) -> bytes:
        try:
            body = self._FMT.pack(self.ar_type, self.ar_uuid.bytes, self.session_key, _mac(self.responder_mac),
                                  self.udp_rt_port)
        except struct.error as exc:
            raise PnioError(f"ARBlockRes field out of range: {exc}") from None
        return block_header(BT_AR_RES, len(body)) + body

    @classmethod
    def decode(cls, data: bytes) -> "ARBlockRes":
        block = _one_block(data, BT_AR_RES)
        _expect(block, BT_AR_RES, cls._FMT.size)
        ar_type, ar_uuid, key, mac, port = cls._FMT.unpack_from(block.content, 0)
        return cls(ar_type, uuid.UUID(bytes=ar_uuid), key, mac, port)


_RW_HEAD = struct.Struct(">H16sIHH2sHI")   # seq, AR UUID, API, slot, subslot, padding, index, length: 34 bytes


@dataclass(frozen=True)
class RecordAddress:
    api: int = API_PROFIDRIVE
    slot: int = 1
    subslot: int = 1
    index: int = INDEX_PROFIDRIVE

    def describe(self) -> str:
        return f"API 0x{self.api:X} slot {self.slot} subslot 0x{self.subslot:X} index 0x{self.index:X}"


def _rw_head(seq: int, ar_uuid: uuid.UUID, addr: RecordAddress, length: int) -> bytes:
    try:
        return _RW_HEAD.pack(seq, ar_uuid.bytes, addr.api, addr.slot, addr.subslot, b"\0\0", addr.index, length)
    except struct.error as exc:
        raise PnioError(f"record header field out of range: {exc}") from None


def _rw_parse(content: bytes) -> tuple[int, uuid.UUID, RecordAddress, int]:
    seq, ar, api, slot, subslot, _pad, index, length = _RW_HEAD.unpack_from(content, 0)
    return seq, uuid.UUID(bytes=ar), RecordAddress(api, slot, subslot, index), length


# ---------------------------------------------------------------- a client's record access, without objects
#
# Why beside the block classes: a PNU read is a write record and a read record, each encoded and decoded
# once per request; the dataclasses (a UUID, a RecordAddress, a RawBlock list per block) cost more than the
# rest of the call. These functions use the same layouts (_RW_HEAD); the classes below call them to encode.

_WRITE_REQ_HEAD = block_header(BT_WRITE_REQ, 58)
_READ_REQ_HEAD = block_header(BT_READ_REQ, 58)
_PAD24 = bytes(24)
_PAD8 = bytes(8)


def write_request(seq: int, ar: bytes, address: RecordAddress, data: bytes) -> bytes:
    """IODWriteReqHeader + record data (``ar``: the AR UUID's 16 bytes)."""
    try:
        head = _RW_HEAD.pack(seq, ar, address.api, address.slot, address.subslot, b"\0\0", address.index, len(data))
    except struct.error as exc:
        raise PnioError(f"record header field out of range: {exc}") from None
    return _WRITE_REQ_HEAD + head + _PAD24 + data


def read_request(seq: int, ar: bytes, address: RecordAddress, length: int, target_ar: bytes = bytes(16)) -> bytes:
    """IODReadReqHeader (``target_ar``: the nil UUID unless a ReadImplicit names one)."""
    try:
        head = _RW_HEAD.pack(seq, ar, address.api, address.slot, address.subslot, b"\0\0", address.index, length)
    except struct.error as exc:
        raise PnioError(f"record header field out of range: {exc}") from None
    return _READ_REQ_HEAD + head + target_ar + _PAD8


def _first_block(data: bytes, btype: int) -> tuple[bytes, int]:
    """(content, end) of the block of type ``btype``: the first one if it is (the usual case), else searched."""
    if len(data) >= 6 and BLOCK_HEADER.unpack_from(data, 0)[0] == btype:
        length = BLOCK_HEADER.unpack_from(data, 0)[1]
        if length < 2 or 4 + length > len(data):
            raise PnioError(f"block 0x{btype:04X} announces {length} bytes, {len(data) - 4} present")
        return bytes(data[6:4 + length]), 4 + length
    block = _one_block(data, btype)
    return block.content, -1


def write_response(data: bytes) -> tuple[int, int, "PnioStatus"]:
    """(sequence number, record index, PNIOStatus) of an IODWriteResHeader."""
    if len(data) >= 48:  # the usual answer, one unpack: the header block first, as long as it should be
        btype, length, seq, index, status = _WRITE_RES_FIELDS.unpack_from(data)
        if btype == BT_WRITE_RES and 60 <= length <= len(data) - 4:
            return seq, index, PnioStatus.decode_bytes(status)
    return _write_response(data)


def _write_response(data: bytes) -> tuple[int, int, "PnioStatus"]:
    """:func:`write_response` by the general block rules (the header block searched when it is not first)."""
    content, _end = _first_block(data, BT_WRITE_RES)
    if len(content) < 58:
        raise PnioError(f"block 0x{BT_WRITE_RES:04X} has {len(content)} bytes, needs 58")
    seq, _ar, _api, _slot, _subslot, _pad, index, _length = _RW_HEAD.unpack_from(content, 0)
    return seq, index, PnioStatus.decode_bytes(content[38:42])


def read_response(data: bytes) -> tuple[int, int, bytes]:
    """(sequence number, record index, record data) of an IODReadResHeader and the data after it."""
    if len(data) >= 64:  # the usual answer, one unpack: the header block first, 60 bytes long, its data after it
        btype, length, seq, index, record_length = _READ_RES_FIELDS.unpack_from(data)
        if btype == BT_READ_RES and length == 60 and 64 + record_length <= len(data):
            return seq, index, bytes(data[64:64 + record_length])
    return _read_response(data)


def _read_response(data: bytes) -> tuple[int, int, bytes]:
    """:func:`read_response` by the general block rules."""
    content, end = _first_block(data, BT_READ_RES)
    if end < 0:  # found by the general split, which keeps the record data in the content
        block = _one_block(data, BT_READ_RES)
        _expect(block, BT_READ_RES, 58)
        seq, _ar, _api, _slot, _subslot, _pad, index, length = _RW_HEAD.unpack_from(block.content, 0)
        return seq, index, block.content[58:58 + length]
    if end != 64:
        raise PnioError(f"block 0x{BT_READ_RES:04X} must be 60 bytes long, not {end - 4}")
    seq, _ar, _api, _slot, _subslot, _pad, index, length = _RW_HEAD.unpack_from(content, 0)
    record = data[end:end + length]
    if len(record) != length:
        raise PnioError(f"read response announces {length} record bytes, {len(record)} present")
    return seq, index, bytes(record)


# BlockHeader (type, length; version skipped) and the fields of the record header a client reads (_RW_HEAD after 6
# bytes: sequence number, then AR UUID, API, slot, subslot, padding skipped, index; a write response's PNIOStatus
# after the record length and AdditionalValue1/2, a read response's record length)
_WRITE_RES_FIELDS = struct.Struct(">HH2xH26xH8x4s")
_READ_RES_FIELDS = struct.Struct(">HH2xH26xHI")


@dataclass(frozen=True)
class IODWriteReq:
    seq_number: int
    ar_uuid: uuid.UUID
    address: RecordAddress
    data: bytes

    def encode(self) -> bytes:
        return write_request(self.seq_number, self.ar_uuid.bytes, self.address, bytes(self.data))

    @classmethod
    def decode(cls, data: bytes) -> "IODWriteReq":
        block = _one_block(data, BT_WRITE_REQ)
        _expect(block, BT_WRITE_REQ, 58)
        seq, ar, addr, length = _rw_parse(block.content)
        return cls(seq, ar, addr, block.content[58:58 + length])


@dataclass(frozen=True)
class IODWriteRes:
    seq_number: int
    ar_uuid: uuid.UUID
    address: RecordAddress
    record_length: int
    status: PnioStatus = OK
    additional1: int = 0
    additional2: int = 0

    def encode(self) -> bytes:
        body = (_rw_head(self.seq_number, self.ar_uuid, self.address, self.record_length)
                + struct.pack(">HH", self.additional1 & 0xFFFF, self.additional2 & 0xFFFF)
                + self.status.encode() + bytes(16))
        return block_header(BT_WRITE_RES, len(body)) + body

    @classmethod
    def decode(cls, data: bytes) -> "IODWriteRes":
        block = _one_block(data, BT_WRITE_RES)
        _expect(block, BT_WRITE_RES, 58)
        seq, ar, addr, length = _rw_parse(block.content)
        add1, add2 = struct.unpack_from(">HH", block.content, 34)
        return cls(seq, ar, addr, length, PnioStatus.decode_bytes(block.content[38:42]), add1, add2)


@dataclass(frozen=True)
class IODReadReq:
    """Read request header. ``target_ar_uuid`` is used by ReadImplicit (nil AR UUID)."""

    seq_number: int
    ar_uuid: uuid.UUID
    address: RecordAddress
    max_length: int
    target_ar_uuid: uuid.UUID = NIL_UUID

    def encode(self) -> bytes:
        return read_request(self.seq_number, self.ar_uuid.bytes, self.address, self.max_length,
                            self.target_ar_uuid.bytes)

    @classmethod
    def decode(cls, data: bytes) -> "IODReadReq":
        block = _one_block(data, BT_READ_REQ)
        _expect(block, BT_READ_REQ, 34)
        seq, ar, addr, length = _rw_parse(block.content)
        target = block.content[34:50]
        target_uuid = uuid.UUID(bytes=target) if len(target) == 16 else NIL_UUID
        return cls(seq, ar, addr, length, target_uuid)


@dataclass(frozen=True)
class IODReadRes:
    seq_number: int
    ar_uuid: uuid.UUID
    address: RecordAddress
    data: bytes
    additional1: int = 0
    additional2: int = 0

    def encode(self) -> bytes:
        body = (_rw_head(self.seq_number, self.ar_uuid, self.address, len(self.data))
                + struct.pack(">HH", self.additional1 & 0xFFFF, self.additional2 & 0xFFFF) + bytes(20))
        return block_header(BT_READ_RES, len(body)) + body + bytes(self.data)

    @classmethod
    def decode(cls, data: bytes) -> "IODReadRes":
        block = _one_block(data, BT_READ_RES)
        _expect(block, BT_READ_RES, 58)
        seq, ar, addr, length = _rw_parse(block.content)
        add1, add2 = struct.unpack_from(">HH", block.content, 34)
        return cls(seq, ar, addr, block.content[58:58 + length], add1, add2)


@dataclass(frozen=True)
class ReleaseBlock:
    """IODReleaseBlock (0x0114 request / 0x8114 response)."""

    ar_uuid: uuid.UUID
    session_key: int
    command: int = CONTROL_RELEASE
    properties: int = 0
    response: bool = False

    _FMT = struct.Struct(">2s16sH2sHH")

    def encode(self) -> bytes:
        try:
            body = self._FMT.pack(b"\0\0", self.ar_uuid.bytes, self.session_key, b"\0\0", self.command, self.properties)
        except struct.error as exc:
            raise PnioError(f"release block field out of range: {exc}") from None
        return block_header(BT_RELEASE_RES if self.response else BT_RELEASE_REQ, len(body)) + body

    @classmethod
    def decode(cls, data: bytes) -> "ReleaseBlock":
        blocks = split_blocks(data)
        if not blocks or blocks[0].type not in (BT_RELEASE_REQ, BT_RELEASE_RES):
            raise PnioError("release block (0x0114/0x8114) missing")
        block = blocks[0]
        _expect(block, block.type, cls._FMT.size)
        _p, ar, key, _p2, command, props = cls._FMT.unpack_from(block.content, 0)
        return cls(uuid.UUID(bytes=ar), key, command, props, block.type == BT_RELEASE_RES)


# ---------------------------------------------------------------- I&M0

@dataclass(frozen=True)
class IM0:
    """Identification & Maintenance 0 (record 0xAFF0): who made the device and what it runs."""

    vendor_id: int
    order_id: str
    serial_number: str
    hardware_revision: int
    sw_revision: tuple[str, int, int, int]   # prefix ('V', 'R', 'P', 'U', 'T'), functional, bugfix, internal
    revision_counter: int = 0
    profile_id: int = API_PROFIDRIVE
    profile_specific_type: int = 0
    im_version: tuple[int, int] = (1, 1)
    im_supported: int = 0

    _FMT = struct.Struct(">H20s16sHcBBBHHHBBH")

    def encode(self) -> bytes:
        try:
            body = self._FMT.pack(
                self.vendor_id, self.order_id.encode("ascii").ljust(20), self.serial_number.encode("ascii").ljust(16),
                self.hardware_revision, self.sw_revision[0].encode("ascii"), *self.sw_revision[1:],
                self.revision_counter, self.profile_id, self.profile_specific_type, *self.im_version, self.im_supported)
        except (struct.error, UnicodeEncodeError, TypeError) as exc:
            raise PnioError(f"I&M0 field not encodable: {exc}") from None
        return block_header(BT_IM0, len(body)) + body

    @classmethod
    def decode(cls, data: bytes) -> "IM0":
        block = _one_block(data, BT_IM0)
        _expect(block, BT_IM0, cls._FMT.size)
        (vendor, order, serial, hw, prefix, f, b, i, counter, profile, ptype, vhi, vlo,
         supported) = cls._FMT.unpack_from(block.content, 0)
        return cls(vendor, _text(order), _text(serial), hw, (_text(prefix), f, b, i), counter, profile, ptype,
                   (vhi, vlo), supported)

    @property
    def software(self) -> str:
        p, f, b, i = self.sw_revision
        return f"{p}{f}.{b}.{i}"

    def to_json(self) -> dict[str, object]:
        """Stable keys for ``akdctl info --json``."""
        return {
            "vendor_id": f"0x{self.vendor_id:04X}", "order_id": self.order_id, "serial_number": self.serial_number,
            "hardware_revision": self.hardware_revision, "software_revision": self.software,
            "revision_counter": self.revision_counter, "profile_id": f"0x{self.profile_id:04X}",
            "profile_specific_type": self.profile_specific_type, "im_version": f"{self.im_version[0]}.{self.im_version[1]}",
            "im_supported": f"0x{self.im_supported:04X}",
        }


def _text(raw: bytes) -> str:
    return raw.decode("latin-1").rstrip(" \0")


#: The one-unpack layouts of write_response/read_response (header block first), for protocol/pnio_call.py, which
#: reads them at their place in a whole reply datagram instead of a copy of its blocks (issue 29, row pn).
WRITE_RES_FIELDS = _WRITE_RES_FIELDS
READ_RES_FIELDS = _READ_RES_FIELDS
