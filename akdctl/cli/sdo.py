"""``akdctl sdo read|write``: CANopen/CoE objects by index:subindex."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.drive.values import TYPE_HELP
from akdctl.errors import SdoAborted, UsageError

#: SDO abort "object does not exist in the object dictionary" (CiA 301).
_NO_OBJECT = 0x06020000


@contextlib.contextmanager
def _hinting(address_text: str) -> Iterator[None]:
    """An unknown object (catalogue or drive) named by a bare decimal index gets the hex reading as a hint."""
    from akdctl.drive.objects import hex_hint

    try:
        yield
    except (UsageError, SdoAborted) as exc:
        if isinstance(exc, UsageError) or exc.code == _NO_OBJECT:
            exc.message += hex_hint(address_text)
        raise


@click.group()
def sdo() -> None:
    """Read and write CANopen/CoE objects by SDO (index:subindex, e.g. 0x6041:0).

    \b
    Examples:
      akdctl sdo read 0x6041
      akdctl sdo list --catalogue
    """


@sdo.command("read")
@click.argument("address", metavar="INDEX[:SUB]")
@click.argument("type_name", metavar="[TYPE]", required=False)
def read(address: str, type_name: str | None) -> None:
    """Upload an object; TYPE defaults to the catalogue's type.

    TYPE: {types}.

    \b
    Examples:
      akdctl sdo read 0x6041
      akdctl sdo read 0x1018:1 u32
      akdctl -T ecat-udp://10.0.0.5/1001 sdo read 0x1008
    """
    from akdctl.catalog.objects import object_name
    from akdctl.drive.objects import parse_address
    from akdctl.drive.values import decode_as, display, json_value, resolve_type, value_words

    app = get_app()
    addr = parse_address(address)
    with _hinting(address):
        dtype, entry = resolve_type(addr, type_name)
        data = app.objects().upload(addr.index, addr.subindex)
    value = decode_as(dtype, data, f"object {addr.label}", named_by_user=type_name is not None)
    text, hex_text = display(dtype, value, (addr.index, addr.subindex))
    name = entry.name if entry is not None else (object_name(addr.index) or "")
    words = value_words(value, obj=(addr.index, addr.subindex))
    app.emit(
        {"target": app.target.display, "index": addr.index, "subindex": addr.subindex, "name": name,
         "type": dtype, "value": json_value(dtype, value), "raw": data.hex(), **({"meaning": words} if words else {})},
        lambda: Doc(f"object {addr.label}", app.target.display)
        .kv("name", name).kv("type", dtype).kv("value", text).kv("hex", hex_text or data.hex(" ")),
    )


read.help = (read.help or "").replace("{types}", TYPE_HELP)  # the one list (drive/values.TYPE_HELP)


@sdo.command("write")
@click.argument("address", metavar="INDEX[:SUB]")
@click.argument("args", nargs=-1, required=True, metavar="[TYPE] VALUE")
@click.option("--verify", is_flag=True, help="Read the object back and compare (exit 5 on a difference).")
@click.option("--dry-run", is_flag=True, help="Print what would be written and whether it needs consent; write nothing.")
def write(address: str, args: tuple[str, ...], verify: bool, dry_run: bool) -> None:
    """Download a value; TYPE defaults to the catalogue's type; VALUE '-' reads stdin.

    \b
    Examples:
      akdctl sdo write 0x6060:0 i8 3
      akdctl -y sdo write 0x607A:0 -1000 --verify
      echo 01ff | akdctl sdo write 0x2013:1 os -
    """
    from akdctl.catalog.objects import object_name
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import raw_write
    from akdctl.drive.objects import parse_address
    from akdctl.drive.values import encode, resolve_type
    app = get_app()
    addr = parse_address(address)
    if len(args) == 1:
        type_name, value_text = None, args[0]
    elif len(args) == 2:
        type_name, value_text = args
    else:
        raise UsageError(f"too many values for sdo write: expected [TYPE] VALUE, got {len(args)} arguments")
    with _hinting(address):
        dtype, entry = resolve_type(addr, type_name)
    if value_text == "-":
        value_text = sys.stdin.read().strip()
    if entry is not None and not entry.writable:
        raise UsageError(f"object {addr.label} ({entry.name}) is read-only")
    value, data = encode(dtype, value_text)
    name = entry.name if entry is not None else (object_name(addr.index) or "")
    target = raw_write.object_target(addr.index, addr.subindex, dtype, value, data,
                                     entry.name if entry is not None else "")
    plan = raw_write.plan(app.connection, raw_write.SetRequest([target], verify))
    if dry_run:
        render_dry_run(app, plan)
        return
    consent_plan(app, plan)
    with _hinting(address):
        raw_write.execute(app.connection, plan)
    app.emit(
        {"target": app.target.display, "index": addr.index, "subindex": addr.subindex, "name": name,
         "type": dtype, "written": data.hex(), "verified": verify},
        lambda: Doc(f"object {addr.label} written", app.target.display)
        .kv("name", name).kv("type", dtype).kv("value", value_text).kv("bytes", data.hex(" ")),
    )


@sdo.command("list")
@click.argument("pattern", required=False, metavar="[TEXT|INDEX]")
@click.option("--catalogue", is_flag=True, help="List akdctl's catalogue (the AKD ESI) instead of asking the drive.")
@click.option("--objects-only", is_flag=True, help="Objects without their entries (one request per object).")
def list_(pattern: str | None, catalogue: bool, objects_only: bool) -> None:
    """List the object dictionary as the drive reports it (SDO information service, CoE service 8; like IgH's
    'ethercat sdos'), or akdctl's catalogue with --catalogue. TEXT keeps objects whose name contains it,
    INDEX (0x6041) one object.

    \b
    Examples:
      akdctl -T ecat-udp://10.0.0.5/1001 sdo list
      akdctl sdo list --catalogue homing
    """
    from akdctl.drive.dictionary import catalogue_dictionary, read_dictionary

    app = get_app()
    wanted = _wanted(pattern, catalogue, app)
    if catalogue:
        rows, source = catalogue_dictionary(entries=not objects_only, wanted=wanted), "catalogue"
    else:
        try:
            rows = read_dictionary(app.objects(), entries=not objects_only, wanted=wanted)
        except UsageError as exc:  # a link without the service (CANopen, PROFIdrive): say what does work
            exc.message += "; 'akdctl sdo list --catalogue' lists akdctl's catalogue"
            raise
        source = app.target.display
    if pattern is not None and not _is_index(pattern):
        needle = pattern.lower()
        rows = [r for r in rows if needle in r.name.lower() or any(needle in e.name.lower() for e in r.entries)]
    app.emit({"source": source, "service": None if catalogue else "SDO information (CoE service 8)",
              "objects": [r.to_json() for r in rows]},
             lambda: _dictionary_doc(rows, source, catalogue))


def _is_index(text: str) -> bool:
    return text.lower().startswith("0x") or text.lower().endswith("h")


def _wanted(pattern: str | None, catalogue: bool, app: Any) -> Any:
    """One object when PATTERN is an index (0x6041, 6041h); None (all) otherwise."""
    from akdctl.drive.objects import parse_address

    if pattern is None or not _is_index(pattern):
        return None
    index = parse_address(pattern).index
    return lambda i: i == index


def _dictionary_doc(rows: list[Any], source: str, catalogue: bool) -> Doc:
    title = "object dictionary" + (" (akdctl catalogue)" if catalogue else " (SDO information service)")
    table: list[list[Any]] = []
    for row in rows:
        table.append([f"0x{row.index:04X}", "", row.name, row.object_code, "", "", ""])
        table.extend(["", f"{e.subindex}", f"  {e.name}", e.type, e.bits, e.access, e.pdo] for e in row.entries)
    doc = Doc(title, source).table(["index", "sub", "name", "type", "bits", "access", "pdo"], table)
    return doc.line(f"{len(rows)} object(s), {sum(len(r.entries) for r in rows)} entries")
