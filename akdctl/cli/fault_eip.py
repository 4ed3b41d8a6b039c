"""``fault dump`` / ``fault ack`` on an ``eip://`` target: what CIP offers (:mod:`akdctl.drive.eip_faults`), rendered.

Why beside cli/fault.py and not in it: that module renders the PROFIdrive and CoE views; an EtherNet/IP target has
neither, and its view (general fault, DRV.FAULT1, what is not offered) is a document of its own. cli/fault.py only
asks :func:`eip_only` and hands over.
"""

from __future__ import annotations

from typing import Any

from akdctl.cli.output import Doc


def eip_only(app: Any) -> bool:
    """The target speaks CIP only (no PNU, no object access): the fault commands read drive/eip_faults.py."""
    conn = app.connection
    return bool(conn.has_cip and not conn.has_parameters and not conn.has_objects)


def _eip_doc(data: dict[str, Any]) -> Doc:
    eip = data["eip"]
    doc = Doc("fault dump (EtherNet/IP)", data["target"])
    doc.kv("fault present", {True: "yes", False: "no", None: "unknown"}[eip["fault_present"]])
    doc.table(["code", "name", "kind"], [[e["code"] or "?", e["name"], e["kind"]] for e in eip["active"]]
              or [["-", "none active", ""]], title="active faults")
    for key, text in eip["sources"].items():
        doc.kv(f"source {key}", text)
    for key, text in eip["errors"].items():
        doc.kv(f"not read: {key}", text)
    for key, text in eip["not_offered"].items():
        doc.kv(f"not offered: {key}", text)
    return doc


def eip_dump(app: Any, fmt: str) -> None:
    """``fault dump`` over eip://: JSON, markdown or the table."""
    from akdctl.cli.output import emit_json, render
    from akdctl.drive.eip_faults import dump

    data = dump(app.connection)
    if app.json or fmt == "json":
        emit_json(data)
    elif fmt == "markdown":
        render(dump_markdown_eip(data))
    else:
        render(_eip_doc(data))


def dump_markdown_eip(data: dict[str, Any]) -> str:
    """The same document as markdown for a ticket (cli/fault.py's table helpers)."""
    from akdctl.cli.fault import _md_escape, _md_table

    doc = _eip_doc(data)
    lines = [f"## AKD fault dump — {_md_escape(data.get('target', ''))}", ""]
    lines += _md_table(["item", "value"], [[k, v] for k, v in doc.pairs]) + [""]
    for table in doc.tables:
        lines += [f"### {_md_escape(table.title)}", ""] + _md_table(table.columns, table.rows) + [""]
    return "\n".join(lines).rstrip() + "\n"


def eip_ack(app: Any) -> None:
    """``fault ack`` over eip://: nothing to do without a fault; with one, refused naming it and the reason."""
    from akdctl.drive.eip_faults import NOT_OFFERED, read
    from akdctl.errors import UsageError

    eip = read(app.connection)
    if eip["fault_present"] is False:
        result = {"target": app.target.display, "acknowledged": [], "still_active": [], "fault_present": False,
                  "via": "eip", "note": "no active fault: nothing was written"}
        app.emit(result, Doc("fault acknowledge", app.target.display).line("no active fault: nothing to acknowledge"))
        return
    active = ", ".join(e["code"] or "a fault" for e in eip["active"]) or "state unknown"
    raise UsageError(f"cannot acknowledge over EtherNet/IP ({active} active): {NOT_OFFERED['acknowledge']}")
