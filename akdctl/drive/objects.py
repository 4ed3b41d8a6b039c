"""Object access with meaning: parse ``0x6041[:0]``, pick the type, encode and decode values.

The type comes from what the user typed (``u16``, ``i8``, ``vs`` …) or, when
omitted, from the catalogue; an object the catalogue does not know needs an
explicit type. Values go over the wire little-endian, as CANopen and CoE send
them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from akdctl.errors import UsageError

_ADDRESS = re.compile(r"^\s*(?P<index>0[xX][0-9A-Fa-f]{1,4}|[0-9A-Fa-f]{1,4}[hH]|\d+)\s*(?:[:.](?P<sub>0[xX][0-9A-Fa-f]{1,2}|\d+))?\s*$")


@dataclass(frozen=True)
class ObjectAddress:
    index: int
    subindex: int

    @property
    def label(self) -> str:
        return f"0x{self.index:04X}:{self.subindex}"


def parse_address(text: str) -> ObjectAddress:
    """``0x6041``, ``0x6041:0``, ``0x60C1:1``, ``6041h`` (CiA notation) → index and subindex.

    A bare number is decimal, as everywhere in akdctl; hex needs ``0x`` or ``h``.
    """
    match = _ADDRESS.match(text)
    if not match:
        raise UsageError(f"cannot parse object address {text!r}: expected INDEX[:SUB], e.g. 0x6041:0")
    index_text = match.group("index")
    if index_text.lower().endswith("h"):
        index = int(index_text[:-1], 16)
    elif index_text.lower().startswith("0x"):
        index = int(index_text, 16)
    else:
        index = int(index_text, 10)
    sub_text = match.group("sub")
    # int(text, 0) refuses leading zeros ("0x1C12:01", as the manuals write it): parse by form.
    sub = (int(sub_text, 16) if sub_text.lower().startswith("0x") else int(sub_text, 10)) if sub_text else 0
    if not 0 <= index <= 0xFFFF:
        raise UsageError(f"object index {index:#x} is outside 0x0000..0xFFFF")
    if not 0 <= sub <= 0xFF:
        raise UsageError(f"subindex {sub} is outside 0..255")
    return ObjectAddress(index, sub)


def resolve_type(address: ObjectAddress, type_name: str | None) -> tuple[str, Any]:
    """The data type to use and the catalogue entry (or None)."""
    from akdctl.catalog.objects import lookup, subentries
    from akdctl.protocol.datatypes import TYPES

    entry = lookup(address.index, address.subindex)
    if type_name is not None:
        if type_name not in TYPES:
            raise UsageError(f"unknown type {type_name!r}; types: {', '.join(TYPES)}")
        return type_name, entry
    if entry is None:
        if subentries(address.index):
            raise UsageError(f"object {address.label}: subindex {address.subindex} is not in the catalogue; give a type")
        raise UsageError(
            f"unknown object {address.label} (not in the AKD catalogue); give its type, e.g. 'sdo read {address.label} u32'"
        )
    return entry.short_type, entry


def decode(type_name: str, data: bytes) -> Any:
    from akdctl.errors import MalformedReply
    from akdctl.protocol.datatypes import DataTypeError, unpack

    try:
        return unpack(type_name, data)
    except DataTypeError as exc:
        raise MalformedReply(f"reply does not fit type {type_name}: {exc} (raw {data.hex(' ') or 'empty'})") from None


def encode(type_name: str, text: str) -> tuple[Any, bytes]:
    from akdctl.protocol.datatypes import DataTypeError, pack, parse_value

    try:
        value = parse_value(type_name, text)
        return value, pack(type_name, value)
    except DataTypeError as exc:
        raise UsageError(f"bad value {text!r} for type {type_name}: {exc}") from None


def display(type_name: str, value: Any) -> tuple[str, str]:
    """(value text, hex text) for human output."""
    from akdctl.protocol.datatypes import TYPES, format_value

    t = TYPES[type_name]
    text = format_value(type_name, value)
    if t.kind in ("int", "uint") and t.size:
        return text, f"0x{value & ((1 << (8 * t.size)) - 1):0{2 * t.size}X}"
    return text, ""


def json_value(type_name: str, value: Any) -> Any:
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).hex()
    return value
