"""CIP messages (CIP Vol. 1): logical-segment paths, Message Router request/response, and the
Connection Manager's Forward_Open / Large_Forward_Open / Forward_Close.

Codes only; words for general and extended status live in ``catalog/texts.py``.
Malformed input raises :class:`CodecError` only.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from functools import lru_cache

from akdctl.protocol.errors import CodecError

# Services
GET_ATTRIBUTES_ALL = 0x01
SET_ATTRIBUTES_ALL = 0x02
GET_ATTRIBUTE_SINGLE = 0x0E
SET_ATTRIBUTE_SINGLE = 0x10
FORWARD_CLOSE = 0x4E
FORWARD_OPEN = 0x54
LARGE_FORWARD_OPEN = 0x5B
REPLY = 0x80
SERVICE_NAMES = {GET_ATTRIBUTES_ALL: "Get_Attributes_All", SET_ATTRIBUTES_ALL: "Set_Attributes_All",
                 GET_ATTRIBUTE_SINGLE: "Get_Attribute_Single", SET_ATTRIBUTE_SINGLE: "Set_Attribute_Single",
                 FORWARD_CLOSE: "Forward_Close", FORWARD_OPEN: "Forward_Open",
                 LARGE_FORWARD_OPEN: "Large_Forward_Open"}

# Classes the AKD implements (reference/ethernetip.md 1.2)
IDENTITY = 0x01
MESSAGE_ROUTER = 0x02
ASSEMBLY = 0x04
CONNECTION_MANAGER = 0x06
PARAMETER = 0x0F
POSITION_CONTROLLER_SUPERVISOR = 0x24
POSITION_CONTROLLER = 0x25
TCPIP = 0xF5
ETHERNET_LINK = 0xF6

# General status codes (texts: catalog.texts.CIP_STATUS_TEXTS)
SUCCESS = 0x00
CONNECTION_FAILURE = 0x01
RESOURCE_UNAVAILABLE = 0x02
PATH_SEGMENT_ERROR = 0x04
PATH_DESTINATION_UNKNOWN = 0x05
SERVICE_NOT_SUPPORTED = 0x08
INVALID_ATTRIBUTE_VALUE = 0x09
ALREADY_IN_STATE = 0x0B
OBJECT_STATE_CONFLICT = 0x0C
ATTRIBUTE_NOT_SETTABLE = 0x0E
PRIVILEGE_VIOLATION = 0x0F
DEVICE_STATE_CONFLICT = 0x10
NOT_ENOUGH_DATA = 0x13
ATTRIBUTE_NOT_SUPPORTED = 0x14
TOO_MUCH_DATA = 0x15
OBJECT_DOES_NOT_EXIST = 0x16
INVALID_PARAMETER = 0x20

# Connection Manager extended status (general status 0x01)
EXT_CONNECTION_IN_USE = 0x0100
EXT_OWNERSHIP_CONFLICT = 0x0106
EXT_CONNECTION_NOT_FOUND = 0x0107
EXT_INVALID_CONNECTION_TYPE = 0x0108
EXT_INVALID_CONNECTION_SIZE = 0x0109
EXT_RPI_NOT_SUPPORTED = 0x0111
EXT_OUT_OF_CONNECTIONS = 0x0113
EXT_INVALID_OT_SIZE = 0x0127
EXT_INVALID_TO_SIZE = 0x0128
EXT_INVALID_CONFIGURATION_PATH = 0x0129
EXT_INVALID_CONSUMING_PATH = 0x012A
EXT_INVALID_PRODUCING_PATH = 0x012B


def _pack(fmt: str, what: str, *values: int) -> bytes:
    """struct.pack with out-of-range fields reported as CodecError (one place for every CM structure)."""
    try:
        return struct.pack(fmt, *values)
    except struct.error as exc:
        raise CodecError(f"{what} field out of range: {exc}") from None


def _words(payload: bytes, what: str) -> bytes:
    """A trailing path / application reply: whole 16-bit words, at most 255 of them."""
    if len(payload) % 2 or len(payload) > 510:
        raise CodecError(f"{what} must be whole words (at most 255)")
    return payload


def _unpack_sized(data: bytes, fmt: str, what: str) -> tuple[tuple[int, ...], bytes]:
    """Fixed fields whose last value counts the 16-bit words that must follow exactly."""
    size = struct.calcsize(fmt)
    if len(data) < size:
        raise CodecError(f"{what} needs {size} bytes, got {len(data)}")
    values = struct.unpack_from(fmt, data)
    if len(data) != size + 2 * values[-1]:
        raise CodecError(f"{what} announces {values[-1]} words, {len(data) - size} bytes follow")
    return values, bytes(data[size:])


_TRIAD = "<HHIBx"      # serial, vendor, originator serial, word count, reserved


# ---------------------------------------------------------------- paths

@dataclass(frozen=True)
class Path:
    """A logical path: class, instance, optional attribute; connection points for connection paths."""

    class_id: int
    instance: int | None = None
    attribute: int | None = None
    points: tuple[int, ...] = ()
    key: "ElectronicKey | None" = None

    def encode(self) -> bytes:
        out = self.key.encode() if self.key is not None else b""
        out += _segment(0x20, self.class_id, "class")
        if self.instance is not None:
            out += _segment(0x24, self.instance, "instance")
        for point in self.points:
            out += _segment(0x2C, point, "connection point")
        if self.attribute is not None:
            out += _segment(0x30, self.attribute, "attribute")
        return out

    @property
    def label(self) -> str:
        parts = [f"0x{self.class_id:02X}", str(self.instance if self.instance is not None else "-")]
        if self.attribute is not None:
            parts.append(str(self.attribute))
        return "/".join(parts)


def _segment(base: int, value: int, what: str) -> bytes:
    """8-bit logical format below 256, else the padded 16-bit format (32-bit for instances above 65535)."""
    if not isinstance(value, int) or value < 0:
        raise CodecError(f"{what} {value!r} is not a non-negative integer")
    if value <= 0xFF:
        return bytes([base, value])
    if value <= 0xFFFF:
        return bytes([base | 1, 0]) + struct.pack("<H", value)
    if value <= 0xFFFFFFFF and base in (0x24, 0x2C):
        return bytes([base | 2, 0]) + struct.pack("<I", value)
    raise CodecError(f"{what} {value} is too large for a logical segment")


@dataclass(frozen=True)
class ElectronicKey:
    """Logical electronic key segment (0x34, key format 4); zeros are wildcards."""

    vendor: int = 0
    device_type: int = 0
    product_code: int = 0
    major: int = 0            # bit 7 = compatibility bit
    minor: int = 0

    def encode(self) -> bytes:
        return bytes([0x34, 0x04]) + _pack("<HHHBB", "electronic key", self.vendor, self.device_type,
                                           self.product_code, self.major, self.minor)


_KINDS = {0x20: "class", 0x24: "instance", 0x2C: "point", 0x30: "attribute"}


def decode_path(data: bytes) -> Path:
    """Logical segments in padded format (and an electronic key); other segment types raise CodecError."""
    pos = 0
    found: dict[str, int] = {}
    points: list[int] = []
    key: ElectronicKey | None = None
    while pos < len(data):
        seg = data[pos]
        if seg == 0x34:
            if pos + 10 > len(data) or data[pos + 1] != 0x04:
                raise CodecError(f"electronic key segment at byte {pos} is truncated or not key format 4")
            if key is not None:
                raise CodecError("path carries two electronic keys")
            key = ElectronicKey(*struct.unpack_from("<HHHBB", data, pos + 2))
            pos += 10
            continue
        kind = _KINDS.get(seg & 0xFC)
        fmt = seg & 0x03
        if kind is None or fmt == 3:
            raise CodecError(f"unsupported path segment 0x{seg:02X} at byte {pos}")
        size = (1, 2, 4)[fmt]
        start = pos + (1 if fmt == 0 else 2)
        if fmt and pos + 1 < len(data) and data[pos + 1] != 0:
            raise CodecError(f"pad byte of segment 0x{seg:02X} is not zero")
        if start + size > len(data):
            raise CodecError(f"path segment 0x{seg:02X} at byte {pos} is truncated")
        value = int.from_bytes(data[start:start + size], "little")
        pos = start + size
        if kind == "point":
            points.append(value)
        elif kind in found:
            raise CodecError(f"path names the {kind} twice")
        else:
            found[kind] = value
    if "class" not in found:
        raise CodecError("path has no class segment")
    return Path(found["class"], found.get("instance"), found.get("attribute"), tuple(points), key)


# ---------------------------------------------------------------- requests / responses

@dataclass(frozen=True)
class Request:
    service: int
    path: bytes
    data: bytes = b""

    def encode(self) -> bytes:
        if not 0 <= self.service < 0x80:
            raise CodecError(f"request service 0x{self.service:X} out of range 0..0x7F")
        if len(self.path) % 2 or len(self.path) > 510:
            raise CodecError(f"request path of {len(self.path)} bytes is not a whole number of words (<= 255)")
        return bytes([self.service, len(self.path) // 2]) + self.path + self.data

    @classmethod
    def decode(cls, data: bytes) -> "Request":
        if len(data) < 2:
            raise CodecError(f"CIP request needs 2 bytes, got {len(data)}")
        service, words = data[0], data[1]
        if service & REPLY:
            raise CodecError(f"service 0x{service:02X} has the reply bit set")
        end = 2 + 2 * words
        if end > len(data):
            raise CodecError(f"request path of {words} words is truncated")
        return cls(service, bytes(data[2:end]), bytes(data[end:]))

    @property
    def name(self) -> str:
        return SERVICE_NAMES.get(self.service, f"service 0x{self.service:02X}")


def request(service: int, class_id: int, instance: int, attribute: int | None = None, data: bytes = b"") -> Request:
    return Request(service, Path(class_id, instance, attribute).encode(), data)


@dataclass(frozen=True)
class Response:
    service: int                       # the request's service (without the reply bit)
    status: int = SUCCESS
    extended: tuple[int, ...] = ()     # additional status words
    data: bytes = b""

    @property
    def ok(self) -> bool:
        return self.status == SUCCESS

    def encode(self) -> bytes:
        if not 0 <= self.service < 0x80:
            raise CodecError(f"reply service 0x{self.service:X} out of range")
        if not 0 <= self.status <= 0xFF or len(self.extended) > 255:
            raise CodecError("general status or additional status out of range")
        if any(not 0 <= w <= 0xFFFF for w in self.extended):
            raise CodecError("additional status words must fit 16 bits")
        return (bytes([self.service | REPLY, 0, self.status, len(self.extended)])
                + b"".join(struct.pack("<H", w) for w in self.extended) + self.data)

    @classmethod
    def decode(cls, data: bytes) -> "Response":
        if len(data) < 4:
            raise CodecError(f"CIP response needs 4 bytes, got {len(data)}")
        if not data[0] & REPLY:
            raise CodecError(f"service 0x{data[0]:02X} lacks the reply bit")
        words = data[3]
        end = 4 + 2 * words
        if end > len(data):
            raise CodecError(f"additional status of {words} words is truncated")
        extended = tuple(struct.unpack_from(f"<{words}H", data, 4))
        return cls(data[0] & 0x7F, data[2], extended, bytes(data[end:]))


# ---------------------------------------------------------------- Connection Manager


# network connection parameter fields
TYPE_NULL, TYPE_MULTICAST, TYPE_P2P = 0, 1, 2
PRIORITY_LOW, PRIORITY_HIGH, PRIORITY_SCHEDULED, PRIORITY_URGENT = 0, 1, 2, 3
TRANSPORT_CLASS1_CYCLIC = 0x01        # direction client, trigger cyclic, class 1
TRANSPORT_CLASS3_SERVER = 0xA3        # server, application trigger, class 3


@dataclass(frozen=True)
class NetParams:
    """Network connection parameters of one direction (16 bits in Forward_Open, 32 in Large_Forward_Open)."""

    size: int
    conn_type: int = TYPE_P2P
    priority: int = PRIORITY_SCHEDULED
    variable: bool = False
    owner: bool = False

    def encode(self, large: bool) -> int:
        limit = 0xFFFF if large else 0x1FF
        if not 0 <= self.size <= limit:
            raise CodecError(f"connection size {self.size} exceeds {limit}")
        if not 0 <= self.conn_type <= 3 or not 0 <= self.priority <= 3:
            raise CodecError("connection type and priority are 2-bit fields")
        shift = 16 if large else 0
        return (self.size | (int(self.variable) << (9 + shift)) | (self.priority << (10 + shift))
                | (self.conn_type << (13 + shift)) | (int(self.owner) << (15 + shift)))

    @classmethod
    def decode(cls, value: int, large: bool) -> "NetParams":
        shift = 16 if large else 0
        size = value & (0xFFFF if large else 0x1FF)
        return cls(size, (value >> (13 + shift)) & 3, (value >> (10 + shift)) & 3,
                   bool(value >> (9 + shift) & 1), bool(value >> (15 + shift) & 1))


@dataclass(frozen=True)
class ForwardOpen:
    """Forward_Open (``large=False``) or Large_Forward_Open request data."""

    ot_connection_id: int
    to_connection_id: int
    serial: int
    vendor: int
    originator_serial: int
    ot_rpi_us: int
    ot_params: NetParams
    to_rpi_us: int
    to_params: NetParams
    path: bytes
    transport: int = TRANSPORT_CLASS1_CYCLIC
    timeout_multiplier: int = 0
    tick: int = 0x0A
    timeout_ticks: int = 0x0E
    large: bool = False

    @property
    def service(self) -> int:
        return LARGE_FORWARD_OPEN if self.large else FORWARD_OPEN

    @staticmethod
    def _fmt(large: bool) -> str:
        pfmt = "I" if large else "H"
        return f"<BBIIHHIB3xI{pfmt}I{pfmt}BB"

    def encode(self) -> bytes:
        path = _words(self.path, "connection path")
        return _pack(self._fmt(self.large), "Forward_Open", self.tick, self.timeout_ticks, self.ot_connection_id,
                     self.to_connection_id, self.serial, self.vendor, self.originator_serial,
                     self.timeout_multiplier, self.ot_rpi_us, self.ot_params.encode(self.large), self.to_rpi_us,
                     self.to_params.encode(self.large), self.transport, len(path) // 2) + path

    @classmethod
    def decode(cls, data: bytes, large: bool = False) -> "ForwardOpen":
        values, path = _unpack_sized(data, cls._fmt(large), f"{'Large_' if large else ''}Forward_Open")
        tick, ticks, ot_id, to_id, serial, vendor, oserial, mult, ot_rpi, ot_p, to_rpi, to_p, transport, _ = values
        return cls(ot_id, to_id, serial, vendor, oserial, ot_rpi, NetParams.decode(ot_p, large), to_rpi,
                   NetParams.decode(to_p, large), path, transport, mult, tick, ticks, large)


@dataclass(frozen=True)
class ForwardOpenReply:
    ot_connection_id: int
    to_connection_id: int
    serial: int
    vendor: int
    originator_serial: int
    ot_api_us: int
    to_api_us: int
    application: bytes = b""

    def encode(self) -> bytes:
        app = _words(self.application, "application reply")
        return _pack("<IIHHIIIBx", "Forward_Open reply", self.ot_connection_id, self.to_connection_id, self.serial,
                     self.vendor, self.originator_serial, self.ot_api_us, self.to_api_us, len(app) // 2) + app

    @classmethod
    def decode(cls, data: bytes) -> "ForwardOpenReply":
        values, app = _unpack_sized(data, "<IIHHIIIBx", "Forward_Open reply")
        return cls(*values[:7], app)


@dataclass(frozen=True)
class ConnectionTriad:
    """What identifies a connection to the target: serial, originator vendor, originator serial."""

    serial: int
    vendor: int
    originator_serial: int


@dataclass(frozen=True)
class ForwardClose:
    serial: int
    vendor: int
    originator_serial: int
    path: bytes = b""
    tick: int = 0x0A
    timeout_ticks: int = 0x0E

    @property
    def triad(self) -> ConnectionTriad:
        return ConnectionTriad(self.serial, self.vendor, self.originator_serial)

    def encode(self) -> bytes:
        path = _words(self.path, "connection path")
        return _pack("<BB" + _TRIAD[1:], "Forward_Close", self.tick, self.timeout_ticks, self.serial, self.vendor,
                     self.originator_serial, len(path) // 2) + path

    @classmethod
    def decode(cls, data: bytes) -> "ForwardClose":
        (tick, ticks, serial, vendor, oserial, _), path = _unpack_sized(data, "<BB" + _TRIAD[1:], "Forward_Close")
        return cls(serial, vendor, oserial, path, tick, ticks)


@dataclass(frozen=True)
class ForwardCloseReply:
    serial: int
    vendor: int
    originator_serial: int
    application: bytes = b""

    def encode(self) -> bytes:
        app = _words(self.application, "application reply")
        return _pack(_TRIAD, "Forward_Close reply", self.serial, self.vendor, self.originator_serial,
                     len(app) // 2) + app

    @classmethod
    def decode(cls, data: bytes) -> "ForwardCloseReply":
        (serial, vendor, oserial, _), app = _unpack_sized(data, _TRIAD, "Forward_Close reply")
        return cls(serial, vendor, oserial, app)


@dataclass(frozen=True)
class ConnectionFailure:
    """The data of an unsuccessful Forward_Open / Forward_Close reply (general status 0x01)."""

    serial: int
    vendor: int
    originator_serial: int
    remaining_path_words: int = 0

    def encode(self) -> bytes:
        return _pack(_TRIAD, "connection failure", self.serial, self.vendor, self.originator_serial,
                     self.remaining_path_words)

    @classmethod
    def decode(cls, data: bytes) -> "ConnectionFailure":
        if len(data) < 10:
            raise CodecError(f"unsuccessful Forward_Open reply needs 10 bytes, got {len(data)}")
        return cls(*struct.unpack_from(_TRIAD, data))


# ---------------------------------------------------------------- elementary data types

@dataclass(frozen=True)
class CipType:
    code: int
    name: str
    short: str        # akdctl type name (protocol.datatypes)


# CIP elementary type codes (CIP Vol. 1 C-6.1); the AKD Parameter object's attribute 5 uses them [M-26].
CIP_TYPES: dict[int, CipType] = {t.code: t for t in (
    CipType(0xC1, "BOOL", "bool"), CipType(0xC2, "SINT", "i8"), CipType(0xC3, "INT", "i16"),
    CipType(0xC4, "DINT", "i32"), CipType(0xC5, "LINT", "i64"), CipType(0xC6, "USINT", "u8"),
    CipType(0xC7, "UINT", "u16"), CipType(0xC8, "UDINT", "u32"), CipType(0xC9, "ULINT", "u64"),
    CipType(0xCA, "REAL", "r32"), CipType(0xCB, "LREAL", "r64"),
)}


def short_string(text: str) -> bytes:
    raw = text.encode("ascii", "replace")
    if len(raw) > 255:
        raise CodecError("SHORT_STRING longer than 255 bytes")
    return bytes([len(raw)]) + raw


def decode_short_string(data: bytes) -> str:
    if not data or len(data) != 1 + data[0]:
        raise CodecError("SHORT_STRING length byte does not match the data")
    return data[1:].decode("ascii", "replace")


@dataclass(frozen=True)
class IdentityAttributes:
    """Identity object (class 1) attributes 1-7, in Get_Attributes_All order."""

    vendor: int
    device_type: int
    product_code: int
    revision: tuple[int, int]
    status: int
    serial: int
    product_name: str

    def encode(self) -> bytes:
        return _pack("<HHHBBHI", "identity", self.vendor, self.device_type, self.product_code, self.revision[0],
                     self.revision[1], self.status, self.serial) + short_string(self.product_name)

    @classmethod
    def decode(cls, data: bytes) -> "IdentityAttributes":
        if len(data) < 15:
            raise CodecError(f"Identity Get_Attributes_All needs at least 15 bytes, got {len(data)}")
        vendor, dtype, code, major, minor, status, serial = struct.unpack_from("<HHHBBHI", data)
        nlen = data[14]
        if len(data) < 15 + nlen:
            raise CodecError("identity product name is truncated")
        # OpENer appends further attributes (state, configuration consistency ...) after the name
        return cls(vendor, dtype, code, (major, minor), status, serial, data[15:15 + nlen].decode("ascii", "replace"))



# ---------------------------------------------------------------- a client's per-request path

@lru_cache(maxsize=1024)
def attribute_path(class_id: int, instance: int, attribute: int | None = None) -> bytes:
    """``Path(class_id, instance, attribute).encode()``, remembered: a client asks the same few attributes again
    and again (a poll), and the encoded path is the same bytes each time."""
    return Path(class_id, instance, attribute).encode()


@lru_cache(maxsize=1024)
def get_attribute_single(class_id: int, instance: int, attribute: int) -> Request:
    """The Get_Attribute_Single request for one attribute, remembered (a Request is immutable): a poll asks the
    same attributes again and again."""
    return Request(GET_ATTRIBUTE_SINGLE, attribute_path(class_id, instance, attribute))


def decode_response(data: bytes) -> Response:
    """:meth:`Response.decode`, reading a reply without additional status words (nearly every reply) without
    building a struct format for them."""
    if len(data) >= 4 and data[0] & REPLY and not data[3]:
        return Response(data[0] & 0x7F, data[2], (), data[4:])
    return Response.decode(data)
