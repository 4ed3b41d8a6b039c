"""EtherNet/IP encapsulation (CIP Vol. 2, chapter 2) and the common packet format.

Why a codec of its own: the same frames are built by akdctl's client, parsed by
the simulator's face and checked in tests, so the layout is written once. Pure
bytes in, objects out; malformed input raises :class:`CodecError` only.

An encapsulation packet is a 24-byte little-endian header (command, length of
the data that follows, session handle, status, 8-byte sender context, options)
plus ``length`` bytes of command data. SendRRData / SendUnitData carry an
interface handle, a timeout and a *common packet format* (CPF): an item count
and typed items (address item, data item, socket-address items). Class-1 I/O
datagrams on UDP 2222 are a bare CPF (sequenced address item + connected data
item), without the encapsulation header.
"""

from __future__ import annotations

import ipaddress
import struct
from dataclasses import dataclass, field

from akdctl.protocol.cip import IdentityAttributes
from akdctl.protocol.errors import CodecError

TCP_PORT = 44818                 # encapsulation and explicit messaging (also UDP ListIdentity)
IO_PORT = 2222                   # class-1 I/O datagrams
HEADER_SIZE = 24
PROTOCOL_VERSION = 1
MAX_DATA = 65511                 # length field limit (the header's 16 bits minus the header)

# Encapsulation commands
NOP = 0x0000
LIST_SERVICES = 0x0004
LIST_IDENTITY = 0x0063
LIST_INTERFACES = 0x0064
REGISTER_SESSION = 0x0065
UNREGISTER_SESSION = 0x0066
SEND_RR_DATA = 0x006F
SEND_UNIT_DATA = 0x0070
COMMAND_NAMES = {NOP: "NOP", LIST_SERVICES: "ListServices", LIST_IDENTITY: "ListIdentity",
                 LIST_INTERFACES: "ListInterfaces", REGISTER_SESSION: "RegisterSession",
                 UNREGISTER_SESSION: "UnRegisterSession", SEND_RR_DATA: "SendRRData",
                 SEND_UNIT_DATA: "SendUnitData"}

# Encapsulation status codes (texts: catalog.texts.ENIP_STATUS_TEXTS)
STATUS_SUCCESS = 0x0000
STATUS_INVALID_COMMAND = 0x0001
STATUS_NO_MEMORY = 0x0002
STATUS_INCORRECT_DATA = 0x0003
STATUS_INVALID_SESSION = 0x0064
STATUS_INVALID_LENGTH = 0x0065
STATUS_UNSUPPORTED_PROTOCOL = 0x0069

# Common packet format item type IDs
ITEM_NULL = 0x0000
ITEM_LIST_IDENTITY = 0x000C
ITEM_CONNECTED_ADDRESS = 0x00A1
ITEM_CONNECTED_DATA = 0x00B1
ITEM_UNCONNECTED_DATA = 0x00B2
ITEM_LIST_SERVICES = 0x0100
ITEM_SOCKADDR_O2T = 0x8000
ITEM_SOCKADDR_T2O = 0x8001
ITEM_SEQUENCED_ADDRESS = 0x8002

_HEADER = struct.Struct("<HHII8sI")


# ---------------------------------------------------------------- header

def command_name(command: int) -> str:
    return COMMAND_NAMES.get(command, f"command 0x{command:04X}")


@dataclass(frozen=True)
class Header:
    command: int
    length: int
    session: int = 0
    status: int = 0
    context: bytes = bytes(8)
    options: int = 0


@dataclass(frozen=True)
class Packet:
    """One encapsulation packet: header fields and the command data."""

    command: int
    data: bytes = b""
    session: int = 0
    status: int = 0
    context: bytes = bytes(8)
    options: int = 0

    def encode(self) -> bytes:
        if len(self.data) > MAX_DATA:
            raise CodecError(f"encapsulation data of {len(self.data)} bytes exceeds {MAX_DATA}")
        if len(self.context) != 8:
            raise CodecError("sender context must be 8 bytes")
        for name, value, bits in (("command", self.command, 16), ("session", self.session, 32),
                                  ("status", self.status, 32), ("options", self.options, 32)):
            _check_uint(name, value, bits)
        return _HEADER.pack(self.command, len(self.data), self.session, self.status, self.context,
                            self.options) + bytes(self.data)


def _check_uint(name: str, value: int, bits: int) -> None:
    if not isinstance(value, int) or not 0 <= value < (1 << bits):
        raise CodecError(f"{name} {value!r} does not fit {bits} bits")


def decode_header(data: bytes) -> Header:
    """The 24-byte header at the start of ``data`` (a stream reader's first step)."""
    if len(data) < HEADER_SIZE:
        raise CodecError(f"encapsulation header needs {HEADER_SIZE} bytes, got {len(data)}")
    command, length, session, status, context, options = _HEADER.unpack_from(data)
    return Header(command, length, session, status, bytes(context), options)


def decode_packet(data: bytes) -> Packet:
    """A whole packet; the header's length must match the bytes that follow exactly."""
    head = decode_header(data)
    body = bytes(data[HEADER_SIZE:])
    if len(body) != head.length:
        raise CodecError(f"encapsulation header announces {head.length} data bytes, {len(body)} follow")
    return Packet(head.command, body, head.session, head.status, head.context, head.options)


# ---------------------------------------------------------------- RegisterSession

def register_session_data(version: int = PROTOCOL_VERSION, options: int = 0) -> bytes:
    _check_uint("protocol version", version, 16)
    _check_uint("options", options, 16)
    return struct.pack("<HH", version, options)


def decode_register_session(data: bytes) -> tuple[int, int]:
    """(protocol version, options flags) of a RegisterSession request or reply."""
    if len(data) != 4:
        raise CodecError(f"RegisterSession data must be 4 bytes, got {len(data)}")
    return struct.unpack("<HH", data)  # type: ignore[return-value]


# ---------------------------------------------------------------- common packet format

@dataclass(frozen=True)
class Item:
    type_id: int
    data: bytes = b""


def encode_cpf(items: list[Item] | tuple[Item, ...]) -> bytes:
    if len(items) > 0xFFFF:
        raise CodecError("too many CPF items")
    out = bytearray(struct.pack("<H", len(items)))
    for item in items:
        _check_uint("item type", item.type_id, 16)
        if len(item.data) > 0xFFFF:
            raise CodecError(f"CPF item of {len(item.data)} bytes is too long")
        out += struct.pack("<HH", item.type_id, len(item.data)) + bytes(item.data)
    return bytes(out)


def decode_cpf(data: bytes) -> list[Item]:
    """Every item; the items must use up ``data`` exactly."""
    if len(data) < 2:
        raise CodecError("common packet format needs an item count")
    (count,) = struct.unpack_from("<H", data)
    pos, items = 2, []
    for n in range(count):
        if pos + 4 > len(data):
            raise CodecError(f"CPF item {n + 1} of {count} is truncated")
        type_id, length = struct.unpack_from("<HH", data, pos)
        pos += 4
        if pos + length > len(data):
            raise CodecError(f"CPF item {n + 1} (type 0x{type_id:04X}) announces {length} bytes, "
                             f"{len(data) - pos} remain")
        items.append(Item(type_id, bytes(data[pos:pos + length])))
        pos += length
    if pos != len(data):
        raise CodecError(f"{len(data) - pos} bytes follow the last CPF item")
    return items


@dataclass(frozen=True)
class RRData:
    """SendRRData / SendUnitData command data: interface handle, timeout, CPF items."""

    items: tuple[Item, ...]
    timeout: int = 0
    interface: int = 0

    def encode(self) -> bytes:
        _check_uint("interface handle", self.interface, 32)
        _check_uint("timeout", self.timeout, 16)
        return struct.pack("<IH", self.interface, self.timeout) + encode_cpf(self.items)

    @classmethod
    def decode(cls, data: bytes) -> "RRData":
        if len(data) < 6:
            raise CodecError(f"SendRRData/SendUnitData needs 6 bytes before the CPF, got {len(data)}")
        interface, timeout = struct.unpack_from("<IH", data)
        return cls(tuple(decode_cpf(data[6:])), timeout, interface)

    def item(self, type_id: int) -> Item | None:
        return next((i for i in self.items if i.type_id == type_id), None)


def unconnected(message: bytes, timeout: int = 0) -> RRData:
    """UCMM: a Null address item and an unconnected data item with the CIP message (no route path)."""
    return RRData((Item(ITEM_NULL), Item(ITEM_UNCONNECTED_DATA, message)), timeout)


def unconnected_message(rr: RRData) -> bytes:
    """The CIP message of a UCMM SendRRData: a Null address item and an unconnected data item,
    optionally followed by socket-address items (a Forward_Open names its T->O port in one)."""
    items = rr.items
    if len(items) < 2 or items[0].type_id != ITEM_NULL or items[1].type_id != ITEM_UNCONNECTED_DATA or any(
            i.type_id not in (ITEM_SOCKADDR_O2T, ITEM_SOCKADDR_T2O) for i in items[2:]):
        kinds = ", ".join(f"0x{i.type_id:04X}" for i in items)
        raise CodecError(f"expected a Null address item and an unconnected data item, got items [{kinds}]")
    if items[0].data:
        raise CodecError("the Null address item must be empty")
    return items[1].data


# ---------------------------------------------------------------- socket address item

@dataclass(frozen=True)
class SockAddr:
    """sockaddr_in as CIP carries it: big-endian family (2), port and IPv4 address, 8 zero bytes."""

    host: str = "0.0.0.0"
    port: int = 0
    family: int = 2

    def encode(self) -> bytes:
        _check_uint("port", self.port, 16)
        _check_uint("family", self.family, 16)
        try:
            addr = ipaddress.IPv4Address(self.host).packed
        except ValueError:
            raise CodecError(f"{self.host!r} is not an IPv4 address") from None
        return struct.pack(">HH4s8s", self.family, self.port, addr, bytes(8))

    @classmethod
    def decode(cls, data: bytes) -> "SockAddr":
        if len(data) != 16:
            raise CodecError(f"socket address item must be 16 bytes, got {len(data)}")
        family, port, addr, _zero = struct.unpack(">HH4s8s", data)
        return cls(str(ipaddress.IPv4Address(addr)), port, family)


# ---------------------------------------------------------------- ListIdentity

@dataclass(frozen=True)
class Identity:
    """The CIP identity item a ListIdentity reply carries: encapsulation version, socket address, the
    Identity object's attributes 1-7 (the layout of its Get_Attributes_All) and the state byte."""

    vendor: int
    device_type: int
    product_code: int
    revision: tuple[int, int]
    status: int
    serial: int
    product_name: str
    state: int = 0xFF
    address: SockAddr = field(default_factory=SockAddr)
    version: int = PROTOCOL_VERSION

    @property
    def attributes(self) -> IdentityAttributes:
        return IdentityAttributes(self.vendor, self.device_type, self.product_code, self.revision, self.status,
                                  self.serial, self.product_name)

    def encode(self) -> bytes:
        _check_uint("version", self.version, 16)
        _check_uint("state", self.state, 8)
        return (struct.pack("<H", self.version) + self.address.encode() + self.attributes.encode()
                + bytes([self.state]))

    @classmethod
    def decode(cls, data: bytes) -> "Identity":
        if len(data) < 2 + 16 + 15 + 1:
            raise CodecError(f"ListIdentity item of {len(data)} bytes is too short")
        (version,) = struct.unpack_from("<H", data)
        address = SockAddr.decode(data[2:18])
        if len(data) != 34 + data[32]:
            raise CodecError(f"ListIdentity item: product name of {data[32]} bytes and a state byte need "
                             f"{34 + data[32]} bytes, got {len(data)}")
        attrs = IdentityAttributes.decode(data[18:-1])
        return cls(attrs.vendor, attrs.device_type, attrs.product_code, attrs.revision, attrs.status, attrs.serial,
                   attrs.product_name, data[-1], address, version)

    def to_json(self) -> dict[str, object]:
        return {"vendor": self.vendor, "device_type": self.device_type, "product_code": self.product_code,
                "revision": f"{self.revision[0]}.{self.revision[1]:03d}", "status": self.status,
                "serial": self.serial, "product_name": self.product_name, "state": self.state,
                "socket_address": f"{self.address.host}:{self.address.port}"}


def list_identity_reply(identity: Identity) -> bytes:
    return encode_cpf([Item(ITEM_LIST_IDENTITY, identity.encode())])


def decode_list_identity(data: bytes) -> list[Identity]:
    return [Identity.decode(item.data) for item in decode_cpf(data) if item.type_id == ITEM_LIST_IDENTITY]


# ---------------------------------------------------------------- class-1 I/O datagrams

@dataclass(frozen=True)
class IoPacket:
    """A class-1 datagram: sequenced address item (connection ID, encapsulation sequence number) and
    connected data item (16-bit CIP sequence count, then the application data, which for a
    32-bit run/idle header format starts with that header)."""

    connection_id: int
    sequence: int
    cip_sequence: int
    data: bytes

    def encode(self) -> bytes:
        _check_uint("connection id", self.connection_id, 32)
        _check_uint("sequence number", self.sequence, 32)
        _check_uint("CIP sequence count", self.cip_sequence, 16)
        return encode_cpf([Item(ITEM_SEQUENCED_ADDRESS, struct.pack("<II", self.connection_id, self.sequence)),
                           Item(ITEM_CONNECTED_DATA, struct.pack("<H", self.cip_sequence) + bytes(self.data))])

    @classmethod
    def decode(cls, data: bytes) -> "IoPacket":
        items = decode_cpf(data)
        if len(items) < 2 or items[0].type_id != ITEM_SEQUENCED_ADDRESS or items[1].type_id != ITEM_CONNECTED_DATA:
            raise CodecError("class-1 datagram needs a sequenced address item and a connected data item")
        if len(items[0].data) != 8:
            raise CodecError(f"sequenced address item must be 8 bytes, got {len(items[0].data)}")
        if len(items[1].data) < 2:
            raise CodecError("connected data item lacks its sequence count")
        conn, seq = struct.unpack("<II", items[0].data)
        (count,) = struct.unpack_from("<H", items[1].data)
        return cls(conn, seq, count, items[1].data[2:])


RUN = 0x00000001  # 32-bit run/idle header: bit 0 = run


def with_run_idle(data: bytes, run: bool = True) -> bytes:
    return struct.pack("<I", RUN if run else 0) + bytes(data)


def split_run_idle(data: bytes) -> tuple[bool, bytes]:
    if len(data) < 4:
        raise CodecError("O->T data lacks its 32-bit run/idle header")
    (header,) = struct.unpack_from("<I", data)
    return bool(header & RUN), bytes(data[4:])


# ---------------------------------------------------------------- a client's per-request path

# Why a second way to the same bytes: a client sends one SendRRData per CIP request and reads one header per
# reply; building Packet, RRData and Item objects for each (and a header object for each reply) was most of the
# client's CPU per request. These pack and unpack the same layout in one struct call each; the tests hold them
# equal to the general encoders and decoders above. The sender context is read as the 64-bit number a client
# counts in it (its bytes are opaque to the target, which only echoes them).

_HEADER_COUNTED = struct.Struct("<HHIIQI")
_UCMM = struct.Struct("<HHIIQIIHHHHHH")   # header; interface handle, timeout, 2 items: Null (type, 0), data (type, length)
_UCMM_ITEMS = struct.Struct("<IHHHHHH")
UCMM_OVERHEAD = _UCMM_ITEMS.size          # SendRRData bytes before the CIP message of a UCMM request


def pack_packet(command: int, data: bytes, session: int, context: int) -> bytes:
    """``Packet(command, data, session, 0, context as 8 little-endian bytes).encode()`` in one pack."""
    if len(data) > MAX_DATA:
        raise CodecError(f"encapsulation data of {len(data)} bytes exceeds {MAX_DATA}")
    try:
        return _HEADER_COUNTED.pack(command, len(data), session, 0, context, 0) + data
    except struct.error as exc:
        raise CodecError(f"encapsulation header field out of range: {exc}") from None


def pack_ucmm(session: int, context: int, message: bytes) -> bytes:
    """A whole UCMM request packet -- ``Packet(SEND_RR_DATA, unconnected(message).encode(), session, 0,
    context).encode()`` -- in one pack: header, interface handle 0, timeout 0, Null address item, unconnected data
    item carrying ``message``."""
    size = len(message)
    if size > MAX_DATA - UCMM_OVERHEAD:
        raise CodecError(f"CIP message of {size} bytes does not fit one encapsulation packet")
    try:
        return _UCMM.pack(SEND_RR_DATA, UCMM_OVERHEAD + size, session, 0, context, 0, 0, 0, 2, ITEM_NULL, 0,
                          ITEM_UNCONNECTED_DATA, size) + message
    except struct.error as exc:
        raise CodecError(f"encapsulation header field out of range: {exc}") from None


def unpack_header(data: bytes) -> tuple[int, int, int, int, int, int]:
    """(command, length, session, status, context as a number, options) of the header at the start of ``data``
    (at least :data:`HEADER_SIZE` bytes): :func:`decode_header` without the object."""
    if len(data) < HEADER_SIZE:
        raise CodecError(f"encapsulation header needs {HEADER_SIZE} bytes, got {len(data)}")
    return _HEADER_COUNTED.unpack_from(data)  # type: ignore[return-value]


def ucmm_reply_message(data: bytes) -> bytes:
    """The CIP message of a UCMM SendRRData's command data: ``unconnected_message(RRData.decode(data))``, read
    with one unpack when the data is the plain Null-item + data-item layout (any other layout takes the general
    decoder, with its checks and its error)."""
    if len(data) >= UCMM_OVERHEAD:
        _interface, _timeout, count, null_type, null_length, item_type, length = _UCMM_ITEMS.unpack_from(data)
        if (count == 2 and null_type == ITEM_NULL and null_length == 0 and item_type == ITEM_UNCONNECTED_DATA
                and length == len(data) - UCMM_OVERHEAD):
            return data[UCMM_OVERHEAD:]
    return unconnected_message(RRData.decode(data))
