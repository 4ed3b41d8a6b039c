"""``akdctl param``: AKD parameters by their own names (DRV.OPMODE, VL.KP ...) on every transport.

``params`` is the same group (an alias); its TOML/JSON ``backup`` is a subcommand here, and ``restore``/``diff``
take either a backup or the AKD's text parameter file, told apart by content. ``diff`` exits 5 when it finds a
difference, like ``params diff``.
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import CheckFailed, UsageError


@click.group()
def param() -> None:
    """Read, write, list, save, dump and restore AKD parameters by name (DRV.OPMODE, VL.KP and the rest).

    Names work on every target: akd:// speaks them, sim/ecat/can use the CoE object and its scale,
    eip:// the Parameter instance, mb:// the register 2(n-1), pn:// the PNU where one exists.

    \b
    Examples:
      akdctl param get DRV.OPMODE VL.KP
      akdctl -T akd://192.168.0.10 param get 'VL.*'
      akdctl -y param set VL.KP=0.5
      akdctl params backup -o axis1.toml
    """


def _live(conn: Any, how: str) -> dict[str, Any]:
    from akdctl.drive.name_discovery import discover

    return dict(discover(conn, how)["names"])


def _mark(row: Any) -> str:
    marks = [f"{k} {v}" for k, v in row.marks if v == "I"]
    return "[I: " + ", ".join(marks) + "]" if marks else ""


@param.command("get")
@click.argument("names", nargs=-1, required=True, metavar="NAME|GLOB...")
@click.option("--raw", is_flag=True, help="Also show the wire value, its scale and the address used.")
@click.option("--live", is_flag=True, help="Ask the drive which names it has (DRV.LIST / SDO information, "
                                           "cached per firmware); its answer overrides the catalogue.")
def get(names: tuple[str, ...], raw: bool, live: bool) -> None:
    """Read parameters by name or glob; values print with their unit.

    A glob reads the names the target can reach and lists the others as skipped.

    \b
    Examples:
      akdctl param get DRV.OPMODE VL.KP HOME.MODE
      akdctl param get 'UNIT.*' --raw --json
    """
    from akdctl.drive import names as ops

    app = get_app()
    conn = app.connection
    how = ops.route(conn) if live else ""
    rows = ops.expand(names, _live(conn, how) if live else None)
    how = how or ops.route(conn)
    explicit = {n.strip().upper() for n in names if not any(c in n for c in "*?[")}
    readings, skipped = [], []
    for row in rows:
        if row.name not in explicit and (not row.readable or not ops.reachable(row, how)):
            skipped.append(row.name)
            continue
        readings.append(ops.read(conn, row, how))
    data = {"target": app.target.display, "route": how, "parameters": [r.to_json(raw) for r in readings]}
    if skipped:
        data["skipped"] = skipped

    def human() -> Doc:
        columns = ["name", "value"] + (["wire", "scale", "address"] if raw else []) + ["note"]
        table = []
        for r in readings:
            note = r.note or (_mark(r.row) if raw else "")
            table.append([r.row.name, r.text] + ([r.raw, r.scale, r.address] if raw else []) + [note])
        doc = Doc("AKD parameters", app.target.display).table(columns, table)
        if skipped:
            doc.line(f"skipped (not readable over {ops.ROUTE_WORDS[how]}): {', '.join(skipped)}")
        return doc

    app.emit(data, human)


def _assignments(texts: tuple[str, ...]) -> list[tuple[str, str]]:
    out = []
    for at, text in enumerate(texts):
        name, sep, value = text.partition("=")
        if not sep or not name.strip():
            following = texts[at + 1] if at + 1 < len(texts) else ""
            hint = f" (write it as {text}={following})" if sep == "" and following and "=" not in following else ""
            raise UsageError(f"expected NAME=VALUE, got {text!r}{hint}")
        out.append((name.strip(), value.strip()))
    return out


@param.command("set")
@click.argument("assignments", nargs=-1, required=True, metavar="NAME=VALUE...")
@click.option("--raw", is_flag=True, help="VALUE is the integer the fieldbus carries (no scale applied).")
@click.option("--dry-run", is_flag=True, help="Show the plan (writes, consent, notes); write nothing.")
@click.option("--live", is_flag=True, help="Use the names and addresses the drive reports (see 'param get --live').")
def set_(assignments: tuple[str, ...], raw: bool, dry_run: bool, live: bool) -> None:
    """Change parameters by name: all are checked (class, range, reachability) before anything is written,
    each is read back. Writes that can power or move the axis need consent.

    \b
    Examples:
      akdctl -y param set VL.KP=0.5 VL.KI=120
      akdctl param set DRV.OPMODE=2 --dry-run
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import names as ops

    app = get_app()
    found = _live(app.connection, ops.route(app.connection)) if live else None
    plan = ops.plan(app.connection, _assignments(assignments), raw=raw, live=found)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)
    done = ops.execute(app.connection, plan)
    app.emit({"target": app.target.display, "written": done, "notes": plan.notes},
             lambda: Doc("AKD parameters written", app.target.display).table(
                 ["name", "value", "wire", "read back"],
                 [[d["name"], d["value"], d["wire"], d["read_back"]] for d in done]))


@param.command("list")
@click.argument("pattern", required=False, metavar="[GLOB]")
@click.option("--live", is_flag=True, help="List what the drive reports (akd:// DRV.LIST, CoE SDO information), "
                                           "cached per firmware version; --refresh asks again.")
@click.option("--refresh", is_flag=True, help="With --live: ask the drive even when its answer is cached.")
def list_(pattern: str | None, live: bool, refresh: bool) -> None:
    """List the catalogue's names (class, kind, unit, addresses, [I] marks); GLOB or a family (VL) filters.

    \b
    Examples:
      akdctl param list VL
      akdctl param list '*.KP' --json
      akdctl -T akd://192.168.0.10 param list --live
    """
    from akdctl.catalog.akd_params import all_params, matching

    app = get_app()
    source = "catalogue"
    if live:
        from akdctl.drive import names as ops
        from akdctl.drive.name_discovery import discover

        found = discover(app.connection, ops.route(app.connection), refresh=refresh)
        source = f"{app.target.display} (firmware {found['firmware']}{', cached' if found['cached'] else ''})"
        rows = ops.expand([pattern or "*"], found["names"])
        rows = [r for r in rows if r.name in found["names"]]
    else:
        rows = matching(pattern) if pattern else list(all_params())
    if pattern and not rows:
        raise UsageError(f"no AKD parameter matches {pattern!r}")
    app.emit({"source": source, "parameters": [r.to_json() for r in rows]},
             lambda: Doc("AKD parameters", source).table(
                 ["name", "class", "kind", "unit", "CoE", "n", "PNU", "inferred"],
                 [[r.name, r.access, r.kind, r.unit, "" if r.coe is None else f"0x{r.coe[0]:04X}:{r.coe[1]}",
                   r.n or "", r.pnu or "", _mark(r)] for r in rows]))


@param.command("help")
@click.argument("name", metavar="NAME")
def help_(name: str) -> None:
    """Everything the catalogue knows of one name: class, unit, range, default, each transport's address,
    sources, and which facts are inferred [I].

    \b
    Examples:
      akdctl param help VL.KP
      akdctl param help HOME.MODE --json
    """
    from akdctl.drive import names as ops

    app = get_app()
    row = ops.resolve(name)
    gated = ops.classify(row)

    def human() -> Doc:
        doc = Doc(row.name, "catalogue").kv("class", row.access).kv("kind", row.kind)
        for key, value in (("unit", row.unit), ("min", row.minimum), ("max", row.maximum), ("default", row.default),
                           ("note", row.note)):
            if value:
                doc.kv(key, value)
        for key, value in row.addresses().items():
            doc.kv(key, value)
        if gated is not None:
            doc.kv("gate", gated.reason + (" (while enabled)" if gated.when_enabled else ""))
        return doc.kv("source", row.source).kv("marks", " ".join(f"{k}={v}" for k, v in row.marks))

    data = row.to_json()
    data["gate"] = None if gated is None else {"reason": gated.reason, "when_enabled": gated.when_enabled}
    app.emit(data, human)


@param.command("save")
@click.option("--dry-run", is_flag=True, help="Show what would be sent; send nothing.")
def save(dry_run: bool) -> None:
    """Save the drive's RAM parameters to non-volatile memory (DRV.NVSAVE; CoE 1010h:1 "save").

    \b
    Examples:
      akdctl param save
      akdctl -T akd://192.168.0.10 param save
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import names as ops

    app = get_app()
    plan = ops.plan_save(app.connection)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)  # never gated: shows the plan's note
    result = ops.execute_save(app.connection, plan)
    app.emit({"target": app.target.display, **result}, f"saved to non-volatile memory on {app.target.display}")


def _dump_rows(pattern: str | None) -> list[Any]:
    from akdctl.catalog.akd_params import all_params, matching

    rows = matching(pattern) if pattern else list(all_params())
    return [r for r in rows if r.access == "NV" and r.kind in ("int", "float", "string")]


@param.command("dump")
@click.argument("file", metavar="FILE")
@click.option("--only", "pattern", metavar="GLOB", help="Only the NV names matching GLOB.")
def dump(file: str, pattern: str | None) -> None:
    """Write the drive's NV parameters (those the target reaches) to FILE as AKD 'NAME value' lines.

    The file restores over any transport ('param restore FILE').

    \b
    Examples:
      akdctl param dump axis1.akd
      akdctl -T eip://192.168.0.10 param dump axis1.akd --only 'VL.*'
    """
    from pathlib import Path

    from akdctl.drive import names as ops
    from akdctl.drive.param_file import render
    from akdctl.io.atomic import require_directory, write_user_file
    from akdctl.profiles.akd_values import format_value

    app = get_app()
    require_directory(Path(file))
    readings, skipped = ops.read_all(app.connection, _dump_rows(pattern))
    empty = [r.row.name for r in readings if r.row.kind == "string" and not str(r.value)]
    readings = [r for r in readings if r.row.name not in empty]   # a 'NAME' line without value replays as a read
    header = [f"akdctl param dump of {app.target.display}",
              f"{len(readings)} NV parameters; units at the drive's UNIT.* settings"]
    if skipped:
        header.append("not reachable over this transport: " + " ".join(r.name for r in skipped))
    if empty:
        header.append("empty (not written): " + " ".join(empty))
    write_user_file(Path(file), render(((r.row.name, format_value(r.row.kind, r.value)) for r in readings), header))
    app.emit({"target": app.target.display, "file": file, "written": len(readings),
              "skipped": [r.name for r in skipped]},
             f"{len(readings)} parameters written to {file}" + (f"; {len(skipped)} not reachable here" if skipped else ""))


def _load(file: str) -> tuple[str, bytes]:
    """('akd', bytes) for an AKD text file; ('backup', b'') for a 'param backup' file, which 'params' reads
    itself (a .toml/.json name, or content that is TOML/JSON)."""
    from akdctl.drive.param_file import LIMIT, kind_of
    from akdctl.io.safe_read import read_regular

    if file.lower().endswith((".toml", ".json")):
        return "backup", b""
    data = read_regular(file, limit=LIMIT, what="a parameter file")
    return ("akd" if kind_of(data) == "akd" else "backup"), data


@param.command("restore")
@click.argument("file", metavar="FILE")
@click.option("--dry-run", is_flag=True, help="Show the plan (old -> new for every difference); write nothing.")
@click.option("--save", is_flag=True, help="Then save to non-volatile memory (DRV.NVSAVE).")
@click.option("--force", is_flag=True, help="(TOML/JSON backups) restore even onto another drive type.")
@click.pass_context
def restore(ctx: click.Context, file: str, dry_run: bool, save: bool, force: bool) -> None:
    """Write FILE's values that differ from the drive: an AKD text file (NAME value lines) by name over any
    transport, or a 'param backup' TOML/JSON file as 'params restore' does.

    \b
    Examples:
      akdctl param restore axis1.akd --dry-run
      akdctl -y -T akd://192.168.0.10 param restore axis1.akd --save
    """
    kind, data = _load(file)
    if kind != "akd":
        from akdctl.cli import params as backups

        ctx.invoke(backups.restore, file=file, dry_run=dry_run, force=force, save=save)
        return
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import names as ops
    from akdctl.drive.param_file import parse

    app = get_app()
    entries = parse(data, file)
    plan = ops.plan(app.connection, [(name, value) for _, name, value in entries], operation="param restore",
                    only_changes=True, skip_unreachable=True)
    if dry_run:
        return render_dry_run(app, plan, file=file)
    consent_plan(app, plan)
    done = ops.execute(app.connection, plan) if plan.writes else []
    if save and done:
        ops.execute_save(app.connection, ops.plan_save(app.connection))

    def human() -> Doc:
        doc = Doc("parameters restored", app.target.display)
        if not done:
            return doc.line(f"nothing to write: every value reachable here already equals {file}'s")
        return doc.table(["name", "value"], [[d["name"], d["value"]] for d in done])

    app.emit({"target": app.target.display, "file": file, "written": done, "notes": plan.notes,
              "saved": save and bool(done)}, human)


@param.command("diff")
@click.argument("file", required=False, metavar="[FILE]")
@click.argument("other", required=False, metavar="[B]")
@click.option("--against", "against", metavar="TARGET", help="Compare with another drive (its NV parameters).")
@click.option("--defaults", is_flag=True, help="Compare with the published defaults (the default without FILE).")
@click.option("--all", "include_all", is_flag=True, help="(TOML/JSON backups) also compare live values.")
@click.pass_context
def diff(ctx: click.Context, file: str | None, other: str | None, against: str | None, defaults: bool,
         include_all: bool) -> None:
    """Compare the drive's parameters with published defaults, a file (AKD text or a TOML/JSON backup) or
    another drive; exit 5 when anything differs, 0 when nothing does.

    \b
    Examples:
      akdctl param diff axis1.akd
      akdctl param diff --against akd://192.168.0.11
      akdctl param diff --defaults --json
    """
    from akdctl.drive import names as ops
    from akdctl.profiles.akd_values import format_value, parse_text, same_value

    if sum(bool(x) for x in (file, against, defaults)) > 1:
        raise UsageError("compare with one of: FILE, --against TARGET, --defaults")
    if file is not None:
        kind, data = _load(file)
        if kind != "akd":
            from akdctl.cli import params as backups

            ctx.invoke(backups.diff, a=file, b=other, include_all=include_all)
            return
    if other is not None:
        raise UsageError("a second file is compared only between TOML/JSON backups ('params diff A B')")
    app = get_app()
    conn = app.connection
    how = ops.route(conn)
    expected: dict[str, Any] = {}
    source = "published defaults"
    other_conn = None
    try:
        if file is not None:
            from akdctl.drive.param_file import parse

            source = file
            for _, name, value in parse(data, file):
                row = ops.resolve(name)
                try:
                    expected[row.name] = parse_text(row.kind if row.kind != "raw" else "int", value)
                except ValueError as exc:
                    raise UsageError(f"{file}: {row.name}: {exc}") from None
        elif against is not None:
            from akdctl.connection import Connection
            from akdctl.transport.registry import parse_target

            other_conn = Connection(parse_target(against, "--against"), app.options, app.profile)
            source = other_conn.target.display
            readings, _ = ops.read_all(other_conn, _dump_rows(None))
            expected = {r.row.name: r.value for r in readings}
        else:
            for row in _dump_rows(None):
                if row.default and row.kind != "string":
                    expected[row.name] = parse_text(row.kind, row.default)
        rows = [ops.resolve(name) for name in expected]
        readings, skipped = ops.read_all(conn, rows)
    finally:
        if other_conn is not None:
            other_conn.close()
    differences = [[r.row.name, format_value(r.row.kind, expected[r.row.name], r.unit), r.text]
                   for r in readings if not same_value(r.row.kind, r.value, expected[r.row.name])]
    data_out = {"target": app.target.display, "against": source, "compared": len(readings),
                "differences": [{"name": d[0], "expected": d[1], "drive": d[2]} for d in differences],
                "not_reachable": [r.name for r in skipped]}

    def human() -> Doc:
        doc = Doc(f"{app.target.display} vs {source}", app.target.display)
        if differences:
            doc.table(["name", source, app.target.display], differences)
        else:
            doc.line(f"no differences in {len(readings)} parameters")
        if skipped:
            doc.line(f"not reachable over {ops.ROUTE_WORDS[how]}: {', '.join(r.name for r in skipped)}")
        return doc

    failure = CheckFailed(f"{len(differences)} parameter(s) differ from {source}") if differences else None
    if failure is not None:
        data_out["error"] = failure.to_json()   # one document: the comparison, and why the exit is 5
    app.emit(data_out, human)
    if failure is not None:
        failure.reported = True
        raise failure


def _add_backup() -> None:
    """``param backup`` is today's TOML/JSON backup (cli/params.py), added here as it is."""
    from akdctl.cli import params as backups

    param.add_command(backups.backup, "backup")


_add_backup()
