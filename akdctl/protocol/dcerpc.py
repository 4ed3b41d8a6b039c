"""DCE/RPC version 4 (connectionless) packet header, as PROFINET IO uses it on UDP.

PNIO speaks DCE/RPC CL over UDP port 34964. Every datagram is an 80-byte
header followed by the body (the NDR-encoded PNIO arguments). The header's
integers and the three leading groups of each UUID follow the *data
representation* (``drep``) the sender announces, so a decoder must honour
both byte orders even though akdctl itself always sends big-endian: a device
may answer little-endian (many PLC stacks do).

Pure codec: bytes in, dataclasses out; only :class:`DceRpcError` escapes.
"""

from __future__ import annotations

import struct
import uuid
from dataclasses import dataclass, field, replace

from akdctl.protocol.errors import CodecError

HEADER_SIZE = 80
RPC_VERSION = 4

# packet types (DCE 1.1 RPC, chapter 12)
PT_REQUEST = 0
PT_PING = 1
PT_RESPONSE = 2
PT_FAULT = 3
PT_WORKING = 4
PT_NOCALL = 5
PT_REJECT = 6
PT_ACK = 7
PT_CL_CANCEL = 8
PT_FACK = 9
PT_CANCEL_ACK = 10

PACKET_TYPE_NAMES = {
    PT_REQUEST: "request", PT_PING: "ping", PT_RESPONSE: "response", PT_FAULT: "fault",
    PT_WORKING: "working", PT_NOCALL: "nocall", PT_REJECT: "reject", PT_ACK: "ack",
    PT_CL_CANCEL: "cancel", PT_FACK: "fack", PT_CANCEL_ACK: "cancel-ack",
}

# flags1 bits (DCE 1.1: the "last fragment" bit is 0x02, "fragment" 0x04, "no fack" 0x08)
FLAG_LASTFRAG = 0x02
FLAG_FRAG = 0x04
FLAG_NOFACK = 0x08
FLAG_MAYBE = 0x10
FLAG_IDEMPOTENT = 0x20
FLAG_BROADCAST = 0x40

DREP_BIG = b"\x00\x00\x00"      # big-endian integers, ASCII, IEEE floats
DREP_LITTLE = b"\x10\x00\x00"   # little-endian integers, ASCII, IEEE floats

class DceRpcError(CodecError):
    """A datagram that is not a valid DCE/RPC v4 connectionless packet."""


def uuid_to_wire(value: uuid.UUID, little: bool) -> bytes:
    """UUID bytes in the order the data representation announces."""
    return value.bytes_le if little else value.bytes


def uuid_from_wire(data: bytes, little: bool) -> uuid.UUID:
    if len(data) != 16:
        raise DceRpcError(f"UUID needs 16 bytes, got {len(data)}")
    return uuid.UUID(bytes_le=bytes(data)) if little else uuid.UUID(bytes=bytes(data))


class _HeaderFlags:
    """What the header's type and flags say, the same for the decoded :class:`RpcHeader` and the :class:`RpcView`."""

    __slots__ = ()
    ptype: int
    flags1: int

    @property
    def is_fragment(self) -> bool:
        return bool(self.flags1 & FLAG_FRAG)

    @property
    def is_last_fragment(self) -> bool:
        return not self.is_fragment or bool(self.flags1 & FLAG_LASTFRAG)

    @property
    def type_name(self) -> str:
        return PACKET_TYPE_NAMES.get(self.ptype, f"type {self.ptype}")


@dataclass(frozen=True)
class RpcHeader(_HeaderFlags):
    """The 80-byte DCE/RPC CL header. ``body_length`` is filled by :func:`encode_packet`."""

    ptype: int
    object_uuid: uuid.UUID
    interface_uuid: uuid.UUID
    activity_uuid: uuid.UUID
    sequence: int
    opnum: int
    flags1: int = 0
    flags2: int = 0
    drep: bytes = DREP_BIG
    server_boot: int = 0
    interface_version: int = 1
    interface_hint: int = 0xFFFF
    activity_hint: int = 0xFFFF
    fragment: int = 0
    body_length: int = 0
    auth_protocol: int = 0
    serial: int = 0
    version: int = field(default=RPC_VERSION)

    @property
    def little_endian(self) -> bool:
        return (self.drep[0] >> 4) == 1



@dataclass(frozen=True)
class RpcPacket:
    header: RpcHeader
    body: bytes


def encode_packet(header: RpcHeader, body: bytes = b"") -> bytes:
    """Header + body; ``body_length`` is set from ``body``."""
    try:
        if len(header.drep) != 3 or (header.drep[0] >> 4) not in (0, 1):
            raise DceRpcError(f"unsupported data representation {header.drep.hex()}")
        if len(body) > 0xFFFF:
            raise DceRpcError(f"body of {len(body)} bytes does not fit one datagram; fragment it")
        little = header.little_endian
        order = "<" if little else ">"
        head = struct.pack(
            ">BBBB3sB", header.version, header.ptype, header.flags1, header.flags2,
            header.drep, (header.serial >> 8) & 0xFF,
        )
        head += uuid_to_wire(header.object_uuid, little)
        head += uuid_to_wire(header.interface_uuid, little)
        head += uuid_to_wire(header.activity_uuid, little)
        head += struct.pack(
            order + "IIIHHHHH", header.server_boot, header.interface_version, header.sequence,
            header.opnum, header.interface_hint, header.activity_hint, len(body), header.fragment,
        )
        head += struct.pack(">BB", header.auth_protocol, header.serial & 0xFF)
    except struct.error as exc:
        raise DceRpcError(f"header field out of range: {exc}") from None
    return head + bytes(body)


_REQUEST_HEAD = struct.Struct(">BBBB3sB")
_FIELDS_BE = struct.Struct(">IIIHHHHH")
_FIELDS_LE = struct.Struct("<IIIHHHHH")


class RpcView(_HeaderFlags):
    """A received datagram as a client needs it: header fields and body, the UUIDs left as wire bytes.

    Why not :class:`RpcHeader`: decoding three ``uuid.UUID`` objects and an 18-field frozen dataclass per
    datagram costs more than the rest of a client's call; a client compares the activity bytes with its
    own (:meth:`RequestTemplate.is_ours`). :func:`decode_packet` builds the full header from a view.
    """

    __slots__ = ("data", "ptype", "flags1", "flags2", "drep", "serial_hi", "little", "sequence", "opnum",
                 "fragment", "fields", "body")

    @property
    def header(self) -> "RpcView":  # the shape Reassembler reads (packet.header, packet.body)
        return self

    @property
    def activity(self) -> bytes:
        return self.data[40:56]

    @property
    def little_endian(self) -> bool:
        return self.little



def view_packet(data: bytes) -> RpcView:
    """Parse one datagram's header (UUIDs stay bytes); the body is cut to the announced length."""
    size = len(data)
    if size < HEADER_SIZE:
        raise DceRpcError(f"datagram of {size} bytes is shorter than the 80-byte DCE/RPC header")
    version, ptype, flags1, flags2, drep, serial_hi = _REQUEST_HEAD.unpack_from(data, 0)
    if version != RPC_VERSION:
        raise DceRpcError(f"DCE/RPC version {version}, expected 4 (connectionless)")
    order = drep[0] >> 4
    if order not in (0, 1):
        raise DceRpcError(f"unsupported integer representation in drep {drep.hex()}")
    fields = (_FIELDS_LE if order else _FIELDS_BE).unpack_from(data, 56)
    length = fields[6]
    if HEADER_SIZE + length > size:
        raise DceRpcError(f"body length {length} exceeds the {size - HEADER_SIZE} bytes received")
    view = RpcView()
    view.data = data
    view.ptype, view.flags1, view.flags2, view.drep, view.serial_hi = ptype, flags1, flags2, drep, serial_hi
    view.little = order == 1
    view.fields = fields
    view.sequence, view.opnum, view.fragment = fields[2], fields[3], fields[7]
    view.body = bytes(data[HEADER_SIZE:HEADER_SIZE + length])
    return view


def decode_packet(data: bytes) -> RpcPacket:
    """Parse one datagram into a full :class:`RpcHeader` (UUIDs decoded); the body is cut to the announced length."""
    data = bytes(data)
    view = view_packet(data)
    little = view.little
    boot, if_vers, seq, opnum, ihint, ahint, length, frag = view.fields
    header = RpcHeader(
        ptype=view.ptype, object_uuid=uuid_from_wire(data[8:24], little),
        interface_uuid=uuid_from_wire(data[24:40], little), activity_uuid=uuid_from_wire(data[40:56], little),
        sequence=seq, opnum=opnum, flags1=view.flags1, flags2=view.flags2, drep=view.drep, server_boot=boot,
        interface_version=if_vers, interface_hint=ihint, activity_hint=ahint, fragment=frag,
        body_length=length, auth_protocol=data[78], serial=(view.serial_hi << 8) | data[79], version=RPC_VERSION,
    )
    return RpcPacket(header, view.body)


class RequestTemplate:
    """The request header of one client activity, encoded once: per call only the sequence number,
    the operation and the body length change (written into a copy of the template)."""

    __slots__ = ("_head", "_activity_be", "_activity_le")

    def __init__(self, object_uuid: uuid.UUID, interface_uuid: uuid.UUID, activity_uuid: uuid.UUID,
                 flags1: int = FLAG_IDEMPOTENT) -> None:
        header = RpcHeader(ptype=PT_REQUEST, object_uuid=object_uuid, interface_uuid=interface_uuid,
                           activity_uuid=activity_uuid, sequence=0, opnum=0, flags1=flags1)
        self._head = bytearray(encode_packet(header))
        self._activity_be = activity_uuid.bytes
        self._activity_le = activity_uuid.bytes_le

    def packet(self, sequence: int, opnum: int, body: bytes) -> bytes:
        """Header + body of one request (big-endian data representation, as akdctl always sends)."""
        if len(body) > 0xFFFF:
            raise DceRpcError(f"body of {len(body)} bytes does not fit one datagram; fragment it")
        head = self._head
        try:
            _SEQ_OP.pack_into(head, 64, sequence, opnum)
        except struct.error as exc:
            raise DceRpcError(f"header field out of range: {exc}") from None
        _LENGTH.pack_into(head, 74, len(body))
        return bytes(head) + body

    def is_ours(self, view: RpcView) -> bool:
        """Whether a reply belongs to this activity (compared in the byte order the reply announces)."""
        return view.data[40:56] == (self._activity_le if view.little else self._activity_be)


_SEQ_OP = struct.Struct(">IH")
_LENGTH = struct.Struct(">H")


def fragment_body(header: RpcHeader, body: bytes, max_body: int) -> list[bytes]:
    """Split one call's body into datagrams of at most ``max_body`` body bytes.

    A body that fits is sent unfragmented (no FRAG flag) so ordinary peers see
    ordinary packets. Fragments carry FRAG, the last one LASTFRAG, and NOFACK
    so the receiver need not acknowledge each one.
    """
    if max_body < 8:
        raise DceRpcError("fragment size must be at least 8 bytes")
    if len(body) <= max_body:
        return [encode_packet(replace(header, fragment=0), body)]
    pieces = [body[i:i + max_body] for i in range(0, len(body), max_body)]
    out = []
    for number, piece in enumerate(pieces):
        flags = (header.flags1 | FLAG_FRAG | FLAG_NOFACK) & ~FLAG_LASTFRAG
        if number == len(pieces) - 1:
            flags |= FLAG_LASTFRAG
        out.append(encode_packet(replace(header, flags1=flags, fragment=number), piece))
    return out


class Reassembler:
    """Collects the fragments of one call (one activity + sequence number).

    Fragments may arrive out of order or twice (UDP); the body is complete
    once every number up to the one flagged LASTFRAG has been seen.
    """

    def __init__(self, max_body: int | None = None) -> None:
        self._parts: dict[int, bytes] = {}
        self._last: int | None = None
        self._size = 0
        self.max_body = max_body  # the most one reassembled body may hold (a hostile peer's fragments end there)
        self.first: RpcHeader | None = None

    def add(self, packet: "RpcPacket | RpcView") -> bytes | None:
        """Feed one packet; returns the whole body once complete, else ``None``."""
        head = packet.header
        if not head.is_fragment:
            self.first = head
            return packet.body
        if head.fragment > 0x3FFF:
            raise DceRpcError(f"fragment number {head.fragment} is implausibly high")
        if self.first is None or head.fragment == 0:
            self.first = head if head.fragment == 0 or self.first is None else self.first
        if head.fragment not in self._parts:
            self._size += len(packet.body)
            if self.max_body is not None and self._size > self.max_body:
                raise DceRpcError(f"fragments of more than {self.max_body} bytes for one call")
        self._parts[head.fragment] = packet.body
        if head.flags1 & FLAG_LASTFRAG:
            self._last = head.fragment
        if self._last is None or any(n not in self._parts for n in range(self._last + 1)):
            return None
        return b"".join(self._parts[n] for n in range(self._last + 1))

    @property
    def highest_contiguous(self) -> int:
        """Highest fragment number received with no gap before it (-1 if none)."""
        n = -1
        while n + 1 in self._parts:
            n += 1
        return n
