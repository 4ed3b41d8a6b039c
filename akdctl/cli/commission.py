"""``akdctl commission RECIPE.toml``: apply, prove and document a configuration with one command.

The whole recipe is validated first (nothing is written to the drive before
that); ``--dry-run`` stops there and prints the plan. A run stops at the first
failing step with the axis stopped and disabled; reports are written either way
(``--report FILE``, repeatable, kind by suffix: ``.json`` or ``.xml`` JUnit).
Exit codes are akdctl's (errors.py): 0 all steps passed, 2 recipe invalid,
5 a check failed, 1 the drive refused or faulted, 3 link lost, 4 safety
refusal (no consent, a limit), 130 interrupted.
"""

from __future__ import annotations

import sys
from typing import Any

import click

from akdctl.cli.consent import require_consent
from akdctl.cli.context import get_app
from akdctl.cli.output import Doc, message
from akdctl.cli.signals import stop_signals
from akdctl.errors import Interrupted


@click.command("commission")
@click.argument("recipe", metavar="RECIPE.toml", type=click.Path(dir_okay=False))
@click.option("--dry-run", is_flag=True, help="Validate the whole recipe and print the plan; touch no drive.")
@click.option("--report", "reports", multiple=True, metavar="FILE",
              help="Write a report: .json (JSON) or .xml (JUnit XML). Repeatable.")
@click.option("--output-dir", metavar="DIR", type=click.Path(file_okay=False),
              help="Where backup steps write their files (default: the current directory).")
@click.option("--allow-outside-includes", "allow_outside", is_flag=True,
              help="Let include/restore steps read files outside the recipe's folder.")
def commission(recipe: str, dry_run: bool, reports: tuple[str, ...], output_dir: str | None,
               allow_outside: bool) -> None:
    """Run a commissioning recipe (TOML): set/expect parameters, map process data, select a telegram,
    enable, home, move, wait, check faults, save, back up.

    \b
    Examples:
      akdctl commission examples/commission-sim.toml --dry-run
      akdctl --yes commission examples/commission-sim.toml --report report.json --report junit.xml
    """
    from akdctl.recipe import load_and_validate, report, runner
    from akdctl.recipe.loader import RecipeError, display_path
    from akdctl.recipe.ops import Session

    app = get_app()
    for path in reports:
        report.kind_of(path)  # a bad suffix is a usage error before anything runs
    try:
        raw, steps = load_and_validate(recipe, allow_outside=allow_outside, conn=app)
    except RecipeError as exc:
        if len(exc.problems) > 1:
            message("akdctl: the recipe has these problems:")
            for problem in exc.problems:
                message(f"  {problem}")
        raise
    shown = display_path(raw.path.resolve(), None) if raw.path.is_absolute() else recipe
    target = app.target.display
    meta = {"recipe": raw.name, "description": raw.description, "file": shown, "target": target}
    if dry_run:
        result = runner.plan_only(steps, **meta)
        for path in reports:
            report.write(result, path)
        app.emit(result.to_json(), lambda: _plan_doc(result))
        return
    _consent(app, steps)
    progress = message if (sys.stderr.isatty() or app.verbose) else None
    with stop_signals() as stop:
        session = Session(app.connection, runner.output_dir_for(output_dir), stop)
        result = runner.run(steps, session, progress, **meta)
        if isinstance(result.error, Interrupted):
            stop.mark(result.error)
            result.exit_code = result.error.exit_code
        for path in reports:
            report.write(result, path)
        _finish(app, result)


def _finish(app: Any, result: Any) -> None:
    """Print the result; a failed run raises its error (already reported) with the step and the axis state."""
    app.emit(result.to_json(), lambda: _result_doc(result))
    if result.error is not None:
        failed = result.failed_step
        exc = result.error
        if failed is not None:
            exc.message = f"step {failed.step.number} ({failed.step.name}) failed at {failed.step.where}: {exc.message}"
            said = [part for part in result.safe_state.split("; ") if part and part not in exc.message]
            if said:  # what the step's own error already said ("axis stopped") is not said twice
                exc.message += "; " + "; ".join(said)
        exc.reported = True
        raise exc


def _consent(app: Any, steps: list[Any]) -> None:
    """Steps that power or move the axis (motion steps, set steps writing gated addresses) need the one consent."""
    from akdctl.drive import gate

    enabled: bool | None = False
    if any(g.when_enabled for s in steps for g in s.gated):
        enabled = gate.drive_enabled(app.connection)  # reads only; a mode/mapping change matters on an enabled drive
    asking = [s for s in steps if s.motion or gate.needing_consent(s.gated, enabled)]
    if not asking:
        return
    what = "; ".join(f"step {s.number}: {s.plan}" for s in asking)
    require_consent(app, f"run the recipe, which powers or moves the axis ({what})")


def _plan_doc(result: object) -> Doc:
    doc = Doc(f"commissioning plan: {result.recipe} (dry run, nothing touched)", result.target)  # type: ignore[attr-defined]
    doc.table(["step", "action", "plan", "where"],
              [[r.step.number, r.step.action, r.step.plan, r.step.where]
               for r in result.results])  # type: ignore[attr-defined]
    return doc


def _result_doc(result: object) -> Doc:
    r = result  # type: ignore[assignment]
    doc = Doc(f"commissioning: {r.recipe}", r.target)  # type: ignore[attr-defined]
    doc.kv("result", "PASSED" if r.passed else "FAILED")  # type: ignore[attr-defined]
    doc.kv("duration", f"{r.duration:.2f} s")  # type: ignore[attr-defined]
    if r.safe_state:  # type: ignore[attr-defined]
        doc.kv("axis", r.safe_state)  # type: ignore[attr-defined]
    doc.table(["step", "action", "name", "status", "time", "message"],
              [[s.step.number, s.step.action, s.step.name, s.status, f"{s.duration:.2f}", s.message]
               for s in r.results])  # type: ignore[attr-defined]
    return doc
