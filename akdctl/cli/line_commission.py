"""``akdctl commission RECIPE --inventory FILE``: one recipe, a line of drives, one consent, one report.

Why here and not in the recipe runner: each drive runs the unchanged single-drive ``commission`` in its own
process (its owner lock, its stop-on-error, its safe state). This module only prepares the line: the recipe with
each drive's values substituted (:func:`akdctl.drive.inventory.substitute`), every drive's recipe validated before
any drive is touched, the one consent naming every drive that will be powered or moved, then the aggregated JSON
and JUnit reports (one test suite per drive, one test case per step) that CI systems read.

Substituted recipes are written beside the recipe (hidden ``.akdctl-line-PID-NAME.toml`` files, removed when the
line ends) so that the recipe's includes and restore files resolve exactly as for a single drive.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from akdctl.cli.line import DriveRun, LineArgs, child_argv, confirm_line, finish, run_all
from akdctl.errors import UsageError


def _recipe_index(rest: list[str]) -> int:
    try:
        start = rest.index("commission")
    except ValueError:
        raise UsageError("commission needs a RECIPE.toml") from None
    skip_value = {"--report", "--output-dir"}
    i = start + 1
    while i < len(rest):
        token = rest[i]
        if token in skip_value:
            i += 2
            continue
        if not token.startswith("-"):
            return i
        i += 1
    raise UsageError("commission needs a RECIPE.toml")


def _take_option(rest: list[str], name: str) -> list[str]:
    """Remove every ``name VALUE`` / ``name=VALUE`` from ``rest``; the values in order."""
    values: list[str] = []
    i = 0
    while i < len(rest):
        token = rest[i]
        if token == name and i + 1 < len(rest):
            values.append(rest[i + 1])
            del rest[i:i + 2]
            continue
        if token.startswith(name + "="):
            values.append(token.split("=", 1)[1])
            del rest[i]
            continue
        i += 1
    return values


def _root_value(rest: list[str], *names: str) -> str | None:
    for i, token in enumerate(rest):
        for name in names:
            if token == name and i + 1 < len(rest):
                return rest[i + 1]
            if token.startswith(name + "="):
                return token.split("=", 1)[1]
    return None


def run_commission(line: LineArgs, inv: Any, drives: list[Any]) -> int:
    from akdctl.drive.inventory import substitute
    from akdctl.io.safe_read import FileRefused, read_bounded
    from akdctl.recipe import report as recipe_report

    rest = list(line.rest)
    index = _recipe_index(rest)
    recipe_path = Path(rest[index])
    reports = _take_option(rest, "--report")
    for path in reports:
        recipe_report.kind_of(path)  # a bad suffix or a missing directory: refused before anything runs
    output_dirs = _take_option(rest, "--output-dir")
    dry_run = "--dry-run" in rest
    index = _recipe_index(rest)
    try:
        text = read_bounded(recipe_path, 1 << 20).decode("utf-8")
    except (OSError, FileRefused, UnicodeDecodeError) as exc:
        raise UsageError(f"recipe {recipe_path}: cannot be read ({getattr(exc, 'strerror', None) or exc})") from None
    written: list[Path] = []
    try:
        per_drive: dict[str, Path] = {}
        for drive in drives:
            own = substitute(text, drive, what=f"recipe {recipe_path}")
            if own == text:
                per_drive[drive.name] = recipe_path
                continue
            hidden = recipe_path.parent / f".akdctl-line-{os.getpid()}-{drive.name}.toml"
            try:
                fd = os.open(hidden, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            except OSError as exc:
                raise UsageError(f"recipe {recipe_path}: cannot write the substituted recipe of drive "
                                 f"{drive.name!r} beside it ({exc.strerror})") from None
            written.append(hidden)
            _ORIGINAL[str(hidden)] = recipe_path.name
            with os.fdopen(fd, "w", encoding="utf-8") as handle:
                handle.write(own)
            per_drive[drive.name] = hidden
        moving = _validate_all(line, rest, drives, per_drive, recipe_path)
        if moving and not dry_run:
            shown = "; ".join(f"{name} ({target}): {what}" for name, target, what in moving)
            confirm_line(f"run recipe {recipe_path.name} on {len(drives)} drive(s), which powers or moves the axis "
                         f"of {len(moving)}: {shown}", line.yes)
        return _run(line, inv, drives, rest, index, per_drive, reports, output_dirs, dry_run)
    finally:
        for path in written:
            with contextlib.suppress(OSError):
                path.unlink()


def _validate_all(line: LineArgs, rest: list[str], drives: list[Any], per_drive: dict[str, Path],
                  shown: Path) -> list[tuple[str, str, str]]:
    """Every drive's recipe validated (nothing read from any drive); the drives whose steps power or move."""
    from akdctl.cli.context import AppContext
    from akdctl.recipe import load_and_validate
    from akdctl.recipe.loader import RecipeError

    allow_outside = "--allow-outside-includes" in rest
    moving: list[tuple[str, str, str]] = []
    for drive in drives:
        app = AppContext(target_text=drive.target, config_path=_root_value(rest, "--config"),
                         profile_name=_root_value(rest, "--profile"), yes=True)
        try:
            _, steps = load_and_validate(per_drive[drive.name], allow_outside=allow_outside, conn=app)
        except RecipeError as exc:
            first = exc.problems[0] if exc.problems else str(exc)
            more = f" (and {len(exc.problems) - 1} more)" if len(exc.problems) > 1 else ""
            raise UsageError(f"recipe {shown} for drive {drive.name!r} ({drive.target}): {first}{more}; "
                             "nothing was written to any drive") from None
        finally:
            app.close()
        asking = [s for s in steps if s.motion or any(g is not None for g in s.gated)]
        if asking:
            moving.append((drive.name, drive.target, ", ".join(f"step {s.number} {s.action}" for s in asking)))
    return moving


def _run(line: LineArgs, inv: Any, drives: list[Any], rest: list[str], index: int, per_drive: dict[str, Path],
         reports: list[str], output_dirs: list[str], dry_run: bool) -> int:
    with tempfile.TemporaryDirectory(prefix="akdctl-line-") as scratch:
        runs = []
        for drive in drives:
            args = list(rest)
            args[index] = str(per_drive[drive.name])
            files = {"json": str(Path(scratch) / f"{drive.name}.json"), "xml": str(Path(scratch) / f"{drive.name}.xml")}
            args += ["--report", files["json"], "--report", files["xml"]]
            if output_dirs:
                own = Path(output_dirs[-1]) / drive.name
                if not Path(output_dirs[-1]).is_dir():
                    raise UsageError(f"--output-dir {output_dirs[-1]}: no such directory (akdctl creates only the "
                                     "per-drive folders inside it)")
                own.mkdir(exist_ok=True)
                args += ["--output-dir", str(own)]
            if not dry_run and "--yes" not in args and "-y" not in args:
                args.insert(0, "--yes")  # the line's one consent was given above
            run = DriveRun(drive, child_argv(drive.target, args, json_output=True))
            run.files = files
            runs.append(run)
        from akdctl.cli.line import _progress, fork_mode, warm_up

        if fork_mode():
            warm_up(("commission",))
        completed = run_all(runs, line.parallel, stop_on_error=line.stop_on_error,
                            on_done=None if line.json else _progress)
        for run in runs:  # the user wrote one recipe: name it, not the hidden per-drive copy
            hidden = per_drive[run.drive.name]
            if hidden.name.startswith(".akdctl-line-"):
                run.stdout = _unhide(run.stdout, hidden, run.drive.name)
                run.stderr = _unhide(run.stderr, hidden, run.drive.name)
                for path in run.files.values():
                    with contextlib.suppress(OSError):
                        Path(path).write_text(_unhide(Path(path).read_text(encoding="utf-8"), hidden,
                                                      run.drive.name), encoding="utf-8")
        reports_json = [_read_json(r) for r in runs]
        for path in reports:
            _write_report(path, line, inv, runs, reports_json)
        if not line.json:
            for run in runs:  # the human report per drive is its step table, not the child's JSON
                run.stdout = _step_table(run, reports_json[runs.index(run)])
        return finish(line, inv, runs, completed)


def _unhide(text: str, hidden: Path, drive: str) -> str:
    """The per-drive copy's names replaced by the recipe's own (``line.toml[axis1]``)."""
    original = hidden.parent / _ORIGINAL.get(str(hidden), hidden.name)
    text = text.replace(str(hidden), f"{original}[{drive}]")
    return text.replace(hidden.name, f"{original.name}[{drive}]").replace(hidden.stem, f"{original.stem}[{drive}]")


_ORIGINAL: dict[str, str] = {}


def _read_json(run: DriveRun) -> dict[str, Any] | None:
    try:
        return json.loads(Path(run.files["json"]).read_text(encoding="utf-8"))
    except (OSError, ValueError, KeyError):
        return None


def _step_table(run: DriveRun, report: dict[str, Any] | None) -> str:
    if report is None:
        return ""
    lines = []
    for step in report.get("steps", report.get("results", [])):
        if isinstance(step, dict):
            number = step.get("step", step.get("number", "?"))
            lines.append(f"   step {number} {step.get('action', '')} {step.get('name', '')}: "
                         f"{step.get('status', '')} {step.get('message', '') or ''}".rstrip())
    return "\n".join(lines) + ("\n" if lines else "")


def _write_report(path: str, line: LineArgs, inv: Any, runs: list[DriveRun],
                  reports_json: list[dict[str, Any] | None]) -> None:
    from akdctl.cli.line import summary
    from akdctl.io.atomic import write_user_file

    if path.lower().endswith(".json"):
        document = {"inventory": inv.path, "command": "commission", "summary": summary(runs),
                    "drives": [{**r.drive.to_json(), "state": r.state, "exit_code": r.exit_code,
                                **({"skipped": r.skipped} if r.skipped else {}), "report": rep}
                               for r, rep in zip(runs, reports_json)]}
        write_user_file(Path(path), json.dumps(document, indent=2, default=str) + "\n")
        return
    suites = ET.Element("testsuites", {"name": f"akdctl commission line {Path(inv.path).name}"})
    totals = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    for run in runs:
        suite = None
        try:
            tree = ET.parse(run.files["xml"])
            suite = tree.getroot().find("testsuite")
        except (OSError, ET.ParseError, KeyError):
            suite = None
        if suite is None:  # the drive never wrote its report: one case saying why
            suite = ET.Element("testsuite", {"tests": "1", "failures": "0", "errors": "0" if run.skipped else "1",
                                             "skipped": "1" if run.skipped else "0"})
            case = ET.SubElement(suite, "testcase", {"name": "commission", "classname": f"line.{run.drive.name}"})
            if run.skipped:
                ET.SubElement(case, "skipped", {"message": run.skipped})
            else:
                error = ET.SubElement(case, "error", {"message": f"exit {run.exit_code}"})
                error.text = run.stderr[-2000:]
        suite.set("name", f"{run.drive.name} ({run.drive.target})")
        for case in suite.iter("testcase"):
            case.set("classname", f"line.{run.drive.name}.{case.get('classname', 'commission')}")
        for key in totals:
            totals[key] += int(suite.get(key, "0") or 0)
        suites.append(suite)
    for key, value in totals.items():
        suites.set(key, str(value))
    ET.indent(suites)
    write_user_file(Path(path), '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(suites, encoding="unicode") + "\n")


__all__ = ["run_commission"]
