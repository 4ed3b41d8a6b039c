"""``akdctl pdo show|presets|map``: EtherCAT/CoE process-data mapping."""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import UsageError


@click.group()
def pdo() -> None:
    """Show, plan and apply process-data (PDO) mapping (EtherCAT manual 5.5-5.7).

    PDOs: fixed 0x1701, 0x1702, 0x1720-0x1725 (Rx) and 0x1B01, 0x1B20-0x1B26 (Tx);
    flexible 0x1600-0x1603 (Rx) and 0x1A00-0x1A03 (Tx), each at most 8 bytes.

    \b
    Examples:
      akdctl -T ecat-udp://10.0.0.5/1001 pdo show
      akdctl pdo presets 0x1B20
    """


def _entry_rows(direction_json: dict[str, Any]) -> list[list[Any]]:
    rows = []
    for pdo_json in direction_json["pdos"]:
        kind = "fixed" if pdo_json["fixed"] else "flexible"
        if not pdo_json["entries"]:
            rows.append([f"{pdo_json['name']} ({kind})", "", "", "(empty)", "", "", ""])
        for n, entry in enumerate(pdo_json["entries"], start=1):
            label = f"{pdo_json['name']} ({kind}, {pdo_json['bytes']} bytes)" if n == 1 else ""
            rows.append([label, n, entry["address"], entry["name"], entry["type"], entry["bit_offset"], entry["bits"]])
    return rows


def _mapping_doc(doc: Doc, mapping_json: dict[str, Any]) -> Doc:
    from akdctl.drive.pdo import WORDS

    for direction in ("rx", "tx"):
        d = mapping_json[direction]
        assigned = ", ".join(d["assigned"]) or "(none)"
        doc.table(["PDO", "entry", "object", "name", "type", "bit offset", "bits"], _entry_rows(d),
                  title=f"{WORDS[direction]}: {d['assign_object']} = {assigned}; {d['bytes']} of {d['max_bytes']} bytes")
    return doc


@pdo.command("show")
def show() -> None:
    """The assignment (0x1C12/0x1C13), each assigned PDO and its entries, with bit offsets and byte totals.

    Bit offsets count from the start of the direction's process image.

    \b
    Examples:
      akdctl -T ecat-udp://10.0.0.5/1001 pdo show
      akdctl pdo show --json
    """
    from akdctl.drive.pdo import al_state_of, read_mapping

    app = get_app()
    channel = app.objects()
    mapping = read_mapping(channel)
    state = al_state_of(app.connection)
    data = {"target": app.target.display, "al_state": state, **{d: m.to_json() for d, m in mapping.items()}}

    def human() -> Doc:
        doc = Doc("PDO mapping", app.target.display)
        if state is not None:
            doc.kv("AL state", state)
        doc.kv("Rx bytes", f"{data['rx']['bytes']} (at most {data['rx']['max_bytes']})")
        doc.kv("Tx bytes", f"{data['tx']['bytes']} (at most {data['tx']['max_bytes']})")
        return _mapping_doc(doc, data)

    app.emit(data, human)


@pdo.command("presets")
@click.argument("numbers", nargs=-1, metavar="[PDO]...")
def presets(numbers: tuple[str, ...]) -> None:
    """Every fixed PDO of the AKD with its contents and size (from the catalogue; no drive needed).

    Name PDOs (e.g. 0x1B20) to see their entries one by one.

    \b
    Examples:
      akdctl pdo presets
      akdctl pdo presets 0x1701 0x1B20
    """
    from akdctl.catalog import objects as oc
    from akdctl.drive.pdo import SHORT, describe_pdo, parse_pdo_arg

    app = get_app()
    wanted = []
    for text in numbers:
        number, _ = parse_pdo_arg(text)
        if oc.fixed_pdo(number) is None:
            raise UsageError(f"0x{number:04X} is not a fixed PDO of the AKD; fixed PDOs: "
                             + ", ".join(f"0x{n:04X}" for n in (*oc.FIXED_RX_PDOS, *oc.FIXED_TX_PDOS)))
        wanted.append(number)
    chosen = wanted or [*oc.FIXED_RX_PDOS, *oc.FIXED_TX_PDOS]
    described = [describe_pdo(n, oc.fixed_pdo(n) or ()) for n in chosen]
    data = {"source": "catalogue", "pdos": described}

    def human() -> Doc:
        doc = Doc("fixed PDOs of the AKD", "catalogue")
        if wanted:
            for p in described:
                doc.table(["entry", "object", "name", "type", "bit offset", "bits"],
                          [[n, e["address"], e["name"], e["type"], e["bit_offset"], e["bits"]]
                           for n, e in enumerate(p["entries"], start=1)],
                          title=f"{p['name']} ({SHORT[p['direction']]}PDO, {p['bytes']} bytes)")
            return doc
        rows = [[p["name"], SHORT[p["direction"]], p["bytes"], len(p["entries"]),
                 ", ".join(f"{e['address']} {e['name']}" for e in p["entries"])] for p in described]
        return doc.table(["PDO", "dir", "bytes", "entries", "contents"], rows)

    app.emit(data, human)


def _startup_doc(steps: list[Any], title: str, source: str) -> Doc:
    return Doc(title, source).table(
        ["Transition", "Protocol", "Index", "Data", "Comment"],
        [[s.transition, "CoE", s.address, s.data_text, s.comment] for s in steps],
    )


@pdo.command("map")
@click.option("--rx", "rx", multiple=True, metavar="PDO[=ENTRIES]",
              help="Assign an RxPDO (repeat for more); 0x1600=0x6040:0/16,0x60C1:1/32 also defines a flexible one.")
@click.option("--tx", "tx", multiple=True, metavar="PDO[=ENTRIES]",
              help="Assign a TxPDO (repeat for more); 0x1A00=0x6041:0/16,0x6063:0/32 also defines a flexible one.")
@click.option("--define", "define", multiple=True, metavar="PDO=ENTRIES",
              help="Define a flexible PDO's entries without assigning it (the manual's 5.6.1 example).")
@click.option("--file", "file", metavar="FILE", type=click.Path(dir_okay=False),
              help="Read the mapping from a TOML (.toml) or JSON file (keys rx, tx, define, opmode, cycle_time).")
@click.option("--opmode", metavar="MODE", help="Also write 0x6060 (number, or pp/pv/tq/hm/ip/csp).")
@click.option("--cycle-time", "cycle_time", metavar="TIME", help="Also write 0x60C2 (e.g. 2ms, 250us or 2,-3).")
@click.option("--dry-run", is_flag=True, help="Print the startup list; write nothing.")
@click.option("--export", "export", metavar="FILE.json", type=click.Path(dir_okay=False),
              help="Write the startup list as JSON.")
@click.option("--force", is_flag=True, help="Skip akdctl's own checks and let the drive answer.")
def map_(rx: tuple[str, ...], tx: tuple[str, ...], define: tuple[str, ...], file: str | None, opmode: str | None,
         cycle_time: str | None, dry_run: bool, export: str | None, force: bool) -> None:
    """Change the mapping with the manual's sequence, then read it back and compare (exit 5 on a difference).

    \b
    Entries are INDEX:SUB/BITS; pad odd lengths with 0x0002:0/8 (Rx) or 0x2002:1/8 (Tx).
    Everything is checked before the first write: PDO <= 8 bytes, Rx <= 22 and Tx <= 32
    bytes, even lengths, mappable objects in the right direction, drive in PRE-OP.

    \b
    Examples:
      akdctl -y pdo map --rx 0x1701 --tx 0x1B20
      akdctl -y pdo map --rx 0x1600=0x6040:0/16,0x60C1:1/32 --tx 0x1A00=0x6041:0/16,0x6063:0/32
      akdctl pdo map --file mapping.toml --dry-run
    """
    import json as jsonlib

    from akdctl.cli.consent import consent_plan
    from akdctl.drive import pdo as dp

    app = get_app()
    if file and (rx or tx or define or opmode is not None or cycle_time is not None):
        raise UsageError("give the mapping either with --file or with --rx/--tx/--define/--opmode/--cycle-time")
    mapping = dp.load_plan_file(file) if file else dp.build_plan(rx, tx, define, opmode, cycle_time)
    request = dp.map_request(mapping, force=force)
    steps = dp.startup_list(mapping)
    if export:
        from pathlib import Path

        from akdctl.io.atomic import write_user_file  # the one rule for files akdctl writes (mode, directory)

        write_user_file(Path(export), jsonlib.dumps(dp.export_json(steps, mapping), indent=2) + "\n")
    plan = dp.plan(app.connection, request)
    data: dict[str, Any] = {"plan": mapping.to_json(), "startup": [s.to_json() for s in steps],
                            "problems": request.problems, "dry_run": dry_run, "write_plan": plan.to_json()}
    if dry_run:
        def planned() -> Doc:
            doc = Doc("startup list (dry run, nothing written)", plan.target)
            for text in plan.preconditions:
                doc.kv("precondition", text)
            if plan.needing_consent:
                doc.kv("needs consent", plan.consent_text)
            for text in plan.notes:
                doc.kv("note", text)
            return doc.table(["Transition", "Protocol", "Index", "Data", "Comment"],
                             [[s.transition, "CoE", s.address, s.data_text, s.comment] for s in steps])

        app.emit(data, planned)
        return
    consent_plan(app, plan)
    result = dp.execute(app.connection, plan)
    after = result["mapping"]
    data.update({"target": app.target.display, "written": result["sdo_downloads"], "verified": True,
                 "differences": [], "mapping": after})

    def human() -> Doc:
        doc = _startup_doc(steps, f"PDO mapping written ({result['sdo_downloads']} SDO downloads)",
                           app.target.display)
        doc.kv("read back", "identical")
        return _mapping_doc(doc, after)

    app.emit(data, human)
