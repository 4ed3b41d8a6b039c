"""PROFIdrive base-mode parameter access (BMP): request and response blocks, both directions.

The AKD's parameter manager is reached through PROFINET record 47 (``0x2F``); what
travels in that record is the block encoded here. The client (``channels.bmp``)
encodes requests and decodes responses, the simulator (``sim.pnu_server``) does
the opposite, so both ends share one implementation of the layout.

Layout (all multi-byte fields big-endian, SPEC-NOTES 1)::

    request  = ref u8, request id u8, axis u8, n u8,
               n × (attribute u8, elements u8, PNU u16, subindex u16),
               [change only] n × value block
    response = ref u8, response id u8, axis u8, n u8, n × value block
    value block = format u8, number of values u8, values, one zero pad byte
                  when the value bytes are odd (blocks are word aligned)

A negative parameter result is a value block of format 0x44 with one or two
u16 values (error value, additional info). SPEC-NOTES 2: attribute "value" is
0x10. SPEC-NOTES 3: a positive change response is either the bare 4-byte header
or, as the seed manuals print it, the header plus one ``00 00`` block per
parameter; both decode, and :func:`encode_response` emits the seed form.
SPEC-NOTES 4: 1..39 parameters, 1..234 elements, subindex 0..0xFFFE, at most 240
bytes per block -- checked when encoding and when decoding.

Every malformed input raises :class:`BmpError` (a
:class:`~akdctl.protocol.errors.CodecError`); nothing else escapes.
"""

from __future__ import annotations

import operator
import struct
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from akdctl.protocol.errors import CodecError
from akdctl.protocol.record import Record

# --- field values ---------------------------------------------------------------------------------------------

ATTR_VALUE = 0x10
ATTR_DESCRIPTION = 0x20
ATTR_TEXT = 0x30
ATTRIBUTES = (ATTR_VALUE, ATTR_DESCRIPTION, ATTR_TEXT)

REQ_READ = 0x01
REQ_CHANGE = 0x02

RESP_READ_OK = 0x01
RESP_CHANGE_OK = 0x02
RESP_READ_NAK = 0x81
RESP_CHANGE_NAK = 0x82
#: Response ID for a request ID the device does not know (PROFIdrive "service not supported").
RESP_NOT_SUPPORTED = 0x80
RESPONSE_IDS = (RESP_READ_OK, RESP_CHANGE_OK, RESP_READ_NAK, RESP_CHANGE_NAK, RESP_NOT_SUPPORTED)

MAX_PARAMETERS = 39
MAX_ELEMENTS = 234
MAX_SUBINDEX = 0xFFFE
MAX_BLOCK = 240
HEADER_SIZE = 4
ADDRESS_SIZE = 6
DESCRIPTION_SIZE = 46

#: Largest element the AKD uses (SPEC-NOTES 5: byte, word, dword): the default for response size planning.
DEFAULT_ELEMENT_SIZE = 4

# Error values (PROFIdrive error value 1) that the server and tests name.
ERR_PNU = 0x00
ERR_READ_ONLY = 0x01
ERR_LIMIT = 0x02
ERR_SUBINDEX = 0x03
ERR_NO_ARRAY = 0x04
ERR_DATA_TYPE = 0x05
ERR_RESET_ONLY = 0x06
ERR_DESCRIPTION_READ_ONLY = 0x07
ERR_NO_DESCRIPTION = 0x09
ERR_NO_OPERATION_PRIORITY = 0x0B
ERR_NO_TEXT = 0x0F
ERR_OPERATING_STATE = 0x11
ERR_VALUE = 0x14
ERR_RESPONSE_TOO_LONG = 0x15
ERR_ADDRESS = 0x16
ERR_FORMAT = 0x17
ERR_VALUE_COUNT = 0x18
ERR_AXIS = 0x19
ERR_TEXT_READ_ONLY = 0x20
ERR_SERVICE = 0x21
ERR_TOO_MANY = 0x22
ERR_NO_MULTI = 0x23

# Identifier (V2) bits of a parameter description (PROFIdrive table 18).
ID_NO_STANDARDISATION = 1 << 8
ID_READ_ONLY = 1 << 9
ID_TEXT = 1 << 10
ID_CHANGED = 1 << 12
ID_RESET_ONLY = 1 << 13
ID_ARRAY = 1 << 14


class BmpError(CodecError):
    """A base-mode parameter block that does not decode, or an object that cannot be encoded."""


class _Formats(type):
    """Iterating :class:`Format` yields its values in order, as iterating the enum it was did."""

    def __iter__(cls) -> Iterator[int]:
        return iter(cls._values)  # type: ignore[attr-defined]


class Format(metaclass=_Formats):
    """Format byte of a value block; the standard data types double as description data types.

    Plain integer constants (``Format.INT16 == 3``; ``for f in Format`` yields the values, :func:`format_name` the
    names): an enum of 36 members costs more to create at every start than a command spends on its parameters.
    """

    BOOLEAN = 0x01
    INT8 = 0x02
    INT16 = 0x03
    INT32 = 0x04
    UINT8 = 0x05
    UINT16 = 0x06
    UINT32 = 0x07
    FLOAT32 = 0x08
    VISIBLE_STRING = 0x09
    OCTET_STRING = 0x0A
    TIME_OF_DAY = 0x0C
    FLOAT64 = 0x0F
    UNICODE_STRING = 0x27
    BINARY_DATE = 0x32
    TIME_OF_DAY_NO_DATE = 0x34
    TIME_DIFFERENCE = 0x35
    TIME_DIFFERENCE_NO_DATE = 0x36
    INT64 = 0x37
    UINT64 = 0x38
    ZERO = 0x40
    BYTE = 0x41
    WORD = 0x42
    DWORD = 0x43
    ERROR = 0x44
    # Profile-specific types: description identifiers, but some devices also answer with them as formats.
    N2 = 113
    N4 = 114
    V2 = 115
    L2 = 116
    R2 = 117
    T2 = 118
    T4 = 119
    D2 = 120
    E2 = 121
    C4 = 122
    X2 = 123
    X4 = 124


Format._values = tuple(value for name, value in vars(Format).items() if name.isupper())  # type: ignore[attr-defined]
_FORMAT_NAMES = {value: name for name, value in vars(Format).items() if name.isupper()}

# struct code per numeric format; the byte count follows from it.
_STRUCT: dict[int, str] = {
    Format.INT8: "b", Format.INT16: "h", Format.INT32: "i", Format.INT64: "q",
    Format.UINT8: "B", Format.UINT16: "H", Format.UINT32: "I", Format.UINT64: "Q",
    Format.FLOAT32: "f", Format.FLOAT64: "d",
    Format.BYTE: "B", Format.WORD: "H", Format.DWORD: "I",
    Format.N2: "h", Format.X2: "h", Format.E2: "h",
    Format.V2: "H", Format.L2: "H", Format.R2: "H", Format.T2: "H", Format.D2: "H",
    Format.N4: "i", Format.X4: "i", Format.C4: "i", Format.T4: "I",
}
# Date/time types travel as raw octets of a fixed size (their calendar meaning is not the codec's business).
_RAW_SIZE: dict[int, int] = {
    Format.TIME_OF_DAY: 6,
    Format.BINARY_DATE: 7,
    Format.TIME_OF_DAY_NO_DATE: 4,
    Format.TIME_DIFFERENCE: 6,
    Format.TIME_DIFFERENCE_NO_DATE: 4,
}
#: The formats whose one value is a whole string (the wire "number of values" counts characters/octets).
STRING_FORMATS = frozenset({Format.VISIBLE_STRING, Format.OCTET_STRING, Format.UNICODE_STRING})
_KNOWN_FORMATS = frozenset(int(f) for f in Format)


def format_size(fmt: int) -> int:
    """Bytes per value of ``fmt`` on the wire (per character for strings; 0 for Zero, 2 for Error)."""
    size = _SIZES.get(fmt)
    if size is not None:
        return size
    return _format_size(fmt)


def _format_size(fmt: int) -> int:
    if fmt in _STRUCT:
        return struct.calcsize(">" + _STRUCT[fmt])
    if fmt in _RAW_SIZE:
        return _RAW_SIZE[fmt]
    if fmt in (Format.BOOLEAN, Format.VISIBLE_STRING, Format.OCTET_STRING):
        return 1
    if fmt in (Format.UNICODE_STRING, Format.ERROR):
        return 2
    if fmt == Format.ZERO:
        return 0
    raise BmpError(f"unknown format 0x{fmt:02X}")


_SIZES: dict[int, int] = {int(f): _format_size(f) for f in Format}


def format_name(fmt: int) -> str:
    """Readable name of a format byte, also for reserved ones."""
    name = _FORMAT_NAMES.get(fmt)
    return name if name is not None else f"format 0x{fmt:02X}"


def to_signed(value: int, bits: int) -> int:
    """Reinterpret an unsigned ``bits``-wide value (Byte/Word/DWord formats are unsigned) as two's complement."""
    value &= (1 << bits) - 1
    return value - (1 << bits) if value >> (bits - 1) else value


def to_unsigned(value: int, bits: int) -> int:
    """Two's-complement bits of a signed value, for writing it with a Byte/Word/DWord format."""
    return value & ((1 << bits) - 1)


def _pad(n: int) -> int:
    """Word alignment: odd byte counts take one zero pad byte."""
    return n + (n & 1)


# --- data classes ---------------------------------------------------------------------------------------------

Scalar = int | float | bytes | str


class ParameterAddress(Record):
    """One parameter in a request: ``count`` elements from ``subindex`` on, of one attribute."""

    __slots__ = ("pnu", "subindex", "count", "attribute")

    def __init__(self, pnu: int, subindex: int = 0, count: int = 1, attribute: int = ATTR_VALUE) -> None:
        self.pnu = pnu
        self.subindex = subindex
        self.count = count
        self.attribute = attribute

    def __str__(self) -> str:
        attr = {ATTR_VALUE: "", ATTR_DESCRIPTION: " description", ATTR_TEXT: " text"}.get(
            self.attribute, f" attribute 0x{self.attribute:02X}")
        span = f"[{self.subindex}]" if self.count == 1 else f"[{self.subindex}..{self.subindex + self.count - 1}]"
        return f"PNU {self.pnu}{span}{attr}"


class ParameterValue(Record):
    """The values of one parameter, in one wire format.

    Numeric formats hold one python number per element. The string formats
    (VisibleString, OctetString, UnicodeString) hold exactly one ``str``/``bytes``
    whose length is the wire "number of values". Date/time formats hold one
    ``bytes`` of the format's size per element. Byte/Word/DWord values are
    unsigned: use :func:`to_signed` when the parameter is signed.
    """

    __slots__ = ("format", "values")

    def __init__(self, format: int, values: tuple[Scalar, ...]) -> None:  # noqa: A002
        self.format = format
        self.values = values if type(values) is tuple else tuple(values)

    @property
    def count(self) -> int:
        """The wire "number of values" (characters/octets for strings)."""
        if self.format in STRING_FORMATS and len(self.values) == 1:
            value = self.values[0]
            if self.format == Format.UNICODE_STRING and isinstance(value, str):
                return len(value.encode("utf-16-be", "surrogatepass")) // 2
            return len(value)  # type: ignore[arg-type]
        return len(self.values)

    @property
    def value(self) -> Scalar:
        """The single value (first element) -- what most PNUs have."""
        if not self.values:
            raise BmpError("parameter value has no elements")
        return self.values[0]

    @classmethod
    def of(cls, fmt: int, *values: Scalar) -> "ParameterValue":
        return cls(fmt, tuple(values))


class ParameterFailure(Record):
    """A negative per-parameter result: PROFIdrive error value and optional additional info.

    Codes only: the words are :func:`akdctl.catalog.texts.profidrive_error_text` and
    :func:`~akdctl.catalog.texts.profidrive_failure_detail`.
    """

    __slots__ = ("error", "additional")

    def __init__(self, error: int, additional: int | None = None) -> None:
        self.error = error
        self.additional = additional


ParameterResult = ParameterValue | ParameterFailure | None


class ParameterRequest(Record):
    """A read (``REQ_READ``) or change (``REQ_CHANGE``) request; ``values`` only for changes, one per address."""

    __slots__ = ("reference", "request_id", "axis", "addresses", "values")

    def __init__(self, reference: int, request_id: int, axis: int, addresses: tuple[ParameterAddress, ...],
                 values: tuple[ParameterValue, ...] = ()) -> None:
        self.reference = reference
        self.request_id = request_id
        self.axis = axis
        self.addresses = addresses if type(addresses) is tuple else tuple(addresses)
        self.values = values if type(values) is tuple else tuple(values)


class ParameterResponse(Record):
    """A response: one result per parameter (``None`` = accepted change, no values)."""

    __slots__ = ("reference", "response_id", "axis", "results")

    def __init__(self, reference: int, response_id: int, axis: int, results: tuple[ParameterResult, ...]) -> None:
        self.reference = reference
        self.response_id = response_id
        self.axis = axis
        self.results = results if type(results) is tuple else tuple(results)

    @property
    def negative(self) -> bool:
        return bool(self.response_id & 0x80)


# --- value blocks ---------------------------------------------------------------------------------------------


def _check_u8(name: str, value: object) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= 0xFF:
        raise BmpError(f"{name} must be 0..255, not {value!r}")
    return value


def check_address(address: object) -> ParameterAddress:
    """``address`` itself when it is a ParameterAddress within the wire limits, else BmpError."""
    if not isinstance(address, ParameterAddress):
        raise BmpError(f"not a parameter address: {address!r}")
    pnu, subindex, count, attribute = address.pnu, address.subindex, address.count, address.attribute
    if (type(pnu) is int and type(subindex) is int and type(count) is int and attribute in ATTRIBUTES
            and 1 <= pnu <= 0xFFFF and 0 <= subindex <= MAX_SUBINDEX and 1 <= count <= MAX_ELEMENTS):
        return address  # the usual case, in one test (this runs once per parameter on every request)
    if attribute not in ATTRIBUTES:
        raise BmpError(f"{address}: attribute 0x{attribute:02X} is not value/description/text" if isinstance(
            attribute, int) else f"attribute {attribute!r} is not an integer")
    for name, value, low, high in (
        ("PNU", pnu, 1, 0xFFFF),
        ("subindex", subindex, 0, MAX_SUBINDEX),
        ("number of elements", count, 1, MAX_ELEMENTS),
    ):
        if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
            raise BmpError(f"{name} must be {low}..{high}, not {value!r}")
    return address


def _encode_scalar(fmt: int, value: object) -> bytes:
    """One element of a numeric / boolean / date-time format."""
    if fmt == Format.BOOLEAN:
        if value is True or value is False or value in (0, 1):
            if isinstance(value, (int, bool)):
                return bytes([int(value)])
        raise BmpError(f"BOOLEAN value must be True/False or 0/1, not {value!r}")
    if fmt in _RAW_SIZE:
        if not isinstance(value, (bytes, bytearray)) or len(value) != _RAW_SIZE[fmt]:
            raise BmpError(f"{format_name(fmt)} value must be {_RAW_SIZE[fmt]} bytes, not {value!r}")
        return bytes(value)
    code = _STRUCT[fmt]
    if code in "fd":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise BmpError(f"{format_name(fmt)} value must be a number, not {value!r}")
        try:
            return struct.pack(">" + code, float(value))
        except (OverflowError, struct.error) as exc:
            raise BmpError(f"{value!r} does not fit {format_name(fmt)}") from exc
    if isinstance(value, bool) or not isinstance(value, int):
        raise BmpError(f"{format_name(fmt)} value must be an integer, not {value!r}")
    try:
        return struct.pack(">" + code, value)
    except struct.error as exc:
        raise BmpError(f"{value} is out of range for {format_name(fmt)}") from exc


def _value_bytes(value: ParameterValue) -> bytes:
    """The raw (unpadded) value bytes of a block, validating count and types."""
    fmt = value.format
    if not isinstance(fmt, int) or fmt not in _KNOWN_FORMATS:
        raise BmpError(f"cannot encode unknown format {fmt!r}")
    if fmt == Format.ERROR:
        raise BmpError("format 0x44 (error) is carried by ParameterFailure, not ParameterValue")
    if fmt == Format.ZERO:
        if value.values:
            raise BmpError("format 0x40 (zero) carries no values")
        return b""
    if fmt in STRING_FORMATS:
        if len(value.values) != 1:
            raise BmpError(f"{format_name(fmt)} holds exactly one string, not {len(value.values)} values")
        item = value.values[0]
        if fmt == Format.OCTET_STRING:
            if not isinstance(item, (bytes, bytearray)):
                raise BmpError(f"OCTET_STRING value must be bytes, not {item!r}")
            data = bytes(item)
        elif not isinstance(item, str):
            raise BmpError(f"{format_name(fmt)} value must be str, not {item!r}")
        elif fmt == Format.VISIBLE_STRING:
            try:
                data = item.encode("latin-1")
            except UnicodeEncodeError as exc:
                raise BmpError(f"VISIBLE_STRING {item!r} has characters outside ISO 8859-1") from exc
        else:
            data = item.encode("utf-16-be", "surrogatepass")
        count = len(data) // format_size(fmt)
    else:
        count = len(value.values)
        data = b"".join(_encode_scalar(fmt, v) for v in value.values)
    if not 1 <= count <= MAX_ELEMENTS:
        raise BmpError(f"a {format_name(fmt)} block must hold 1..{MAX_ELEMENTS} values, not {count}")
    return data


def encode_value_block(value: ParameterValue) -> bytes:
    """Format, number of values, values, pad byte if odd."""
    data = _value_bytes(value)
    block = bytes([value.format, value.count if value.format != Format.ZERO else 0]) + data
    return block + b"\x00" * (len(data) & 1)


def _encode_failure(failure: ParameterFailure) -> bytes:
    if not isinstance(failure.error, int) or not 0 <= failure.error <= 0xFFFF:
        raise BmpError(f"error value must be 0..0xFFFF, not {failure.error!r}")
    if failure.additional is not None and (not isinstance(failure.additional, int)
                                           or not 0 <= failure.additional <= 0xFFFF):
        raise BmpError(f"additional info must be 0..0xFFFF, not {failure.additional!r}")
    return pack_failure_block(failure.error, failure.additional)


def pack_failure_block(error: int, additional: int | None = None) -> bytes:
    """An error block (format 0x44): the error value, and the additional information when there is one
    (values masked to 16 bits: the server's fast path passes what the model raised)."""
    if additional is None:
        return struct.pack(">BBH", Format.ERROR, 1, error & 0xFFFF)
    return struct.pack(">BBHH", Format.ERROR, 2, error & 0xFFFF, additional & 0xFFFF)


_ZERO_FORMATS = (0x00, int(Format.ZERO))
_ERROR = int(Format.ERROR)
_NUMERIC: dict[tuple[int, int], struct.Struct] = {}  # (format, count) -> Struct: built once per shape


def decode_value_block(data: bytes, offset: int) -> tuple[ParameterResult, int]:
    """Decode the block at ``offset``; returns the result and the offset after it (pad included).

    A missing pad byte is tolerated only at the very end of ``data``.
    Format 0x40 (and the seed's 0x00) with no values decodes to ``None``.
    """
    size_all = len(data)
    if offset + 2 > size_all:
        raise BmpError(f"value block at byte {offset} is cut short (need format and number of values)")
    fmt, count = data[offset], data[offset + 1]
    start = offset + 2
    if fmt in _ZERO_FORMATS:
        if count:
            raise BmpError(f"format 0x{fmt:02X} at byte {offset} announces {count} values; it carries none")
        return None, start
    per = _SIZES.get(fmt)
    if per is None:
        raise BmpError(f"unknown format 0x{fmt:02X} at byte {offset}")
    if count == 0:
        raise BmpError(f"{format_name(fmt)} block at byte {offset} has no values")
    if fmt == _ERROR and count not in (1, 2):
        raise BmpError(f"error block at byte {offset} has {count} values; it must have 1 or 2")
    if count > MAX_ELEMENTS:
        raise BmpError(f"block at byte {offset} announces {count} values (at most {MAX_ELEMENTS})")
    size = per * count
    end = start + size
    if end > size_all:
        raise BmpError(f"{format_name(fmt)} block at byte {offset} announces {count} values "
                       f"({size} bytes) but only {size_all - start} follow")
    after = start + size + (size & 1)
    if after > size_all:  # the last block's pad byte may be missing
        after = size_all
    code = _STRUCT.get(fmt)
    if code is not None and fmt != _ERROR:
        shape = _NUMERIC.get((fmt, count))
        if shape is None:
            shape = _NUMERIC[(fmt, count)] = struct.Struct(f">{count}{code}")
        return ParameterValue(fmt, shape.unpack_from(data, start)), after
    return _decode_values(fmt, count, data[start:end]), after


def _decode_values(fmt: int, count: int, raw: bytes) -> ParameterResult:
    if fmt == Format.ERROR:
        words = struct.unpack(f">{count}H", raw)
        return ParameterFailure(words[0], words[1] if count == 2 else None)
    if fmt == Format.BOOLEAN:
        return ParameterValue(fmt, tuple(bool(b) for b in raw))
    if fmt == Format.OCTET_STRING:
        return ParameterValue(fmt, (bytes(raw),))
    if fmt == Format.VISIBLE_STRING:
        return ParameterValue(fmt, (raw.decode("latin-1"),))
    if fmt == Format.UNICODE_STRING:
        try:
            return ParameterValue(fmt, (raw.decode("utf-16-be", "surrogatepass"),))
        except UnicodeDecodeError as exc:  # pragma: no cover - surrogatepass accepts any even length
            raise BmpError("UNICODE_STRING does not decode") from exc
    if fmt in _RAW_SIZE:
        step = _RAW_SIZE[fmt]
        return ParameterValue(fmt, tuple(raw[i:i + step] for i in range(0, len(raw), step)))
    return ParameterValue(fmt, struct.unpack(f">{count}{_STRUCT[fmt]}", raw))


# --- requests -------------------------------------------------------------------------------------------------


def decode_header(data: bytes) -> tuple[int, int, int, int]:
    """Reference, request/response ID, axis, number of parameters."""
    if len(data) < HEADER_SIZE:
        raise BmpError(f"block of {len(data)} bytes is shorter than the 4-byte header")
    return data[0], data[1], data[2], data[3]


_ADDRESS = struct.Struct(">BBHH")  # attribute, number of elements, PNU, subindex


def decode_address(data: bytes, offset: int) -> ParameterAddress:
    """The 6-byte parameter address at ``offset`` (limits not checked: the server answers them per parameter)."""
    if offset + ADDRESS_SIZE > len(data):
        raise BmpError(f"parameter address at byte {offset} is cut short")
    attribute, count, pnu, subindex = _ADDRESS.unpack_from(data, offset)
    return ParameterAddress(pnu, subindex, count, attribute)


def request_size(request: ParameterRequest) -> int:
    """Encoded size of a request in bytes (without validating it)."""
    size = HEADER_SIZE + ADDRESS_SIZE * len(request.addresses)
    for value in request.values:
        size += 2 + _pad(len(_value_bytes(value)))
    return size


def encode_request(request: ParameterRequest, *, addresses_checked: bool = False) -> bytes:
    """Encode a request, refusing anything a device would reject at the header or address level.

    ``addresses_checked``: every address already passed :func:`check_address` (the parameter
    channel checks each address once, on entry, before anything is sent).
    """
    _check_u8("request reference", request.reference)
    _check_u8("axis", request.axis)
    if request.request_id not in (REQ_READ, REQ_CHANGE):
        raise BmpError(f"request ID must be 0x01 (read) or 0x02 (change), not {request.request_id!r}")
    n = len(request.addresses)
    if not 1 <= n <= MAX_PARAMETERS:
        raise BmpError(f"a request carries 1..{MAX_PARAMETERS} parameters, not {n}")
    out = bytearray((request.reference, request.request_id, request.axis, n))
    for address in request.addresses:
        a = address if addresses_checked else check_address(address)
        out += struct.pack(">BBHH", a.attribute, a.count, a.pnu, a.subindex)
    if request.request_id == REQ_READ:
        if request.values:
            raise BmpError("a read request carries no values")
    else:
        if len(request.values) != n:
            raise BmpError(f"a change request needs one value per parameter: {n} parameters, "
                           f"{len(request.values)} values")
        for address, value in zip(request.addresses, request.values):
            if not isinstance(value, ParameterValue):
                raise BmpError(f"not a parameter value: {value!r}")
            if value.format == Format.ZERO:
                raise BmpError(f"{address}: a change request needs values, not format 0x40")
            block = encode_value_block(value)
            if value.count != address.count:
                raise BmpError(f"{address}: number of elements {address.count} but {value.count} values")
            out += block
    if len(out) > MAX_BLOCK:
        raise BmpError(f"request of {len(out)} bytes exceeds the {MAX_BLOCK}-byte block")
    return bytes(out)


def decode_request(data: bytes) -> ParameterRequest:
    """Decode a request strictly (the server does its own staged checks to pick error values)."""
    data = bytes(data)
    if len(data) > MAX_BLOCK:
        raise BmpError(f"request of {len(data)} bytes exceeds the {MAX_BLOCK}-byte block")
    reference, request_id, axis, n = decode_header(data)
    if request_id not in (REQ_READ, REQ_CHANGE):
        raise BmpError(f"request ID 0x{request_id:02X} is neither read (0x01) nor change (0x02)")
    if not 1 <= n <= MAX_PARAMETERS:
        raise BmpError(f"number of parameters {n} is outside 1..{MAX_PARAMETERS}")
    addresses = []
    for i in range(n):
        address = decode_address(data, HEADER_SIZE + ADDRESS_SIZE * i)
        try:
            addresses.append(check_address(address))
        except BmpError as exc:
            raise BmpError(f"parameter {i + 1}: {exc}") from None
    offset = HEADER_SIZE + ADDRESS_SIZE * n
    values: list[ParameterValue] = []
    if request_id == REQ_CHANGE:
        for i, address in enumerate(addresses):
            result, offset = decode_value_block(data, offset)
            if not isinstance(result, ParameterValue):
                raise BmpError(f"parameter {i + 1}: a change request needs a value block, not "
                               f"{'an error block' if result is not None else 'format zero'}")
            if result.count != address.count:
                raise BmpError(f"parameter {i + 1}: number of elements {address.count} but "
                               f"{result.count} values")
            values.append(result)
    if offset != len(data):
        raise BmpError(f"{len(data) - offset} unexpected bytes after the last parameter")
    return ParameterRequest(reference, request_id, axis, tuple(addresses), tuple(values))


# --- responses ------------------------------------------------------------------------------------------------


def encode_response(response: ParameterResponse, *, compact: bool = False) -> bytes:
    """Encode a response.

    A positive change response is emitted as the seed manuals show it (header plus
    one ``00 00`` block per parameter, SPEC-NOTES 3) unless ``compact`` asks for the
    bare header. In a negative change response accepted parameters are listed as
    format 0x40 with no values.
    """
    _check_u8("request reference", response.reference)
    _check_u8("axis", response.axis)
    rid = response.response_id
    if rid not in RESPONSE_IDS:
        raise BmpError(f"unknown response ID {rid!r}")
    n = len(response.results)
    if not 1 <= n <= MAX_PARAMETERS:
        raise BmpError(f"a response carries 1..{MAX_PARAMETERS} parameters, not {n}")
    out = bytearray((response.reference, rid, response.axis, n))
    for i, result in enumerate(response.results):
        where = f"parameter {i + 1}"
        if isinstance(result, ParameterFailure):
            if rid in (RESP_READ_OK, RESP_CHANGE_OK):
                raise BmpError(f"{where}: a positive response cannot carry an error")
            out += _encode_failure(result)
        elif isinstance(result, ParameterValue):
            if rid not in (RESP_READ_OK, RESP_READ_NAK):
                raise BmpError(f"{where}: only read responses carry values")
            if result.format == Format.ZERO:
                out += b"\x40\x00"
            else:
                out += encode_value_block(result)
        elif result is None:
            if rid == RESP_CHANGE_OK:
                if not compact:
                    out += b"\x00\x00"
            elif rid == RESP_CHANGE_NAK:
                out += b"\x40\x00"
            else:
                raise BmpError(f"{where}: a read response needs a value or an error")
        else:
            raise BmpError(f"{where}: not a parameter result: {result!r}")
    if rid == RESP_NOT_SUPPORTED and not all(isinstance(r, ParameterFailure) for r in response.results):
        raise BmpError("a 'service not supported' response carries only errors")
    if len(out) > MAX_BLOCK:
        raise BmpError(f"response of {len(out)} bytes exceeds the {MAX_BLOCK}-byte block")
    return bytes(out)


def decode_response(data: bytes, request: ParameterRequest | None = None) -> ParameterResponse:
    """Decode a response; with ``request``, also check that it answers that request.

    Checks against the request: reference, axis, response ID (the request's ID, its
    negative form, or 0x80), one result per parameter, and for value reads the
    number of values asked for. A negative response with a single error for a
    multi-parameter request is how devices refuse a whole request (header errors):
    that error is applied to every parameter.
    """
    data = bytes(data)
    if len(data) > MAX_BLOCK:
        raise BmpError(f"response of {len(data)} bytes exceeds the {MAX_BLOCK}-byte block")
    reference, rid, axis, n = decode_header(data)
    if rid not in RESPONSE_IDS:
        raise BmpError(f"unknown response ID 0x{rid:02X}")
    if not 1 <= n <= MAX_PARAMETERS:
        raise BmpError(f"number of parameters {n} is outside 1..{MAX_PARAMETERS}")
    if request is not None:
        if reference != request.reference:
            raise BmpError(f"response reference {reference} does not match request reference "
                           f"{request.reference} (a stale or foreign reply)")
        if rid not in (request.request_id, request.request_id | 0x80, RESP_NOT_SUPPORTED):
            raise BmpError(f"response ID 0x{rid:02X} does not answer a "
                           f"{'read' if request.request_id == REQ_READ else 'change'} request")
        if axis != request.axis:
            raise BmpError(f"response is for axis {axis}, the request was for axis {request.axis}")
    results: list[ParameterResult] = []
    if rid == RESP_CHANGE_OK and len(data) == HEADER_SIZE:
        results = [None] * n
    else:
        offset = HEADER_SIZE
        for i in range(n):
            try:
                result, offset = decode_value_block(data, offset)
            except BmpError as exc:
                raise BmpError(f"parameter {i + 1} of {n}: {exc}") from None
            if isinstance(result, ParameterValue) and rid not in (RESP_READ_OK, RESP_READ_NAK):
                raise BmpError(f"parameter {i + 1}: a {format_name(result.format)} value block in a "
                               f"response with ID 0x{rid:02X}")
            results.append(result)
        if offset != len(data):
            raise BmpError(f"{len(data) - offset} unexpected bytes after parameter {n}")
    if request is not None:
        results = _match_request(results, rid, request)
    return ParameterResponse(reference, rid, axis, tuple(results))


def _match_request(results: list[ParameterResult], rid: int, request: ParameterRequest) -> list[ParameterResult]:
    wanted = len(request.addresses)
    if len(results) != wanted:
        if rid & 0x80 and len(results) == 1 and isinstance(results[0], ParameterFailure):
            return [results[0]] * wanted
        raise BmpError(f"response carries {len(results)} results for {wanted} parameters")
    for i, (address, result) in enumerate(zip(request.addresses, results)):
        if request.request_id == REQ_READ and result is None:
            raise BmpError(f"parameter {i + 1} ({address}): read answered with no value")
        if (isinstance(result, ParameterValue) and address.attribute == ATTR_VALUE
                and result.count != address.count):
            raise BmpError(f"parameter {i + 1} ({address}): asked for {address.count} values, "
                           f"got {result.count}")
    return results


# --- parameter description (attribute 0x20) -------------------------------------------------------------------

_DESCRIPTION = struct.Struct(">HHfH4s16s4s4s2sHHH")
assert _DESCRIPTION.size == DESCRIPTION_SIZE

#: Description element per subindex (PROFIdrive table 17): name, format of the element read alone.
DESCRIPTION_ELEMENTS: dict[int, tuple[str, int]] = {
    1: ("identifier", Format.V2),
    2: ("number of elements", Format.UINT16),
    3: ("standardisation factor", Format.FLOAT32),
    4: ("variable attribute", Format.OCTET_STRING),
    5: ("reserved", Format.OCTET_STRING),
    6: ("name", Format.VISIBLE_STRING),
    7: ("low limit", Format.OCTET_STRING),
    8: ("high limit", Format.OCTET_STRING),
    9: ("reserved", Format.OCTET_STRING),
    10: ("ID extension", Format.V2),
    11: ("normalisation reference parameter", Format.UINT16),
    12: ("normalisation field", Format.V2),
}

#: Byte range of each description element inside the 46-byte block (subindex -> (start, end)).
DESCRIPTION_OFFSETS: dict[int, tuple[int, int]] = {
    1: (0, 2), 2: (2, 4), 3: (4, 8), 4: (8, 10), 5: (10, 14), 6: (14, 30), 7: (30, 34), 8: (34, 38),
    9: (38, 40), 10: (40, 42), 11: (42, 44), 12: (44, 46),
}


class ParameterDescription(Record):
    """The 46-byte PROFIdrive parameter description.

    ``identifier`` is the V2 identifier: data type in bits 0..7 plus the ``ID_*``
    flags. ``low_limit``/``high_limit`` are the raw 4-octet fields (use
    :meth:`limits` for numbers). ``name`` is at most 16 ISO 8859-1 characters.
    """

    __slots__ = ("identifier", "elements", "standardisation_factor", "variable_attribute", "name", "low_limit",
                 "high_limit", "id_extension", "normalisation_ref", "normalisation_field")

    def __init__(self, identifier: int, elements: int = 0, standardisation_factor: float = 1.0,
                 variable_attribute: int = 0, name: str = "", low_limit: bytes = b"\x00\x00\x00\x00",
                 high_limit: bytes = b"\x00\x00\x00\x00", id_extension: int = 0, normalisation_ref: int = 0,
                 normalisation_field: int = 0) -> None:
        self.identifier = identifier
        self.elements = elements
        self.standardisation_factor = standardisation_factor
        self.variable_attribute = variable_attribute
        self.name = name
        self.low_limit = low_limit
        self.high_limit = high_limit
        self.id_extension = id_extension
        self.normalisation_ref = normalisation_ref
        self.normalisation_field = normalisation_field

    @property
    def data_type(self) -> int:
        return self.identifier & 0xFF

    @property
    def is_array(self) -> bool:
        return bool(self.identifier & ID_ARRAY)

    @property
    def read_only(self) -> bool:
        return bool(self.identifier & ID_READ_ONLY)

    @property
    def reset_only(self) -> bool:
        return bool(self.identifier & ID_RESET_ONLY)

    @property
    def has_text(self) -> bool:
        return bool(self.identifier & ID_TEXT)

    def limits(self) -> tuple[int | float, int | float] | None:
        """Low/high limit as numbers for the numeric data types the fields can hold, else ``None``.

        Types narrower than 4 bytes are right-aligned in the field (as the Siemens
        reference implementation stores them); signed ones are sign-extended.
        """
        t = self.data_type
        if t == Format.FLOAT32:
            return (struct.unpack(">f", self.low_limit)[0], struct.unpack(">f", self.high_limit)[0])
        if t not in _STRUCT or _STRUCT[t] in "qQd":
            return None
        bits = 8 * format_size(t)
        signed = _STRUCT[t].islower()
        out = []
        for raw in (self.low_limit, self.high_limit):
            number = int.from_bytes(raw, "big") & ((1 << bits) - 1)
            out.append(to_signed(number, bits) if signed else number)
        return out[0], out[1]

    @staticmethod
    def limit_bytes(data_type: int, value: int | float) -> bytes:
        """Encode a number into a 4-octet limit field for ``data_type`` (inverse of :meth:`limits`)."""
        if data_type == Format.FLOAT32:
            return _encode_scalar(Format.FLOAT32, value)
        if data_type not in _STRUCT or _STRUCT[data_type] in "qQdf":
            raise BmpError(f"{format_name(data_type)} has no 4-byte limit encoding")
        raw = _encode_scalar(data_type, value)
        return (int.from_bytes(raw, "big")).to_bytes(4, "big")


def encode_description(description: ParameterDescription) -> bytes:
    d = description
    for name, value in (("identifier", d.identifier), ("number of elements", d.elements),
                        ("variable attribute", d.variable_attribute), ("ID extension", d.id_extension),
                        ("normalisation reference parameter", d.normalisation_ref),
                        ("normalisation field", d.normalisation_field)):
        if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= 0xFFFF:
            raise BmpError(f"description {name} must be 0..0xFFFF, not {value!r}")
    for name, raw in (("low limit", d.low_limit), ("high limit", d.high_limit)):
        if not isinstance(raw, (bytes, bytearray)) or len(raw) != 4:
            raise BmpError(f"description {name} must be 4 bytes, not {raw!r}")
    if not isinstance(d.standardisation_factor, (int, float)) or isinstance(d.standardisation_factor, bool):
        raise BmpError(f"standardisation factor must be a number, not {d.standardisation_factor!r}")
    if not isinstance(d.name, str):
        raise BmpError(f"description name must be str, not {d.name!r}")
    try:
        name = d.name.encode("latin-1")
    except UnicodeEncodeError as exc:
        raise BmpError(f"description name {d.name!r} has characters outside ISO 8859-1") from exc
    if len(name) > 16:
        raise BmpError(f"description name {d.name!r} is longer than 16 characters")
    factor = _encode_scalar(Format.FLOAT32, d.standardisation_factor)
    return _DESCRIPTION.pack(
        d.identifier, d.elements, struct.unpack(">f", factor)[0], d.variable_attribute, b"\x00" * 4,
        name.ljust(16, b" "), bytes(d.low_limit), bytes(d.high_limit), b"\x00\x00", d.id_extension,
        d.normalisation_ref, d.normalisation_field,
    )


def decode_description(data: bytes) -> ParameterDescription:
    data = bytes(data)
    if len(data) != DESCRIPTION_SIZE:
        raise BmpError(f"a parameter description is {DESCRIPTION_SIZE} bytes, not {len(data)}")
    (identifier, elements, factor, variable, _r1, name, low, high, _r2, id_ext,
     norm_ref, norm_field) = _DESCRIPTION.unpack(data)
    return ParameterDescription(
        identifier=identifier, elements=elements, standardisation_factor=factor,
        variable_attribute=variable, name=name.decode("latin-1").rstrip(" \x00"),
        low_limit=low, high_limit=high, id_extension=id_ext, normalisation_ref=norm_ref,
        normalisation_field=norm_field,
    )


def description_element(description: ParameterDescription, subindex: int) -> ParameterValue:
    """The value a description read of element ``subindex`` (1..12) returns; 0 is the whole block."""
    raw = encode_description(description)
    if subindex == 0:
        return ParameterValue(Format.OCTET_STRING, (raw,))
    if subindex not in DESCRIPTION_ELEMENTS:
        raise BmpError(f"description has no element {subindex}")
    fmt = DESCRIPTION_ELEMENTS[subindex][1]
    start, end = DESCRIPTION_OFFSETS[subindex]
    chunk = raw[start:end]
    if fmt == Format.OCTET_STRING:
        return ParameterValue(fmt, (chunk,))
    if fmt == Format.VISIBLE_STRING:
        return ParameterValue(fmt, (chunk.decode("latin-1"),))
    return ParameterValue(fmt, struct.unpack(">" + _STRUCT[fmt], chunk))


# --- request references ---------------------------------------------------------------------------------------


def next_reference(reference: int) -> int:
    """The reference after ``reference``: 1..255, wrapping past 255 to 1 (0 is reserved)."""
    return reference % 255 + 1


# ---------------------------------------------------------------------------- the server's fast path, both layouts
# A read is the request every poll makes; the simulated drive answers it straight from the model's raw values
# instead of building, checking and encoding result objects. The layouts it packs are written here, beside the
# general encoders they must equal (tests/test_pnu_server.py holds both paths byte-equal), not in the server.

def iter_read_addresses(data: bytes, n: int) -> "Iterator[tuple[int, int, int, int]]":
    """(attribute, number of elements, PNU, subindex) of the ``n`` addresses after the header (limits not
    checked; the caller checked the request's length)."""
    unpack = _ADDRESS.unpack_from
    for i in range(n):
        yield unpack(data, HEADER_SIZE + ADDRESS_SIZE * i)


_RAW_CODES = {Format.BYTE: "B", Format.WORD: "H", Format.DWORD: "I"}  # the untyped formats a raw read answers with
_RAW_BLOCKS: dict[tuple[int, int], struct.Struct] = {}  # (format, count) -> the value block's layout, built once


def raw_block_layout(fmt: int, count: int) -> struct.Struct | None:
    """The value block of ``count`` unsigned elements of Byte/Word/DWord (format, count, values, pad byte if
    odd) -- the layout :func:`encode_value_block` writes for them; None for any other format."""
    block = _RAW_BLOCKS.get((fmt, count))
    if block is None:
        code = _RAW_CODES.get(fmt)
        if code is None:
            return None
        pad = "x" if count * format_size(fmt) & 1 else ""
        block = _RAW_BLOCKS[(fmt, count)] = struct.Struct(f">BB{count}{code}{pad}")
    return block


def pack_read_response(request: bytes, blocks: "list[bytes]", negative: bool) -> bytes:
    """A read response to ``request`` from its value/error blocks, already packed: the request's reference,
    axis and number of parameters, the response ID (negative when any block is an error block)."""
    return bytes((request[0], RESP_READ_NAK if negative else RESP_READ_OK, request[2], len(blocks))) + b"".join(blocks)


# ---------------------------------------------------------------------------- the client's read, once per shape
# A poll reads the same parameters again and again. The client encodes a read request once per list of addresses
# (with encode_request) and patches the reference per call; it reads the usual response - the reference, axis and one
# block per parameter it asked for - with the one block decoder, and leaves anything else to decode_response, which
# words what is wrong. tests/test_bmp_read_template.py holds both equal to the general codec.

_REFERENCE_BYTE = [bytes((i,)) for i in range(256)]
#: A read answer's layout (ReadTemplate._shape): the whole response as one Struct, what picks each block's format and
#: count out of what it unpacks, their expected values, and each block's format and the span of its values.
_Shape = tuple[struct.Struct, Callable[[tuple[object, ...]], tuple[int, ...]], tuple[int, ...],
               list[tuple[int, int, int]]]


def address_key(addresses: Sequence[object]) -> tuple[tuple[int, int, int, int], ...] | None:
    """(PNU, subindex, count, attribute) of every address when each is a ParameterAddress of plain ints that
    :func:`check_address` accepts, as one hashable key; None when one is not (check_address then says why)."""
    key = []
    for a in addresses:
        if a.__class__ is not ParameterAddress:
            return None
        pnu, subindex, count, attribute = a.pnu, a.subindex, a.count, a.attribute  # type: ignore[attr-defined]
        if not (type(pnu) is int and type(subindex) is int and type(count) is int and type(attribute) is int
                and attribute in ATTRIBUTES and 1 <= pnu <= 0xFFFF and 0 <= subindex <= MAX_SUBINDEX
                and 1 <= count <= MAX_ELEMENTS):
            return None
        key.append((pnu, subindex, count, attribute))
    return tuple(key)


class ReadTemplate:
    """The read request of ``addresses`` on ``axis``, encoded once by :func:`encode_request`; :meth:`request` gives
    it with a reference, :meth:`results` reads the usual answer."""

    __slots__ = ("addresses", "axis", "_tail", "_shape", "_last")

    def __init__(self, axis: int, addresses: "tuple[ParameterAddress, ...]", *, addresses_checked: bool = False) -> None:
        self.axis = axis
        self.addresses = addresses
        self._tail = encode_request(ParameterRequest(1, REQ_READ, axis, addresses),
                                    addresses_checked=addresses_checked)[1:]
        #: The layout of the last answer when every block was numeric values (_Shape). A poll's answers keep their
        #: shape; one that does not is read block by block.
        self._shape: _Shape | None = None
        #: The last answer read (its length, its bytes after the reference) and its results: the results are a
        #: function of those bytes alone (the reference is checked first, the addresses are the template's), so an
        #: answer whose bytes are all the same - a poll of a value that did not change - reads as the same results
        #: (ParameterValue/ParameterFailure are immutable records; the list is new each time). Any other byte, a
        #: changed value among them, is read anew.
        self._last: tuple[int, bytes, tuple[ParameterResult, ...]] | None = None

    def request(self, reference: int) -> bytes:
        """The request's bytes with ``reference`` (1..255)."""
        return _REFERENCE_BYTE[reference] + self._tail

    def results(self, data: bytes, reference: int) -> "list[ParameterResult] | None":
        """One result per address - what ``decode_response(data, request).results`` gives - when ``data`` is a read
        response (positive or negative) with ``reference``, the axis, one block per address and, for values, the
        number of values asked for; else None (decode_response decides and words what is wrong)."""
        addresses = self.addresses
        size = len(data)
        if size > MAX_BLOCK or size < HEADER_SIZE or data[0] != reference or data[2] != self.axis \
                or data[3] != len(addresses) or (data[1] != RESP_READ_OK and data[1] != RESP_READ_NAK):
            return None
        last = self._last
        if last is not None and last[0] == size and data.endswith(last[1]):  # the same answer as the last one
            return list(last[2])
        shape = self._shape
        if shape is not None and shape[0].size == size:  # the answer looks like the last one: one unpack
            layout, heads, expected, blocks = shape
            fields = layout.unpack(data)
            if heads(fields) == expected:
                read = [ParameterValue(fmt, fields[start:stop]) for fmt, start, stop in blocks]
                self._last = (size, data[1:], tuple(read))
                return read
        offset = HEADER_SIZE
        results: list[ParameterResult] = []
        try:
            for address in addresses:
                result, offset = decode_value_block(data, offset)
                if result is None or (result.__class__ is ParameterValue and address.attribute == ATTR_VALUE
                                      and result.count != address.count):  # type: ignore[union-attr]
                    return None
                results.append(result)
        except BmpError:
            return None
        if offset != size:
            return None
        self._shape = _numeric_shape(results, size)
        self._last = (size, data[1:], tuple(results))
        return results

    def request_object(self, reference: int) -> ParameterRequest:
        """The request as a message (for :func:`decode_response` when :meth:`results` leaves the answer to it)."""
        return ParameterRequest(reference, REQ_READ, self.axis, self.addresses)


def _numeric_shape(results: list[ParameterResult], size: int) -> _Shape | None:
    """The layout of a read response whose blocks are all numeric values, as :func:`decode_value_block` reads them
    (format, count, the values by the format's struct code, a pad byte after an odd number of value bytes); None
    when a block is anything else or the layout does not span ``size`` bytes."""
    codes = [">4x"]
    heads: list[int] = []
    expected: list[int] = []
    blocks: list[tuple[int, int, int]] = []
    at = 0  # position in the unpacked fields
    for result in results:
        if result.__class__ is not ParameterValue:
            return None
        fmt = result.format  # type: ignore[union-attr]
        code = _STRUCT.get(fmt)
        count = len(result.values)  # type: ignore[union-attr]
        if code is None or fmt == _ERROR or not 1 <= count <= MAX_ELEMENTS:
            return None
        odd = count * _SIZES[fmt] & 1
        codes.append(f"BB{count}{code}{'x' if odd else ''}")
        heads += (at, at + 1)
        expected += (fmt, count)
        blocks.append((fmt, at + 2, at + 2 + count))
        at += 2 + count
    layout = struct.Struct("".join(codes))
    if layout.size != size or len(heads) < 2:
        return None
    return layout, operator.itemgetter(*heads), tuple(expected), blocks


def first_read_address(data: bytes) -> tuple[int, int, int, int]:
    """(attribute, number of elements, PNU, subindex) of the first address after the header: what
    :func:`iter_read_addresses` yields first, without a generator (the server's one-parameter read, issue 29)."""
    return _ADDRESS.unpack_from(data, HEADER_SIZE)  # type: ignore[return-value]


# ---------------------------------------------------------------------------- the server's one-parameter read, whole
_RAW_RESPONSES: dict[tuple[int, int], struct.Struct | None] = {}  # (format, count) -> the whole response, built once


def raw_read_response_layout(fmt: int, count: int) -> struct.Struct | None:
    """A positive read response of one parameter, ``count`` unsigned Byte/Word/DWord elements: reference, response ID,
    axis, number of parameters 1, then the value block :func:`raw_block_layout` packs -- the bytes
    :func:`pack_read_response` joins from them, in one pack; None for any other format or a block that does not fit
    a response (the general path answers and refuses those)."""
    layout = _RAW_RESPONSES.get((fmt, count), _ABSENT)
    if layout is _ABSENT:
        block = raw_block_layout(fmt, count)
        layout = None if block is None or block.size > MAX_BLOCK - HEADER_SIZE \
            else struct.Struct(">BBBB" + block.format[1:])
        _RAW_RESPONSES[(fmt, count)] = layout
    return layout  # type: ignore[return-value]


_ABSENT = object()


def one_read_response_packer(fmt: int, axis: int) -> tuple[Any, bytes] | None:
    """:func:`raw_read_response_layout` ``(fmt, 1)`` with every field but the reference and the value fixed:
    ``(pack, fixed)`` such that ``pack(reference, fixed, value)`` writes what
    ``raw_read_response_layout(fmt, 1).pack(reference, RESP_READ_OK, axis, 1, fmt, 1, value)`` writes (and raises
    the same ``struct.error`` for a value out of range); None where that layout is None. Why: a planned read
    (the simulator's PNU server, issue 29) packs three arguments instead of seven."""
    layout = raw_read_response_layout(fmt, 1)
    if layout is None:
        return None
    value = layout.format[len(">BBBBBB"):]  # the element (and a pad byte), as raw_block_layout writes it
    return struct.Struct(">B5s" + value).pack, bytes((RESP_READ_OK, axis, 1, fmt, 1))


# ---------------------------------------------------------------------------- the server's batch read, whole
def raw_batch_response_layout(blocks: "Sequence[tuple[int, int]]", axis: int) -> "tuple[Any, list[Any]] | None":
    """A positive read response of ``len(blocks)`` parameters, each ``(format, count)`` unsigned Byte/Word/DWord
    elements, as one pack: ``(pack, arguments)`` where ``arguments`` holds every field but the reference (argument
    0) and the values, and the values of block ``i`` go to ``arguments[at:at + count]`` for the ``at`` of
    :func:`raw_batch_value_positions`; ``pack(*arguments)`` then writes what :func:`pack_read_response` joins from
    the :func:`raw_block_layout` blocks (and raises the same ``struct.error`` for a value out of range). None when a
    block is of another format, or a block or the whole does not fit a response (the general path refuses those).
    Why: a poll's batch (the simulator's PNU server, issue 29) packs once, not once per parameter."""
    codes = [">BBBB"]
    arguments: list[Any] = [0, RESP_READ_OK, axis, len(blocks)]
    for fmt, count in blocks:
        block = raw_block_layout(fmt, count)
        if block is None or block.size > MAX_BLOCK - HEADER_SIZE:
            return None
        codes.append(block.format[1:])
        arguments += (fmt, count)
        arguments += [0] * count
    layout = struct.Struct("".join(codes))
    if layout.size > MAX_BLOCK:
        return None
    return layout.pack, arguments


def raw_batch_value_positions(blocks: "Sequence[tuple[int, int]]") -> list[int]:
    """Where each block's values start among the arguments :func:`raw_batch_response_layout` gives."""
    positions = []
    at = 4
    for _fmt, count in blocks:
        positions.append(at + 2)
        at += 2 + count
    return positions
