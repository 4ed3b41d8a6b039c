"""``akdctl params backup|restore|diff``: a drive's configuration as a file, compared and put back.

``diff`` exits 5 (check failed) when it finds a difference and 0 when there is
none, like ``diff(1)`` but with akdctl's documented "check failed" code, so a CI
job can use ``akdctl params diff golden.toml`` as a gate; the differences are
printed (or in the ``--json`` document) either way.
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import CheckFailed


@click.group()
def params() -> None:
    """Back up, restore and compare drive parameters (TOML or JSON files).

    \b
    Examples:
      akdctl params backup -o axis1.toml
      akdctl params diff axis1.toml
    """


@params.command("backup")
@click.option("-o", "--output", "output", required=True, metavar="FILE",
              help="Backup file in an existing directory; .toml or .json chooses the format. Written atomically.")
@click.option("--source", type=click.Choice(["auto", "pnu", "objects", "all"]), default="auto", show_default=True,
              help="PNUs (PROFIdrive), objects (CoE/CANopen) or both; auto = PNUs where the target has them.")
@click.option("--group", "groups", multiple=True, metavar="GROUP",
              help="Only these groups (PNU: signal, profidrive, telegram, fault, identity, jog; "
                   "objects: pdo, comm, akd, cia402). Repeatable.")
@click.option("--only", "only", multiple=True, metavar="LIST",
              help="Only these PNUs/objects, comma-separated (930,922,0x6060:0). Repeatable.")
def backup(output: str, source: str, groups: tuple[str, ...], only: tuple[str, ...]) -> None:
    """Read every readable catalogue parameter (batched) into FILE with target, identity, firmware, time.

    \b
    Examples:
      akdctl params backup -o axis1.toml
      akdctl params backup -o axis1.json --group identity
    """
    from akdctl.drive import snapshot

    app = get_app()
    if not output.lower().endswith((".toml", ".json")):
        from akdctl.errors import UsageError

        raise UsageError(f"backup file {output}: use a .toml or .json suffix (the format follows it)")
    from pathlib import Path

    from akdctl.io.atomic import require_directory

    require_directory(Path(output))  # before the drive is read: akdctl creates no directories
    conn = app.connection
    if only:
        items = snapshot.select_items([], only=only)
        sources = sorted({"pnu" if i.kind == "pnu" else "objects" for i in items})
    else:
        sources = snapshot.choose_sources(conn, source)
        items = snapshot.select_items(sources, groups)
    before = _round_trips(conn)
    snap = snapshot.take(conn, items, app.target.display, sources)
    trips = {k: v - before.get(k, 0) for k, v in _round_trips(conn).items()}
    path = snapshot.write_file(snap, output)
    data = {"target": app.target.display, "file": str(path), "time": snap.time, "identity": snap.identity,
            "pnus": len(snap.pnus), "objects": len(snap.objects), "refused": snap.refused, "round_trips": trips}

    def human() -> Doc:
        doc = Doc("parameter backup", app.target.display)
        doc.kv("file", str(path)).kv("firmware", snap.firmware or "?")
        doc.kv("PNUs", len(snap.pnus)).kv("objects", len(snap.objects))
        doc.kv("round trips", ", ".join(f"{k} {v}" for k, v in trips.items()) or "0")
        for key, text in snap.refused.items():
            doc.line(f"refused by the drive, not in the backup: {key}: {text}")
        return doc

    app.emit(data, human)


def _round_trips(conn: Any) -> dict[str, int]:
    out = {}
    if conn.has_parameters:
        out["pnu requests"] = conn.parameters().requests
    if conn.has_objects:
        out["sdo transfers"] = conn.objects().requests
    return out


@params.command("restore")
@click.argument("file", metavar="FILE")
@click.option("--dry-run", is_flag=True, help="Print old → new for every difference; write nothing.")
@click.option("--force", is_flag=True, help="Restore even if the file is of a different drive type.")
@click.option("--save", is_flag=True, help="Then save to non-volatile memory (DRV.NVSAVE, 0x1010:1 = \"save\").")
def restore(file: str, dry_run: bool, force: bool, save: bool) -> None:
    """Write the values of FILE that differ from the drive, in a safe order, and verify each.

    The control word and set points are never written; the operating mode,
    units and telegram go before the values that depend on them.

    \b
    Examples:
      akdctl params restore axis1.toml --dry-run
      akdctl -y params restore axis1.toml --save
    """
    from akdctl.cli.consent import consent_plan
    from akdctl.drive import snapshot

    app = get_app()
    request = snapshot.RestoreRequest(snapshot.load_file(file), force=force, save=save)
    plan = snapshot.plan(app.connection, request)
    if dry_run:
        result = snapshot.RestoreResult(plan.data["changes"], [], False, plan.data["mismatches"])
    else:
        consent_plan(app, plan)
        result = snapshot.execute(app.connection, plan)
    data = {"target": app.target.display, "file": file, "dry_run": dry_run, **result.to_json(),
            "plan": plan.to_json()}

    def human() -> Doc:
        title = "restore plan (dry run: nothing written)" if dry_run else "parameters restored"
        doc = Doc(title, app.target.display)
        for warning in result.identity_warnings:
            doc.line(f"warning: identity differs ({warning}); restored because of --force")
        if not result.changes:
            doc.line("the drive already holds every value of the file: nothing to write")
        for change in result.changes:
            doc.line(f"{change.item.key:>10}  {change.item.name}: {snapshot.describe_value(change.old)} → "
                     f"{snapshot.describe_value(change.new)}")
        if not dry_run and result.changes:
            doc.line(f"{len(result.changes)} value(s) written and verified")
        if result.saved:
            doc.line("saved to non-volatile memory")
        return doc

    app.emit(data, human)


@params.command("diff")
@click.argument("a", metavar="A")
@click.argument("b", metavar="[B]", required=False)
@click.option("--all", "include_all", is_flag=True,
              help="Compare every value, live ones (status word, actual values) included.")
def diff(a: str, b: str | None, include_all: bool) -> None:
    """Compare backup A with the drive, or with backup B. Exit 0 if equal, 5 if they differ.

    Configuration values are compared (add --all for live values too); with two
    files, values only one of them holds are listed but do not count.

    \b
    Examples:
      akdctl params diff axis1.toml
      akdctl params diff axis1.toml axis2.toml --all
    """
    from akdctl.drive import snapshot

    app = get_app()
    first = snapshot.load_file(a)
    if b is not None:
        second = snapshot.load_file(b)
        actual = second.values()
        other = b
    else:
        items = [snapshot.resolve_item(k) for k in first.values()]
        if not include_all:
            items = [i for i in items if i.restorable]
        actual, _ = snapshot.read_values(app.connection, items)
        other = app.target.display
    differences = snapshot.compare(first.values(), actual, include_all=include_all)
    only_a, only_b = snapshot.one_sided(first.values(), actual, include_all=include_all)
    data = {"a": a, "b": other, "equal": not differences, "differences": [d.to_json() for d in differences],
            "only_in_a": only_a, "only_in_b": only_b}

    def human() -> Doc:
        doc = Doc(f"diff {a} ↔ {other}", "" if b is not None else app.target.display)
        for label, keys in ((f"only in {a}", only_a), (f"only in {other}", only_b)):
            if keys:
                shown = ", ".join(keys[:12]) + (f" … ({len(keys)} in all)" if len(keys) > 12 else "")
                doc.line(f"{label} (not compared): {shown}")
        if not differences:
            doc.line("no differences")
            return doc
        doc.table(["parameter", "name", "A", "B"],
                  [[d.key, d.name, snapshot.describe_value(d.new), snapshot.describe_value(d.old)]
                   for d in differences])
        return doc

    app.emit(data, human)
    if differences:
        exc = CheckFailed(f"{len(differences)} difference(s) between {a} and {other}")
        exc.reported = True
        raise exc
