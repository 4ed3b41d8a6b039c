"""AKD faults (F-numbers) and warnings (n-numbers), with their emergency codes.

Why one table: the same fault reaches us three ways - as an F/n number (PROFIdrive fault
buffer PNU 947, AKD objects 0x2001/0x2012), as a CiA 301 EMCY code (CoE/CANopen
emergencies, 0x1003), or as text a user types ('F501'). Keeping the mapping in one place
is what SPEC-NOTES 14 and 21 ask for. The data (data/faults.csv) lists every entry of the
public EMCY table; the drive's reaction and a remedy are filled in only where a public
source states them (named in the `source` column).

Loading is lazy (functools.cache); lookups never raise on unknown input.
"""
from __future__ import annotations

import re
from functools import cache

from akdctl.protocol.record import Record

__all__ = ["Fault", "faults", "by_code", "by_number", "by_emcy", "describe_number", "emcy_text", "where_to_look"]


class Fault(Record):
    """One AKD fault or warning.

    code: 'F501' / 'n503' ('' for the generic EMCY entries without an AKD number);
    number: 501 (None when code is ''); kind: 'fault' or 'warning' as the AKD's prefix says
    (F / n), 'none' for the EMCY code 0x0000 (error reset: no error); emcy: CiA 301
    emergency error code; reaction/remedy: '' when no public source gives them.
    """

    __slots__ = ("code", "number", "kind", "emcy", "name", "reaction", "remedy", "source")

    def __init__(self, code: str, number: int | None, kind: str, emcy: int, name: str, reaction: str = "",
                 remedy: str = "", source: str = "") -> None:
        self.code = code
        self.number = number
        self.kind = kind
        self.emcy = emcy
        self.name = name
        self.reaction = reaction
        self.remedy = remedy
        self.source = source

    @property
    def is_warning(self) -> bool:
        return self.code.startswith("n") or (not self.code and self.kind == "warning")

    def describe(self) -> str:
        """'F501 DC Bus link over-voltage' - what a status line shows."""
        return f"{self.code} {self.name}".strip()


@cache
def faults() -> list[Fault]:
    """Every entry of the table, in the table's order (grouped by EMCY code)."""
    import csv  # here: the simulator imports this module at every start, the table is read only when asked for

    from akdctl.catalog import data_text

    text = data_text("faults.csv")
    lines = [line for line in text.splitlines() if line and not line.startswith("#")]
    result: list[Fault] = []
    for row in csv.DictReader(lines):
        result.append(Fault(
            code=row["code"],
            number=int(row["number"]) if row["number"] else None,
            kind=row["kind"],
            emcy=int(row["emcy"], 16),
            name=row["name"],
            reaction=row.get("reaction", ""),
            remedy=row.get("remedy", ""),
            source=row.get("source", ""),
        ))
    return result


@cache
def _by_code() -> dict[str, Fault]:
    return {f.code.upper(): f for f in faults() if f.code}


@cache
def _by_emcy() -> dict[int, list[Fault]]:
    grouped: dict[int, list[Fault]] = {}
    for f in faults():
        grouped.setdefault(f.emcy, []).append(f)
    return grouped


_CODE = r"^\s*([FfNn])\s*0*(\d{1,4})\s*$"  # compiled on first use (re caches it): not at every start


def by_number(number: int, *, warning: bool = False) -> Fault | None:
    """Fault F<number> (or warning n<number> when warning=True, or as a fallback).

    Why the preference: fault buffers (PNU 947, 0x2012) carry bare numbers that are
    F-numbers (SPEC-NOTES 14); a warning with the same number is the second choice.
    """
    table = _by_code()
    first, second = ("N", "F") if warning else ("F", "N")
    return table.get(f"{first}{number}") or table.get(f"{second}{number}")


def by_code(code: str | int) -> Fault | None:
    """Look up 'F501', 'f501', 'n503', 'F 501' or 501; None if unknown or malformed."""
    if isinstance(code, bool):
        return None
    if isinstance(code, int):
        return by_number(code)
    if not isinstance(code, str):
        return None
    m = re.match(_CODE, code)
    if m:
        return _by_code().get(f"{m.group(1).upper()}{int(m.group(2))}")
    stripped = code.strip()
    if stripped.isdigit():
        return by_number(int(stripped))
    return None


def by_emcy(code: int) -> list[Fault]:
    """Entries carrying a CiA 301 emergency code ([] if none)."""
    return list(_by_emcy().get(code, []))


def describe_number(number: int) -> str:
    """Text for a bare fault number from a fault buffer; never raises."""
    try:
        fault = by_number(int(number))
    except (TypeError, ValueError):
        return f"unknown fault {number!r}"
    if fault is None:
        return f"unknown fault {number}"
    return fault.describe()


def emcy_text(code: int) -> str:
    """Text for an emergency error code: the AKD fault(s) behind it, or the code in hex."""
    try:
        code = int(code)
    except (TypeError, ValueError):
        return f"emergency {code!r}"
    if code == 0:
        return "no error (emergency reset)"
    found = by_emcy(code)
    if not found:
        return f"emergency 0x{code:04X}"
    return "; ".join(f.describe() for f in found)


def where_to_look(fault: Fault) -> str:
    """Where a technician finds the remedy our table does not give (no public source we cite states it)."""
    name = fault.code or f"emergency 0x{fault.emcy:04X}"
    return (f"no public source we cite gives a remedy for {name}; look it up in Kollmorgen's AKD Fault Card or the "
            "'Fault and Warning Messages' table of the AKD User Guide (kdn.kollmorgen.com), or read DRV.FAULTS / "
            "DRV.WARNINGS in WorkBench, which print the drive's own text")
