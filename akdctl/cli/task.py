"""``akdctl task list|show|set|start``: the AKD's stored motion tasks (program mode, PROFINET manual 5.10.1).

Thin: the table is :mod:`akdctl.drive.tasks` (CoE objects MT.NUM/MT.LOAD/MT.SET, docs/fidelity.md F11), the
``task set`` is a write plan asked and run like every other (:func:`akdctl.cli.consent.consent_plan`), and ``task start`` is a motion that runs
the one planner, consent and stop-signal path of ``move`` (:func:`akdctl.cli.motion._plan_and_run`).
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.cli.parsing import Duration

_COLUMNS = ["task", "position", "mode", "velocity [rpm]", "accel [rpm/s]", "decel [rpm/s]"]


def _row(task: Any) -> list[Any]:
    if not task.configured:
        return [task.number, "(not configured)", "", "", "", ""]
    return [task.number, f"{task.position_rev:.6g} rev", "relative" if task.relative else "absolute",
            f"{task.velocity_rpm:.6g}", f"{task.acc_rpm_s:.6g}", f"{task.dec_rpm_s:.6g}"]


@click.group()
def task() -> None:
    """Stored motion tasks: list, show, set, and start one (program mode).

    The table is read and written through the AKD's CoE objects MT.NUM (0x365B),
    MT.LOAD (0x3432) and MT.SET (0x3431) with MT.P/MT.V/MT.ACC/MT.DEC/MT.CNTL
    (0x607A, 0x6081, 0x6083, 0x6084, 0x35B9); a task starts over the PROFIdrive
    parameter channel (SATZANW, STW1 bit 6), homed and in telegram 7 or 9.

    \b
    Examples:
      akdctl task set 5 --position 2.5 --velocity 300 --accel 2000 --yes
      akdctl task start 5 --yes
    """


@task.command("list")
@click.option("--count", type=click.IntRange(1, 128), default=16, show_default=True,
              help="List tasks 0..COUNT-1.")
@click.option("--all", "show_all", is_flag=True, help="Also list tasks that are not configured.")
def list_(count: int, show_all: bool) -> None:
    """The stored tasks 0..COUNT-1 (each loaded with MT.LOAD to be read).

    \b
    Examples:
      akdctl task list --count 8
    """
    from akdctl.drive import tasks

    app = get_app()
    objects = tasks.objects_of(app.connection)
    tasks.refuse_if_moving(app.connection)  # a read is never a motion: no consent, refused while moving
    found = tasks.read_tasks(objects, list(range(count)))
    shown = [t for t in found if show_all or t.configured]
    app.emit({"target": app.target.display, "tasks": [t.to_json() for t in shown], "note": tasks.RESTORED_NOTE},
             lambda: Doc("motion tasks", app.target.display).table(
                 _COLUMNS, [_row(t) for t in shown] or [["", "(none configured)", "", "", "", ""]]))


@task.command("show")
@click.argument("number", type=int)
def show(number: int) -> None:
    """One stored task's parameters.

    \b
    Examples:
      akdctl task show 4
    """
    from akdctl.drive import tasks

    app = get_app()
    tasks.check_number(number)
    objects = tasks.objects_of(app.connection)
    tasks.refuse_if_moving(app.connection)  # a read is never a motion: no consent, refused while moving
    found = tasks.read_task(objects, number)
    app.emit({"target": app.target.display, **found.to_json(), "note": tasks.RESTORED_NOTE},
             lambda: Doc(f"motion task {number}", app.target.display).table(_COLUMNS, [_row(found)]))


@task.command("set")
@click.argument("number", type=int)
@click.option("--position", type=float, required=True, help="Target (absolute) or distance (--relative), in rev.")
@click.option("--velocity", type=float, required=True, help="rpm.")
@click.option("--accel", type=float, required=True, help="rpm/s.")
@click.option("--decel", type=float, help="rpm/s (default: --accel).")
@click.option("--relative/--absolute", default=False, help="Relative to the start position (default absolute).")
@click.option("--dry-run", is_flag=True, help="Show what would be written; write nothing.")
def set_(number: int, position: float, velocity: float, accel: float, decel: float | None, relative: bool,
         dry_run: bool) -> None:
    """Store a task (MT.P/MT.V/MT.ACC/MT.DEC/MT.CNTL, then MT.SET); nothing moves.

    The values must pass what 'move' with them would (the config profile's limits, the drive's
    set-point ranges), as 'task start' checks them again.

    \b
    Examples:
      akdctl task set 5 --position 2.5 --velocity 300 --accel 2000 --yes
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import tasks

    app = get_app()
    accepted = tasks.plan_set(app.connection, tasks.TaskRequest(number, position, velocity, accel, decel, relative))
    if dry_run:
        return render_dry_run(app, accepted)
    consent_plan(app, accepted)
    stored = tasks.execute_set(app.connection, accepted)
    app.emit({"target": app.target.display, **stored.to_json()},
             lambda: Doc(f"motion task {number} stored", app.target.display).table(_COLUMNS, [_row(stored)]))


@task.command("start")
@click.argument("number", type=int)
@click.option("--max-time", "--timeout", "task_timeout", type=Duration(0.0, 3600.0), metavar="DURATION",
              help="How long the task may take before the axis is stopped (30, 30s, 2m; default from the task). "
                   "'task start --timeout' is this option too; the per-request wait is the global 'akdctl --timeout'.")
@click.option("--json", "json_output", is_flag=True, help="Machine-readable JSON on stdout.")
@click.option("-y", "--yes", "yes_flag", is_flag=True, help="Consent to motion without a prompt.")
@click.option("--dry-run", is_flag=True, help="Show the plan (the stored task as it will run); move nothing.")
def start(number: int, task_timeout: float | None, json_output: bool, yes_flag: bool, dry_run: bool) -> None:
    """Start stored task NUMBER and wait for target reached (the consent and stop path of 'move').

    \b
    Examples:
      akdctl task start 4 --yes
    """
    from akdctl.cli.motion import _plan_and_run
    from akdctl.drive.motion_plan import MotionRequest

    app = get_app()
    app.json = app.json or json_output
    app.yes = app.yes or yes_flag
    _plan_and_run(app, MotionRequest("task", task=number, timeout_s=task_timeout), "task finished",
                  {"task": number}, dry_run=dry_run)
