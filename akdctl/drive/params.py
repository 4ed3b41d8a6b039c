"""PNU access with meaning: parse what the user typed, read/write in batches, sign and scale.

``964[0..4]`` is PNU 964 elements 0 to 4; ``947[3]`` one element; ``964`` a
whole array; names work too (``STW1``). ``964:0..4`` and ``947:3`` mean the same
as the bracket forms: zsh (and bash with ``failglob``) treat unquoted brackets as
a glob, so the colon form needs no quoting. Assignments are ``PNU[SUB]=V[,V…]``
with decimal or 0x-hex values, checked against the catalogue before anything
is sent. Reading and writing typed values is :mod:`akdctl.drive.values`
(one :class:`ParameterChannel` call each, so the channel can batch them).
"""

from __future__ import annotations

import re
from typing import Any

from akdctl.catalog.pnus import by_name, lookup
from akdctl.drive.values import PnuSpec, check_pnu_values
from akdctl.errors import UsageError

__all__ = ["description_json", "fit_values", "parse_assignment", "parse_pnu_spec"]

# Patterns, compiled on first use: ``pnu get 930`` (a bare number) needs neither.
_SPEC = r"^\s*(?P<pnu>[A-Za-z_][A-Za-z0-9_]*|\d+|0[xX][0-9A-Fa-f]+)\s*(\[\s*(?P<a>\w+)?\s*(\.\.\s*(?P<b>\w+))?\s*\])?\s*$"


_COLON = r"^\s*(?P<pnu>[^:\[\]\s]+)\s*:\s*(?P<sub>[^:\[\]]*?)\s*$"


def _brackets(text: str) -> str:
    """``964:0..4`` → ``964[0..4]`` (the one place the colon form is understood); other text unchanged."""
    match = re.match(_COLON, text) if ":" in text else None
    return f"{match.group('pnu')}[{match.group('sub')}]" if match else text


def _spec_parts(text: str) -> tuple[str, str | None, str | None] | None:
    """(PNU, first, last) as written, or None: a bare number directly, anything else by :data:`_SPEC`."""
    plain = text.strip()
    if plain.isdecimal():
        return plain, None, None
    match = re.match(_SPEC, text)
    return (match.group("pnu"), match.group("a"), match.group("b")) if match else None


def _int(text: str, what: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise UsageError(f"{what}: {text!r} is not a number (use decimal or 0x-hex)") from None


def parse_pnu_spec(text: str) -> PnuSpec:
    """Parse ``930``, ``964[0..4]`` (or ``964:0..4``), ``947[3]`` (``947:3``), ``STW1``; checks against the
    catalogue when known."""
    shown, text = text, _brackets(text)
    named = by_name(shown) if not shown.strip().isdecimal() else None
    if named is not None:  # a catalogue name as a whole, spaces and all ("Operating mode"): the one resolver
        return PnuSpec(named.pnu, 0, named.length if named.is_array else 1, named)
    parts = _spec_parts(text)
    if parts is None:
        raise UsageError(f"cannot parse PNU address {shown!r}: expected PNU, PNU[SUB], PNU[FROM..TO] or PNU:FROM..TO, "
                         "e.g. 964:0..4 (brackets need quotes in zsh: '964[0..4]')")
    name, a, b = parts
    if name[0].isalpha() and not name.lower().startswith("0x"):
        info = by_name(name)
        if info is None:
            raise UsageError(f"unknown PNU name {name!r} (see 'akdctl pnu list')")
        pnu = info.pnu
    else:
        pnu = _int(name, "PNU")
        info = lookup(pnu)
    if not 1 <= pnu <= 0xFFFF:
        raise UsageError(f"PNU {pnu} is outside 1..65535")
    if a is None and b is None:
        if "[" in text:
            raise UsageError(f"cannot parse PNU address {shown!r}: empty subindex")
        sub, count = 0, (info.length if info is not None and info.is_array else 1)
    else:
        sub = _int(a, f"subindex of PNU {pnu}") if a is not None else 0
        last = _int(b, f"subindex of PNU {pnu}") if b is not None else sub
        if last < sub:
            raise UsageError(f"PNU address {shown!r}: range end {last} is before its start {sub}")
        count = last - sub + 1
    if not 0 <= sub <= 0xFFFE:
        raise UsageError(f"PNU address {shown!r}: subindex {sub} is outside 0..65534")
    if not 1 <= count <= 234:
        raise UsageError(f"PNU address {shown!r}: {count} elements; one request carries 1..234 elements")
    if info is not None:
        if not info.is_array and (sub != 0 or count != 1):
            raise UsageError(f"PNU {pnu} ({info.name}) is not an array; no subindex allowed")
        if info.is_array and sub + count > info.length:
            raise UsageError(
                f"PNU {pnu} ({info.name}) has elements 0..{info.length - 1}; {shown!r} asks beyond them"
            )
    return PnuSpec(pnu, sub, count, info)


def parse_assignment(text: str) -> tuple[PnuSpec, list[int]]:
    """Parse ``930=2``, ``1004=-500``, ``915[0..2]=1,5,6``; values range-checked by the catalogue."""
    left, sep, right = text.partition("=")
    if not sep or not right.strip():
        raise UsageError(f"cannot parse {text!r}: expected PNU=VALUE, e.g. 930=2")
    left = _brackets(left)
    spec = parse_pnu_spec(left)
    info = spec.info
    if info is None:
        raise UsageError(f"PNU {spec.pnu} is not in the catalogue, so its data type is unknown; cannot write it")
    if not info.writable:
        raise UsageError(f"PNU {spec.pnu} ({info.name}) is read-only")
    values = [_int(v.strip(), f"value for PNU {spec.pnu}") for v in right.split(",")]
    return fit_values(spec, values, ranged=".." in left), values


def fit_values(spec: PnuSpec, values: list[int], *, ranged: bool) -> PnuSpec:
    """The one check of values for a catalogue PNU address (``pnu set``, recipe set/expect steps): an array
    addressed without a range takes as many elements as values are given; the count, the array's length and
    every value's limits (:func:`akdctl.drive.values.check_pnu_values`) are checked; the address to write is
    returned."""
    info = spec.info
    if info is None:
        raise UsageError(f"PNU {spec.pnu} is not in the catalogue, so its data type is unknown; cannot write it")
    if not ranged and info.is_array:
        spec = PnuSpec(spec.pnu, spec.subindex, len(values), info)
    if len(values) != spec.count:
        raise UsageError(f"PNU {spec.label}: {spec.count} element(s) addressed but {len(values)} value(s) given")
    if spec.subindex + spec.count > info.length:
        raise UsageError(f"PNU {spec.pnu} ({info.name}) has elements 0..{info.length - 1}; too many values")
    check_pnu_values(info, values)
    return spec


def description_json(description: Any) -> dict[str, Any]:
    """A PROFIdrive parameter description (attribute 0x20) in words, for output."""
    from akdctl.protocol.bmp import format_name

    limits = description.limits()
    return {
        "name": description.name,
        "data_type": format_name(description.data_type),
        "array": description.is_array,
        "elements": description.elements,
        "read_only": description.read_only,
        "limits": list(limits) if limits is not None else None,
        "standardisation_factor": description.standardisation_factor,
        "identifier": f"0x{description.identifier:04X}",
    }
