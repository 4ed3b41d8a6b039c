"""Object addresses as users write them: ``0x6041``, ``0x6041:0``, ``6041h``.

Turning an object's bytes into a value and back (by the catalogue's type or one
the user names) is :mod:`akdctl.drive.values`.
"""

from __future__ import annotations

import re

from akdctl.errors import UsageError
from akdctl.protocol.record import Record

__all__ = ["ObjectAddress", "parse_address"]

# Compiled on first use: ``0x6041`` alone, the usual address, is read without it.
_ADDRESS = r"^\s*(?P<index>0[xX][0-9A-Fa-f]{1,4}|[0-9A-Fa-f]{1,4}[hH]|\d+)\s*(?:[:.](?P<sub>0[xX][0-9A-Fa-f]{1,2}|\d+))?\s*$"
_HEX = frozenset("0123456789abcdefABCDEF")


def _address_parts(text: str) -> tuple[str, str | None] | None:
    """(index, subindex) as written, or None: a bare ``0x`` index directly, anything else by :data:`_ADDRESS`."""
    plain = text.strip()
    if plain[:2] in ("0x", "0X") and 3 <= len(plain) <= 6 and _HEX.issuperset(plain[2:]):
        return plain, None
    match = re.match(_ADDRESS, text)
    return (match.group("index"), match.group("sub")) if match else None


class ObjectAddress(Record):
    __slots__ = ("index", "subindex")

    def __init__(self, index: int, subindex: int) -> None:
        self.index = index
        self.subindex = subindex

    @property
    def label(self) -> str:
        return f"0x{self.index:04X}:{self.subindex}"


def parse_address(text: str) -> ObjectAddress:
    """``0x6041``, ``0x6041:0``, ``0x60C1:1``, ``6041h`` (CiA notation) → index and subindex.

    A bare number is decimal, as everywhere in akdctl; hex needs ``0x`` or ``h``.
    """
    parts = _address_parts(text)
    if parts is None:
        raise UsageError(f"cannot parse object address {text!r}: expected INDEX[:SUB], e.g. 0x6041:0")
    index_text, sub_text = parts
    if index_text.lower().endswith("h"):
        index = int(index_text[:-1], 16)
    elif index_text.lower().startswith("0x"):
        index = int(index_text, 16)
    else:
        index = int(index_text, 10)
    # int(text, 0) refuses leading zeros ("0x1C12:01", as the manuals write it): parse by form.
    sub = (int(sub_text, 16) if sub_text.lower().startswith("0x") else int(sub_text, 10)) if sub_text else 0
    if not 0 <= index <= 0xFFFF:
        raise UsageError(f"object index {index:#x} is outside 0x0000..0xFFFF")
    if not 0 <= sub <= 0xFF:
        raise UsageError(f"subindex {sub} is outside 0..255")
    return ObjectAddress(index, sub)


def hex_hint(text: str) -> str:
    """A hint when ``text`` is a bare decimal index the catalogue lacks but whose hex reading it has, else ``""``.

    Why: object indices are written in hex everywhere in the manuals, so ``sdo read 6041`` almost always means
    0x6041; we keep decimal as the rule (as for PNUs) and say what was probably meant.
    """
    from akdctl.catalog.objects import object_name

    match = re.match(_ADDRESS, text)
    index_text = match.group("index") if match else ""
    if not index_text.isdigit():
        return ""
    decimal, as_hex = int(index_text, 10), int(index_text, 16)
    if object_name(decimal) is not None or as_hex > 0xFFFF or object_name(as_hex) is None:
        return ""
    sub = f":{match.group('sub')}" if match and match.group("sub") else ""
    return (f"; a bare index is decimal ({index_text} = 0x{decimal:04X}): did you mean 0x{as_hex:04X}{sub} "
            f"({object_name(as_hex)})?")
