"""``akdctl cip get|set``: CIP attributes by class/instance/attribute over an eip:// target."""

from __future__ import annotations

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.drive.values import TYPE_HELP
from akdctl.errors import UsageError

def parse_path(text: str) -> tuple[int, int, int]:
    """CLASS/INSTANCE/ATTRIBUTE, each decimal or 0x-hex."""
    parts = text.split("/")
    if len(parts) != 3:
        raise UsageError(f"bad CIP path {text!r}: expected CLASS/INSTANCE/ATTRIBUTE, e.g. 0x0F/796/1 or 1/1/7")
    values = []
    for name, part, high in zip(("class", "instance", "attribute"), parts, (0xFFFF, 0xFFFFFFFF, 0xFFFF)):
        try:
            value = int(part, 0)
        except ValueError:
            raise UsageError(f"bad CIP path {text!r}: {name} {part!r} is not a number (decimal or 0x-hex)") from None
        if not 0 <= value <= high:
            raise UsageError(f"bad CIP path {text!r}: {name} {value} is outside 0..{high}")
        values.append(value)
    return values[0], values[1], values[2]


def attributes(app) -> object:  # type: ignore[no-untyped-def]
    """The target's CIP attribute channel (UsageError naming eip:// when it has none)."""
    return app.connection.cip()


@click.group()
def cip() -> None:
    """Read and write CIP attributes (EtherNet/IP explicit messaging, eip:// targets).

    \b
    Examples:
      akdctl -T eip://192.168.0.20 cip get 1/1/7 vs
    """


@cip.command("get")
@click.argument("path", metavar="CLASS/INSTANCE/ATTRIBUTE")
@click.argument("type_name", metavar="[TYPE]", required=False)
def get(path: str, type_name: str | None) -> None:
    """Get_Attribute_Single; TYPE decodes the value (default: hex octets).

    TYPE: {types}.

    \b
    Examples:
      akdctl -T eip://192.168.0.20 cip get 0x0F/796/1 u32
      akdctl -T eip://192.168.0.20 cip get 1/1/7 vs
    """
    from akdctl.drive.values import check_type_name, decode_as, display, json_value

    class_id, instance, attribute = parse_path(path)
    dtype = check_type_name(type_name or "os")
    app = get_app()
    data = attributes(app).get(class_id, instance, attribute)
    label = f"0x{class_id:02X}/{instance}/{attribute}"
    value = decode_as(dtype, data, f"attribute {label}", named_by_user=type_name is not None)
    text, hex_text = display(dtype, value)
    app.emit({"target": app.target.display, "class": class_id, "instance": instance, "attribute": attribute,
              "type": dtype, "value": json_value(dtype, value), "raw": data.hex()},
             lambda: Doc(f"attribute {label}", app.target.display).kv("type", dtype).kv("value", text)
             .kv("hex", hex_text or data.hex(" ")))


get.help = (get.help or "").replace("{types}", TYPE_HELP)  # the one list (drive/values.TYPE_HELP)


@cip.command("set")
@click.argument("path", metavar="CLASS/INSTANCE/ATTRIBUTE")
@click.argument("type_name", metavar="TYPE")
@click.argument("value_text", metavar="VALUE")
@click.option("--dry-run", is_flag=True, help="Print what would be written and whether it needs consent; write nothing.")
def set_(path: str, type_name: str, value_text: str, dry_run: bool) -> None:
    """Set_Attribute_Single with VALUE packed as TYPE (decimal or 0x-hex numbers).

    \b
    Examples:
      akdctl -T eip://192.168.0.20 -y cip set 0x25/1/7 i32 65536
      akdctl -T eip://192.168.0.20 cip set 0x25/1/3 u8 1 --dry-run
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import eip_params
    from akdctl.drive.values import check_type_name, encode

    class_id, instance, attribute = parse_path(path)
    value, data = encode(check_type_name(type_name), value_text)
    app = get_app()
    attributes(app)  # a target without CIP is refused before anything else
    plan = eip_params.plan(app.connection, eip_params.attribute_request(class_id, instance, attribute, type_name,
                                                                        value, data))
    if dry_run:
        render_dry_run(app, plan)
        return
    consent_plan(app, plan)
    eip_params.execute(app.connection, plan)
    label = f"0x{class_id:02X}/{instance}/{attribute}"
    app.emit({"target": app.target.display, "class": class_id, "instance": instance, "attribute": attribute,
              "type": type_name, "written": data.hex()},
             lambda: Doc(f"attribute {label} written", app.target.display).kv("type", type_name)
             .kv("value", value_text).kv("bytes", data.hex(" ")))
