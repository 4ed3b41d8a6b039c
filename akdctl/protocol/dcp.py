"""PROFINET DCP (Discovery and basic Configuration Protocol) frames, EtherType 0x8892.

A DCP PDU follows the Ethernet header: FrameID (0xFEFE identify request,
0xFEFF identify response, 0xFEFD get/set), ServiceID, ServiceType, Xid,
ResponseDelay (reserved in responses), DCPDataLength, then blocks of
Option, Suboption, Length, data padded to an even length. Response blocks
other than the control response start with a 2-byte BlockInfo; set request
blocks start with a 2-byte BlockQualifier.

Pure codec: only :class:`DcpError` escapes.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from akdctl.protocol.errors import CodecError

ETHERTYPE = 0x8892
IDENTIFY_MULTICAST = bytes.fromhex("010ecf000000")

FRAME_GET_SET = 0xFEFD
FRAME_IDENTIFY_REQ = 0xFEFE
FRAME_IDENTIFY_RES = 0xFEFF
FRAME_HELLO = 0xFEFC

SERVICE_GET = 3
SERVICE_SET = 4
SERVICE_IDENTIFY = 5
SERVICE_HELLO = 6
TYPE_REQUEST = 0
TYPE_RESPONSE = 1
TYPE_NOT_SUPPORTED = 5

OPT_IP = (1, 2)
OPT_FAMILY = (2, 1)           # "device vendor" / type of station
OPT_NAME = (2, 2)
OPT_DEVICE_ID = (2, 3)
OPT_ROLE = (2, 4)
OPT_OPTIONS = (2, 5)
OPT_CONTROL_START = (5, 1)
OPT_CONTROL_STOP = (5, 2)
OPT_SIGNAL = (5, 3)
OPT_CONTROL_RESPONSE = (5, 4)
OPT_FACTORY_RESET = (5, 5)
OPT_RESET_TO_FACTORY = (5, 6)
OPT_ALL = (0xFF, 0xFF)

QUALIFIER_TEMPORARY = 0
QUALIFIER_PERMANENT = 1

ROLES = {0x01: "IO device", 0x02: "IO controller", 0x04: "IO multidevice", 0x08: "PN supervisor"}
BLOCK_ERRORS = {0: "ok", 1: "option not supported", 2: "suboption not supported or no data set",
                3: "suboption not set", 4: "resource error", 5: "set not possible by local reasons",
                6: "in operation, set not possible"}

_HEAD = struct.Struct(">HBBIHH")


class DcpError(CodecError):
    """Bytes that are not a valid DCP PDU."""


@dataclass(frozen=True)
class Block:
    option: int
    suboption: int
    data: bytes = b""

    @property
    def key(self) -> tuple[int, int]:
        return (self.option, self.suboption)


@dataclass(frozen=True)
class DcpPdu:
    frame_id: int
    service_id: int
    service_type: int
    xid: int
    blocks: tuple[Block, ...] = field(default_factory=tuple)
    response_delay: int = 0

    def encode(self) -> bytes:
        body = b""
        if self.service_id == SERVICE_GET and self.service_type == TYPE_REQUEST:
            # a Get request names options only: (option, suboption) pairs without length or data
            body = b"".join(bytes((b.option, b.suboption)) for b in self.blocks)
        for block in self.blocks if not body else ():
            if len(block.data) > 0xFFFF:
                raise DcpError("DCP block too long")
            body += struct.pack(">BBH", block.option, block.suboption, len(block.data)) + block.data
            if len(block.data) % 2:
                body += b"\0"
        try:
            head = _HEAD.pack(self.frame_id, self.service_id, self.service_type, self.xid, self.response_delay,
                              len(body))
        except struct.error as exc:
            raise DcpError(f"DCP header field out of range: {exc}") from None
        return head + body

    @classmethod
    def decode(cls, data: bytes) -> "DcpPdu":
        if len(data) < _HEAD.size:
            raise DcpError(f"DCP PDU of {len(data)} bytes is shorter than its 12-byte header")
        frame_id, service, stype, xid, delay, length = _HEAD.unpack_from(data, 0)
        if frame_id not in (FRAME_GET_SET, FRAME_IDENTIFY_REQ, FRAME_IDENTIFY_RES, FRAME_HELLO):
            raise DcpError(f"frame ID 0x{frame_id:04X} is not DCP")
        if _HEAD.size + length > len(data):
            raise DcpError(f"DCP data length {length} exceeds the {len(data) - _HEAD.size} bytes present")
        body = data[_HEAD.size:_HEAD.size + length]
        blocks = []
        pos = 0
        if service == SERVICE_GET and stype == TYPE_REQUEST:
            if len(body) % 2:
                raise DcpError("Get request with an odd number of option bytes")
            pairs = tuple(Block(body[i], body[i + 1]) for i in range(0, len(body), 2))
            return cls(frame_id, service, stype, xid, pairs, delay)
        while pos < len(body):
            if len(body) - pos < 4:
                raise DcpError("truncated DCP block header")
            opt, sub, blen = struct.unpack_from(">BBH", body, pos)
            if pos + 4 + blen > len(body):
                raise DcpError(f"DCP block {opt}/{sub} announces {blen} bytes, {len(body) - pos - 4} present")
            blocks.append(Block(opt, sub, body[pos + 4:pos + 4 + blen]))
            pos += 4 + blen + (blen % 2)
        return cls(frame_id, service, stype, xid, tuple(blocks), delay)


def ethernet(dst: bytes, src: bytes, payload: bytes) -> bytes:
    return bytes(dst) + bytes(src) + struct.pack(">H", ETHERTYPE) + payload


def split_ethernet(frame: bytes) -> tuple[bytes, bytes, bytes]:
    """(dst, src, DCP payload) of a frame; skips one 802.1Q tag; raises DcpError for other EtherTypes."""
    if len(frame) < 14:
        raise DcpError("frame shorter than an Ethernet header")
    dst, src = frame[:6], frame[6:12]
    ethertype = struct.unpack_from(">H", frame, 12)[0]
    offset = 14
    if ethertype == 0x8100 and len(frame) >= 18:
        ethertype = struct.unpack_from(">H", frame, 16)[0]
        offset = 18
    if ethertype != ETHERTYPE:
        raise DcpError(f"EtherType 0x{ethertype:04X} is not PROFINET")
    return dst, src, frame[offset:]


# ---------------------------------------------------------------- station description

@dataclass
class Station:
    """What DCP identify tells about a device."""

    mac: str = ""
    name: str = ""
    ip: str = ""
    netmask: str = ""
    gateway: str = ""
    vendor_id: int | None = None
    device_id: int | None = None
    role: int | None = None
    family: str = ""
    ip_set: bool = False

    @property
    def role_text(self) -> str:
        if self.role is None:
            return ""
        return ", ".join(text for bit, text in ROLES.items() if self.role & bit) or f"0x{self.role:02X}"

    def to_json(self) -> dict[str, object]:
        return {"mac": self.mac, "name": self.name, "ip": self.ip, "netmask": self.netmask, "gateway": self.gateway,
                "vendor_id": None if self.vendor_id is None else f"0x{self.vendor_id:04X}",
                "device_id": None if self.device_id is None else f"0x{self.device_id:04X}",
                "role": self.role_text, "family": self.family}


def mac_text(mac: bytes) -> str:
    return ":".join(f"{b:02x}" for b in mac)


def mac_bytes(text: str) -> bytes:
    parts = text.replace("-", ":").split(":")
    try:
        value = bytes(int(p, 16) for p in parts)
    except ValueError:
        raise DcpError(f"{text!r} is not a MAC address") from None
    if len(value) != 6:
        raise DcpError(f"{text!r} is not a MAC address")
    return value


def _ip(data: bytes) -> str:
    return ".".join(str(b) for b in data)


def station_from_blocks(mac: bytes, blocks: tuple[Block, ...]) -> Station:
    """Fill a Station from identify/get response blocks (each starting with BlockInfo)."""
    st = Station(mac=mac_text(mac))
    for block in blocks:
        value = block.data[2:]
        if block.key == OPT_NAME:
            st.name = value.rstrip(b"\0").decode("ascii", "replace")
        elif block.key == OPT_IP and len(value) >= 12:
            st.ip, st.netmask, st.gateway = _ip(value[0:4]), _ip(value[4:8]), _ip(value[8:12])
            st.ip_set = bool(block.data[:2] != b"\0\0")
        elif block.key == OPT_DEVICE_ID and len(value) >= 4:
            st.vendor_id, st.device_id = struct.unpack_from(">HH", value, 0)
        elif block.key == OPT_ROLE and value:
            st.role = value[0]
        elif block.key == OPT_FAMILY:
            st.family = value.rstrip(b"\0").decode("ascii", "replace")
    return st


def station_blocks(st: Station, wanted: tuple[int, int] = OPT_ALL) -> tuple[Block, ...]:
    """Identify/get response blocks for a Station (the device side)."""
    def ip4(text: str) -> bytes:
        try:
            parts = bytes(int(x) for x in (text or "0.0.0.0").split("."))
        except ValueError:
            raise DcpError(f"{text!r} is not an IPv4 address") from None
        if len(parts) != 4:
            raise DcpError(f"{text!r} is not an IPv4 address")
        return parts

    blocks = [
        Block(*OPT_NAME, b"\0\0" + st.name.encode("ascii")),
        Block(*OPT_IP, (b"\0\x01" if st.ip_set else b"\0\0") + ip4(st.ip) + ip4(st.netmask) + ip4(st.gateway)),
        Block(*OPT_DEVICE_ID, b"\0\0" + struct.pack(">HH", st.vendor_id or 0, st.device_id or 0)),
        Block(*OPT_ROLE, b"\0\0" + bytes((st.role or 1, 0))),
        Block(*OPT_FAMILY, b"\0\0" + st.family.encode("ascii")),
    ]
    if wanted == OPT_ALL:
        return tuple(blocks)
    return tuple(b for b in blocks if b.key == wanted)


def control_response(option: tuple[int, int], error: int = 0) -> Block:
    """The set response block: which option was set and the block error."""
    return Block(*OPT_CONTROL_RESPONSE, bytes((option[0], option[1], error)))


def valid_station_name(name: str) -> bool:
    """PROFINET NameOfStation: DNS-like labels of lower-case letters, digits and '-', 1..240 characters."""
    if not 1 <= len(name) <= 240 or name != name.lower():
        return False
    for label in name.split("."):
        if not 1 <= len(label) <= 63 or label[0] == "-" or label[-1] == "-":
            return False
        if not all(c.isascii() and (c.isalnum() or c == "-") for c in label):
            return False
    return not name.startswith("port-")
