"""Scalar data types shared by CANopen/CoE objects and PROFIdrive parameters.

Objects and parameters are raw bytes on the wire; the catalog names each one's
type. Short names (``u8`` .. ``u64``, ``i8`` .. ``i64``, ``r32``, ``r64``,
``vs`` visible string, ``os`` octet string, ``bool``) are what users type and
what the catalog stores; the ESI names (USINT, UDINT, STRING(n), BIT2 ...) and
CANopen data type codes (0x0001 ..) map onto them so an object description
from an ESI file or from the SDO information service lands on the same type.

CANopen/CoE data is little-endian, PROFIdrive big-endian: ``endian`` is "<" or ">".
Range checks happen here, before anything reaches a drive.
"""

from __future__ import annotations

import math
import re
import struct

from akdctl.protocol.errors import CodecError
from akdctl.protocol.record import Record


class DataTypeError(CodecError):
    """A value that does not fit its type, bytes of the wrong size, or an unknown type name."""


class DataType(Record):
    """One scalar type: size in bytes (None = variable length), CANopen code, ESI names."""

    __slots__ = ("name", "size", "code", "kind", "esi", "fmt")

    def __init__(self, name: str, size: int | None, code: int, kind: str, esi: tuple[str, ...],
                 fmt: str = "") -> None:
        self.name = name
        self.size = size
        self.code = code
        self.kind = kind  # "bool", "uint", "int", "float", "str", "bytes"
        self.esi = esi
        self.fmt = fmt  # struct format character for fixed-size numbers

    @property
    def bits(self) -> int | None:
        return None if self.size is None else 8 * self.size

    @property
    def minimum(self) -> int | None:
        if self.kind == "uint" or self.kind == "bool":
            return 0
        if self.kind == "int" and self.size is not None:
            return -(1 << (8 * self.size - 1))
        return None

    @property
    def maximum(self) -> int | None:
        if self.kind == "bool":
            return 1
        if self.kind == "uint" and self.size is not None:
            return (1 << (8 * self.size)) - 1
        if self.kind == "int" and self.size is not None:
            return (1 << (8 * self.size - 1)) - 1
        return None


TYPES: dict[str, DataType] = {
    t.name: t
    for t in (
        DataType("bool", 1, 0x0001, "bool", ("BOOL", "BOOLEAN", "BIT1"), "B"),
        DataType("i8", 1, 0x0002, "int", ("SINT", "INTEGER8"), "b"),
        DataType("i16", 2, 0x0003, "int", ("INT", "INTEGER16"), "h"),
        DataType("i32", 4, 0x0004, "int", ("DINT", "INTEGER32"), "i"),
        DataType("u8", 1, 0x0005, "uint", ("USINT", "UNSIGNED8", "BYTE"), "B"),
        DataType("u16", 2, 0x0006, "uint", ("UINT", "UNSIGNED16", "WORD"), "H"),
        DataType("u32", 4, 0x0007, "uint", ("UDINT", "UNSIGNED32", "DWORD"), "I"),
        DataType("r32", 4, 0x0008, "float", ("REAL", "REAL32"), "f"),
        DataType("vs", None, 0x0009, "str", ("STRING", "VISIBLE_STRING")),
        DataType("os", None, 0x000A, "bytes", ("OCTET_STRING", "ARRAY OF BYTE")),
        DataType("r64", 8, 0x0011, "float", ("LREAL", "REAL64"), "d"),
        DataType("i64", 8, 0x0015, "int", ("LINT", "INTEGER64"), "q"),
        DataType("u64", 8, 0x001B, "uint", ("ULINT", "UNSIGNED64", "LWORD"), "Q"),
    )
}

_BY_CODE: dict[int, str] = {t.code: t.name for t in TYPES.values()}
# ETG.1000.6 bit types BIT1..BIT8 (codes 0x30..0x37): an SDO moves them in one byte.
_BY_CODE.update({0x0030: "bool", **{0x0030 + n: "u8" for n in range(1, 8)}})

_BY_ESI: dict[str, str] = {esi: t.name for t in TYPES.values() for esi in t.esi}
_BY_ESI.update({f"BIT{n}": "u8" for n in range(2, 9)})

# Patterns, compiled on first use (re caches them): an SDO command never parses an ESI type name.
_STRING_RE = r"^STRING\s*\(\s*\d+\s*\)$"
_BYTE_ARRAY_RE = r"^ARRAY\s*\[\s*\d+\s*\.\.\s*\d+\s*\]\s*OF\s*(BYTE|USINT)$"
_OCTET_RE = r"^OCTET_STRING\s*(\(\s*\d+\s*\))?$"


def get_type(name: str) -> DataType:
    """Look up a short name (``u16``); unknown names raise DataTypeError."""
    try:
        return TYPES[name]
    except (KeyError, TypeError):
        known = ", ".join(TYPES)
        raise DataTypeError(f"unknown data type {name!r} (known: {known})") from None


def type_for_code(code: int) -> str:
    """Short name for a CANopen data type code (as the SDO information service reports it)."""
    try:
        return _BY_CODE[code]
    except (KeyError, TypeError):
        raise DataTypeError(f"unsupported CANopen data type code 0x{code:04X}") from None


def type_for_esi(esi_name: str) -> str:
    """Short name for an ESI ``<Type>`` (USINT, STRING(10), BIT3, ARRAY [0..3] OF BYTE, ...)."""
    text = str(esi_name).strip().upper()
    if text in _BY_ESI:
        return _BY_ESI[text]
    if re.match(_STRING_RE, text):
        return "vs"
    if re.match(_BYTE_ARRAY_RE, text) or re.match(_OCTET_RE, text):
        return "os"
    raise DataTypeError(f"ESI type {esi_name!r} is not a scalar type akdctl knows (structured DTxxxx types are records)")


def _endian(endian: str) -> str:
    if endian not in ("<", ">"):
        raise DataTypeError(f"endian must be '<' or '>' (got {endian!r})")
    return endian


def pack(type_name: str, value: object, endian: str = "<") -> bytes:
    """Encode a value; out-of-range or wrongly typed values raise DataTypeError."""
    t = get_type(type_name)
    order = _endian(endian)
    if t.kind == "bool":
        if value not in (0, 1) or isinstance(value, float):
            raise DataTypeError(f"{value!r} is not a boolean (0/1)")
        return b"\x01" if value else b"\x00"
    if t.kind in ("int", "uint"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise DataTypeError(f"{type_name} needs an integer, not {value!r}")
        low, high = t.minimum, t.maximum
        assert low is not None and high is not None
        if not low <= value <= high:
            raise DataTypeError(f"{value} is out of range for {type_name} ({low}..{high})")
        return struct.pack(order + t.fmt, value)
    if t.kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise DataTypeError(f"{type_name} needs a number, not {value!r}")
        try:
            number = float(value)
            return struct.pack(order + t.fmt, number)
        except (OverflowError, struct.error):
            raise DataTypeError(f"{value!r} is out of range for {type_name}") from None
    if t.kind == "str":
        if not isinstance(value, str):
            raise DataTypeError(f"vs needs text, not {value!r}")
        try:
            return value.encode("utf-8")
        except UnicodeEncodeError as exc:
            raise DataTypeError(f"text cannot be encoded: {exc}") from None
    if not isinstance(value, (bytes, bytearray, memoryview)):
        raise DataTypeError(f"os needs bytes, not {value!r}")
    return bytes(value)


def unpack(type_name: str, data: bytes, endian: str = "<") -> object:
    """Decode bytes; fixed-size types need exactly their size.

    Visible strings lose trailing NUL padding (fixed-length string objects are
    padded); invalid UTF-8 is replaced rather than refused, since a display must
    still show what the drive sent.
    """
    t = get_type(type_name)
    order = _endian(endian)
    data = bytes(data)
    if t.size is not None and len(data) != t.size:
        raise DataTypeError(f"{type_name} needs {t.size} bytes, got {len(data)}")
    if t.kind == "bool":
        return data != b"\x00"
    if t.kind in ("int", "uint", "float"):
        return struct.unpack(order + t.fmt, data)[0]
    if t.kind == "str":
        return data.rstrip(b"\x00").decode("utf-8", errors="replace")
    return data


_TRUE = {"1", "true", "yes", "on"}
_FALSE = {"0", "false", "no", "off"}
_HEX_SEPARATORS = r"[\s:\-_,]"  # compiled on first use


def _parse_int(text: str) -> int:
    cleaned = text.strip()
    try:
        return int(cleaned, 0)
    except ValueError:
        pass
    try:
        return int(cleaned, 10)  # leading zeros: "010" is ten, as a technician means it
    except ValueError:
        raise DataTypeError(f"{text!r} is not an integer (decimal or 0x-hex)") from None


def parse_octets(text: str) -> bytes:
    """Hex octets: "01 02", "0102", "01:02", "0x0102"; empty text is zero bytes."""
    cleaned = re.sub(_HEX_SEPARATORS, "", text.strip())
    if cleaned[:2].lower() == "0x":
        cleaned = cleaned[2:]
    if len(cleaned) % 2:
        raise DataTypeError(f"{text!r}: hex octets need an even number of digits")
    try:
        return bytes.fromhex(cleaned)
    except ValueError:
        raise DataTypeError(f"{text!r} is not hex octets (e.g. '01 02' or '0102')") from None


def parse_value(type_name: str, text: str) -> object:
    """Turn what a user typed into a value of the type, range-checked."""
    t = get_type(type_name)
    if not isinstance(text, str):
        raise DataTypeError(f"expected text, got {text!r}")
    if t.kind == "bool":
        word = text.strip().lower()
        if word in _TRUE:
            return True
        if word in _FALSE:
            return False
        raise DataTypeError(f"{text!r} is not a boolean (0/1, true/false, on/off)")
    if t.kind in ("int", "uint"):
        value = _parse_int(text)
        pack(type_name, value)
        return value
    if t.kind == "float":
        try:
            number = float(text.strip())
        except ValueError:
            raise DataTypeError(f"{text!r} is not a number") from None
        if math.isinf(number):
            raise DataTypeError(f"{text!r} is not a finite number")
        pack(type_name, number)
        return number
    if t.kind == "str":
        return text
    return parse_octets(text)


def format_value(type_name: str, value: object) -> str:
    """The inverse of :func:`parse_value` for display: octets as spaced hex, floats as repr."""
    t = get_type(type_name)
    if t.kind == "bytes" and isinstance(value, (bytes, bytearray)):
        return bytes(value).hex(" ")
    if t.kind == "bool":
        return "1" if value else "0"
    return str(value)
