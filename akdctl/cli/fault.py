"""``akdctl fault dump|ack|clear-history|list|explain``: the drive's faults, decoded.

``dump`` is what a support engineer asks a technician for: ``--format
markdown`` pastes straight into a ticket, ``--json`` feeds scripts. The
rendering functions here take the dump *data* (not a drive), so ``akdctl
support show`` renders a bundle's dump exactly as ``fault dump`` printed it.
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc, message
from akdctl.errors import UsageError


@click.group()
def fault() -> None:
    """Fault buffer dump, acknowledge, history and explanations (AKD F/n numbers).

    \b
    Examples:
      akdctl fault dump
      akdctl fault explain F501
    """


# ---------------------------------------------------------------------------- rendering
def _entry_rows(entries: list[dict[str, Any]], *, with_time: bool = False) -> list[list[Any]]:
    rows = []
    for i, e in enumerate(entries, 1):
        row = [i, e.get("code", "?"), e.get("kind", "?"), e.get("name", "")]
        if with_time:
            row.append(e.get("time"))
        rows.append(row)
    return rows


def _bits(value: int | None, fault_bit: str, warn_bit: str) -> str:
    if value is None:
        return "not readable"
    parts = [f"0x{value:04X}", f"{fault_bit} fault {'SET' if value & 0x08 else 'clear'}",
             f"{warn_bit} warning {'SET' if value & 0x80 else 'clear'}"]
    return ", ".join(parts)


def dump_doc(data: dict[str, Any], title: str = "fault dump") -> Doc:
    """A fault dump (the data of :func:`akdctl.drive.faults.dump`) as a human document."""
    doc = Doc(title, str(data.get("target", "")))
    pd = data.get("profidrive")
    if pd is not None:
        if "error" in pd:
            doc.kv("PROFIdrive", f"not readable: {pd['error']}")
        else:
            doc.kv("fault message counter (PNU 944)", pd.get("fault_message_counter"))
            doc.kv("consistent read", f"{'yes' if pd.get('consistent') else 'NO'} ({pd.get('attempts')} attempt(s))")
            doc.kv("ZSW1", _bits(pd.get("zsw1"), "bit 3", "bit 7"))
            doc.table(["#", "code", "kind", "name"], _entry_rows(pd.get("active", [])) or [["-", "", "", "none"]],
                      title="active fault situation (PNU 947[0..7])")
            rows = []
            for situation in pd.get("acknowledged", []):
                k = situation["situation"]
                for i, e in enumerate(situation["faults"], 1):
                    rows.append([k, f"947[{8 * k + i - 1}]", e.get("code"), e.get("kind"), e.get("name")])
            doc.table(["situation", "element", "code", "kind", "name"], rows or [["-", "", "", "", "none"]],
                      title="acknowledged fault situations (1 = newest)")
    co = data.get("canopen")
    if co is not None:
        if "error" in co:
            doc.kv("CANopen/CoE", f"not readable: {co['error']}")
        else:
            reg = co.get("error_register")
            doc.kv("error register (0x1001)",
                   "not readable" if reg is None else f"0x{reg:02X} ({co.get('error_register_text')})")
            doc.kv("statusword (0x6041)", _bits(co.get("statusword"), "bit 3", "bit 7"))
            if not co.get("consistent", True):
                doc.kv("consistent read", f"NO ({co.get('attempts')} attempts)")
            doc.table(["#", "code", "kind", "name"], _entry_rows(co.get("faults", [])) or [["-", "", "", "none"]],
                      title="current faults (0x2001)")
            doc.table(["#", "code", "kind", "name"], _entry_rows(co.get("warnings", [])) or [["-", "", "", "none"]],
                      title="current warnings (0x2000)")
            doc.table(["#", "code", "kind", "name", "time [s]"],
                      _entry_rows(co.get("fault_history", []), with_time=True) or [["-", "", "", "none", ""]],
                      title="fault history (0x2012/0x2013, newest first)")
            doc.table(["#", "raw", "EMCY", "meaning"],
                      [[i, e["raw"], e["emcy"], e["text"]] for i, e in enumerate(co.get("error_history", []), 1)]
                      or [["-", "", "", "none"]], title="error history (0x1003, newest first)")
            if co.get("emergencies"):
                doc.table(["EMCY", "register", "data", "meaning"],
                          [[e["emcy"], f"0x{e['register']:02X}", e["data"], e["text"]] for e in co["emergencies"]],
                          title="emergencies received in this session")
            for section, text in (co.get("errors") or {}).items():
                doc.line(f"{section}: not readable ({text})")
    for key, where in (("akd", "DRV.FAULTS / DRV.WARNINGS"), ("modbus", "DRV.FAULT1 over Modbus")):  # issue 24
        named = data.get(key)
        if named is None:
            continue
        if "error" in named:
            doc.kv(where, f"not readable: {named['error']}")
            continue
        doc.table(["#", "code", "kind", "name"], _entry_rows(named.get("faults", [])) or [["-", "", "", "none"]],
                  title=f"active faults ({where})")
        doc.table(["#", "code", "kind", "name"], _entry_rows(named.get("warnings", [])) or [["-", "", "", "none"]],
                  title="active warnings")
        if named.get("note"):
            doc.line(named["note"])
    return doc


def _md_escape(value: Any) -> str:
    return "" if value is None else str(value).replace("|", "\\|").replace("\n", " ")


def _md_table(columns: list[str], rows: list[list[Any]]) -> list[str]:
    out = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    out += ["| " + " | ".join(_md_escape(c) for c in row) + " |" for row in rows]
    return out


def dump_markdown(data: dict[str, Any]) -> str:
    """The same document as GitHub-flavoured markdown (headings + pipe tables) for a ticket."""
    doc = dump_doc(data)
    lines = [f"## AKD fault dump — {_md_escape(data.get('target', ''))}", ""]
    if doc.pairs:
        lines += _md_table(["item", "value"], [[k, v] for k, v in doc.pairs]) + [""]
    for table in doc.tables:
        lines += [f"### {_md_escape(table.title)}", ""] + _md_table(table.columns, table.rows) + [""]
    for line in doc.lines:
        lines.append(f"- {_md_escape(line)}")
    return "\n".join(lines).rstrip() + "\n"


def _warn_inconsistent(data: dict[str, Any]) -> None:
    for key in ("profidrive", "canopen"):
        section = data.get(key) or {}
        if section and "error" not in section and not section.get("consistent", True):
            message(f"akdctl: warning: the {key} fault buffer kept changing during {section.get('attempts')} "
                    "reads; this dump may mix two fault situations")


# ---------------------------------------------------------------------------- commands
@fault.command("dump")
@click.option("--format", "fmt", type=click.Choice(["table", "markdown", "json"]), default="table", show_default=True,
              help="table (terminal), markdown (paste into a ticket) or json (same as --json).")
def dump(fmt: str) -> None:
    """Read the fault buffer consistently and decode every entry.

    PROFIdrive: PNU 944, 947 (8 situations x 8 numbers), 944 again, repeated if a
    fault arrived meanwhile. CoE/CANopen: 0x1001, 0x1003, 0x2001/0x2000,
    0x2012/0x2013 and the emergencies received.

    \b
    Examples:
      akdctl fault dump
      akdctl fault dump --format markdown > faults.md
    """
    from akdctl.cli.fault_eip import eip_dump, eip_only
    from akdctl.cli.output import emit_json, render
    from akdctl.drive.faults import dump as read_dump

    app = get_app()
    if eip_only(app):  # issue 28: what an eip:// target offers (cli/fault_eip.py)
        return eip_dump(app, fmt)
    data = read_dump(app.connection)
    _warn_inconsistent(data)
    if app.json or fmt == "json":
        emit_json(data)
    elif fmt == "markdown":
        render(dump_markdown(data))
    else:
        render(dump_doc(data))
    failed = [key for key in ("profidrive", "canopen") if isinstance(data.get(key), dict) and "error" in data[key]]
    if failed and len(failed) == len([k for k in ("profidrive", "canopen") if k in data]):
        from akdctl.errors import DriveError

        exc = DriveError(f"the drive refused the fault dump: {data[failed[0]]['error']}")
        exc.reported = True
        raise exc


@fault.command("ack")
@click.option("--dry-run", is_flag=True, help="Print the faults that would be acknowledged and the write; write nothing.")
def ack(dry_run: bool) -> None:
    """Acknowledge the active faults (STW1 bit 7 / controlword bit 7 rising edge).

    Exit 1 if a fault is still active afterwards (its cause persists).

    \b
    Examples:
      akdctl fault ack
      akdctl fault ack --dry-run
    """
    from akdctl.cli.consent import render_dry_run
    from akdctl.cli.fault_eip import eip_ack, eip_only
    from akdctl.drive import faults

    app = get_app()
    if eip_only(app):  # issue 28: what an eip:// target offers (cli/fault_eip.py); it writes nothing, dry run or not
        return eip_ack(app)
    plan = faults.plan(app.connection, faults.AckRequest())
    if dry_run:
        render_dry_run(app, plan)
        return
    result = faults.execute(app.connection, plan)  # never gated: an acknowledge powers nothing
    if result["acknowledged"]:
        text = f"acknowledged {', '.join(result['acknowledged'])}; no fault active"
    elif not result.get("note"):
        text = "acknowledged; no fault active"
    else:
        text = "no active fault: nothing to acknowledge"
    app.emit(result, Doc("fault acknowledge", app.target.display).line(text))


@fault.command("clear-history")
@click.option("--dry-run", is_flag=True, help="Show the plan (the write); write nothing.")
def clear_history(dry_run: bool) -> None:
    """Clear the CiA 301 error history (0x1003:0 = 0) where the drive allows it.

    PROFIdrive offers no way to clear PNU 947; the command says so (exit 2).

    \b
    Examples:
      akdctl -T ecat-udp://10.0.0.5/1001 fault clear-history
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import faults

    app = get_app()
    plan = faults.plan_clear_history(app.connection)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)  # never gated: shows the plan's note
    result = faults.clear_history(app.connection, plan)
    app.emit(result, Doc("fault history", app.target.display).line(
        f"error history 0x1003 cleared ({result['entries_left']} entries left)"))


def _fault_json(f: Any) -> dict[str, Any]:
    from akdctl.catalog.faults import where_to_look

    return {"code": f.code or None, "number": f.number, "kind": f.kind, "emcy": f"0x{f.emcy:04X}", "name": f.name,
            "reaction": f.reaction or None, "remedy": f.remedy or None, "source": f.source,
            **({} if f.remedy else {"where_to_look": where_to_look(f)})}


@fault.command("list")
@click.argument("text", required=False)
@click.option("--kind", type=click.Choice(["fault", "warning", "none"]),
              help="Only faults (F), warnings (n), or 'none' (EMCY 0x0000: error reset, no error).")
def list_(text: str | None, kind: str | None) -> None:
    """The AKD fault/warning catalogue, optionally filtered by kind and by TEXT (code, name or EMCY code).

    \b
    Examples:
      akdctl fault list
      akdctl fault list --kind warning bus
    """
    from akdctl.catalog.faults import faults

    app = get_app()
    needle = (text or "").strip().lower()
    selected = []
    for f in faults():
        if kind is not None and f.kind != kind:
            continue
        haystack = f"{f.code} {f.name} 0x{f.emcy:04x} {f.number or ''}".lower()
        if needle and needle not in haystack:
            continue
        selected.append(f)
    rows = [[f.code or "-", f.kind, f"0x{f.emcy:04X}", f.name] for f in selected]
    app.emit({"count": len(selected), "faults": [_fault_json(f) for f in selected]},
             lambda: Doc(f"AKD faults and warnings ({len(rows)})").table(["code", "kind", "EMCY", "name"], rows))


def _resolve(code: str) -> list[Any]:
    """'F501', 'n503', '501' (F first), or an EMCY code '0x3210' → catalogue entries."""
    from akdctl.catalog.faults import by_code, by_emcy

    text = code.strip()
    if text.lower().startswith("0x"):
        try:
            return by_emcy(int(text, 16))
        except ValueError:
            return []
    found = by_code(text)
    return [found] if found is not None else []


@fault.command("explain")
@click.argument("code", metavar="CODE")
def explain(code: str) -> None:
    """Explain a fault or warning: F501, n503, 501 or an emergency code such as 0x3210.

    \b
    Examples:
      akdctl fault explain F501
      akdctl fault explain 0x3210
    """
    from akdctl.catalog.faults import by_emcy, by_number

    app = get_app()
    found = _resolve(code)
    if not found:
        raise UsageError(f"unknown AKD fault {code!r}: not in the fault table (see 'akdctl fault list')")
    results = []
    for f in found:
        related = [g.code for g in by_emcy(f.emcy) if g.code and g.code != f.code]
        if f.number is not None:
            twin = by_number(f.number, warning=not f.is_warning)
            if twin is not None and twin.code != f.code and twin.code not in related:
                related.append(twin.code)
        results.append({**_fault_json(f), "same_emcy_or_number": related})

    def human() -> Doc:
        doc = Doc(f"AKD {code.strip()}")
        for item in results:
            label = item["code"] or item["emcy"]
            doc.kv(f"{label} name", item["name"])
            doc.kv(f"{label} kind", item["kind"])
            if item["number"] is not None:
                doc.kv(f"{label} number", f"{item['number']} (PNU 947 / 0x2001 / 0x2012 value)")
            doc.kv(f"{label} emergency code", item["emcy"])
            doc.kv(f"{label} drive reaction", item["reaction"] or "not given by a public source")
            doc.kv(f"{label} remedy", item["remedy"] or item["where_to_look"])
            if item["same_emcy_or_number"]:
                doc.kv(f"{label} related", ", ".join(item["same_emcy_or_number"]))
            doc.kv(f"{label} source", item["source"])
        return doc

    app.emit({"query": code, "faults": results}, human)
