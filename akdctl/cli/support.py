"""``akdctl support bundle -o FILE`` and ``akdctl support show FILE``.

The bundle is what a technician sends; ``show`` is what the support engineer
runs on it, on a desk with no drive. See :mod:`akdctl.drive.bundle` for the
file format.
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc, message
from akdctl.errors import CommError, UsageError


@click.group()
def support() -> None:
    """Write a support bundle from a drive, or show one without a drive.

    \b
    Examples:
      akdctl support bundle -o bundle.zip
      akdctl support show bundle.zip
    """


@support.command("bundle")
@click.option("-o", "--output", "output", required=True, metavar="FILE", type=click.Path(dir_okay=False),
              help="Bundle file to write (JSON; a name ending in .zip writes a zip with the JSON inside).")
@click.option("--all-objects", is_flag=True,
              help="Snapshot every readable object of the dictionary, not only the core ones (slow on a real bus).")
@click.option("--scope", "scope_file", metavar="FILE",
              help="Attach a recording ('akdctl scope ... --json > FILE') as the bundle's 'scope' member.")
def bundle(output: str, all_objects: bool, scope_file: str | None) -> None:
    """Collect identity, fault dump, status, parameters, mapping and the session trace into one file.

    A section the drive refuses is recorded in the file; the file is written
    atomically, never half. When the drive does not answer (or stops answering), the
    remaining sections are not read, the file is still written, and the exit code is 3.

    \b
    Examples:
      akdctl support bundle -o bundle.zip
      akdctl -T pn://192.168.0.10 support bundle -o axis1.zip --all-objects
      akdctl support bundle -o bundle.zip --scope jog.json
    """
    from pathlib import Path

    from akdctl.drive import bundle as bundle_mod
    from akdctl.io.atomic import require_directory

    app = get_app()
    require_directory(Path(output))  # before the drive is read
    recording = None
    if scope_file is not None:
        from akdctl.drive.scope_model import load_recording

        recording = load_recording(scope_file).to_json()  # a bad file refuses before the drive is read
    data = bundle_mod.collect(app.connection, all_objects=all_objects)
    if recording is not None:
        data["scope"] = recording
    path = bundle_mod.write(data, output)
    errors = data.get("errors", {})
    summary = {"file": str(path), "format": bundle_mod.FORMAT, "format_version": bundle_mod.FORMAT_VERSION,
               "target": data["target"]["display"], "sections_with_errors": sorted(errors),
               "trace_frames": len(data.get("trace", []))}
    app.emit(summary, lambda: Doc("support bundle written", data["target"]["display"])
             .kv("file", str(path)).kv("trace frames", summary["trace_frames"])
             .kv("sections with errors", ", ".join(sorted(errors)) or "none"))
    for section, text in sorted(errors.items()):
        if section != bundle_mod.LINK_ERROR and not text.startswith(bundle_mod.SKIPPED):
            message(f"akdctl: warning: {section}: {text}")
    lost = errors.get("transport") or errors.get(bundle_mod.LINK_ERROR)
    if lost:
        exc = CommError(f"bundle written to {path}, but the drive did not answer ({lost}); "
                        "the sections after it were not read")
        exc.reported = True
        raise exc


# ---------------------------------------------------------------------------- show
def _flatten(prefix: str, value: Any, doc: Doc) -> None:
    if isinstance(value, dict):
        for key, sub in value.items():
            _flatten(f"{prefix}.{key}" if prefix else str(key), sub, doc)
    elif isinstance(value, list) and value and all(isinstance(v, dict) and "set" in v for v in value):
        doc.kv(prefix, ", ".join(str(v.get("name", v.get("bit"))) for v in value if v.get("set")) or "none set")
    elif isinstance(value, list) and value and all(isinstance(v, dict) and "code" in v for v in value):
        doc.kv(prefix, "; ".join(f"{v.get('code')} {v.get('text', v.get('name', ''))}".strip() for v in value))
    elif isinstance(value, list) and len(value) > 12:
        doc.kv(prefix, f"[{len(value)} values] " + ", ".join(str(v) for v in value[:12]) + ", …")
    else:
        doc.kv(prefix, value)


def _header_doc(data: dict[str, Any], path: str) -> Doc:
    tool, target = data.get("tool", {}), data.get("target", {})
    doc = Doc("support bundle", str(target.get("display", "")))
    doc.kv("file", path).kv("created", data.get("created"))
    doc.kv("written by", f"{tool.get('name', '?')} {tool.get('version', '?')} (Python {tool.get('python', '?')}, "
                         f"{tool.get('platform', '?')})")
    doc.kv("target", f"{target.get('display')} (scheme {target.get('scheme')}, profile "
                     f"{target.get('drive_profile') or 'auto'})")
    for section, text in sorted((data.get("errors") or {}).items()):
        doc.kv(f"error in {section}", text)
    from akdctl.drive.bundle_report import identity

    section = identity(data)  # the page's identity rows: who the drive is in words, then each value with its words
    for key, value in section.pairs:
        doc.kv(f"identity.{key}", value)
    for note in section.notes:
        doc.kv("identity", note)
    return doc


def _status_doc(data: dict[str, Any]) -> Doc:
    doc = Doc("status")
    _flatten("", data.get("status") or {}, doc)
    return doc


def _parameters_doc(data: dict[str, Any]) -> Doc:
    params = data.get("parameters") or {}
    doc = Doc("parameter snapshot")
    if "error" in params:
        return doc.line(f"not readable: {params['error']}")
    trips = params.get("round_trips")
    if isinstance(trips, dict):
        doc.kv("round trips", ", ".join(f"{k} {v}" for k, v in trips.items()) or "none")
    pnus = params.get("pnus")
    if isinstance(pnus, list):
        rows = []
        for r in pnus:
            values = r.get("values")
            shown = r["error"]["text"] if "error" in r else ",".join(str(v) for v in (values or []))
            if len(shown) > 70:
                shown = shown[:67] + "..."
            rows.append([r.get("pnu"), r.get("name") or "?", shown])
        doc.table(["PNU", "name", "value"], rows, title="PNUs")
    elif isinstance(pnus, dict):
        doc.line(f"PNUs not readable: {pnus.get('error')}")
    objects = params.get("objects")
    if isinstance(objects, list):
        doc.table(["object", "name", "value"],
                  [[o.get("object"), o.get("name") or "?", o["error"] if "error" in o else o.get("value", o.get("hex"))]
                   for o in objects], title="objects")
    elif isinstance(objects, dict):
        doc.line(f"objects not readable: {objects.get('error')}")
    return doc


def _mapping_doc(data: dict[str, Any]) -> Doc:
    doc = Doc("process-data mapping")
    mapping = dict(data.get("mapping") or {})
    co = mapping.pop("canopen", None)
    _flatten("", mapping, doc)
    if isinstance(co, dict) and "error" not in co:
        rows = []
        for direction, d in co.items():
            doc.kv(f"canopen {direction}", f"{d.get('assign_object')} = {', '.join(d.get('assigned', [])) or 'none'} "
                                           f"({d.get('bytes')} of {d.get('max_bytes')} bytes)")
            for pdo in d.get("pdos", []):
                for e in pdo.get("entries", []):
                    rows.append([direction, pdo.get("name"), e.get("address"), e.get("bits"), e.get("name")])
        if rows:
            doc.table(["dir", "PDO", "object", "bits", "name"], rows, title="PDO entries")
    elif isinstance(co, dict):
        doc.kv("canopen", f"not readable: {co.get('error')}")
    return doc


def _trace_doc(data: dict[str, Any], full: bool) -> Doc:
    trace = data.get("trace") or []
    doc = Doc(f"session trace ({len(trace)} frames)")
    shown = trace if full else trace[:20]
    for rec in shown:
        arrow = "->" if rec.get("direction") == "tx" else "<-"
        doc.line(f"{arrow} {rec.get('layer', '')!s:8s} {rec.get('hex', '')}")
    if len(shown) < len(trace):
        doc.line(f"… {len(trace) - len(shown)} more frames (--trace-all shows them)")
    return doc


@support.command("show")
@click.argument("file", metavar="FILE")
@click.option("--trace-all", is_flag=True, help="Show every frame of the session trace (default: the first 20).")
@click.option("--html", "html_file", metavar="OUT", type=click.Path(dir_okay=False),
              help="Write one self-contained HTML page (no script, nothing loaded from the network) to OUT.")
@click.option("--format", "fmt", type=click.Choice(["text", "markdown"]), default="text", show_default=True,
              help="markdown: the report as Markdown tables for a ticket, on stdout.")
def show(file: str, trace_all: bool, html_file: str | None, fmt: str) -> None:
    """Render a support bundle (no drive needed). A damaged or foreign file: one-line error, exit 2.

    Only a regular file is read (a FIFO or a device is refused at once), at most 32 MiB, and a zip's
    members at most 64 MiB each unpacked (128 MiB together). --html writes a page with identity,
    status, faults with explanations and remedies, parameters (non-default values highlighted),
    mapping, a scope recording when the bundle holds one, and the session trace; every field is
    escaped. A bundle from a newer akdctl (a later format version) is refused (exit 2).

    \b
    Examples:
      akdctl support show bundle.zip
      akdctl support show bundle.zip --trace-all
      akdctl support show bundle.zip --html bundle.html
      akdctl support show bundle.zip --format markdown > ticket.md
    """
    from akdctl.cli.fault import dump_doc
    from akdctl.cli.output import emit_json, render
    from akdctl.drive.bundle import load

    app = get_app()
    data = load(file)
    if html_file is not None or fmt == "markdown":
        _report(app, data, file, html_file, fmt)
        return
    if app.json:
        emit_json(data)
        return
    docs: list[Doc] = []
    builders = (
        ("header", lambda: _header_doc(data, file)),
        ("faults", lambda: dump_doc(data["faults"]) if isinstance(data.get("faults"), dict)
         and "error" not in data["faults"] else Doc("fault dump").line(
             f"not readable: {(data.get('faults') or {}).get('error', 'missing')}")),
        ("status", lambda: _status_doc(data)),
        ("parameters", lambda: _parameters_doc(data)),
        ("mapping", lambda: _mapping_doc(data)),
        ("trace", lambda: _trace_doc(data, trace_all)),
        *((("scope", lambda: _scope_doc(data["scope"])),) if "scope" in data else ()),
    )
    for name, build in builders:
        try:
            docs.append(build())
        except (KeyError, TypeError, AttributeError, ValueError, IndexError, RecursionError) as exc:
            raise UsageError(f"{file}: damaged support bundle (section {name}: {type(exc).__name__})") from None
    for doc in docs:
        render(doc)


def _report(app: Any, data: dict[str, Any], file: str, html_file: str | None, fmt: str) -> None:
    """``--html`` and/or ``--format markdown``: the report model (drive/bundle_report.py) through its writers."""
    from pathlib import Path

    from akdctl.drive import bundle_report

    try:
        sections = bundle_report.build(data, file)
    except (KeyError, TypeError, AttributeError, ValueError, IndexError, RecursionError) as exc:
        raise UsageError(f"{file}: damaged support bundle ({type(exc).__name__})") from None
    if html_file is not None:
        from akdctl.drive import bundle_html
        from akdctl.io.atomic import write_user_file

        title = f"akdctl support bundle: {bundle_report.text((data.get('target') or {}).get('display'))}"
        write_user_file(Path(html_file), bundle_html.render(sections, title).encode("utf-8"))
        if fmt != "markdown":
            app.emit({"file": file, "html": html_file, "sections": [s.key for s in sections]},
                     Doc("support bundle page written", file).kv("html", html_file))
    if fmt == "markdown":
        import sys

        sys.stdout.write(bundle_report.markdown(sections))
        sys.stdout.flush()


@support.command("diff")
@click.argument("a", metavar="A")
@click.argument("b", metavar="B")
@click.option("--other-drive", is_flag=True, help="Compare bundles of two different drives (refused otherwise).")
@click.option("--all", "include_all", is_flag=True,
              help="Compare live parameter values too (status word, actual position and velocity).")
def diff(a: str, b: str, other_drive: bool, include_all: bool) -> None:
    """Compare two support bundles: identity, firmware, faults, mapping, parameters. Exit 0 if equal, 5 if not.

    Bundles of two different drives (another serial number, or another target where the
    identity lacks one) are refused with exit 2 unless --other-drive.

    \b
    Examples:
      akdctl support diff before.zip after.zip
      akdctl support diff axis1.zip axis2.zip --other-drive --json
    """
    from akdctl.drive.bundle import load
    from akdctl.drive.bundle_diff import compare
    from akdctl.errors import CheckFailed

    app = get_app()
    result = compare(load(a), load(b), names=(a, b), other_drive=other_drive, include_live=include_all)

    def human() -> Doc:
        doc = Doc(f"support bundles {a} vs {b}")
        doc.kv("created", " vs ".join(str(c) for c in result["created"]))
        if not result["same_drive"]:
            doc.kv("drives", "different (--other-drive)")
        for name, rows in result["sections"].items():
            if rows:
                doc.table(["key", "A", "B"], [[r["key"], _cell(r["a"]), _cell(r["b"])] for r in rows],
                          title=f"{name}: {len(rows)} difference(s)")
            else:
                doc.kv(name, "equal")
        return doc

    app.emit(result, human)
    if not result["equal"]:
        exc = CheckFailed(f"the bundles differ in {result['differences']} value(s)")
        exc.reported = True
        raise exc


def _cell(value: Any) -> str:
    if value is None:
        return "(absent)"
    if isinstance(value, list):
        value = ", ".join(str(v) for v in value) or "none"
    value = str(value)
    return value if len(value) <= 60 else value[:57] + "..."


def _scope_doc(recording: Any) -> Doc:
    """The attached recording: its facts and its terminal plot (drive/scope_plot.py)."""
    from akdctl.drive.scope_model import Recording
    from akdctl.drive.scope_plot import terminal_plot

    rec = Recording.from_json(recording)  # ValueError: a damaged member (the caller's one-line error)
    doc = Doc("scope recording", rec.target)
    doc.kv("source", rec.source).kv("trigger", rec.trigger).kv("samples", rec.summary())
    doc.kv("channels", ", ".join(c.legend for c in rec.channels))
    if rec.partial:
        doc.kv("PARTIAL", rec.partial)
    for line in terminal_plot(rec, width=72, height=10).splitlines()[2:]:
        doc.line(line)
    return doc
