"""EtherCAT mailbox header (ETG.1000.4), mailbox error replies, ETG.8200 gateway wrapping.

Every acyclic EtherCAT protocol (CoE, FoE, EoE, ...) travels in a *mailbox*:
a 6-byte header followed by ``length`` bytes of protocol data, written to the
slave's SM0 buffer and read back from SM1. The same frame, prefixed with a
2-byte EtherCAT header of type 5, is what a master's mailbox gateway (ETG.8200,
UDP 34980) accepts, so one codec serves raw, gateway and simulated links.

Layout (little-endian)::

    0  u16  length N of the data after the 6-byte header
    2  u16  station address
    4  u8   bits 0-5 channel, bits 6-7 priority
    5  u8   bits 0-3 type, bits 4-6 counter (1..7, 0 = none), bit 7 reserved
    6  N    data

Decoding accepts a buffer longer than ``6 + N`` (a whole SM1 buffer is read at
once) and ignores the tail. The AKD manual's own example (AKD EtherCAT manual
5.13.3) counts ``length`` from byte 2 instead of byte 6; SPEC-NOTES 15 rules
that such frames decode as printed, so a length that overruns the buffer by
at most the 4 header bytes it double-counts is clipped, not refused.
"""

from __future__ import annotations

import struct

from akdctl.protocol.errors import CodecError
from akdctl.protocol.record import Record

HEADER_SIZE = 6
GATEWAY_HEADER_SIZE = 2
GATEWAY_FRAME_TYPE = 5  # EtherCAT frame type "mailbox" (ETG.8200)
GATEWAY_UDP_PORT = 34980
_MAX_GATEWAY_LENGTH = 0x7FF
MAX_GATEWAY_DATAGRAM = GATEWAY_HEADER_SIZE + _MAX_GATEWAY_LENGTH  # the largest gateway frame, in bytes (2049)


class MailboxError(CodecError):
    """A mailbox header or gateway frame that does not decode or cannot be encoded."""


class MailboxType:
    """Mailbox protocol types (header byte 5, bits 0-3), as plain integer constants (an enum costs more to create at
    every start than it gives)."""

    ERROR = 0
    AOE = 1
    EOE = 2
    COE = 3
    FOE = 4
    SOE = 5
    VOE = 15


class Mailbox(Record):
    """One mailbox frame: header fields plus the protocol data after the header (a Record, as the other codec
    messages on the cold path: ``replace`` gives a rewritten copy)."""

    __slots__ = ("type", "data", "address", "channel", "priority", "counter")

    def __init__(self, type: int, data: bytes, address: int = 0, channel: int = 0, priority: int = 0,
                 counter: int = 0) -> None:
        self.type = type
        self.data = data
        self.address = address
        self.channel = channel
        self.priority = priority
        self.counter = counter


def _check(name: str, value: int, low: int, high: int) -> int:
    if not isinstance(value, int) or not low <= value <= high:
        raise MailboxError(f"mailbox {name} {value!r} out of range {low}..{high}")
    return int(value)


def encode_mailbox(mbx: Mailbox) -> bytes:
    """Header + data, exactly ``6 + len(data)`` bytes (SM buffers are padded by the link)."""
    mtype = _check("type", mbx.type, 0, 15)
    counter = _check("counter", mbx.counter, 0, 7)
    channel = _check("channel", mbx.channel, 0, 0x3F)
    priority = _check("priority", mbx.priority, 0, 3)
    address = _check("address", mbx.address, 0, 0xFFFF)
    data = bytes(mbx.data)
    if len(data) > 0xFFFF:
        raise MailboxError(f"mailbox data of {len(data)} bytes exceeds the 16-bit length field")
    return struct.pack("<HHBB", len(data), address, channel | priority << 6, mtype | counter << 4) + data


_HEADER = struct.Struct("<HHBB")


def pack(mtype: int, data: bytes, address: int, counter: int) -> bytes:
    """The bytes of a mailbox of channel 0, priority 0: the hot path of every client request.

    No dataclass and no range checks: the caller passes a type from :class:`MailboxType`, an address it
    checked once and a counter from :func:`next_counter` (:func:`encode_mailbox` checks everything).
    """
    return _HEADER.pack(len(data), address, 0, mtype | counter << 4) + data


def split(buf: bytes) -> tuple[int, int, int, bytes]:
    """(type, counter, address, data) of a mailbox without building a :class:`Mailbox`; the same length
    rules as :func:`decode_mailbox` (trailing bytes ignored, SPEC-NOTES 15's clipped length)."""
    size = len(buf)
    if size < HEADER_SIZE:
        raise MailboxError(f"mailbox of {size} bytes is shorter than its 6-byte header")
    length, address, _chan_prio, type_counter = _HEADER.unpack_from(buf)
    end = HEADER_SIZE + length
    if end > size:
        # SPEC-NOTES 15: the manual's example counts the length from byte 2.
        if length >= 4 and 2 + length <= size:
            end = 2 + length
        else:
            raise MailboxError(
                f"mailbox header announces {length} data bytes but only {size - HEADER_SIZE} follow"
            )
    return type_counter & 0x0F, (type_counter >> 4) & 0x07, address, bytes(buf[HEADER_SIZE:end])


def decode_mailbox(buf: bytes) -> Mailbox:
    """Parse a mailbox; trailing bytes (the rest of an SM buffer) are ignored."""
    mtype, counter, address, data = split(buf)
    chan_prio = buf[4]
    return Mailbox(
        type=mtype,
        data=data,
        address=address,
        channel=chan_prio & 0x3F,
        priority=chan_prio >> 6,
        counter=counter,
    )


def next_counter(counter: int) -> int:
    """The mailbox counter after ``counter``: 1..7 wrapping, never 0 (0 means "no counter")."""
    return 1 if counter >= 7 or counter < 1 else counter + 1


# --- mailbox error reply (type 0) -------------------------------------------------------------

MAILBOX_ERROR_SERVICE = 0x0001  # "mailbox command" service type of an error reply

ERR_SYNTAX = 1
ERR_UNSUPPORTED_PROTOCOL = 2
ERR_INVALID_CHANNEL = 3
ERR_SERVICE_NOT_SUPPORTED = 4
ERR_INVALID_HEADER = 5
ERR_SIZE_TOO_SHORT = 6
ERR_NO_MORE_MEMORY = 7
ERR_INVALID_SIZE = 8


class MailboxErrorReply(Record):
    """A slave's refusal of a whole mailbox (ETG.1000.6 mailbox error reply, type 0).

    A slave sends it instead of a protocol reply when it cannot even parse the
    request, so a client must report it rather than wait for an SDO answer.
    Its wording is :func:`akdctl.catalog.texts.mailbox_error_text` (codecs return codes).
    """

    __slots__ = ("code",)

    def __init__(self, code: int) -> None:
        self.code = code



def encode_error_reply(reply: MailboxErrorReply) -> bytes:
    """The 4 data bytes of a type-0 mailbox: service type 0x0001, detail code."""
    code = _check("error code", reply.code, 0, 0xFFFF)
    return struct.pack("<HH", MAILBOX_ERROR_SERVICE, code)


def decode_error_reply(data: bytes) -> MailboxErrorReply:
    """Parse the data of a type-0 mailbox."""
    data = bytes(data)
    if len(data) < 4:
        raise MailboxError(f"mailbox error reply of {len(data)} bytes is shorter than 4")
    service, code = struct.unpack_from("<HH", data)
    if service != MAILBOX_ERROR_SERVICE:
        raise MailboxError(f"mailbox error reply with service type 0x{service:04X} (expected 0x0001)")
    return MailboxErrorReply(code)


# --- ETG.8200 mailbox gateway ------------------------------------------------------------------


_GATEWAY_HEADER = struct.Struct("<H")
_GATEWAY_AND_LENGTH = struct.Struct("<HH")  # the EtherCAT header and the mailbox's own length field after it


def wrap_gateway(mailbox: bytes) -> bytes:
    """An encoded mailbox behind the 2-byte EtherCAT header (length | type 5 << 12) a gateway expects."""
    if len(mailbox) > _MAX_GATEWAY_LENGTH:
        raise MailboxError(f"gateway frame of {len(mailbox)} bytes exceeds the 11-bit EtherCAT length")
    return _GATEWAY_HEADER.pack(len(mailbox) | GATEWAY_FRAME_TYPE << 12) + mailbox


def gateway_header(size: int) -> bytes:
    """The 2-byte EtherCAT header :func:`wrap_gateway` puts before a mailbox of ``size`` bytes, alone: a gateway
    that answers many mailboxes of a few sizes keeps one per size and joins it to each (the simulated gateway)."""
    if size > _MAX_GATEWAY_LENGTH:
        raise MailboxError(f"gateway frame of {size} bytes exceeds the 11-bit EtherCAT length")
    return _GATEWAY_HEADER.pack(size | GATEWAY_FRAME_TYPE << 12)


def unwrap_gateway(buf: bytes) -> bytes:
    """The mailbox bytes inside a gateway datagram, checked: type 5, a length that fits the datagram
    and agrees with the mailbox's own length (one rule for the client's and the gateway's side)."""
    size = len(buf)
    if size < GATEWAY_HEADER_SIZE + HEADER_SIZE:
        raise MailboxError(f"gateway datagram of {size} bytes is too short for a mailbox")
    header, inner = _GATEWAY_AND_LENGTH.unpack_from(buf)
    length = header & _MAX_GATEWAY_LENGTH
    if header >> 12 != GATEWAY_FRAME_TYPE or length != HEADER_SIZE + inner or length + GATEWAY_HEADER_SIZE > size:
        _gateway_refused(header, inner, size)
    mailbox = buf[GATEWAY_HEADER_SIZE : GATEWAY_HEADER_SIZE + length]
    return mailbox if mailbox.__class__ is bytes else bytes(mailbox)


def _gateway_refused(header: int, inner: int, size: int) -> None:
    """Raise the error :func:`unwrap_gateway` found (apart, so the checks above are one line)."""
    ftype, length = header >> 12, header & _MAX_GATEWAY_LENGTH
    if ftype != GATEWAY_FRAME_TYPE:
        raise MailboxError(f"EtherCAT frame type {ftype} is not a mailbox (5)")
    if length < HEADER_SIZE or GATEWAY_HEADER_SIZE + length > size:
        raise MailboxError(f"EtherCAT header length {length} does not fit a datagram of {size} bytes")
    raise MailboxError(f"EtherCAT header length {length} disagrees with mailbox length {inner} + 6")


def encode_gateway(mbx: Mailbox) -> bytes:
    """Wrap a mailbox in the 2-byte EtherCAT header (length | type 5 << 12) a gateway expects."""
    return wrap_gateway(encode_mailbox(mbx))


def decode_gateway(buf: bytes) -> Mailbox:
    """Unwrap a gateway datagram; the EtherCAT header must say type 5 and fit the datagram."""
    return decode_mailbox(unwrap_gateway(buf))
