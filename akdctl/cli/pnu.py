"""``akdctl pnu get|set|describe|list``: PROFIdrive parameters by number."""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc


@click.group()
def pnu() -> None:
    """Read, write, describe and list PROFIdrive parameters (PNUs).

    Addresses: 930, 964:0..4 (or quoted '964[0..4]'), 947:3, or a signal name such as STW1.

    \b
    Examples:
      akdctl pnu get 930
      akdctl -y pnu set 930=2
    """


def _hex(value: int, bits: int) -> str:
    return f"0x{value & ((1 << bits) - 1):0{bits // 4}X}"


def _singleturn_bits(channel: Any, readings: list[Any]) -> int:
    """PNU 1002 (singleturn bits) when a position in counts is shown: from the readings, else read (default 16)."""
    from akdctl.drive.values import read_pnus, pnu_spec

    if not any(r.ok and r.spec.info is not None and r.spec.info.unit == "counts" for r in readings):
        return 16
    for reading in readings:
        if reading.ok and reading.spec.pnu == 1002 and reading.spec.subindex == 0 and reading.values:
            return int(reading.values[0])
    back = read_pnus(channel, [pnu_spec(1002)])[0]
    return int(back.values[0]) if back.ok and back.values else 16


def _rows(readings: list[Any], singleturn_bits: int = 16) -> list[list[Any]]:
    from akdctl.drive.values import pnu_display
    from akdctl.profiles.units import describe_scaled

    rows = []
    for reading in readings:
        spec, info = reading.spec, reading.spec.info
        name = info.name if info else "?"
        if not reading.ok:
            rows.append([spec.label, name, "ERROR", f"0x{reading.error:02X}", reading.error_text])
            continue
        bits = info.bits if info else {0x41: 8, 0x42: 16, 0x43: 32}.get(reading.format or 0, 16)
        for offset, value in enumerate(reading.values or []):
            label = spec.label if len(reading.values or []) == 1 else f"{spec.pnu}[{spec.subindex + offset}]"
            if isinstance(value, int):
                rows.append([label, name, pnu_display(spec.pnu, spec.subindex + offset, value), _hex(value, bits),
                             describe_scaled(info.unit, value, singleturn_bits) if info else ""])
            else:
                rows.append([label, name, value, "", ""])
    return rows


def _report_failures(readings: list[Any], verb: str) -> None:
    failed = [r for r in readings if not r.ok]
    if not failed:
        return
    from akdctl.drive.values import pnu_refused

    exc = pnu_refused(failed[0], verb, more=len(failed) - 1)
    exc.reported = True
    raise exc


@pnu.command("get")
@click.argument("addresses", nargs=-1, required=True, metavar="PNU[SUB|FROM..TO]...")
def get(addresses: tuple[str, ...]) -> None:
    """Read one or more PNUs in as few requests as the protocol allows (39 per request).

    \b
    Examples:
      akdctl pnu get 930 '964[0..4]' STW1
      akdctl pnu get 947 --json
    """
    from akdctl.drive.params import parse_pnu_spec
    from akdctl.drive.values import read_pnus

    app = get_app()
    specs = [parse_pnu_spec(text) for text in addresses]
    readings = read_pnus(app.parameters(), specs)
    bits = _singleturn_bits(app.parameters(), readings)
    app.emit(
        {"target": app.target.display, "parameters": [r.to_json() for r in readings]},
        lambda: Doc("PNU values", app.target.display).table(["PNU", "name", "value", "hex", "scaled"],
                                                            _rows(readings, bits)),
    )
    _report_failures(readings, "read")


@pnu.command("set")
@click.argument("assignments", nargs=-1, required=True, metavar="PNU[SUB]=VALUE[,VALUE...]...")
@click.option("--verify", is_flag=True, help="Read every value back and compare (exit 5 on a difference).")
@click.option("--dry-run", is_flag=True, help="Print what would be written and which writes need consent; write nothing.")
def set_(assignments: tuple[str, ...], verify: bool, dry_run: bool) -> None:
    """Change one or more PNUs (all are checked before anything is sent).

    \b
    Examples:
      akdctl -y pnu set 930=2 --verify
      akdctl -y pnu set 1004=-500 1005=500
      akdctl pnu set 930=2 --dry-run
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import raw_write
    from akdctl.drive.params import parse_assignment

    app = get_app()
    request = raw_write.SetRequest([raw_write.pnu_target(*parse_assignment(text)) for text in assignments], verify)
    plan = raw_write.plan(app.connection, request)
    if dry_run:
        render_dry_run(app, plan)
        return
    consent_plan(app, plan)
    raw_write.execute(app.connection, plan)
    from akdctl.drive.values import PnuReading

    app.emit(
        {"target": app.target.display,
         "written": [{**PnuReading(t.spec, values=t.values, format=t.spec.info.wire_format if t.spec.info else None)
                      .to_json(), "gated": w.to_json().get("gated")}
                     for w, t in zip(plan.writes, request.targets)],
         "verified": verify},
        lambda: Doc("PNU written", app.target.display).table(
            ["PNU", "name", "value", "result"],
            [[t.spec.label, t.name or "?", w.display, "ok" + (", read back" if verify else "")]
             for w, t in zip(plan.writes, request.targets)],
        ),
    )


@pnu.command("describe")
@click.argument("address", metavar="PNU")
def describe(address: str) -> None:
    """Show the catalogue entry and the drive's own description (attribute 0x20).

    \b
    Examples:
      akdctl pnu describe 930
      akdctl -T pn://192.168.0.10 pnu describe 947
    """
    from akdctl.catalog.meanings import pnu_meaning
    from akdctl.drive.params import description_json, parse_pnu_spec

    app = get_app()
    spec = parse_pnu_spec(address)
    meaning = pnu_meaning(spec.pnu, spec.subindex)
    channel = app.parameters()
    description = description_json(channel.read_description(spec.pnu))
    info = spec.info
    data: dict[str, Any] = {"target": app.target.display, "pnu": spec.pnu, "drive": description}
    if info is not None:
        data["catalogue"] = {
            "name": info.name, "type": info.type, "access": info.access, "elements": info.elements,
            "limits": list(info.limits()), "unit": info.unit, "description": info.description,
            "akd_parameter": info.akd_parameter, "note": info.note,
        }
        if meaning is not None and meaning.listing():
            data["catalogue"]["values"] = meaning.listing()

    def human() -> Doc:
        doc = Doc(f"PNU {spec.pnu}", app.target.display)
        if info is not None:
            doc.kv("name", info.name).kv("type", info.type).kv("access", info.access)
            if info.is_array:
                doc.kv("elements", info.length)
            lo, hi = info.limits()
            doc.kv("limits", f"{lo} .. {hi}").kv("description", info.description)
            if info.akd_parameter:
                doc.kv("AKD parameter", info.akd_parameter)
            if info.unit:
                doc.kv("unit", info.unit)
            if info.note:
                doc.kv("note", info.note)
            if meaning is not None and meaning.listing():
                doc.kv("values", meaning.listing())
        for key, value in description.items():
            doc.kv(f"drive: {key}", value)
        return doc

    app.emit(data, human)


@pnu.command("list")
@click.option("--group", type=click.Choice(["signal", "profidrive", "telegram", "fault", "identity", "jog"]),
              help="Only this group.")
@click.option("--drive", "from_drive", is_flag=True, help="Ask the drive which PNUs it has (PNU 980..989).")
def list_(group: str | None, from_drive: bool) -> None:
    """List the catalogue's PNUs (name, type, access, elements).

    \b
    Examples:
      akdctl pnu list --group identity
      akdctl pnu list --drive
    """
    from akdctl.catalog.pnus import pnu_table

    app = get_app()
    table = pnu_table()
    numbers = sorted(table)
    source = "catalogue"
    if from_drive:
        from akdctl.drive.values import PnuSpec, read_pnus

        reading = read_pnus(app.parameters(), [PnuSpec(980, 0, table[980].length, table[980])])[0]
        _report_failures([reading], "read")
        listed = []
        for value in reading.values or []:
            if value == 0:
                break
            listed.append(value)
        numbers = listed
        source = app.target.display
    infos = [table.get(n) for n in numbers]
    rows = [
        [n, i.name if i else "?", i.type if i else "", i.access if i else "", i.length if i and i.is_array else "",
         i.description if i else "not in the catalogue"]
        for n, i in zip(numbers, infos)
        if group is None or (i is not None and i.group == group)
    ]
    app.emit(
        {"source": source, "parameters": [
            {"pnu": r[0], "name": r[1], "type": r[2], "access": r[3], "elements": r[4] or None, "description": r[5]}
            for r in rows]},
        lambda: Doc("PNUs", source).table(["PNU", "name", "type", "access", "elements", "description"], rows),
    )
