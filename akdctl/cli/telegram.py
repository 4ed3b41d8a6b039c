"""``akdctl telegram show|set|map``: the PROFIdrive IO telegram (PNU 922, 915, 916, 923)."""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import UsageError


@click.group()
def telegram() -> None:
    """Show and select the PROFIdrive telegram (PROFINET manual 5.8, 5.11).

    Telegrams: 1 (velocity), 7 (motion task), 9 (MDI positioning), 350 (velocity +
    current), 351 (velocity + current + position), 0 (free mapping via PNU 915/916).

    \b
    Examples:
      akdctl telegram show
      akdctl -y telegram set 9
    """


def _state_doc(title: str, source: str, data: dict[str, Any]) -> Doc:
    doc = Doc(title, source)
    doc.kv("telegram (PNU 922)", data["telegram"]).kv("description", data["description"])
    if data["source"]:
        doc.kv("layout from", data["source"])
    for key, heading in (("setpoint", "set points, controller -> drive (PNU 915)"),
                         ("actual", "actual values, drive -> controller (PNU 916)")):
        words = data[key]
        rows = [[w["word"], w["signal"], w["label"], w["text"]] for w in words] or [["", "", "(no words)", ""]]
        doc.table(["word", "signal", "name", "meaning"], rows, title=f"{heading}: {len(words)} words")
    return doc


@telegram.command("show")
def show() -> None:
    """The selected telegram and its IO data word by word in both directions.

    \b
    Examples:
      akdctl telegram show
      akdctl -T pn://192.168.0.10 telegram show --json
    """
    from akdctl.drive.telegram import read_state

    app = get_app()
    state = read_state(app.parameters())
    data = {"target": app.target.display, **state.to_json()}
    app.emit(data, lambda: _state_doc("PROFIdrive telegram", app.target.display, data))


def _run(app: Any, request: Any, dry_run: bool, title: str) -> None:
    """plan -> consent -> execute -> render: the one path of both writing telegram commands."""
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import telegram as dt

    plan = dt.plan(app.connection, request)
    if dry_run:
        render_dry_run(app, plan)
        return
    consent_plan(app, plan)
    state = dt.execute(app.connection, plan)
    data = {"target": app.target.display, **state.to_json()}
    app.emit(data, lambda: _state_doc(title, app.target.display, data))


@telegram.command("set")
@click.argument("number", type=int, metavar="1|7|9|350|351|0")
@click.option("--force", is_flag=True, help="Send a telegram number akdctl does not know; the drive answers.")
@click.option("--dry-run", is_flag=True, help="Print what would be written and whether it needs consent; write nothing.")
def set_(number: int, force: bool, dry_run: bool) -> None:
    """Select a telegram (PNU 922), then read back its layout.

    \b
    Examples:
      akdctl -y telegram set 9
      akdctl telegram set 1 --dry-run
    """
    from akdctl.drive.telegram import select_request

    request = select_request(number, force=force)
    _run(get_app(), request, dry_run, f"telegram {number} selected")


@telegram.command("map")
@click.option("--setpoint", metavar="SIGNALS", help="Set-point signals in IO order, e.g. 1,5 or STW1,NSOLL_A (PNU 915).")
@click.option("--actual", metavar="SIGNALS", help="Actual-value signals in IO order, e.g. 2,6 or ZSW1,NIST_A (PNU 916).")
@click.option("--force", is_flag=True, help="Skip akdctl's own checks; the drive answers.")
@click.option("--dry-run", is_flag=True, help="Print what would be written and whether it needs consent; write nothing.")
def map_(setpoint: str | None, actual: str | None, force: bool, dry_run: bool) -> None:
    """Free mapping for telegram 0 through PNU 915/916, checked against the signal list PNU 923 first.

    \b
    Signals (number = PNU): 1 STW1, 5 NSOLL_A, 32 SATZANW, 34 MDI_TARPOS, 35 MDI_VELOCITY,
    36 MDI_ACC, 37 MDI_DEC, 38 MDI_MOD (set points); 2 ZSW1, 6 NIST_A, 33 AKTSATZ,
    52 ITIST_GLATT (actual values).

    \b
    Examples:
      akdctl -y telegram set 0
      akdctl -y telegram map --setpoint 1,5 --actual 2,6,52
      akdctl telegram map --setpoint 1,5 --dry-run
    """
    from akdctl.drive.telegram import map_request, parse_signals

    if setpoint is None and actual is None:
        raise UsageError("nothing to map: give --setpoint and/or --actual")
    request = map_request(parse_signals(setpoint) if setpoint is not None else None,
                          parse_signals(actual) if actual is not None else None, force=force)
    _run(get_app(), request, dry_run, "telegram 0 mapped")
