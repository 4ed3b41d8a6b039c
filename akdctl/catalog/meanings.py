"""Values in words: the enumerations and bit fields the catalogue knows, for PNUs and CoE/CANopen objects.

Why a table of its own: ``pnu get 930`` answering ``2`` leaves the technician to look up that 2 is position mode;
the words already exist in this project (operating modes, status-word bits, telegrams, fault numbers, vendor IDs),
but scattered where each is used. This module only *points at* them by address (PNU and element, object index
and subindex), so there is still one copy of each word; :func:`akdctl.drive.values.display` is the one place that
shows a value with its meaning. Data only: no I/O.

A :class:`Meaning` is either an enumeration (value → words) or a bit field (bit number → words, every set bit
named). Where a bit's words depend on the operating mode and the mode is not known here, both readings are given
(``velocity error within range / following error in range``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from functools import cache

from akdctl.protocol.record import Record

Names = Mapping[int, str] | Callable[[int], "str | None"]


class Meaning(Record):
    __slots__ = ("names", "bits", "width", "zero")

    def __init__(self, names: Names, bits: bool = False, width: int = 16, zero: str = "no bit set") -> None:
        self.names = names
        self.bits = bits  # a bit field: every set bit is named; else an enumeration
        self.width = width
        self.zero = zero  # a bit field's words for 0

    def name(self, key: int) -> str | None:
        return self.names(key) if callable(self.names) else self.names.get(key)

    def listing(self) -> str | None:
        """Every value (or bit) the catalogue has words for, for a description; None when they are computed."""
        if callable(self.names):
            return None
        return ", ".join(f"{'bit ' if self.bits else ''}{key} {text}" for key, text in sorted(self.names.items()))

    def words(self, value: int) -> str | None:
        """The value in words, or None when the catalogue has no words for it."""
        if isinstance(value, bool) or not isinstance(value, int):
            return None
        if not self.bits:
            return self.name(value)
        value &= (1 << self.width) - 1
        if value == 0:
            return self.zero
        return ", ".join(self.name(n) or f"bit {n}" for n in range(self.width) if value >> n & 1)


class _TextsTable(Mapping[int, str]):
    """A table of ``catalog/texts.py`` (vendor names, error register bits), read on first use: the words of most
    values need none of it, and the texts module is the largest of the catalogue (issue 29, cold start)."""

    def __init__(self, name: str, keep: Callable[[str], bool] = lambda text: True) -> None:
        self._name = name
        self._keep = keep
        self._table: dict[int, str] | None = None

    def _rows(self) -> dict[int, str]:
        if self._table is None:
            from akdctl.catalog import texts

            table: Mapping[int, str] = vars(texts)[self._name]
            self._table = {key: text for key, text in table.items() if self._keep(text)}
        return self._table

    def __getitem__(self, key: int) -> str:
        return self._rows()[key]

    def __iter__(self) -> Iterator[int]:
        return iter(self._rows())

    def __len__(self) -> int:
        return len(self._rows())


def _either(*tables: Mapping[int, str]) -> dict[int, str]:
    """Bit names of several modes in one table: equal names once, differing ones as ``a / b``."""
    out: dict[int, str] = {}
    for bit in sorted({b for t in tables for b in t}):
        names = list(dict.fromkeys(t[bit] for t in tables if bit in t))
        out[bit] = " / ".join(names)
    return out


def _word_names(bits_of: Callable[[int, int | None], list[object]], modes: tuple[int | None, ...]) -> dict[int, str]:
    tables = [{b.number: b.name for b in bits_of(0xFFFF, mode)} for mode in modes]  # type: ignore[attr-defined]
    return {n: name for n, name in _either(*tables).items() if "reserved" not in name}


def _fault(number: int) -> str | None:
    from akdctl.catalog.faults import by_number

    fault = by_number(number) if number else None
    return fault.describe() if fault else None


def _warning(number: int) -> str | None:
    from akdctl.catalog.faults import by_number

    fault = by_number(number, warning=True) if number else None
    return fault.describe() if fault else None


def _emcy(code: int) -> str | None:
    from akdctl.catalog.faults import emcy_text

    return emcy_text(code & 0xFFFF)


def _signal(number: int) -> str | None:
    from akdctl.catalog.telegrams import signal

    sig = signal(number) if number else None
    return sig.name if sig else None


def _telegram(number: int) -> str | None:
    from akdctl.catalog.telegrams import FREE_TELEGRAM, telegram

    if number == FREE_TELEGRAM:
        return "free telegram (PNU 915/916)"
    layout = telegram(number)
    return layout.text if layout else None


def _product(code: int) -> str | None:
    text = code.to_bytes(4, "big").lstrip(b"\0")
    return f"'{text.decode('ascii')}'" if text and all(0x20 < c < 0x7F for c in text) else None


#: CiA 402 0x6040 controlword (reference/cia402_and_canopen_reference.md; bits 4-6, 9 per mode).
_CONTROLWORD = {0: "switch on", 1: "enable voltage", 2: "quick stop (0 = active)", 3: "enable operation",
                4: "new set-point / start homing", 5: "change set immediately", 6: "relative", 7: "fault reset",
                8: "halt", 9: "change on set-point"}
#: CiA 402 0x6502 supported drive modes (the standard's bit assignment; inferred, not in the seed manuals).
_DRIVE_MODES = {0: "profile position", 1: "velocity", 2: "profile velocity", 3: "profile torque", 5: "homing",
                6: "interpolated position", 7: "cyclic synchronous position", 8: "cyclic synchronous velocity",
                9: "cyclic synchronous torque"}


@cache
def _pnus() -> dict[tuple[int, int | None], Meaning]:
    """(PNU, element or None for every element) → meaning."""
    from akdctl.profiles import statusword as sw

    vendor = Meaning(_TextsTable("PI_VENDORS"))
    return {
        (1, None): Meaning(_word_names(sw.stw1_bits, (1, 2)), bits=True),
        (2, None): Meaning(_word_names(sw.zsw1_bits, (1, 2)), bits=True),
        (38, None): Meaning({0: "relative", 1: "absolute"}),
        (915, None): Meaning(_signal), (916, None): Meaning(_signal),
        (922, None): Meaning(_telegram),
        (930, None): Meaning(sw.PROFIDRIVE_MODES),
        (947, None): Meaning(_fault),
        (964, 0): vendor, (975, 0): vendor,
        (965, 0): Meaning({3: "PROFIdrive"}),
        (975, 5): Meaning({1: "axis"}),
    }


@cache
def _objects() -> dict[tuple[int, int | None], Meaning]:
    """(index, subindex or None for every subindex ≥ 1) → meaning."""
    from akdctl.profiles import statusword as sw

    modes = Meaning(sw.CIA402_MODES)
    return {
        (0x1001, 0): Meaning(_TextsTable("ERROR_REGISTER_BITS", lambda text: text != "reserved"), bits=True, width=8,
                             zero="no error"),
        (0x1018, 1): Meaning(_TextsTable("CANOPEN_VENDORS")),
        (0x1018, 2): Meaning(_product),
        (0x1003, None): Meaning(_emcy),
        (0x603F, 0): Meaning(_emcy),
        (0x2000, None): Meaning(_warning),
        (0x2001, None): Meaning(_fault),
        (0x2012, None): Meaning(_fault),
        (0x6040, 0): Meaning(_CONTROLWORD, bits=True),
        (0x6041, 0): Meaning(_word_names(sw.statusword_bits, (1, 6)), bits=True),
        (0x6060, 0): modes,
        (0x6061, 0): modes,
        (0x6502, 0): Meaning(_DRIVE_MODES, bits=True, width=32),
    }


def pnu_meaning(pnu: int, element: int = 0) -> Meaning | None:
    table = _pnus()
    return table.get((pnu, element)) or table.get((pnu, None))


def object_meaning(index: int, subindex: int) -> Meaning | None:
    table = _objects()
    return table.get((index, subindex)) or (table.get((index, None)) if subindex >= 1 else None)
