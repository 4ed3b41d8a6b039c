"""Typed values, once: catalogue types turn drive bytes into values and values into drive bytes.

Why one module: a CANopen object or a PROFIdrive parameter is just bytes on the
wire; its meaning (width, sign, text or octets, the allowed range) is in the
catalogue. Before this module, every reader carried its own struct formats and
its own idea of "signed", so the same 0x6061 was an ``"<b"`` in one file and an
``int.from_bytes`` in another. Here, as in python-canopen's typed variables
(``node.sdo[0x6041].raw``), the catalogue's type decides, and everything else
calls these functions:

* objects (little-endian, SDO): :func:`read_object` / :func:`write_object` by the
  catalogue's type; :func:`decode` / :func:`encode` / :func:`encode_value` for
  bytes already at hand or text a user typed; :func:`resolve_type`, :func:`object_type`;
* the snapshot/recipe form of object values (numbers, text, octets as ``"0x…"``
  hex text): :func:`snapshot_value`, :func:`read_snapshot_value`, :func:`encode_object`;
* PNUs (PROFIdrive, batched through a ParameterChannel): :class:`PnuSpec`,
  :func:`pnu_spec`, :func:`read_pnus`, :func:`write_pnus`, :func:`read_pnu_map`,
  :func:`write_pnu_map`, and :func:`check_pnu_values` for the catalogue's limits.

Encoding refuses a value outside its type or documented limits with a
:class:`~akdctl.errors.UsageError` naming the allowed range, before anything is
sent; decoding a reply that does not fit its type is a
:class:`~akdctl.errors.MalformedReply`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from akdctl.catalog.pnus import PnuInfo, lookup as pnu_lookup
from akdctl.errors import MalformedReply, ParameterRefused, UsageError
from akdctl.protocol.record import Record

#: What a snapshot or recipe holds for one object or PNU (``{"hex": ...}``: a string object's bytes that are not
#: UTF-8 text, kept exactly; see :func:`snapshot_value`).
Value = int | float | str | list[int] | dict[str, str]


# ====================================================================== objects (SDO, little-endian)
def object_label(index: int, subindex: int) -> str:
    return f"0x{index:04X}:{subindex}"


#: The type names a user may give (``sdo``, ``cip``, recipes), as help and error texts list them.
TYPE_HELP = "u8 u16 u32 u64 i8 i16 i32 i64 r32 r64 vs (string) os (hex octets) bool"


def check_type_name(type_name: str) -> str:
    """``type_name`` if it names a data type, else a usage error listing the types (exit 2)."""
    from akdctl.protocol.datatypes import TYPES

    if type_name not in TYPES:
        raise UsageError(f"unknown type {type_name!r}; types: {TYPE_HELP}")
    return type_name


def resolve_type(address: Any, type_name: str | None) -> tuple[str, Any]:
    """The data type to use for ``address`` (``.index``, ``.subindex``) and the catalogue entry (or None).

    A type the user gave wins; otherwise the catalogue's. An object the catalogue
    does not know needs an explicit type.
    """
    from akdctl.catalog.objects import lookup, subentries

    entry = lookup(address.index, address.subindex)
    label = object_label(address.index, address.subindex)
    if type_name is not None:
        return check_type_name(type_name), entry
    if entry is None:
        if subentries(address.index):
            raise UsageError(f"object {label}: subindex {address.subindex} is not in the catalogue; give a type")
        raise UsageError(f"unknown object {label} (not in the AKD catalogue); give its type, e.g. 'sdo read {label} u32'")
    return entry.short_type, entry


class _Address(Record):
    __slots__ = ("index", "subindex")

    def __init__(self, index: int, subindex: int) -> None:
        self.index = index
        self.subindex = subindex


def object_type(index: int, subindex: int) -> str:
    """The catalogue's short type name of an object (``u16``, ``i8``, ``vs`` …); UsageError when unknown.

    An array's elements beyond those the catalogue lists (a drive may report more
    history entries than the ESI shows) share the type of the listed elements.
    """
    from akdctl.catalog.objects import lookup, subentries

    if lookup(index, subindex) is None and subindex > 0:
        kinds = {e.short_type for e in subentries(index) if e.subindex > 0}
        if len(kinds) == 1:
            return kinds.pop()
    return resolve_type(_Address(index, subindex), None)[0]


def decode(type_name: str, data: bytes) -> Any:
    """Bytes of an SDO upload → a value of ``type_name``; MalformedReply when they do not fit.

    A numeric object may arrive in four bytes (CiA 301: an expedited upload
    without size indication); zero padding beyond the type's width is dropped.
    """
    from akdctl.protocol.datatypes import TYPES, DataTypeError, unpack

    data = bytes(data)
    size = TYPES[type_name].size if type_name in TYPES else None
    if size is not None and len(data) > size and not any(data[size:]):
        data = data[:size]
    try:
        return unpack(type_name, data)
    except DataTypeError as exc:
        raise MalformedReply(f"reply does not fit type {type_name}: {exc} (raw {data.hex(' ') or 'empty'})") from None


def decode_as(type_name: str, data: bytes, what: str, *, named_by_user: bool) -> Any:
    """:func:`decode`, where a type the user named that the drive's bytes do not fit is the user's input error.

    ``sdo read 0x6041 u8`` on a 2-byte object is a wrong type given on the command line (exit 2), not a
    malformed reply (exit 3); a reply that does not fit the catalogue's own type stays a MalformedReply.
    """
    try:
        return decode(type_name, data)
    except MalformedReply as exc:
        if not named_by_user:
            raise MalformedReply(f"{what}: {exc.message}") from None
        raise UsageError(f"{what}: the drive answered {len(data)} byte(s) ({bytes(data).hex(' ') or 'empty'}), "
                         f"which type {type_name} does not fit; name a type of that size, or none to use the "
                         "catalogue's") from None


def encode_value(type_name: str, value: Any, what: str = "") -> bytes:
    """A python value → the bytes an SDO download carries; UsageError naming the allowed range."""
    from akdctl.protocol.datatypes import DataTypeError, pack

    try:
        return pack(type_name, value)
    except DataTypeError as exc:
        raise UsageError(f"{what + ': ' if what else ''}bad value {value!r} for type {type_name}: {exc}") from None


def encode(type_name: str, text: str) -> tuple[Any, bytes]:
    """What a user typed → (value, bytes) of ``type_name``; UsageError naming what was wrong."""
    from akdctl.protocol.datatypes import DataTypeError, pack, parse_value

    try:
        value = parse_value(type_name, text)
        return value, pack(type_name, value)
    except DataTypeError as exc:
        raise UsageError(f"bad value {text!r} for type {type_name}: {exc}") from None


def read_object(channel: Any, index: int, subindex: int, type_name: str | None = None) -> Any:
    """Upload one object and decode it by the catalogue's type (or ``type_name``)."""
    kind = type_name if type_name is not None else object_type(index, subindex)
    data = channel.upload(index, subindex)
    try:
        return decode(kind, data)
    except MalformedReply as exc:
        raise MalformedReply(f"object {object_label(index, subindex)}: {exc.message}") from None


def write_object(channel: Any, index: int, subindex: int, value: Any, type_name: str | None = None) -> None:
    """Encode ``value`` by the catalogue's type (or ``type_name``), range-checked, and download it."""
    kind = type_name if type_name is not None else object_type(index, subindex)
    channel.download(index, subindex, encode_value(kind, value, f"object {object_label(index, subindex)}"))


def value_words(value: Any, *, pnu: int | None = None, element: int = 0,
                obj: tuple[int, int] | None = None) -> str | None:
    """A PNU element's or an object's value in words where the catalogue knows them (``catalog/meanings.py``):
    ``2`` of PNU 930 is ``position``, a statusword its set bits by name; None otherwise."""
    from akdctl.catalog.meanings import object_meaning, pnu_meaning

    meaning = pnu_meaning(pnu, element) if pnu is not None else object_meaning(*obj) if obj is not None else None
    return meaning.words(value) if meaning is not None else None


def with_words(text: str, words: str | None) -> str:
    """``2 (position)``: the one way a value and its meaning are shown together."""
    return f"{text} ({words})" if words else text


def display(type_name: str, value: Any, obj: tuple[int, int] | None = None) -> tuple[str, str]:
    """(value text, hex text) for human output; the value text carries its meaning when ``obj`` (index, subindex)
    has one in the catalogue."""
    from akdctl.protocol.datatypes import TYPES, format_value

    t = TYPES[type_name]
    text = format_value(type_name, value)
    if obj is not None:
        text = with_words(text, value_words(value, obj=obj))
    if t.kind in ("int", "uint") and t.size:
        return text, f"0x{value & ((1 << (8 * t.size)) - 1):0{2 * t.size}X}"
    return text, ""


def pnu_display(pnu: int, element: int, value: Any) -> str:
    """A PNU element's value for human output, with its meaning (``pnu get 930`` → ``2 (position)``)."""
    return with_words(str(value), value_words(value, pnu=pnu, element=element))


def json_value(type_name: str, value: Any) -> Any:
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).hex()
    return value


# ---------------------------------------------------------------------- the snapshot's form of object values
def snapshot_value(entry: Any, data: bytes) -> Value:
    """Upload bytes → the value a snapshot/recipe stores: numbers, text, octets (and undecodable data) as "0x…".

    A string object whose bytes are not UTF-8 text is stored as ``{"hex": "41ff42"}``: decoding it would replace
    the bytes with U+FFFD, and a restore would then write other bytes than the drive held and read them back as
    "equal" (issue 23 item 18: a backup always restores what it backed up)."""
    if entry.short_type == "vs":
        try:
            bytes(data).rstrip(b"\x00").decode("utf-8")
        except UnicodeDecodeError:
            return {"hex": bytes(data).hex()}
    try:
        value = decode(entry.short_type, data)
    except MalformedReply:
        return "0x" + bytes(data).hex()
    if isinstance(value, (bytes, bytearray)):
        return "0x" + bytes(value).hex()
    if isinstance(value, bool):
        return int(value)
    return value  # type: ignore[no-any-return]


def read_snapshot_value(channel: Any, entry: Any) -> Value:
    return snapshot_value(entry, channel.upload(entry.index, entry.subindex))


def encode_object(entry: Any, value: Any) -> bytes:
    """A snapshot/recipe value → the bytes an SDO download carries; UsageError when it does not fit."""
    from akdctl.protocol.datatypes import DataTypeError, pack

    kind = entry.short_type
    try:
        if isinstance(value, dict):
            if kind not in ("vs", "os") or set(value) != {"hex"} or not isinstance(value["hex"], str):
                raise DataTypeError('only a string object takes a table, and only as {hex = "..."}')
            return bytes.fromhex(value["hex"])
        if kind == "os":
            if not isinstance(value, str):
                raise DataTypeError("octet strings are written as hex text, e.g. \"0x0102\"")
            text = value[2:] if value.lower().startswith("0x") else value
            return bytes.fromhex(text)
        if kind == "bool":
            return pack("u8", int(value)) if isinstance(value, (bool, int)) else pack("bool", value)
        return pack(kind, value)
    except (DataTypeError, ValueError) as exc:
        raise UsageError(f"object {object_label(entry.index, entry.subindex)} ({entry.name}): bad value {value!r}: {exc}") from None


# ====================================================================== PNUs (PROFIdrive parameters)
class PnuSpec(Record):
    """An address the user asked for: PNU, first element, number of elements."""

    __slots__ = ("pnu", "subindex", "count", "info")

    def __init__(self, pnu: int, subindex: int, count: int, info: PnuInfo | None) -> None:
        self.pnu = pnu
        self.subindex = subindex
        self.count = count
        self.info = info

    @property
    def label(self) -> str:
        if (self.info is None or not self.info.is_array) and self.subindex == 0 and self.count == 1:
            return str(self.pnu)
        if self.count == 1:
            return f"{self.pnu}[{self.subindex}]"
        return f"{self.pnu}[{self.subindex}..{self.subindex + self.count - 1}]"


class PnuReading(Record):
    """One requested address and what came back: values (signed per type) or a failure (mutable, unhashable)."""

    __slots__ = ("spec", "values", "raw", "format", "error", "error_text", "additional")
    __hash__ = None  # type: ignore[assignment]

    def __init__(self, spec: PnuSpec, values: list[int] | None = None, raw: list[Any] | None = None,
                 format: int | None = None, error: int | None = None, error_text: str = "",  # noqa: A002
                 additional: int | None = None) -> None:
        self.spec = spec
        self.values = values
        self.raw = raw
        self.format = format
        self.error = error
        self.error_text = error_text
        self.additional = additional


    @property
    def ok(self) -> bool:
        return self.error is None

    def to_json(self) -> dict[str, Any]:
        info = self.spec.info
        data: dict[str, Any] = {
            "pnu": self.spec.pnu,
            "name": info.name if info else None,
            "subindex": self.spec.subindex,
            "count": self.spec.count,
        }
        if self.ok:
            data["values"] = self.values
            data["format"] = self.format
            words = [value_words(v, pnu=self.spec.pnu, element=self.spec.subindex + i)
                     for i, v in enumerate(self.values or [])]
            if any(words):
                data["meanings"] = words
            if info and info.unit:
                data["unit"] = info.unit
        else:
            data["error"] = {"code": self.error, "text": self.error_text, "additional": self.additional}
        return data


def pnu_spec(pnu: int, subindex: int = 0, count: int | None = None) -> PnuSpec:
    """A catalogue PNU as an address, built directly (a whole array unless ``count`` says otherwise)."""
    info = pnu_lookup(pnu)
    if count is None:
        count = info.length - subindex if info is not None and info.is_array else 1
    return PnuSpec(pnu, subindex, count, info)


def check_pnu_values(info: PnuInfo, values: Sequence[Any], where: str = "") -> None:
    """Every value an integer within the PNU's documented limits (else its type's range); UsageError naming them."""
    lo, hi = info.limits()
    prefix = f"{where}: " if where else ""
    for value in values:
        if isinstance(value, bool) or not isinstance(value, int):
            raise UsageError(f"{prefix}expected an integer, got {value!r}")
        if not lo <= value <= hi:
            raise UsageError(f"{prefix}value {value} for PNU {info.pnu} ({info.name}) is outside {lo}..{hi}")


def _signed(value: int, bits: int) -> int:
    return value - (1 << bits) if value >= 1 << (bits - 1) else value


def pnu_from_wire(info: PnuInfo | None, raw: Sequence[Any]) -> list[Any]:
    """Wire elements → values: Byte/Word/DWord elements of a signed PNU are sign-extended by its type."""
    values = list(raw)
    if info is not None and info.signed and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return [_signed(v, info.bits) for v in values]
    return values


def pnu_to_wire(info: PnuInfo, values: Sequence[int]) -> Any:
    """Values → the ParameterValue a change request carries (the AKD's format, two's complement bits)."""
    from akdctl.protocol.bmp import ParameterValue

    mask = (1 << info.bits) - 1
    return ParameterValue(info.wire_format, tuple(v & mask for v in values))


def read_pnus(channel: Any, specs: Sequence[PnuSpec]) -> list[PnuReading]:
    """Read every spec in one batched channel call; values signed per the catalogue type."""
    from akdctl.protocol.bmp import ParameterAddress, ParameterFailure

    results = channel.read([ParameterAddress(s.pnu, s.subindex, s.count) for s in specs])
    readings = []
    for spec, result in zip(specs, results):
        if isinstance(result, ParameterFailure):
            from akdctl.catalog.texts import profidrive_error_phrase  # here: the texts are read only for a refusal

            readings.append(PnuReading(spec, error=result.error, error_text=profidrive_error_phrase(result.error), additional=result.additional))
            continue
        raw = list(result.values)
        readings.append(PnuReading(spec, values=pnu_from_wire(spec.info, raw), raw=raw, format=result.format))
    return readings


def write_pnus(channel: Any, assignments: Sequence[tuple[PnuSpec, list[int]]]) -> list[PnuReading]:
    """Write every assignment in one batched channel call; one reading per assignment (values = written).

    Values outside a PNU's limits are refused (UsageError) before anything is sent.
    """
    from akdctl.protocol.bmp import ParameterAddress

    items = []
    for spec, values in assignments:
        info = spec.info
        if info is None:
            raise UsageError(f"PNU {spec.pnu} is not in the catalogue, so its data type is unknown; cannot write it")
        check_pnu_values(info, values)
        items.append((ParameterAddress(spec.pnu, spec.subindex, spec.count), pnu_to_wire(info, values)))
    failures = channel.write(items)
    out = []
    for (spec, values), failure in zip(assignments, failures):
        if failure is None:
            out.append(PnuReading(spec, values=list(values), format=spec.info.wire_format if spec.info else None))
        else:
            from akdctl.catalog.texts import profidrive_error_phrase

            out.append(PnuReading(spec, error=failure.error, error_text=profidrive_error_phrase(failure.error), additional=failure.additional))
    return out


def read_pnu_map(channel: Any, pnus: Sequence[int]) -> dict[int, list[int]]:
    """Whole catalogue PNUs in one batched read, by number; a refusal raises ParameterRefused."""
    out: dict[int, list[int]] = {}
    for reading in read_pnus(channel, [pnu_spec(p) for p in pnus]):
        if not reading.ok:
            raise pnu_refused(reading, "read")
        out[reading.spec.pnu] = list(reading.values or [])
    return out


def write_pnu_map(channel: Any, pairs: Sequence[tuple[int, int]]) -> None:
    """Single-element PNUs ``(pnu, value)`` in one batched change; a refusal raises ParameterRefused."""
    for result in write_pnus(channel, [(pnu_spec(pnu, count=1), [value]) for pnu, value in pairs]):
        if not result.ok:
            raise pnu_refused(result, "change")


def pnu_refused(reading: PnuReading, verb: str, *, more: int = 0) -> ParameterRefused:
    """The one error for a PNU the drive refused to ``verb`` (read, change): "drive refused to read PNU 947[3]:
    faulty subindex (error 0x03, subindex 99)" -- every caller (pnu get/set, telegrams, the fault buffer,
    restores, recipes) words it here, as :func:`akdctl.channels.base.sdo_aborted` does for SDO aborts.
    ``more``: how many further addresses of the same request were refused too."""
    from akdctl.catalog.texts import profidrive_error_phrase, profidrive_failure_detail

    info = reading.spec.info
    name = f" ({info.name})" if info is not None else ""
    error = reading.error if reading.error is not None else 0
    detail = profidrive_failure_detail(error, reading.additional)
    if info is not None and info.is_array and reading.additional is not None:  # the element of an array refused
        detail = f"{profidrive_error_phrase(error)} (error 0x{error:02X}, element {reading.additional})"
    return ParameterRefused(
        f"drive refused to {verb} PNU {reading.spec.label}{name}: {detail}"
        + (f" (and {more} more)" if more else ""),
        code=error, details={"pnu": reading.spec.pnu, "subindex": reading.spec.subindex,
                             "additional": reading.additional})
