"""``ecat pdo watch``: akdctl as the EtherCAT master takes the slave to OP with its current mapping and shows the
TxPDO values live, with the working counter of every cycle.

Why a writing operation (plan -> consent -> execute): in OP the RxPDO *is* written every cycle, and the mapped
controlword overrides SDO writes (SPEC-NOTES 23) -- so what goes out is planned first. By default it is the
all-safe image (every output 0: controlword 0 = disable voltage, set points 0), which needs no consent;
explicit output values (``--out 0x6040:0=15``) are classified by the gate like any object write and need
consent. The run ends at ``--for`` or Ctrl-C, or early, with words and an exit code, when the working counter
drops (exit 3: the slave did not take or give its data) or the slave leaves OP (exit 1, with the AL status
code). The slave is left in PRE-OP, outputs last written as 0.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from akdctl.catalog import objects as oc
from akdctl.catalog.texts import al_status_line
from akdctl.drive.gate import EVERY_CYCLE, Gated, classify_object
from akdctl.drive.operation import PlannedWrite, WritePlan
from akdctl.errors import CommError, DriveError, UsageError

if TYPE_CHECKING:
    from akdctl.connection import Connection

_SIGNED = ("SINT", "INT", "DINT", "LINT", "INTEGER8", "INTEGER16", "INTEGER32", "INTEGER64")

#: Units of the CiA 402 objects an AKD maps most, in the AKD's default scaling (counts = 2^16 per revolution,
#: docs: profiles/units.py CIA_COUNTS_PER_REV); anything else shows its raw value.
UNITS = {0x6064: "counts", 0x6063: "counts", 0x607A: "counts", 0x60F4: "counts", 0x606C: "counts/s",
         0x60FF: "counts/s", 0x6077: "per mille of rated torque", 0x6071: "per mille of rated torque",
         0x6078: "per mille of rated current", 0x2077: "mA"}


def _shown(index: int, raw: int) -> str:
    """The value as a technician reads it: positions also in revolutions, velocities in rpm (AKD default
    scaling, 2^16 counts per revolution), status/control words in hex."""
    from akdctl.profiles.units import CIA_COUNTS_PER_REV, cia_rpm

    unit = UNITS.get(index, "")
    if unit == "counts":
        return f"{raw} counts ({raw / CIA_COUNTS_PER_REV:.3f} rev)"
    if unit == "counts/s":
        return f"{raw} counts/s ({cia_rpm(raw):.1f} rpm)"
    if index in (0x6040, 0x6041):
        return f"0x{raw:04X}"
    return f"{raw} {unit}".strip()


class Layout:
    """The process image of one direction: (entry, bit offset, name, signed) in mapping order."""

    def __init__(self, pdos: list[tuple[int, tuple[oc.PdoEntry, ...]]]) -> None:
        self.fields: list[tuple[oc.PdoEntry, int, str, bool]] = []
        bit = 0
        for _number, entries in pdos:
            for entry in entries:
                obj = oc.lookup(entry.index, entry.subindex)
                if not entry.is_padding and entry.index >= 0x0008:
                    name = obj.name if obj else f"0x{entry.index:04X}:{entry.subindex:02X}"
                    signed = bool(obj and obj.type.upper() in _SIGNED)
                    self.fields.append((entry, bit, name, signed))
                bit += entry.bits
        self.bytes = (bit + 7) // 8

    def decode(self, data: bytes) -> list[dict[str, Any]]:
        value = int.from_bytes(data, "little")
        out = []
        for entry, bit, name, signed in self.fields:
            raw = field_value(value, bit, entry.bits, signed)
            out.append({"address": f"0x{entry.index:04X}:{entry.subindex:02X}", "name": name, "value": raw,
                        "unit": UNITS.get(entry.index, ""), "shown": _shown(entry.index, raw)})
        return out

    def encode(self, values: dict[tuple[int, int], int]) -> bytes:
        image = 0
        for entry, bit, _name, _signed in self.fields:
            v = values.get((entry.index, entry.subindex), 0)
            image |= (v & ((1 << entry.bits) - 1)) << bit
        return image.to_bytes(self.bytes, "little")

    def has(self, index: int, sub: int) -> bool:
        return any(e.index == index and e.subindex == sub for e, _b, _n, _s in self.fields)

    def field(self, index: int, sub: int) -> tuple[int, int, bool] | None:
        """(bit offset, bits, signed) of a mapped entry in the image; None when it is not mapped."""
        for entry, bit, _name, signed in self.fields:
            if entry.index == index and entry.subindex == sub:
                return bit, entry.bits, signed
        return None

    def mapped(self) -> str:
        """The mapped entries, for a message that names them (``0x6041:00, 0x6063:00``)."""
        return ", ".join(f"0x{e.index:04X}:{e.subindex:02X}" for e, _b, _n, _s in self.fields) or "nothing"


def field_value(image: int, bit: int, bits: int, signed: bool) -> int:
    """One entry's raw value out of a process image read as one little-endian integer."""
    raw = (image >> bit) & ((1 << bits) - 1)
    if signed and raw >> (bits - 1):
        raw -= 1 << bits
    return raw


def layouts(conn: "Connection") -> tuple[dict[str, Any], Layout, Layout]:
    """The mapping as the slave holds it now (SDO reads) and the RxPDO/TxPDO images it gives."""
    from akdctl.drive.pdo import read_mapping

    mapping = read_mapping(conn.objects())
    return mapping, Layout(mapping["rx"].pdos), Layout(mapping["tx"].pdos)


def plan(conn: "Connection", outputs: dict[tuple[int, int], int]) -> WritePlan:
    """The watch as a plan: every RxPDO entry written each cycle (0 unless given), a given one needing consent."""
    if not conn.has_process_data:
        raise UsageError(f"'ecat pdo watch' needs akdctl as the EtherCAT master (target ecat://IFNAME[/POS]); "
                         f"{conn.target.display} cannot take the slave to OP")
    mapping, rx, tx = layouts(conn)
    for index, sub in outputs:
        if not rx.has(index, sub):
            raise UsageError(f"0x{index:04X}:{sub:02X} is not in the assigned RxPDOs "
                             f"({', '.join(f'0x{n:04X}' for n in mapping['rx'].assigned) or 'none'}); "
                             "map it first ('akdctl pdo map')")
    writes = []
    for entry, _bit, name, _signed in rx.fields:
        value = outputs.get((entry.index, entry.subindex), 0)
        label = f"RxPDO 0x{entry.index:04X}:{entry.subindex:02X} ({name})"
        gated = None
        if (entry.index, entry.subindex) in outputs:  # any value given is written every cycle: consent, like motion
            gated = classify_object(entry.index, entry.subindex, name) or Gated(label, EVERY_CYCLE)
        writes.append(PlannedWrite(label, value, str(value), gated))
    return WritePlan("ecat pdo watch", conn.target.display, writes,
                     preconditions=[f"RxPDO {mapping['rx'].assigned and ', '.join(f'0x{n:04X}' for n in mapping['rx'].assigned)} "
                                    f"{rx.bytes} bytes, TxPDO {', '.join(f'0x{n:04X}' for n in mapping['tx'].assigned)} "
                                    f"{tx.bytes} bytes"],
                     notes=["every cycle writes these outputs while the slave is in OP; the slave is left in PRE-OP",
                            "all outputs 0 (controlword 0: disable voltage) unless given with --out and --yes"],
                     enabled=None, data={"rx": rx, "tx": tx, "outputs": dict(outputs)})


Sample = Callable[[list[dict[str, Any]], int, int, int], None]  # values, wkc, expected wkc, cycle


def execute(conn: "Connection", plan: WritePlan, duration: float, period: float, on_sample: Sample,
            show_every: float = 0.1) -> dict[str, Any]:
    """PRE-OP -> SAFE-OP -> OP with the mapping, cycle for ``duration`` s, back to PRE-OP. The result document;
    CommError (WKC drop) or DriveError (left OP) end it early, after the slave was taken back to PRE-OP."""
    from akdctl.protocol import ethercat as ec

    rx, tx = plan.data["rx"], plan.data["tx"]
    outputs = rx.encode(plan.data["outputs"])
    cycle = conn.process_data(rx.bytes, tx.bytes)
    last_values: list[dict[str, Any]] = []
    started = time.monotonic()
    ended = "time"
    try:
        enter(cycle, ec.AlState.OP)
        next_show = 0.0
        end = time.monotonic() + duration
        while True:
            now = time.monotonic()
            if now >= end:
                break
            check = now >= next_show  # the AL status rides along at each display refresh (a WKC drop shows sooner)
            inputs, wkc, al = cycle.exchange(outputs, with_status=check)
            last_values = tx.decode(inputs)
            if al is None and wkc != cycle.expected_wkc:
                al = cycle.exchange(outputs)[2]  # why did it drop: a slave out of OP says so
            left = left_state(cycle, al, ec.AlState.OP)
            if left is not None:
                ended = "left-op"
                raise left
            if wkc != cycle.expected_wkc:
                on_sample(last_values, wkc, cycle.expected_wkc, cycle.cycles)
                ended = "wkc"
                raise wkc_dropped(cycle, wkc, cycle.expected_wkc)
            if now >= next_show:
                on_sample(last_values, wkc, cycle.expected_wkc, cycle.cycles)
                next_show = now + show_every
            time.sleep(max(0.0, min(period, end - time.monotonic())))
    finally:
        leave(cycle)
    return {"target": conn.target.display, "cycles": cycle.cycles, "expected_wkc": cycle.expected_wkc,
            "seconds": round(time.monotonic() - started, 3), "period_s": period, "ended": ended,
            "outputs": {f"0x{i:04X}:{s:02X}": v for (i, s), v in plan.data["outputs"].items()},
            "inputs": last_values}


# ---------------------------------------------------------------------- the steps every cyclic run shares
# ``ecat pdo watch`` (OP) and the scope's pdo source (SAFE-OP: drive/scope_pdo_bus.py) bring the slave up, judge
# each cycle and take it back the same way; the steps live here once.

def enter(cycle: Any, state: int) -> None:
    """PRE-OP (where the sync managers may be set), SM2/SM3 and FMMUs for the mapping, SAFE-OP with one exchange
    of all-zero outputs, then OP when ``state`` asks for it. The caller runs :func:`leave` whatever happens."""
    from akdctl.protocol import ethercat as ec

    status, _code = cycle.al_status()
    if status & 0x0F != ec.AlState.PREOP:
        cycle.request_state(ec.AlState.PREOP)
    cycle.configure()
    cycle.request_state(ec.AlState.SAFEOP)
    cycle.exchange(bytes(cycle.rx_bytes))
    if state == ec.AlState.OP:
        cycle.request_state(ec.AlState.OP)


def left_state(cycle: Any, al: int | None, state: int) -> DriveError | None:
    """The error when the AL status ``al`` (None: not read this cycle) shows the slave out of ``state`` or
    flagging an error (exit 1, with the AL status code read now)."""
    from akdctl.protocol import ethercat as ec

    if al is None or (al & 0x0F == state and not al & ec.AL_ERROR_FLAG):
        return None
    code = cycle.al_status()[1]
    return DriveError(f"the slave left {ec.al_state_name(state)} at cycle {cycle.cycles}: now "
                      f"{al_status_line(al, code)}", code=code, details={"al_status": al, "al_status_code": code})


def wkc_dropped(cycle: Any, wkc: int, expected: int) -> CommError:
    """A working counter below the mapping's: the slave did not exchange its process data (exit 3)."""
    return CommError(f"working counter {wkc} where {expected} was expected at cycle {cycle.cycles}: the slave did "
                     "not exchange its process data", details={"wkc": wkc, "expected": expected, "cycle": cycle.cycles})


def leave(cycle: Any) -> None:
    """Outputs 0 once more, then PRE-OP: a known state whatever ended the run (errors here are not the story)."""
    from akdctl.protocol import ethercat as ec

    try:
        cycle.exchange(bytes(cycle.rx_bytes))
    except Exception:  # noqa: BLE001
        pass
    try:
        cycle.request_state(ec.AlState.PREOP)
    except Exception:  # noqa: BLE001
        pass


def image_reader(fields: list[tuple[int, int, bool]],
                 each: Callable[[int], Any] | None = None) -> Callable[[bytes], Sequence[Any]]:
    """A reader of several entries ((bit, bits, signed) each) out of an image at once, value for value what
    :func:`field_value` reads (a tuple; with ``each``, a list of ``each(value)``).

    Why: the scope's pdo source reads its entries every bus cycle. When every entry starts on a byte and is 8,
    16, 32 or 64 bits wide (the usual CiA 402 objects), one precompiled struct reads them all; anything else (a
    bit field, an image shorter than the entries) is read by :func:`field_value`."""
    import operator
    import struct

    def general(image: bytes) -> Sequence[Any]:
        value = int.from_bytes(image, "little")
        raw = tuple(field_value(value, bit, bits, signed) for bit, bits, signed in fields)
        return raw if each is None else list(map(each, raw))

    codes = {8: "b", 16: "h", 32: "i", 64: "q"}
    if not fields or any(bit % 8 or bits not in codes for bit, bits, _signed in fields):
        return general
    unique = sorted(set(fields))
    if any(a[0] + a[1] > b[0] for a, b in zip(unique, unique[1:])):  # overlapping entries: read one by one
        return general
    layout, at = "<", 0
    for bit, bits, signed in unique:
        layout += f"{(bit - at) // 8}x" if bit > at else ""
        layout += codes[bits] if signed else codes[bits].upper()
        at = bit + bits
    reads = struct.Struct(layout).unpack_from
    error = struct.error
    order = [unique.index(f) for f in fields]
    if order == list(range(len(unique))):
        if each is not None:
            def read_each(image: bytes) -> Sequence[Any]:
                try:
                    return list(map(each, reads(image)))
                except error:  # shorter than the entries: as field_value reads it (the missing bits 0)
                    return general(image)
            return read_each

        def read(image: bytes) -> Sequence[Any]:
            try:
                return reads(image)
            except error:
                return general(image)
        return read
    pick = operator.itemgetter(*order) if len(order) > 1 else (lambda got: (got[order[0]],))

    def read_picked(image: bytes) -> Sequence[Any]:
        try:
            picked = pick(reads(image))
        except error:
            return general(image)
        return picked if each is None else list(map(each, picked))
    return read_picked
