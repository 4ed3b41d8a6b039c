"""``akdctl sdo read|write``: CANopen/CoE objects by index:subindex."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator

import click

from akdctl.cli.consent import gate_write
from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import CheckFailed, SdoAborted, UsageError

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
    """Read and write CANopen/CoE objects by SDO (index:subindex, e.g. 0x6041:0)."""


@sdo.command("read")
@click.argument("address", metavar="INDEX[:SUB]")
@click.argument("type_name", metavar="[TYPE]", required=False)
def read(address: str, type_name: str | None) -> None:
    """Upload an object; TYPE defaults to the catalogue's type.

    TYPE: u8 u16 u32 u64 i8 i16 i32 i64 r32 r64 vs os bool.
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


@sdo.command("write")
@click.argument("address", metavar="INDEX[:SUB]")
@click.argument("args", nargs=-1, required=True, metavar="[TYPE] VALUE")
@click.option("--verify", is_flag=True, help="Read the object back and compare (exit 5 on a difference).")
def write(address: str, args: tuple[str, ...], verify: bool) -> None:
    """Download a value; TYPE defaults to the catalogue's type; VALUE '-' reads stdin.

    Examples: sdo write 0x6060:0 i8 3 · sdo write 0x6060:0 3 · echo 01ff | sdo write 0x2013:1 os -
    """
    from akdctl.catalog.objects import object_name
    from akdctl.drive import gate
    from akdctl.drive.objects import parse_address
    from akdctl.drive.values import decode, encode, resolve_type
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
    channel = app.objects()
    gate_write(app, [gate.classify_object(addr.index, addr.subindex, entry.name if entry is not None else "")])
    with _hinting(address):
        channel.download(addr.index, addr.subindex, data)
    if verify:
        back = channel.upload(addr.index, addr.subindex)
        if decode(dtype, back) != value:
            raise CheckFailed(f"object {addr.label}: wrote {value!r}, read back {decode(dtype, back)!r}")
    name = entry.name if entry is not None else (object_name(addr.index) or "")
    app.emit(
        {"target": app.target.display, "index": addr.index, "subindex": addr.subindex, "name": name,
         "type": dtype, "written": data.hex(), "verified": verify},
        lambda: Doc(f"object {addr.label} written", app.target.display)
        .kv("name", name).kv("type", dtype).kv("value", value_text).kv("bytes", data.hex(" ")),
    )
