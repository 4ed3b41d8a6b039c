"""Process-data mapping over CoE: read it, plan a change, turn the plan into the manual's startup list, apply, verify.

Why one module: the order of writes *is* the procedure. EtherCAT manual 5.5/5.6
prescribe it (clear the assignment, write each PDO as clear count / entries /
count, clearing unused PDOs, then assignment entries and count), 5.6.1 shows it
as a TwinCAT startup list, and a drive that meets a different order refuses
(SPEC-NOTES 17). So the plan is validated as a whole first (nothing invalid
reaches a drive unless the user forces it), the startup list is built from it
once, and the same list is printed by ``--dry-run``, exported as JSON and
written to the drive, then everything is read back and compared.

Everything here talks to an :class:`~akdctl.channels.base.ObjectChannel`, so it
works over any transport with SDO access (sim, ecat-udp, ecat, CANopen).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Any

from akdctl.catalog import objects as oc
from akdctl.catalog.objects import PdoEntry
from akdctl.errors import SdoAborted, UsageError

DIRECTIONS = ("rx", "tx")
ASSIGN_INDEX = {"rx": oc.RX_ASSIGN, "tx": oc.TX_ASSIGN}
TOTAL_MAX = {"rx": oc.RX_TOTAL_MAX_BYTES, "tx": oc.TX_TOTAL_MAX_BYTES}
FLEXIBLE = {"rx": oc.FLEXIBLE_RX, "tx": oc.FLEXIBLE_TX}
FIXED = {"rx": oc.FIXED_RX_PDOS, "tx": oc.FIXED_TX_PDOS}
SHORT = {"rx": "Rx", "tx": "Tx"}
WORDS = {"rx": "RxPDO (set points, master -> drive)", "tx": "TxPDO (actual values, drive -> master)"}

# CiA 402 modes of operation a user may name for --opmode (EtherCAT manual 5.8, SPEC-NOTES 20).
OPMODES = {"pp": 1, "pv": 3, "tq": 4, "hm": 6, "ip": 7, "csp": 8}


def direction_of(pdo: int) -> str | None:
    """'rx' for 0x1600-0x1603 and the fixed RxPDOs, 'tx' likewise, None for any other number."""
    if oc.is_rx_pdo(pdo):
        return "rx"
    if oc.is_tx_pdo(pdo):
        return "tx"
    return None


def is_flexible(pdo: int) -> bool:
    return pdo in oc.FLEXIBLE_RX or pdo in oc.FLEXIBLE_TX


# --------------------------------------------------------------------------- describing entries
def entry_info(entry: PdoEntry) -> dict[str, Any]:
    """Name and type of a mapping entry from the catalogue (JSON-able)."""
    obj = oc.lookup(entry.index, entry.subindex)
    name = obj.name if obj else "(not in the catalogue)"
    owner = oc.object_name(entry.index)
    if obj is not None and owner and entry.subindex != 0 and owner != obj.name:
        name = f"{owner}: {obj.name}"
    return {
        "index": entry.index, "subindex": entry.subindex, "address": f"0x{entry.index:04X}:{entry.subindex:02X}",
        "name": name, "type": obj.type if obj else "", "bits": entry.bits,
        "mapping_value": f"0x{entry.mapping_value:08X}", "padding": entry.is_padding,
    }


def describe_pdo(number: int, entries: Sequence[PdoEntry], start_bit: int = 0) -> dict[str, Any]:
    """One PDO with its entries and their bit offsets in the direction's process image."""
    rows = []
    offset = start_bit
    for entry in entries:
        info = entry_info(entry)
        info["bit_offset"] = offset
        offset += entry.bits
        rows.append(info)
    return {
        "number": number, "name": f"0x{number:04X}", "direction": direction_of(number),
        "fixed": oc.fixed_pdo(number) is not None, "entries": rows, "bytes": oc.pdo_bytes(list(entries)),
    }


# --------------------------------------------------------------------------- reading a drive
@dataclass
class DirectionMapping:
    """What one direction of a drive carries: assigned PDOs in order and their entries."""

    direction: str
    pdos: list[tuple[int, tuple[PdoEntry, ...]]]

    @property
    def assigned(self) -> list[int]:
        return [n for n, _ in self.pdos]

    @property
    def total_bytes(self) -> int:
        return sum(oc.pdo_bytes(list(e)) for _, e in self.pdos)

    def to_json(self) -> dict[str, Any]:
        pdos = []
        bit = 0
        for number, entries in self.pdos:
            pdos.append(describe_pdo(number, entries, bit))
            bit += sum(e.bits for e in entries)
        return {
            "assign_object": f"0x{ASSIGN_INDEX[self.direction]:04X}", "assigned": [f"0x{n:04X}" for n in self.assigned],
            "pdos": pdos, "bytes": self.total_bytes, "max_bytes": TOTAL_MAX[self.direction],
        }


def _read_uint(channel: Any, index: int, sub: int) -> int:
    """A count, PDO number or mapping entry, typed by the catalogue (u8 / u16 / u32)."""
    from akdctl.drive.values import read_object

    return read_object(channel, index, sub)  # type: ignore[no-any-return]


def read_pdo(channel: Any, pdo: int) -> tuple[PdoEntry, ...]:
    """A PDO's entries as the drive reports them (sub 0 count, then sub 1..n)."""
    count = _read_uint(channel, pdo, 0)
    if count > oc.MAX_MAPPING_ENTRIES * 2:  # fixed PDOs hold up to 10 entries; anything far beyond is garbage
        from akdctl.errors import MalformedReply

        raise MalformedReply(f"PDO 0x{pdo:04X} reports {count} entries")
    return tuple(PdoEntry.from_mapping_value(_read_uint(channel, pdo, sub)) for sub in range(1, count + 1))


def read_direction(channel: Any, direction: str) -> DirectionMapping:
    index = ASSIGN_INDEX[direction]
    count = _read_uint(channel, index, 0)
    if count > oc.MAX_ASSIGNED_PDOS:
        from akdctl.errors import MalformedReply

        raise MalformedReply(f"0x{index:04X}:00 reports {count} assigned PDOs (at most {oc.MAX_ASSIGNED_PDOS})")
    numbers = [_read_uint(channel, index, sub) for sub in range(1, count + 1)]
    return DirectionMapping(direction, [(n, read_pdo(channel, n)) for n in numbers])


def read_mapping(channel: Any) -> dict[str, DirectionMapping]:
    """Both directions: assignment -> PDOs -> entries."""
    return {d: read_direction(channel, d) for d in DIRECTIONS}


# --------------------------------------------------------------------------- parsing what the user typed
_ENTRY = re.compile(r"^\s*(?P<addr>[^/]+?)\s*(?:/\s*(?P<bits>\d+)\s*)?$")


def parse_entry(text: str) -> PdoEntry:
    """``0x6040:0/16`` (index:sub/bits); bits default to the catalogue's size of the object."""
    from akdctl.drive.objects import parse_address

    match = _ENTRY.match(text)
    if not match:
        raise UsageError(f"cannot parse mapping entry {text!r}: expected INDEX:SUB[/BITS], e.g. 0x6040:0/16")
    addr = parse_address(match.group("addr"))
    if match.group("bits") is not None:
        bits = int(match.group("bits"))
    else:
        obj = oc.lookup(addr.index, addr.subindex)
        if obj is None:
            raise UsageError(f"mapping entry {text!r}: object {addr.label} is not in the catalogue; give /BITS")
        bits = obj.bits
    if not 1 <= bits <= 255:
        raise UsageError(f"mapping entry {text!r}: bit length {bits} is outside 1..255")
    return PdoEntry(addr.index, addr.subindex, bits)


def _parse_number(text: str | int, what: str) -> int:
    if isinstance(text, int) and not isinstance(text, bool):
        return text
    try:
        value = int(str(text).strip(), 0)
    except ValueError:
        raise UsageError(f"{what}: {text!r} is not a number (PDO numbers are written 0x1701)") from None
    if not 0 <= value <= 0xFFFF:
        raise UsageError(f"{what}: {value:#x} is outside 0x0000..0xFFFF")
    return value


def parse_pdo_arg(text: str | int) -> tuple[int, tuple[PdoEntry, ...] | None]:
    """``0x1701`` -> (0x1701, None); ``0x1600=0x6040:0/16,0x60C1:1/32`` -> (0x1600, entries).

    ``0x1600=`` (nothing after '=') defines an empty PDO.
    """
    if isinstance(text, int):
        return _parse_number(text, "PDO"), None
    number_text, sep, rest = str(text).partition("=")
    number = _parse_number(number_text, "PDO")
    if not sep:
        return number, None
    parts = [p for p in (x.strip() for x in rest.split(",")) if p]
    return number, tuple(parse_entry(p) for p in parts)


def parse_cycle_time(text: str) -> tuple[int, int]:
    """``2ms``, ``250us``, ``0.5ms``, ``0.002`` (seconds) or ``2,-3`` -> (0x60C2:01 units, 0x60C2:02 exponent).

    Picks the largest exponent that expresses the time exactly in 1..255 units, so
    ``2ms`` gives (2, -3) as in the manual's startup list (5.6.1).
    """
    raw = text.strip().lower().replace(" ", "")
    if "," in raw:
        units_text, _, exp_text = raw.partition(",")
        try:
            units, exponent = int(units_text, 0), int(exp_text, 0)
        except ValueError:
            raise UsageError(f"cycle time {text!r}: expected UNITS,EXPONENT such as 2,-3") from None
        if not 0 <= units <= 255 or not -128 <= exponent <= 127:
            raise UsageError(f"cycle time {text!r}: units 0..255 and exponent -128..127")
        return units, exponent
    scale = {"ms": Decimal("0.001"), "us": Decimal("0.000001"), "µs": Decimal("0.000001"), "s": Decimal(1)}
    for suffix in ("ms", "us", "µs", "s"):
        if raw.endswith(suffix):
            number_text, factor = raw[: -len(suffix)], scale[suffix]
            break
    else:
        number_text, factor = raw, Decimal(1)
    try:
        seconds = Decimal(number_text) * factor
    except InvalidOperation:
        raise UsageError(f"cycle time {text!r}: expected e.g. 2ms, 250us or 2,-3") from None
    if seconds <= 0:
        raise UsageError(f"cycle time {text!r} must be positive")
    for exponent in range(0, -10, -1):
        units = seconds / (Decimal(10) ** exponent)
        if units == units.to_integral_value() and 1 <= units <= 255:
            return int(units), exponent
    raise UsageError(f"cycle time {text!r} cannot be written as 1..255 units x 10^n s")


def parse_opmode(text: str | int) -> int:
    """``7``, ``ip``, ``csp`` … -> a mode of operation value for 0x6060."""
    if isinstance(text, int) and not isinstance(text, bool):
        value = text
    else:
        key = str(text).strip().lower()
        if key in OPMODES:
            return OPMODES[key]
        try:
            value = int(key, 0)
        except ValueError:
            raise UsageError(f"mode of operation {text!r}: give a number or one of {', '.join(OPMODES)}") from None
    if not -128 <= value <= 127:
        raise UsageError(f"mode of operation {value} is outside -128..127")
    return value


# --------------------------------------------------------------------------- the plan
@dataclass
class PdoPlan:
    """A wanted mapping: per direction the assignment (None = leave alone) and flexible PDO contents."""

    assign: dict[str, list[int] | None] = field(default_factory=lambda: {"rx": None, "tx": None})
    definitions: dict[int, tuple[PdoEntry, ...]] = field(default_factory=dict)
    opmode: int | None = None
    cycle: tuple[int, int] | None = None

    def defined(self, direction: str) -> dict[int, tuple[PdoEntry, ...]]:
        return {n: e for n, e in self.definitions.items() if n in FLEXIBLE[direction]}

    def contents(self, pdo: int) -> tuple[PdoEntry, ...] | None:
        """Entries the PDO will hold: fixed contents, the plan's definition, or None (unknown)."""
        fixed = oc.fixed_pdo(pdo)
        if fixed is not None:
            return fixed
        return self.definitions.get(pdo)

    @property
    def empty(self) -> bool:
        return (all(a is None for a in self.assign.values()) and not self.definitions
                and self.opmode is None and self.cycle is None)

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {}
        for d in DIRECTIONS:
            if self.assign[d] is not None:
                data[d] = [f"0x{n:04X}" for n in self.assign[d] or []]
        data["define"] = {f"0x{n:04X}": [str(e) for e in entries] for n, entries in sorted(self.definitions.items())}
        if self.opmode is not None:
            data["opmode"] = self.opmode
        if self.cycle is not None:
            data["cycle_time"] = list(self.cycle)
        return data


def build_plan(rx: Iterable[str | int] = (), tx: Iterable[str | int] = (), define: Iterable[str] = (),
               opmode: str | int | None = None, cycle_time: str | None = None) -> PdoPlan:
    """Parse ``--rx``/``--tx`` (assign, optionally defining a flexible PDO), ``--define`` (define only)."""
    plan = PdoPlan()

    def add_definition(number: int, entries: tuple[PdoEntry, ...], source: str) -> None:
        if number in plan.definitions and plan.definitions[number] != entries:
            raise UsageError(f"PDO 0x{number:04X} is defined twice with different entries ({source})")
        plan.definitions[number] = entries

    for direction, items in (("rx", rx), ("tx", tx)):
        items = list(items)
        if not items:
            continue
        numbers = []
        for item in items:
            number, entries = parse_pdo_arg(item)
            numbers.append(number)
            if entries is not None:
                add_definition(number, entries, f"--{direction} {item}")
        plan.assign[direction] = numbers
    for item in define:
        number, entries = parse_pdo_arg(item)
        if entries is None:
            raise UsageError(f"--define {item!r}: expected PDO=ENTRIES, e.g. 0x1A00=0x6041:0/16,0x6063:0/32")
        add_definition(number, entries, f"--define {item}")
    if opmode is not None:
        plan.opmode = parse_opmode(opmode)
    if cycle_time is not None:
        plan.cycle = parse_cycle_time(str(cycle_time))
    return plan


def load_plan_file(path: str) -> PdoPlan:
    """A plan from TOML (``.toml``) or JSON: keys ``rx``, ``tx``, ``define`` (lists in the CLI's syntax),
    ``opmode``, ``cycle_time``. Example (TOML)::

        rx = ["0x1600=0x6040:0/16,0x60C1:1/32"]
        tx = ["0x1B01"]
        define = ["0x1A00=0x6041:0/16,0x6063:0/32"]
        opmode = 7
        cycle_time = "2ms"
    """
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as exc:
        raise UsageError(f"cannot read mapping file {path}: {exc.strerror}") from None
    try:
        if file.suffix.lower() == ".toml":
            import tomllib

            data = tomllib.loads(text)
        else:
            data = json.loads(text)
    except (ValueError, UnicodeError) as exc:  # tomllib.TOMLDecodeError and JSONDecodeError are ValueErrors
        raise UsageError(f"mapping file {path} does not parse: {exc}") from None
    if not isinstance(data, dict):
        raise UsageError(f"mapping file {path}: expected a table/object at the top")
    unknown = set(data) - {"rx", "tx", "define", "opmode", "cycle_time"}
    if unknown:
        raise UsageError(f"mapping file {path}: unknown keys {', '.join(sorted(unknown))} "
                         "(allowed: rx, tx, define, opmode, cycle_time)")

    def items(key: str) -> list[str | int]:
        value = data.get(key, [])
        if isinstance(value, (str, int)):
            value = [value]
        if not isinstance(value, list) or not all(isinstance(v, (str, int)) for v in value):
            raise UsageError(f"mapping file {path}: {key!r} must be a list of PDO strings such as \"0x1701\"")
        return value

    define = items("define")
    if not all(isinstance(v, str) for v in define):
        raise UsageError(f"mapping file {path}: 'define' items are strings PDO=ENTRIES")
    cycle = data.get("cycle_time")
    return build_plan(items("rx"), items("tx"), [str(v) for v in define], data.get("opmode"),
                      None if cycle is None else str(cycle))


# --------------------------------------------------------------------------- validation
def validate(plan: PdoPlan) -> list[str]:
    """Every reason the plan cannot work on an AKD (empty list: fine). Rules: EtherCAT manual 5.5/5.6,
    SPEC-NOTES 16 (unknown PDO numbers), 18 (sizes, even lengths, mappable objects), ESI exclusions."""
    problems: list[str] = []
    for number, entries in sorted(plan.definitions.items()):
        direction = direction_of(number)
        if direction is None:
            problems.append(f"0x{number:04X} is not a PDO of the AKD (flexible PDOs: 0x1600-0x1603, 0x1A00-0x1A03)")
            continue
        if not is_flexible(number):
            problems.append(f"0x{number:04X} is a fixed PDO; its contents cannot be changed "
                            "(define 0x1600-0x1603 / 0x1A00-0x1A03 instead)")
            continue
        if plan.assign[direction] is None:
            problems.append(f"0x{number:04X} is defined but no --{direction} assignment is given; mapping a PDO "
                            f"clears the {SHORT[direction]} assignment, so say which PDOs to assign")
        if len(entries) > oc.MAX_MAPPING_ENTRIES:
            problems.append(f"0x{number:04X}: {len(entries)} entries, at most {oc.MAX_MAPPING_ENTRIES}")
        for entry in entries:
            obj = oc.lookup(entry.index, entry.subindex)
            label = f"0x{number:04X}: {entry.index:#06x}:{entry.subindex}"
            if obj is None:
                problems.append(f"{label} is not an object of the AKD")
            elif not (obj.rx_mappable if direction == "rx" else obj.tx_mappable):
                where = {"R": "an RxPDO", "T": "a TxPDO"}.get(obj.pdo)
                problems.append(f"{label} ({obj.name}) cannot be mapped into {'an RxPDO' if direction == 'rx' else 'a TxPDO'}"
                                + (f"; it belongs in {where}" if where else "; it is not PDO-mappable"))
            elif obj.bits != entry.bits:
                problems.append(f"{label} ({obj.name}) has {obj.bits} bits, not {entry.bits}")
        size_bits = sum(e.bits for e in entries)
        if size_bits > 8 * oc.PDO_MAX_BYTES:
            problems.append(f"0x{number:04X} holds {size_bits // 8} bytes; one PDO holds at most {oc.PDO_MAX_BYTES}")
        elif size_bits % 16:
            pad = "0x0002:0/8 (dummy)" if direction == "rx" else "one of 0x2002:1..4/8 (manufacturer status byte)"
            problems.append(f"0x{number:04X} has an odd length ({(size_bits + 7) // 8} bytes); pad it with {pad}")
    for direction in DIRECTIONS:
        numbers = plan.assign[direction]
        if numbers is None:
            continue
        word = SHORT[direction]
        if len(numbers) > oc.MAX_ASSIGNED_PDOS:
            problems.append(f"{len(numbers)} {word}PDOs assigned, at most {oc.MAX_ASSIGNED_PDOS}")
        if len(set(numbers)) != len(numbers):
            problems.append(f"a{'n' if direction == 'rx' else ''} {word}PDO is assigned twice")
        total = 0
        for number in numbers:
            if direction_of(number) is None:
                problems.append(f"0x{number:04X} is not a PDO of the AKD (SPEC-NOTES 16); fixed {word}PDOs: "
                                + ", ".join(f"0x{n:04X}" for n in FIXED[direction]))
                continue
            if direction_of(number) != direction:
                problems.append(f"0x{number:04X} is a{'n' if direction == 'tx' else ''} {SHORT[direction_of(number) or 'rx']}PDO, "
                                f"not a{'n' if direction == 'rx' else ''} {word}PDO")
                continue
            contents = plan.contents(number)
            if contents is None:
                problems.append(f"0x{number:04X} is assigned but its entries are not given; write "
                                f"--{direction} 0x{number:04X}=INDEX:SUB/BITS,...")
                continue
            if not contents:
                problems.append(f"0x{number:04X} is assigned but empty")
            total += oc.pdo_bytes(list(contents))
        if len(numbers) > 1 and any(n in FIXED[direction] for n in numbers):
            problems.append(f"a fixed {word}PDO excludes every other {word}PDO (ESI); assign it alone")
        if total > TOTAL_MAX[direction]:
            problems.append(f"the assigned {word}PDOs hold {total} bytes; at most {TOTAL_MAX[direction]}")
    if plan.cycle is not None:
        units, exponent = plan.cycle
        from akdctl.catalog.texts import cycle_time_text
        from akdctl.profiles.units import cycle_time_problem

        problem = cycle_time_problem(units, exponent)  # the rule the drive applies (profiles/units.py)
        if problem is not None:
            problems.append(cycle_time_text(problem, units, exponent) + " (SPEC-NOTES 20)")
    return problems


# --------------------------------------------------------------------------- the startup list
@dataclass(frozen=True)
class StartupEntry:
    """One line of a TwinCAT-style startup list (EtherCAT manual 5.6.1): an SDO download."""

    transition: str  # "<PS>" generated from the PDO configuration, "PS" an init command of its own
    index: int
    subindex: int
    value: int
    size: int  # bytes on the wire
    comment: str

    @property
    def raw(self) -> int:
        return self.value & ((1 << (8 * self.size)) - 1)

    @property
    def data_text(self) -> str:
        """``0x60410010 (1614872592)``: hex with the object's width, then decimal (manual's Data column)."""
        return f"0x{self.raw:0{2 * self.size}X} ({self.raw})"

    @property
    def address(self) -> str:
        return f"0x{self.index:04X}:{self.subindex:02X}"

    def data(self) -> bytes:
        return self.raw.to_bytes(self.size, "little")

    def to_json(self) -> dict[str, Any]:
        return {"transition": self.transition, "protocol": "CoE", "index": f"0x{self.index:04X}",
                "subindex": self.subindex, "value": self.value, "data": self.data_text, "bytes": self.data().hex(),
                "comment": self.comment}


def _size(index: int, subindex: int) -> int:
    obj = oc.lookup(index, subindex)
    return obj.nbytes if obj is not None else 4


def _entry(transition: str, index: int, subindex: int, value: int, comment: str) -> StartupEntry:
    return StartupEntry(transition, index, subindex, value, _size(index, subindex), comment)


def startup_list(plan: PdoPlan) -> list[StartupEntry]:
    """The SDO downloads that realise a plan, in the manual's order (5.5, 5.6 steps 1-5, 5.6.1).

    Assignments of the directions being changed are cleared first; a direction with
    defined flexible PDOs gets all four of its mapping objects written (the defined
    ones as clear count / entries / count, the others cleared: "Unused PDOs must be
    cleared"), TxPDOs before RxPDOs as in 5.6.1; then each assignment's entries and
    count; then the init commands (mode of operation, cycle time).
    """
    steps: list[StartupEntry] = []
    changed = [d for d in DIRECTIONS if plan.assign[d] is not None]
    for d in changed:
        index = ASSIGN_INDEX[d]
        steps.append(_entry("<PS>", index, 0, 0, f"clear sm pdos (0x{index:04X})"))
    for d in ("tx", "rx"):
        if not plan.defined(d):
            continue
        for pdo in FLEXIBLE[d]:
            steps.append(_entry("<PS>", pdo, 0, 0, f"clear pdo 0x{pdo:04X} entries"))
            entries = plan.definitions.get(pdo, ())
            for sub, entry in enumerate(entries, start=1):
                steps.append(_entry("<PS>", pdo, sub, entry.mapping_value, f"download pdo 0x{pdo:04X} entry"))
            if entries:
                steps.append(_entry("<PS>", pdo, 0, len(entries), f"download pdo 0x{pdo:04X} entry count"))
    for d in changed:
        index = ASSIGN_INDEX[d]
        numbers = plan.assign[d] or []
        for sub, number in enumerate(numbers, start=1):
            steps.append(_entry("<PS>", index, sub, number, f"download pdo 0x{index:04X}:{sub:02X} index"))
        if numbers:
            steps.append(_entry("<PS>", index, 0, len(numbers), f"download pdo 0x{index:04X} count"))
    if plan.opmode is not None:
        steps.append(_entry("PS", 0x6060, 0, plan.opmode, "Opmode"))
    if plan.cycle is not None:
        steps.append(_entry("PS", 0x60C2, 1, plan.cycle[0], "Cycle time"))
        steps.append(_entry("PS", 0x60C2, 2, plan.cycle[1], "Cycle exp"))
    return steps


# --------------------------------------------------------------------------- applying and verifying
def apply(channel: Any, steps: Sequence[StartupEntry]) -> int:
    """Download every step in order; returns the number written. An abort names the step and what is left."""
    steps = _cycle_time_in_drive_order(channel, steps)
    for number, step in enumerate(steps, start=1):
        try:
            channel.download(step.index, step.subindex, step.data())
        except SdoAborted as exc:
            if number == 1:
                left = "nothing was written"
            else:
                done = "step 1 was" if number == 2 else f"steps 1-{number - 1} were"
                left = f"{done} written, so the mapping is incomplete; fix and run again"
            raise SdoAborted(
                f"startup step {number}/{len(steps)} ({step.address} = {step.data_text}, {step.comment}) refused: "
                f"{exc.message}; {left}",
                code=exc.code, details={**exc.details, "step": number, "steps": len(steps)},
            ) from None
    return len(steps)


def _cycle_time_in_drive_order(channel: Any, steps: Sequence[StartupEntry]) -> list[StartupEntry]:
    """The drive checks each 0x60C2 write against the other sub-index (docs/fidelity.md F5): write the exponent
    first when the new units with the current exponent would be refused (e.g. 250 us -> 2 ms)."""
    steps = list(steps)
    at = {s.subindex: i for i, s in enumerate(steps) if s.index == 0x60C2}
    if set(at) != {1, 2} or at[2] != at[1] + 1:
        return steps
    from akdctl.drive.values import read_object
    from akdctl.profiles.units import cycle_time_write_order

    try:
        current = (read_object(channel, 0x60C2, 1), read_object(channel, 0x60C2, 2))
    except SdoAborted:
        return steps
    first = at[1]
    if cycle_time_write_order(current, (steps[first].value, steps[first + 1].value)) == (2, 1):
        steps[first], steps[first + 1] = steps[first + 1], steps[first]
    return steps


def readback_pairs(channel: Any, plan: PdoPlan) -> list[tuple[str, str, str]]:
    """(address, written, read back) for everything the plan wrote, in words (PDO contents, assignments, the
    init commands), for the one comparison :func:`akdctl.drive.operation.check_readback`."""
    pairs: list[tuple[str, str, str]] = []
    for d in DIRECTIONS:
        if plan.defined(d):
            for pdo in FLEXIBLE[d]:
                pairs.append((f"0x{pdo:04X}", _entries_text(plan.definitions.get(pdo, ())),
                              _entries_text(read_pdo(channel, pdo))))
        if plan.assign[d] is not None:
            pairs.append((f"0x{ASSIGN_INDEX[d]:04X}", _numbers_text(plan.assign[d] or []),
                          _numbers_text(read_direction(channel, d).assigned)))
    checks: list[tuple[int, int, int]] = []
    if plan.opmode is not None:
        checks.append((0x6060, 0, plan.opmode))
    if plan.cycle is not None:
        checks += [(0x60C2, 1, plan.cycle[0]), (0x60C2, 2, plan.cycle[1])]
    from akdctl.drive.values import read_object

    for index, sub, want in checks:
        pairs.append((f"0x{index:04X}:{sub:02X}", str(want), str(read_object(channel, index, sub))))
    return pairs


def verify(channel: Any, plan: PdoPlan) -> list[str]:
    """Read everything the plan wrote back; one text per difference (empty: the drive holds the plan)."""
    return [f"{address}: wrote {wrote}, read back {back}"
            for address, wrote, back in readback_pairs(channel, plan) if wrote != back]


def _entries_text(entries: Sequence[PdoEntry]) -> str:
    return "[" + ", ".join(str(e) for e in entries) + "]" if entries else "(empty)"


def _numbers_text(numbers: Sequence[int]) -> str:
    return "[" + ", ".join(f"0x{n:04X}" for n in numbers) + "]" if numbers else "(none)"


#: The one precondition text of a mapping change (SPEC-NOTES 18): the CLI, the recipe and the plan say it so.
PREOP_ONLY = "the PDO mapping can only change in PRE-OP (SPEC-NOTES 18)"


def normal_al_state(state: Any) -> str | None:
    """The one spelling of an EtherCAT AL state: 'PREOP', 'SAFEOP', 'OP', 'INIT', 'BOOT' (None stays None)."""
    return None if state is None else str(state).upper().replace("-", "").replace("_", "").replace(" ", "")


def al_state_of(transport: Any) -> str | None:
    """The EtherCAT AL state if the transport can tell it ('PREOP', 'OP', ...), else None (unknown).

    Transports that know it offer ``al_state() -> str | None``; the others (CANopen,
    PROFINET) have no AL state, and the drive's own check answers.
    """
    getter = getattr(transport, "al_state", None)
    if getter is None or not callable(getter):
        return None
    return normal_al_state(getter())


def export_json(steps: Sequence[StartupEntry], plan: PdoPlan) -> dict[str, Any]:
    """The document ``--export`` writes: the plan and its startup list."""
    return {"format": "akdctl-startup-list", "version": 1, "plan": plan.to_json(),
            "startup": [s.to_json() for s in steps]}


# --------------------------------------------------------------------------- the operation (plan -> execute)
class MapRequest:
    """``pdo map``/a recipe's map step: the mapping (a checked :class:`PdoPlan`) and ``force`` (akdctl's own
    checks and the PRE-OP precondition become notes; the drive answers)."""

    __slots__ = ("mapping", "force", "problems")

    def __init__(self, mapping: PdoPlan, force: bool = False, problems: Sequence[str] = ()) -> None:
        self.mapping = mapping
        self.force = force
        self.problems = list(problems)


def refusal(problems: Sequence[str]) -> UsageError:
    """The one wording of a refused mapping: one problem per line."""
    return UsageError("mapping refused, nothing was written:\n  - " + "\n  - ".join(problems)
                      + "\n  (--force sends it anyway and lets the drive answer)", details={"problems": list(problems)})


def map_request(mapping: PdoPlan, *, force: bool = False) -> MapRequest:
    """Check a mapping without the drive (:func:`validate`); refused unless forced."""
    if mapping.empty:
        raise UsageError("nothing to map: give --rx/--tx (e.g. --rx 0x1701 --tx 0x1B01) or --file")
    problems = validate(mapping)
    if problems and not force:
        raise refusal(problems)
    return MapRequest(mapping, force, problems)


def _gate(step: StartupEntry) -> Any:
    from akdctl.drive.gate import classify_object

    return classify_object(step.index, step.subindex, oc.object_name(step.index) or "")  # the object, not its entry


def gated(request: MapRequest) -> list[Any]:
    """What the startup list writes that the gate classifies (mapping, assignment, mode): without the drive."""
    return [g for g in (_gate(s) for s in startup_list(request.mapping)) if g is not None]


def plan(conn: Any, request: MapRequest) -> Any:
    """The startup list as a write plan; reads the AL state (PRE-OP is the precondition unless forced)."""
    from akdctl.drive.operation import PlannedWrite, WritePlan, read_enabled

    conn.objects()  # a target without SDO access is refused before any consent is asked
    state = al_state_of(conn.transport())
    notes = [f"--force: {p}" for p in request.problems]
    if state is not None and state != "PREOP":
        if not request.force:
            raise UsageError(f"the drive is in {state}; {PREOP_ONLY}. Switch it to PRE-OP first; nothing was "
                             "written.", details={"al_state": state})
        notes.append(f"--force: the drive is in {state}; {PREOP_ONLY}")
    preconditions = [f"EtherCAT state {state}" if state is not None
                     else "EtherCAT state not known on this target (the drive's own check answers)"]
    steps = startup_list(request.mapping)
    writes = [PlannedWrite(f"{s.address} ({s.comment})", s.data().hex(), s.data_text, _gate(s)) for s in steps]
    return WritePlan("pdo map", conn.target.display, writes, preconditions=preconditions, notes=notes,
                     enabled=read_enabled(conn, writes), verify=True, data={"request": request, "steps": steps})


def execute(conn: Any, plan: Any) -> dict[str, Any]:
    """Download the startup list in order, read everything back (one CheckFailed on a difference)."""
    from akdctl.drive.operation import check_readback

    channel = conn.objects()
    written = apply(channel, plan.data["steps"])
    check_readback(readback_pairs(channel, plan.data["request"].mapping))
    return {"sdo_downloads": written, "mapping": {d: m.to_json() for d, m in read_mapping(channel).items()}}
