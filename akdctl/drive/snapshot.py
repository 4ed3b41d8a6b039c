"""Parameter snapshots: back up, compare and restore a drive's configuration.

Why this module: a machine builder commissions the same axis type hundreds of
times and a technician must be able to put a replaced drive back exactly as it
was. So a snapshot is plain data (TOML or JSON) that names the target, the
drive's identity, firmware and time; reading it costs the fewest round trips
the protocol allows (every PNU in ONE batched :func:`~akdctl.drive.values.read_pnus`
call, which the channel packs into the fewest requests its 39-parameter /
240-byte limits allow); and restoring it writes only what differs, in an order
the drive accepts (units and operating mode before values that depend on
them, telegram before its free mapping, PDO mapping with the manual's
clear → entries → count sequence), never the control word, and reads every
written value back.

Items that are *process data* (set points, the control word, command objects)
are backed up for the record where readable but are never restored: writing
them is motion, not configuration.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akdctl.drive.values import (
    PnuSpec,
    Value,
    check_pnu_values,
    encode_object,
    pnu_refused,
    read_pnus,
    read_snapshot_value,
    snapshot_value,
    write_object,
    write_pnus,
)
from akdctl.errors import AkdError, CommError, SafetyRefusal, SdoAborted, UsageError
from akdctl.io.atomic import write_user_file

if TYPE_CHECKING:
    from akdctl.connection import Connection
    from akdctl.drive.operation import WritePlan

SNAPSHOT_FORMAT = 1

# DRV.NVSAVE through the CiA 301 "store parameters" object: the signature "save" (ASCII, little-endian).
NVSAVE_INDEX = 0x1010
NVSAVE_SUBINDEX = 1
NVSAVE_SIGNATURE = 0x65766173

PNU_GROUPS = ("signal", "profidrive", "telegram", "fault", "identity", "jog")
OBJECT_GROUPS = ("pdo", "comm", "akd", "cia402")
SOURCES = ("auto", "pnu", "objects", "all")

# Never written by a restore, whatever a file says: the control words and command objects.
PNU_NEVER_RESTORE = frozenset({1})  # STW1
OBJECT_NEVER = frozenset({0x6040, 0x1010, 0x1011})
# RxPDO-mappable objects are set points (process data) except these configuration values.
_RX_CONFIG = frozenset({0x6060, 0x606D, 0x606E, 0x6072, 0x6081, 0x6083, 0x6084, 0x6087, 0x60B8, 0x60E0, 0x60E1,
                        0x207F})
_PDO_MAPPING = frozenset(range(0x1600, 0x1604)) | frozenset(range(0x1A00, 0x1A04))
_PDO_ASSIGN = frozenset({0x1C12, 0x1C13})
_SCALING = frozenset({0x608F, 0x6091, 0x6092})

# Restore phases: lower first (SPEC-NOTES 13: PNU 1002 scales positions; the telegram decides 915/916).
PHASE_UNITS_MODE = 0
PHASE_TELEGRAM = 1
PHASE_MAPPING = 2
PHASE_ASSIGNMENT = 3
PHASE_REST = 4
TELEGRAM_DERIVED = frozenset({"915", "916"})
_PNU_PHASE = {1002: PHASE_UNITS_MODE, 930: PHASE_UNITS_MODE, 922: PHASE_TELEGRAM, 915: PHASE_MAPPING,
              916: PHASE_MAPPING}


# ---------------------------------------------------------------------------- items
@dataclass(frozen=True)
class Item:
    """One quantity a snapshot holds: a whole PNU or one object sub-entry."""

    key: str  # "930" / "0x6060:0"
    kind: str  # "pnu" or "object"
    name: str
    group: str
    restorable: bool
    phase: int
    info: Any = field(default=None, compare=False)  # PnuInfo or ObjectEntry

    @property
    def index(self) -> int:
        return int(self.key.split(":")[0], 0)

    @property
    def subindex(self) -> int:
        return int(self.key.split(":")[1]) if self.kind == "object" else 0


def object_key(index: int, subindex: int) -> str:
    return f"0x{index:04X}:{subindex}"


def _object_group(index: int) -> str:
    if index in _PDO_MAPPING or index in _PDO_ASSIGN:
        return "pdo"
    if index < 0x2000:
        return "comm"
    if index < 0x6000:
        return "akd"
    return "cia402"


def _object_phase(index: int) -> int:
    if index == 0x6060 or index in _SCALING:
        return PHASE_UNITS_MODE
    if index in _PDO_MAPPING:
        return PHASE_MAPPING
    if index in _PDO_ASSIGN:
        return PHASE_ASSIGNMENT
    return PHASE_REST


def pnu_item(info: Any) -> Item:
    restorable = info.writable and info.group != "signal" and info.pnu not in PNU_NEVER_RESTORE
    return Item(str(info.pnu), "pnu", info.name, info.group, restorable, _PNU_PHASE.get(info.pnu, PHASE_REST), info)


def object_backed_up(entry: Any) -> bool:
    """Configuration objects: readable and writable, not a command or a set point."""
    if entry.access != "rw" or entry.index in OBJECT_NEVER:
        return False
    if entry.pdo == "R" and entry.index not in _RX_CONFIG:
        return False
    return entry.short_type in ("u8", "u16", "u32", "u64", "i8", "i16", "i32", "i64", "r32", "r64", "vs", "os", "bool")


def object_item(entry: Any) -> Item:
    from akdctl.catalog.objects import object_name

    name = object_name(entry.index) or entry.name
    if entry.subindex or len(_subs(entry.index)) > 1:
        name = f"{name} / {entry.name}"
    return Item(object_key(entry.index, entry.subindex), "object", name, _object_group(entry.index),
                object_backed_up(entry), _object_phase(entry.index), entry)


def _subs(index: int) -> list[Any]:
    from akdctl.catalog.objects import subentries

    return subentries(index)


def catalogue_pnu_items() -> list[Item]:
    from akdctl.catalog.pnus import pnu_table

    return [pnu_item(info) for _, info in sorted(pnu_table().items())]


def catalogue_object_items() -> list[Item]:
    from akdctl.catalog.objects import entries

    return [object_item(e) for e in entries().values() if object_backed_up(e)]


def resolve_item(text: str) -> Item:
    """A PNU (``930``, ``STW1``) or object (``0x6060:0``, ``0x6060``) the user named → item."""
    from akdctl.catalog.objects import lookup as object_lookup
    from akdctl.catalog.objects import subentries
    from akdctl.catalog.pnus import by_name, lookup

    cleaned = text.strip()
    if ":" in cleaned or cleaned.lower().endswith("h") and not cleaned.isdigit():
        from akdctl.drive.objects import parse_address

        address = parse_address(cleaned)
        entry = object_lookup(address.index, address.subindex)
        if entry is None:
            raise UsageError(f"unknown object {address.label} (not in the AKD catalogue)")
        return object_item(entry)
    info = by_name(cleaned)
    if info is None:
        try:
            number = int(cleaned, 0)
        except ValueError:
            raise UsageError(f"unknown parameter {text!r}: expected a PNU (930, STW1) or an object (0x6060:0)") from None
        info = lookup(number) if not cleaned.lower().startswith("0x") else None
        if info is None and cleaned.lower().startswith("0x") and subentries(number):
            return object_item(object_lookup(number, 0) or subentries(number)[0])
        if info is None:
            raise UsageError(f"unknown parameter {text!r}: not a PNU or object of the catalogue")
    return pnu_item(info)


def select_items(sources: Sequence[str], groups: Sequence[str] = (), only: Sequence[str] = ()) -> list[Item]:
    """The items to back up: by source ("pnu"/"objects"), narrowed to groups, or an explicit list."""
    if only:
        picked: dict[str, Item] = {}
        for text in only:
            for part in text.split(","):
                if part.strip():
                    item = resolve_item(part)
                    picked.setdefault(item.key, item)
        return list(picked.values())
    for group in groups:
        if group not in PNU_GROUPS + OBJECT_GROUPS:
            raise UsageError(f"unknown group {group!r}; groups: {', '.join(PNU_GROUPS + OBJECT_GROUPS)}")
    items: list[Item] = []
    if "pnu" in sources:
        items += [i for i in catalogue_pnu_items() if not groups or i.group in groups]
    if "objects" in sources:
        items += [i for i in catalogue_object_items() if not groups or i.group in groups]
    return items


def choose_sources(conn: "Connection", source: str) -> list[str]:
    """Which channels a backup reads: ``auto`` = PNUs where the target has them, else objects."""
    if source not in SOURCES:
        raise UsageError(f"unknown source {source!r}; choose one of {', '.join(SOURCES)}")
    has_pnu, has_obj = conn.has_parameters, conn.has_objects
    wanted = {"auto": ["pnu"] if has_pnu else ["objects"], "pnu": ["pnu"], "objects": ["objects"],
              "all": ["pnu", "objects"]}[source]
    if "pnu" in wanted and not has_pnu:
        raise UsageError("this target offers no PROFIdrive parameter channel; use --source objects")
    if "objects" in wanted and not has_obj:
        raise UsageError("this target offers no object channel (SDO); use --source pnu")
    return wanted


# ---------------------------------------------------------------------------- reading
def read_pnu_values(channel: Any, items: Sequence[Item]) -> tuple[dict[str, Value], dict[str, str]]:
    """Every PNU item in one batched read; (values by key, refusals by key)."""

    specs = [PnuSpec(i.index, 0, i.info.length, i.info) for i in items if i.kind == "pnu"]
    if not specs:
        return {}, {}
    # One call: the channel packs the reads into the fewest requests (channels/batching.py).
    readings = read_pnus(channel, specs)
    values: dict[str, Value] = {}
    errors: dict[str, str] = {}
    for reading in readings:
        key = str(reading.spec.pnu)
        if not reading.ok:
            errors[key] = f"{reading.error_text} (error 0x{reading.error:02X})"
            continue
        got = [int(v) for v in reading.values or []]
        values[key] = got if reading.spec.info.is_array else (got[0] if got else 0)
    order = {str(s.pnu): n for n, s in enumerate(specs)}
    return dict(sorted(values.items(), key=lambda kv: order[kv[0]])), errors


def read_object_values(channel: Any, items: Sequence[Item]) -> tuple[dict[str, Value], dict[str, str]]:
    """One SDO upload per object item; refusals recorded, a broken link raises."""
    values: dict[str, Value] = {}
    errors: dict[str, str] = {}
    for item in items:
        if item.kind != "object":
            continue
        try:
            data = channel.upload(item.info.index, item.info.subindex)
        except CommError:
            raise
        except AkdError as exc:
            errors[item.key] = exc.message
            continue
        values[item.key] = snapshot_value(item.info, data)
    return values, errors


def read_values(conn: "Connection", items: Sequence[Item]) -> tuple[dict[str, Value], dict[str, str]]:
    pnu_items = [i for i in items if i.kind == "pnu"]
    obj_items = [i for i in items if i.kind == "object"]
    values: dict[str, Value] = {}
    errors: dict[str, str] = {}
    if pnu_items:
        if not conn.has_parameters:
            raise UsageError("this target offers no PROFIdrive parameter channel; PNUs cannot be read")
        v, e = read_pnu_values(conn.parameters(), pnu_items)
        values.update(v)
        errors.update(e)
    if obj_items:
        if not conn.has_objects:
            raise UsageError("this target offers no object channel (SDO); objects cannot be read")
        v, e = read_object_values(conn.objects(), obj_items)
        values.update(v)
        errors.update(e)
    return values, errors


# ---------------------------------------------------------------------------- identity
IDENTITY_CHECKED = ("manufacturer", "drive_unit_type", "vendor_id", "product_code")


def identity_from_pnus(values: dict[str, Value]) -> dict[str, Any]:
    """Identity fields from PNU 964 (already in a PNU backup: no extra round trip)."""
    from akdctl.drive.identity import backup_drive_unit, drive_unit

    du = values.get("964")
    if not isinstance(du, list) or len(du) < 5:
        return {}
    return backup_drive_unit(drive_unit(du))


def read_identity(conn: "Connection", use_pnu: bool, use_objects: bool) -> dict[str, Any]:
    """The identity fields of the drive from the channels a backup uses (the one identity reader, flattened)."""
    from akdctl.drive import identity

    reading = identity.read_identity(conn, pnus=use_pnu, objects=use_objects, im0=False)
    return identity.backup_identity(reading)


def identity_mismatches(expected: dict[str, Any], actual: dict[str, Any]) -> list[str]:
    """Type-identity fields both sides know and that differ (serial numbers may differ: same type, new unit)."""
    return [f"{key}: file {expected[key]!r}, drive {actual[key]!r}" for key in IDENTITY_CHECKED
            if key in expected and key in actual and expected[key] != actual[key]]


# ---------------------------------------------------------------------------- snapshot data
@dataclass
class Snapshot:
    target: str
    time: str
    identity: dict[str, Any]
    pnus: dict[str, Value] = field(default_factory=dict)
    objects: dict[str, Value] = field(default_factory=dict)
    refused: dict[str, str] = field(default_factory=dict)
    source: str = ""  # the file it came from (not stored)

    @property
    def firmware(self) -> str | None:
        return self.identity.get("firmware") or self.identity.get("software_version")

    def values(self) -> dict[str, Value]:
        return {**self.pnus, **self.objects}

    def to_data(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "akdctl_backup": {"format": SNAPSHOT_FORMAT, "target": self.target, "time": self.time,
                              "firmware": self.firmware or ""},
            "identity": self.identity,
        }
        if self.pnus:
            data["pnus"] = self.pnus
        if self.objects:
            data["objects"] = self.objects
        if self.refused:
            data["refused"] = self.refused
        return data

    @classmethod
    def from_data(cls, data: Any, source: str) -> "Snapshot":
        if not isinstance(data, dict) or not isinstance(data.get("akdctl_backup"), dict):
            raise UsageError(f"{source}: not an akdctl parameter backup (no [akdctl_backup] table)")
        head = data["akdctl_backup"]
        if head.get("format") != SNAPSHOT_FORMAT:
            raise UsageError(f"{source}: backup format {head.get('format')!r} is not supported (expected {SNAPSHOT_FORMAT})")
        snap = cls(str(head.get("target", "")), str(head.get("time", "")), dict(data.get("identity") or {}),
                   source=source)
        for section, store in (("pnus", snap.pnus), ("objects", snap.objects)):
            table = data.get(section) or {}
            if not isinstance(table, dict):
                raise UsageError(f"{source}: [{section}] must be a table of values")
            for key, value in table.items():
                item = _item_for_key(str(key), section, source)
                _check_value(item, value, f"{source}: [{section}] {key}")
                store[item.key] = value
        snap.refused = {str(k): str(v) for k, v in dict(data.get("refused") or {}).items()}
        return snap


def _item_for_key(key: str, section: str, source: str) -> Item:
    try:
        item = resolve_item(key)
    except UsageError as exc:
        raise UsageError(f"{source}: [{section}] {key!r}: {exc.message}") from None
    if (section == "pnus") != (item.kind == "pnu"):
        raise UsageError(f"{source}: [{section}] {key!r} is a{'n object' if item.kind == 'object' else ' PNU'}, "
                         f"not a{' PNU' if section == 'pnus' else 'n object'}")
    return item


def _check_value(item: Item, value: Any, where: str) -> None:
    """A file's value fits the item's type (checked before anything is written)."""
    if item.kind == "pnu":
        info = item.info
        values = value if isinstance(value, list) else [value]
        if info.is_array != isinstance(value, list):
            raise UsageError(f"{where}: expected {'a list of' if info.is_array else 'one'} integer"
                             f"{'s' if info.is_array else ''} for PNU {info.pnu} ({info.name})")
        if len(values) > info.length:
            raise UsageError(f"{where}: PNU {info.pnu} ({info.name}) has {info.length} elements, file has {len(values)}")
        for v in values:
            if isinstance(v, bool) or not isinstance(v, int):
                raise UsageError(f"{where}: expected an integer, got {v!r}")
        if item.restorable:
            check_pnu_values(info, values, where)
        return
    encode_object(item.info, value)


def values_equal(a: Any, b: Any) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        try:
            return math.isclose(float(a), float(b), rel_tol=1e-6, abs_tol=1e-9)
        except (TypeError, ValueError):
            return False
    if isinstance(a, str) and isinstance(b, str) and a.lower().startswith("0x") and b.lower().startswith("0x"):
        return a.lower() == b.lower()
    return a == b


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def take(conn: "Connection", items: Sequence[Item], target: str, sources: Sequence[str]) -> Snapshot:
    """Read every item (one batched PNU read, one SDO upload per object) into a snapshot."""
    values, errors = read_values(conn, items)
    identity = identity_from_pnus(values) if "964" in values else {}
    need_pnu_identity = "pnu" in sources and not identity
    extra = read_identity(conn, need_pnu_identity, "objects" in sources)
    identity.update(extra)
    snap = Snapshot(target, now_iso(), identity, refused=errors)
    for item in items:
        if item.key in values:
            (snap.pnus if item.kind == "pnu" else snap.objects)[item.key] = values[item.key]
    return snap


# ---------------------------------------------------------------------------- files
def write_file(snapshot: Snapshot, path: str | os.PathLike[str]) -> Path:
    """Write TOML (``.toml``) or JSON (``.json``) atomically: a crash never leaves half a backup."""
    target = Path(path)
    suffix = target.suffix.lower()
    if suffix == ".toml":
        text = to_toml(snapshot.to_data(), comments=_comments(snapshot))
    elif suffix == ".json":
        text = json.dumps(snapshot.to_data(), indent=2) + "\n"
    else:
        raise UsageError(f"backup file {target.name}: use a .toml or .json suffix (the format follows it)")
    write_user_file(target, text)
    return target


#: A backup file at most this large is read (a full AKD snapshot is a few hundred kB).
MAX_BACKUP_BYTES = 16 * 1024 * 1024


def load_file(path: str | os.PathLike[str]) -> Snapshot:
    """A backup file: a regular file (no FIFO or device), at most :data:`MAX_BACKUP_BYTES`, TOML or JSON;
    every problem is one line, exit 2."""
    from akdctl.io.safe_read import read_regular_text

    source = Path(path)
    if not source.exists() and not source.is_symlink():
        raise UsageError(f"backup file {source} does not exist")
    text = read_regular_text(source, limit=MAX_BACKUP_BYTES, what="a backup file")
    try:
        if source.suffix.lower() == ".json":
            try:
                data = json.loads(text)
            except json.JSONDecodeError as exc:
                raise UsageError(f"{source}:{exc.lineno}: not valid JSON: {exc.msg}") from None
        else:
            try:
                data = tomllib.loads(text)
            except tomllib.TOMLDecodeError as exc:
                raise UsageError(f"{source}: not valid TOML: {exc}") from None
    except RecursionError:
        raise UsageError(f"{source}: nested too deeply to be a backup file") from None
    except ValueError as exc:  # e.g. an integer beyond Python's digit limit
        raise UsageError(f"{source}: not a backup file ({exc})".splitlines()[0][:300]) from None
    return Snapshot.from_data(data, str(source))


def _comments(snapshot: Snapshot) -> dict[str, str]:
    out = {}
    for key in snapshot.values():
        try:
            item = resolve_item(key)
        except UsageError:
            continue
        out[key] = item.name + ("" if item.restorable else " (not restored)")
    return out


def _toml_key(key: str) -> str:
    return key if key.replace("_", "").replace("-", "").isalnum() and not key[0].isdigit() else json.dumps(key)


def toml_string(text: str) -> str:
    """A TOML basic string for any text a drive's string object can hold: JSON's escapes are TOML's (\\b \\t \\n
    \\f \\r \\" \\\\ \\uXXXX) and cover every C0 control; TOML also forbids a raw DEL (U+007F), which JSON
    leaves alone, so it is escaped too (issue 23 item 18: a backup always restores)."""
    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_toml_key(str(k))} = {_toml_value(v)}" for k, v in value.items()
                                if v is not None) + " }"
    raise UsageError(f"cannot write {type(value).__name__} value to TOML")


def to_toml(data: dict[str, Any], comments: dict[str, str] | None = None, prefix: str = "") -> str:
    """A small TOML writer for snapshot-shaped data (nested tables of scalars and lists)."""
    comments = comments or {}
    lines: list[str] = []
    scalars = [(k, v) for k, v in data.items() if not isinstance(v, dict) and v is not None]
    tables = [(k, v) for k, v in data.items() if isinstance(v, dict)]
    for key, value in scalars:
        note = comments.get(str(key))
        lines.append(f"{_toml_key(str(key))} = {_toml_value(value)}" + (f"  # {note}" if note else ""))
    for key, value in tables:
        name = f"{prefix}.{_toml_key(str(key))}" if prefix else _toml_key(str(key))
        body = to_toml(value, comments, name)
        if lines:
            lines.append("")
        lines.append(f"[{name}]")
        if body:
            lines.append(body.rstrip("\n"))
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- diff
@dataclass(frozen=True)
class Difference:
    key: str
    name: str
    old: Any  # the drive's (or file B's) value; None when missing
    new: Any  # file A's value; None when missing
    restorable: bool

    def to_json(self) -> dict[str, Any]:
        return {"key": self.key, "name": self.name, "a": self.new, "b": self.old, "restorable": self.restorable}


def compare(wanted: dict[str, Value], actual: dict[str, Value], *, include_all: bool = False) -> list[Difference]:
    """Differences between the wanted values (file A) and the actual ones (drive or file B).

    Only restorable (configuration) items by default: live values such as the
    status word or actual velocity always differ and say nothing about setup.
    """
    out = []
    for key in wanted:
        if key not in actual:
            continue  # one-sided keys: see one_sided()
        item = resolve_item(key)
        if not include_all and not item.restorable:
            continue
        a, b = wanted[key], actual[key]
        if not values_equal(a, b):
            out.append(Difference(key, item.name, b, a, item.restorable))
    return out


def one_sided(wanted: dict[str, Value], actual: dict[str, Value], *, include_all: bool = False) -> tuple[list[str], list[str]]:
    """Keys only in A and only in B (files of different scope); listed, not counted as differences."""
    def keep(key: str) -> bool:
        return include_all or resolve_item(key).restorable

    return ([k for k in wanted if k not in actual and keep(k)], [k for k in actual if k not in wanted and keep(k)])


# ---------------------------------------------------------------------------- restore
@dataclass
class Change:
    item: Item
    old: Any
    new: Any

    def to_json(self) -> dict[str, Any]:
        return {"key": self.item.key, "name": self.item.name, "old": self.old, "new": self.new,
                "phase": self.item.phase}


def plan_restore(snapshot: Snapshot, current: dict[str, Value]) -> list[Change]:
    """What must be written to make the drive equal the snapshot, in a safe order."""
    changes = []
    telegram = snapshot.pnus.get("922", current.get("922"))
    for key, new in snapshot.values().items():
        item = resolve_item(key)
        if not item.restorable:
            continue
        if key in TELEGRAM_DERIVED and telegram not in (None, 0):
            continue  # a standard telegram fixes its IO words; 915/916 are writable only with telegram 0
        old = current.get(key)
        if old is not None and values_equal(old, new):
            continue
        changes.append(Change(item, old, new))
    position = {key: n for n, key in enumerate(snapshot.values())}
    changes.sort(key=lambda c: (c.item.phase, c.item.kind != "pnu", c.item.index if c.item.kind == "object" else 0,
                                c.item.subindex, position[c.item.key]))
    return changes


def restorable_items(snapshot: Snapshot) -> list[Item]:
    return [item for item in (resolve_item(k) for k in snapshot.values()) if item.restorable]


def apply_changes(conn: "Connection", changes: Sequence[Change]) -> list[dict[str, Any]]:
    """Write the changes in order, then read every one back; CheckFailed when a value did not stick."""

    done: list[dict[str, Any]] = []
    pnu_batch: list[Change] = []

    def flush() -> None:
        if not pnu_batch:
            return
        assignments = []
        for change in pnu_batch:
            info = change.item.info
            values = change.new if isinstance(change.new, list) else [change.new]
            assignments.append((PnuSpec(info.pnu, 0, len(values), info), [int(v) for v in values]))
        results = write_pnus(conn.parameters(), assignments)
        for change, result in zip(pnu_batch, results):
            if not result.ok:
                exc = pnu_refused(result, "change")
                exc.message += f" (to {change.new}); {len(done)} change(s) were written before it"
                exc.details["written"] = done
                raise exc
            done.append(change.to_json())
        pnu_batch.clear()

    phase = None
    for change in changes:
        if change.item.phase != phase:
            flush()  # a later phase depends on the earlier one having been accepted
            phase = change.item.phase
        if change.item.kind == "pnu":
            if not conn.has_parameters:
                raise UsageError("this target offers no PROFIdrive parameter channel; the backup holds PNUs")
            pnu_batch.append(change)
            continue
        flush()
    flush()
    _write_objects(conn, [c for c in changes if c.item.kind == "object"], done)
    verify(conn, changes)
    return done


def _write_objects(conn: "Connection", changes: Sequence[Change], done: list[dict[str, Any]]) -> None:
    if not changes:
        return
    if not conn.has_objects:
        raise UsageError("this target offers no object channel (SDO); the backup holds objects")
    channel = conn.objects()
    by_index: dict[int, list[Change]] = {}
    order: list[int] = []
    for change in changes:
        if change.item.info.index not in by_index:
            order.append(change.item.info.index)
        by_index.setdefault(change.item.info.index, []).append(change)
    for index in order:
        group = by_index[index]
        counted = index in _PDO_MAPPING or index in _PDO_ASSIGN
        if counted:
            # EtherCAT manual 5.6 / SPEC-NOTES 17: count 0, entries, count.
            entries = [c for c in group if c.item.info.subindex != 0]
            count = next((c for c in group if c.item.info.subindex == 0), None)
            sub0 = _subs(index)[0]
            final = count.new if count is not None else None
            if final is None:
                final = read_snapshot_value(channel, sub0)
            _download(channel, sub0, 0, done, label=f"{object_key(index, 0)} = 0 (clear before changing entries)")
            for change in entries:
                _download(channel, change.item.info, change.new, done, change=change)
            _download(channel, sub0, final, done, change=count)
        else:
            for change in group:
                _download(channel, change.item.info, change.new, done, change=change)


def _download(channel: Any, entry: Any, value: Any, done: list[dict[str, Any]], *, change: Change | None = None,
              label: str = "") -> None:
    data = encode_object(entry, value)
    try:
        channel.download(entry.index, entry.subindex, data)
    except SdoAborted as exc:
        raise SdoAborted(f"drive refused {object_key(entry.index, entry.subindex)} ({entry.name}) = {value!r}: "
                         f"{exc.message}; {len(done)} change(s) were written before it", code=exc.code,
                         details={"written": done}) from None
    if change is not None:
        done.append(change.to_json())
    elif label:
        done.append({"key": object_key(entry.index, entry.subindex), "name": entry.name, "new": value, "note": label})


def verify(conn: "Connection", changes: Sequence[Change]) -> None:
    """Read every changed item back (one batched PNU read + SDO uploads) and compare (the one read-back)."""
    from akdctl.drive.operation import check_readback

    if not changes:
        return
    values, errors = read_values(conn, [c.item for c in changes])
    pairs = []
    for change in changes:
        key = change.item.key
        back = f"refused: {errors[key]}" if key in errors else values.get(key)
        if values_equal(back, change.new):
            back = change.new  # equal as the snapshot compares (float tolerance, hex case)
        pairs.append((f"{key} ({change.item.name})", change.new, back))
    check_readback(pairs)


def save_nonvolatile(conn: "Connection") -> None:
    """DRV.NVSAVE: 0x1010:1 = "save" (0x65766173); the AKD keeps the values over a power cycle."""
    if not conn.has_objects:
        raise UsageError("saving to non-volatile memory needs the object channel (0x1010); this target has none")
    write_object(conn.objects(), NVSAVE_INDEX, NVSAVE_SUBINDEX, NVSAVE_SIGNATURE)


@dataclass
class RestoreResult:
    changes: list[Change]
    written: list[dict[str, Any]]
    saved: bool
    identity_warnings: list[str]

    def to_json(self) -> dict[str, Any]:
        return {"changes": [c.to_json() for c in self.changes], "written": self.written, "saved": self.saved,
                "identity_mismatches": self.identity_warnings}


class RestoreRequest:
    """``params restore FILE``/a recipe's restore step: the snapshot, ``force`` (restore a backup of another
    drive type), ``save`` (then DRV.NVSAVE)."""

    __slots__ = ("snapshot", "force", "save")

    def __init__(self, snapshot: Snapshot, *, force: bool = False, save: bool = False) -> None:
        self.snapshot = snapshot
        self.force = force
        self.save = save


#: The precondition of every restore: parameters change only on a disabled drive.
DISABLED = "drive disabled (parameters are restored only with the power stage off)"


def plan(conn: "Connection", request: RestoreRequest) -> "WritePlan":
    """Reads the identity and the current values; the differences in their safe order are the writes.

    Refused here, before anything is written: a backup of another drive type (unless forced) and, when there is
    anything to write, a drive that is enabled or does not say.
    """
    from akdctl.drive.gate import drive_enabled
    from akdctl.drive.operation import PlannedWrite, WritePlan

    snapshot = request.snapshot
    items = restorable_items(snapshot)
    use_pnu = any(i.kind == "pnu" for i in items) or not conn.has_objects
    use_obj = any(i.kind == "object" for i in items) or not conn.has_parameters
    mismatches = identity_mismatches(snapshot.identity, read_identity(conn, use_pnu, use_obj))
    if mismatches and not request.force:
        raise SafetyRefusal("the backup is of a different drive type (" + "; ".join(mismatches)
                            + "); refusing to restore (use --force to restore anyway)",
                            details={"mismatches": mismatches})
    current, _ = read_values(conn, items)
    changes = plan_restore(snapshot, current)
    enabled: bool | None = False
    if changes:
        enabled = drive_enabled(conn)  # the one "is the power stage on?" rule (the axis status)
        if enabled is not False:
            state = "is enabled (operation enabled)" if enabled else "does not tell whether it is enabled"
            raise SafetyRefusal(f"the drive {state}; disable it before restoring parameters")
    # No write carries a gate verdict: the precondition above (power stage off, read just now) is what keeps
    # a restore from moving the axis, and the control word is never restorable; the README's restore needs no
    # consent, as before.
    writes = [PlannedWrite(f"{c.item.key} ({c.item.name})", c.new,
                           f"{describe_value(c.new)} (now {describe_value(c.old)})") for c in changes]
    notes = [f"identity differs ({m}); restored because of --force" for m in mismatches]
    if any(c.item.kind == "object" and (c.item.index in _PDO_MAPPING or c.item.index in _PDO_ASSIGN)
           for c in changes):
        notes.append("a PDO mapping or assignment is cleared (count 0) before its entries change (SPEC-NOTES 17)")
    if request.save:
        notes.append("then saved to non-volatile memory (DRV.NVSAVE, 0x1010:1 = \"save\")")
    return WritePlan("params restore", conn.target.display, writes, preconditions=[DISABLED] if changes else [],
                     notes=notes, enabled=enabled, verify=True,
                     data={"request": request, "changes": changes, "mismatches": mismatches})


def execute(conn: "Connection", plan: "WritePlan") -> "RestoreResult":
    """Write the plan's changes in order, read every one back (one CheckFailed), then save if asked."""
    request: RestoreRequest = plan.data["request"]
    changes: list[Change] = plan.data["changes"]
    written = apply_changes(conn, changes) if changes else []
    if request.save:
        save_nonvolatile(conn)
    return RestoreResult(changes, written, request.save, plan.data["mismatches"])


def restore(conn: "Connection", snapshot: Snapshot, *, dry_run: bool = False, force: bool = False,
            save: bool = False) -> RestoreResult:
    """Make the drive equal the snapshot's configuration values: :func:`plan` then (unless ``dry_run``)
    :func:`execute`."""
    planned = plan(conn, RestoreRequest(snapshot, force=force, save=save))
    if dry_run:
        return RestoreResult(planned.data["changes"], [], False, planned.data["mismatches"])
    return execute(conn, planned)


def describe_value(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, dict) and set(value) == {"hex"}:
        return f"0x{value['hex']} (bytes, not UTF-8 text)"
    if isinstance(value, list):
        return "[" + ", ".join(str(v) for v in value) + "]"
    return str(value)

