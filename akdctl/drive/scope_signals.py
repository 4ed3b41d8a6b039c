"""What the poll source reads for a signal name, and how one sample of all of them is read.

Why a table of live views: an AKD parameter name (VL.FB) is what a technician types, but the fieldbus value that
moves with the axis is often another address: the CiA 402 velocity actual value 0x606C, PROFIdrive's NIST_A (PNU 6).
So the names the scope knows map to the live address of each channel kind, with the scale to engineering units
(the tool's conventions: CiA positions 65536 counts/rev, profiles/units.py; PROFIdrive N2/X2 normalisations, seed
003 §5.6). Anything else is read by address: ``0x606C[:0]`` (the catalogue's type), ``PNU 6``/``pnu:6`` (the
catalogue's sign), or an AKD name the catalogue maps to an object (raw value; the AKD-names catalogue of
``catalog/akd_params.py`` when present gives its scale).

One sample = one batched PNU read for all PNU signals (the PROFIdrive channel packs up to 39 per request) plus one
SDO upload per object (the AKD has no SDO Complete Access: foe-alias-recorder.md §C2).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import Any

from akdctl.errors import UsageError
from akdctl.protocol.record import Record

_CIA_REV = 1.0 / 65536


class Signal(Record):
    """One polled signal: ``kind`` "pnu" (``pnu``, ``sub``) or "object" (``index``, ``sub``, ``type``);
    ``convert(raw) -> float`` in ``unit``; ``address`` as the user reads it."""

    __slots__ = ("address", "convert", "index", "kind", "name", "pnu", "sub", "type", "unit")

    def __init__(self, name: str, unit: str, address: str, kind: str, *, pnu: int = 0, index: int = 0, sub: int = 0,
                 type: str = "", convert: Callable[[Any], float] = float) -> None:
        self.name = name
        self.unit = unit
        self.address = address
        self.kind = kind
        self.pnu = pnu
        self.index = index
        self.sub = sub
        self.type = type
        self.convert = convert


def _scaled(factor: float) -> Callable[[Any], float]:
    if factor == 1.0:  # float(raw) * 1.0 is float(raw), bit for bit: no call around it (the pdo source, per cycle)
        return float

    def convert(raw: Any) -> float:
        return float(raw) * factor
    return convert


def _x15_rpm(raw: Any) -> float:
    from akdctl.profiles.units import x_to_rpm

    return x_to_rpm(int(raw), 15)


#: AKD name -> its live CiA 402 object: (index, sub, type, factor, unit).
LIVE_OBJECTS: dict[str, tuple[int, int, str, float, str]] = {
    "VL.FB": (0x606C, 0, "i32", 60.0 * _CIA_REV, "rpm"),
    "VL.CMD": (0x606B, 0, "i32", 60.0 * _CIA_REV, "rpm"),
    "PL.FB": (0x6064, 0, "i32", _CIA_REV, "rev"),
    "PL.CMD": (0x60FC, 0, "i32", _CIA_REV, "rev"),
    "PL.ERR": (0x60F4, 0, "i32", _CIA_REV, "rev"),
    "IL.FB": (0x6077, 0, "i16", 0.1, "% rated torque"),
    "STATUSWORD": (0x6041, 0, "u16", 1.0, ""),
}
#: AKD name -> its live PROFIdrive signal PNU: (pnu, converter, unit). PL.FB needs PNU 1002 (added at resolve).
LIVE_PNUS: dict[str, tuple[int, Callable[[Any], float], str]] = {
    "VL.FB": (6, _x15_rpm, "rpm"),
    "VL.CMD": (5, _x15_rpm, "rpm"),
    "IL.FB": (52, lambda raw: int(raw) * 100.0 / (1 << 14), "% DRV.IPEAK"),
    "STATUSWORD": (2, float, ""),
}
ALIASES = {"DS402.STATUSWORD": "STATUSWORD", "ZSW1": "STATUSWORD", "SW": "STATUSWORD", "STATUS": "STATUSWORD"}
_AKD_NAME = re.compile(r"[A-Z][A-Z0-9]*\.[A-Z0-9.]+")
NAMES_HELP = "VL.FB, VL.CMD, PL.FB, PL.CMD, PL.ERR, IL.FB, STATUSWORD, 0xINDEX[:SUB], PNU N, an AKD name"


class Resolver:
    """Turns names into :class:`Signal` s for one connection (which channels it offers decides the address)."""

    def __init__(self, has_pnus: bool, has_objects: bool, singleturn_bits: Callable[[], int] | None = None, *,
                 prefer_objects: bool = False, has_commands: bool = False) -> None:
        self.has_pnus = has_pnus
        self.has_objects = has_objects
        #: the AKD's ASCII channel (akd://): an AKD name is read as the text line ``NAME`` -> ``value [unit]``
        self.has_commands = has_commands
        self._singleturn_bits = singleturn_bits
        #: a CiA 402 axis on a target with both channels: its live values are the objects (VL.CMD = 0x606B, not
        #: PROFIdrive's NSOLL_A, which such an axis never writes)
        self.prefer_objects = prefer_objects

    def resolve(self, text: str) -> Signal:
        name = text.strip()
        upper = ALIASES.get(name.upper(), name.upper())
        pnu_match = re.fullmatch(r"(?:PNU[ :]?)(\d+)(?:\[(\d+)\])?", upper.replace(" ", ""))
        obj_match = re.fullmatch(r"0X([0-9A-F]{1,4})(?::(0X[0-9A-F]{1,2}|\d{1,3}))?", upper)
        if pnu_match:
            return self._pnu_address(name, int(pnu_match.group(1)), int(pnu_match.group(2) or 0))
        if obj_match:
            sub_text = obj_match.group(2) or "0"
            sub = int(sub_text, 16) if sub_text.startswith("0X") else int(sub_text)
            return self._object_address(name, int(obj_match.group(1), 16), sub)
        if not self.has_pnus and not self.has_objects and self.has_commands and _AKD_NAME.fullmatch(upper):
            return Signal(name, "", f"{upper} (ASCII)", "command", type=upper)
        if self.prefer_objects and self.has_objects and upper in LIVE_OBJECTS:
            return self._live_object(name, upper)
        if self.has_pnus and upper in LIVE_PNUS:
            pnu, convert, unit = LIVE_PNUS[upper]
            return Signal(name, unit, f"PNU {pnu}", "pnu", pnu=pnu, convert=convert)
        if self.has_pnus and upper == "PL.FB":
            bits = self._singleturn_bits() if self._singleturn_bits else 16
            return Signal(name, "rev", "PNU 28", "pnu", pnu=28, convert=lambda raw: int(raw) / float(1 << bits))
        if self.has_objects and upper in LIVE_OBJECTS:
            return self._live_object(name, upper)
        if upper in LIVE_PNUS or upper in LIVE_OBJECTS or upper == "PL.FB":
            offered = "PROFIdrive parameters" if self.has_pnus else "SDO objects" if self.has_objects else "no channel"
            raise UsageError(f"signal {name}: not readable live over this target ({offered}); "
                             "try --source recorder, or its address (0x..., PNU N)")
        return self._named(name, upper)

    def _live_object(self, name: str, upper: str) -> Signal:
        index, sub, type_name, factor, unit = LIVE_OBJECTS[upper]
        return Signal(name, unit, f"0x{index:04X}:{sub}", "object", index=index, sub=sub, type=type_name,
                      convert=_scaled(factor))

    def _pnu_address(self, name: str, pnu: int, sub: int) -> Signal:
        from akdctl.catalog.pnus import lookup

        if not self.has_pnus:
            raise UsageError(f"signal {name}: this target offers no PROFIdrive parameters")
        info = lookup(pnu)
        if info is None:
            raise UsageError(f"signal {name}: unknown PNU {pnu} (not in the AKD catalogue)")
        if info.access == "wo" or info.type in ("OS", "VS"):
            raise UsageError(f"signal {name}: PNU {pnu} ({info.name}) is not a number the scope can plot")
        return Signal(name, "", f"PNU {pnu}" + (f"[{sub}]" if sub else ""), "pnu", pnu=pnu, sub=sub)

    def _object_address(self, name: str, index: int, sub: int) -> Signal:
        from akdctl.catalog.objects import lookup

        if not self.has_objects:
            raise UsageError(f"signal {name}: this target offers no SDO objects")
        entry = lookup(index, sub)
        if entry is None:
            raise UsageError(f"signal {name}: unknown object 0x{index:04X}:{sub} (not in the AKD catalogue)")
        if not entry.readable or entry.short_type in ("vs", "os"):
            raise UsageError(f"signal {name}: 0x{index:04X}:{sub} ({entry.name}) is not a readable number")
        return Signal(name, "", f"0x{index:04X}:{sub}", "object", index=index, sub=sub, type=entry.short_type)

    def _named(self, name: str, upper: str) -> Signal:
        coe = _akd_names_coe(upper)
        if coe is not None and self.has_objects:
            index, sub, type_name, factor, unit, mark = coe
            signal = self._object_address(name, index, sub)
            signal.type = type_name or signal.type
            signal.unit = unit
            if factor is not None:
                signal.convert = _scaled(factor)
                if factor != 1.0:
                    signal.address += f" /{1 / factor:g}" + (f" [{mark}]" if mark else "")
            return signal
        from akdctl.catalog.objects import by_param

        entries = by_param(upper) if "." in upper else []
        if entries and self.has_objects:
            entry = entries[0]
            return self._object_address(name, entry.index, entry.subindex)
        raise UsageError(f"unknown signal {name!r}; signals: {NAMES_HELP}")


def _akd_names_coe(upper: str) -> tuple[int, int, str, float | None, str, str] | None:
    """(index, sub, type, factor, unit, scale mark) of an AKD name from the AKD-names catalogue
    (:mod:`akdctl.catalog.akd_params`: ``coe`` = (index, sub), ``coe_type``, ``scale`` = "1000" when wire 1000 is
    1.000, "var" when it depends on UNIT.*, ``unit``, ``mark("scale")``); None when the name has no CoE address."""
    from akdctl.catalog import akd_params

    row = akd_params.lookup(upper)
    if row is None or not row.coe:
        return None
    try:
        scale = float(row.scale or "")
        factor: float | None = 1.0 / scale if scale else None
    except ValueError:
        factor = None  # "var" (depends on UNIT.*) or unknown: the raw integer, said so by the unit
    unit = (row.unit or "") if factor is not None else "raw"
    return int(row.coe[0]), int(row.coe[1]), row.coe_type or "", factor, unit, str(row.mark("scale") or "")


class Sampler:
    """Reads one sample of ``signals`` (plus, optionally, the status word for a bit trigger) per :meth:`read`."""

    def __init__(self, conn: Any, signals: Sequence[Signal]) -> None:
        self.conn = conn
        self.signals = list(signals)
        self._pnu_slots = [i for i, s in enumerate(self.signals) if s.kind == "pnu"]
        self._specs: list[Any] = []
        if self._pnu_slots:
            from akdctl.drive.values import pnu_spec

            self._specs = [pnu_spec(self.signals[i].pnu, self.signals[i].sub, 1) for i in self._pnu_slots]

    @property
    def requests_per_sample(self) -> int:
        return (1 if self._pnu_slots else 0) + sum(1 for s in self.signals if s.kind in ("object", "command"))

    def read(self) -> list[float]:
        """One value per signal, in engineering units; a refusal or a lost answer raises (the caller keeps what
        it has and marks the recording partial)."""
        from akdctl.errors import DriveError

        row: list[float] = [0.0] * len(self.signals)
        if self._pnu_slots:
            from akdctl.drive.values import read_pnus

            for slot, reading in zip(self._pnu_slots, read_pnus(self.conn.parameters(), self._specs)):
                if not reading.ok or not reading.values:
                    raise DriveError(f"{self.signals[slot].address}: {reading.error_text or 'no value'}")
                row[slot] = self.signals[slot].convert(reading.values[0])
        for slot, signal in enumerate(self.signals):
            if signal.kind == "object":
                from akdctl.drive.values import read_object

                value = read_object(self.conn.objects(), signal.index, signal.sub, signal.type)
                row[slot] = signal.convert(value)
            elif signal.kind == "command":
                value, unit = parse_reading(self.conn.commands().command(signal.type), signal.type)
                signal.unit = signal.unit or unit  # the drive names it in every reply (UNIT.* decides)
                row[slot] = value
        return row


def parse_reading(reply: str, name: str) -> tuple[float, str]:
    """``value [unit]`` (akd-ascii-channel.md §2.1: floats with their unit in brackets, integers bare) -> (value,
    unit); MalformedReply for anything else (a text report is no signal)."""
    import math

    from akdctl.errors import MalformedReply

    match = re.fullmatch(r"\s*([-+]?[0-9.]+(?:[eE][-+]?\d+)?)\s*(?:\[([^\]]*)\])?\s*", reply)
    value = float(match.group(1)) if match else math.nan
    if match is None or not math.isfinite(value):
        raise MalformedReply(f"{name}: the drive answered {reply[:60]!r}, not a number")
    return value, (match.group(2) or "").strip()
