"""``akdctl param diff --inventory FILE [--reference NAME]``: a line's parameters side by side.

Why: thirty drives that should be identical except for a name and a few tuning values. Each drive's
configuration is read by the single-drive backup (one process per drive, in parallel: ``params backup``), then
compared here value by value with the backup's own rules (:mod:`akdctl.drive.snapshot`: only restorable
configuration values, live values never count; ``values_equal``). Shown are only the parameters that differ, and
for each which drives differ from the majority -- or from ``--reference NAME``. Exit 5 on any difference, so CI
can gate a line on it; a drive that could not be read is reported and makes the exit code its own.
"""

from __future__ import annotations

import tempfile
from collections import Counter
from pathlib import Path
from typing import Any

from akdctl.cli.line import DriveRun, LineArgs, child_argv, run_all, summary, summary_line, worst
from akdctl.errors import EXIT_CHECK, EXIT_OK, UsageError


def _take_reference(rest: list[str]) -> str | None:
    for i, token in enumerate(rest):
        if token == "--reference" and i + 1 < len(rest):
            value = rest[i + 1]
            del rest[i:i + 2]
            return value
        if token.startswith("--reference="):
            del rest[i]
            return token.split("=", 1)[1]
    return None


def _backup_args(rest: list[str], path: str) -> list[str]:
    """The drive's command line: the root options the user gave, then ``params backup -o PATH`` with the
    ``--source`` the user chose (auto: PNUs where the drive has them, else objects)."""
    head: list[str] = []
    for token in rest:
        if token in ("param", "params"):
            break
        head.append(token)
    head = [t for t in head if t != "--json"]
    source = _option_value(rest, "--source") or "auto"
    return [*head, "params", "backup", "-o", path, "--source", source]


def _option_value(rest: list[str], name: str) -> str | None:
    for i, token in enumerate(rest):
        if token == name and i + 1 < len(rest):
            return rest[i + 1]
        if token.startswith(name + "="):
            return token.split("=", 1)[1]
    return None


def _bucket(value: Any) -> str:
    from akdctl.drive.snapshot import describe_value

    return describe_value(value)


def run_param_diff(line: LineArgs, inv: Any, drives: list[Any]) -> int:
    from akdctl.cli.output import Doc, emit_json, inert, message
    from akdctl.drive import snapshot

    rest = list(line.rest)
    reference = _take_reference(rest)
    if reference is not None and reference not in {d.name for d in drives}:
        raise UsageError(f"--reference {reference!r} is not one of the selected drives "
                         f"({', '.join(d.name for d in drives)})")
    include_all = "--all" in rest
    with tempfile.TemporaryDirectory(prefix="akdctl-line-") as scratch:
        runs = []
        for drive in drives:
            path = str(Path(scratch) / f"{drive.name}.toml")
            run = DriveRun(drive, child_argv(drive.target, _backup_args(rest, path), json_output=False))
            run.files = {"backup": path}
            runs.append(run)
        from akdctl.cli.line import fork_mode, warm_up

        if fork_mode():
            warm_up(("params",))
        completed = run_all(runs, line.parallel)
        values: dict[str, dict[str, Any]] = {}
        for run in runs:
            if run.exit_code == EXIT_OK:
                values[run.drive.name] = snapshot.load_file(run.files["backup"]).values()
    read = [r for r in runs if r.drive.name in values]
    keys: set[str] = set()
    for table in values.values():
        keys |= set(table)
    differences: list[dict[str, Any]] = []
    partial: list[str] = []
    for key in sorted(keys):
        item = snapshot.resolve_item(key)
        if not include_all and not item.restorable:
            continue
        holding = {name: table[key] for name, table in values.items() if key in table}
        if len(holding) < len(values):
            partial.append(key)
        if len(holding) < 2:
            continue
        if reference is not None and reference in holding:
            base = holding[reference]
            differ = [n for n, v in holding.items() if not snapshot.values_equal(v, base)]
            expected = _bucket(base)
        else:
            counts = Counter(_bucket(v) for v in holding.values())
            expected, _ = counts.most_common(1)[0]
            differ = [n for n, v in holding.items() if _bucket(v) != expected]
        if differ:
            differences.append({"key": key, "name": item.name, "expected": expected,
                                "by": "reference " + reference if reference else "majority",
                                "differ": {n: _bucket(holding[n]) for n in differ},
                                "values": {n: _bucket(v) for n, v in holding.items()}})
    counts = summary(runs)
    code = worst(runs)
    if code == EXIT_OK and differences:
        code = EXIT_CHECK
    if line.json:
        emit_json({"inventory": inv.path, "command": "param diff", "reference": reference,
                   "compared": [r.drive.name for r in read], "equal": not differences, "differences": differences,
                   "not_everywhere": partial, "drives": [r.to_json() for r in runs], "summary": counts})
    else:
        title = f"line parameters: {len(read)} drive(s) compared by " + (f"reference {reference}" if reference
                                                                           else "majority")
        doc = Doc(title, inv.path)
        if not differences:
            doc.line("no differences")
        else:
            doc.table(["parameter", "name", "expected", "differs on"],
                      [[d["key"], d["name"], d["expected"], ", ".join(f"{n}={v}" for n, v in d["differ"].items())]
                       for d in differences])
        if partial:
            doc.line(f"not held by every drive (compared where held): {', '.join(partial[:12])}"
                     + (f" ... ({len(partial)} in all)" if len(partial) > 12 else ""))
        for run in runs:
            if run.exit_code != EXIT_OK:
                last = [t for t in run.stderr.splitlines() if t.strip()][-1:] or [run.skipped or "no output"]
                doc.line(inert(f"{run.drive.name} ({run.drive.target}): not read (exit {run.exit_code}): {last[0]}"))
        from akdctl.cli.output import render

        render(doc)
    message(summary_line("param diff", counts) + (f"; {len(differences)} parameter(s) differ" if differences else "")
            + ("" if completed else " (interrupted)"))
    return code


__all__ = ["run_param_diff"]
