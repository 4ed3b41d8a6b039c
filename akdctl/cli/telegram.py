"""``akdctl telegram show|set|map``: the PROFIdrive IO telegram (PNU 922, 915, 916, 923)."""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc, message
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


@telegram.command("set")
@click.argument("number", type=int, metavar="1|7|9|350|351|0")
@click.option("--force", is_flag=True, help="Send a telegram number akdctl does not know; the drive answers.")
def set_(number: int, force: bool) -> None:
    """Select a telegram (PNU 922), then read back its layout.

    \b
    Examples:
      akdctl -y telegram set 9
      akdctl -y telegram set 1
    """
    from akdctl.catalog.telegrams import FREE_TELEGRAM, TELEGRAMS
    from akdctl.drive.telegram import select_telegram

    known = (*TELEGRAMS, FREE_TELEGRAM)
    if number not in known:
        if not force:
            raise UsageError(f"telegram {number} is not offered by the AKD; choose one of "
                             + ", ".join(str(n) for n in sorted(known)) + " (nothing was written)")
        message(f"akdctl: warning: --force: telegram {number} is not one the AKD documents")
    if not 0 <= number <= 0xFFFF:
        raise UsageError(f"telegram {number} is outside 0..65535")
    app = get_app()
    channel = app.parameters()
    from akdctl.cli.consent import gate_write
    from akdctl.drive.gate import classify_pnu

    gate_write(app, [classify_pnu(922, "Telegram selection")])  # the telegram of an enabled drive is gated
    state = select_telegram(channel, number)
    data = {"target": app.target.display, **state.to_json()}
    app.emit(data, lambda: _state_doc(f"telegram {number} selected", app.target.display, data))


@telegram.command("map")
@click.option("--setpoint", metavar="SIGNALS", help="Set-point signals in IO order, e.g. 1,5 or STW1,NSOLL_A (PNU 915).")
@click.option("--actual", metavar="SIGNALS", help="Actual-value signals in IO order, e.g. 2,6 or ZSW1,NIST_A (PNU 916).")
@click.option("--force", is_flag=True, help="Skip akdctl's own checks; the drive answers.")
def map_(setpoint: str | None, actual: str | None, force: bool) -> None:
    """Free mapping for telegram 0 through PNU 915/916, checked against the signal list PNU 923 first.

    \b
    Signals (number = PNU): 1 STW1, 5 NSOLL_A, 32 SATZANW, 34 MDI_TARPOS, 35 MDI_VELOCITY,
    36 MDI_ACC, 37 MDI_DEC, 38 MDI_MOD (set points); 2 ZSW1, 6 NIST_A, 33 AKTSATZ,
    52 ITIST_GLATT (actual values).

    \b
    Examples:
      akdctl -y telegram set 0
      akdctl -y telegram map --setpoint 1,5 --actual 2,6,52
    """
    from akdctl.drive.telegram import map_free, parse_signals, read_state, validate_free_map

    if setpoint is None and actual is None:
        raise UsageError("nothing to map: give --setpoint and/or --actual")
    wanted_set = parse_signals(setpoint) if setpoint is not None else None
    wanted_act = parse_signals(actual) if actual is not None else None
    app = get_app()
    channel = app.parameters()
    state = read_state(channel)
    problems = validate_free_map(wanted_set or [], wanted_act or [], state.signal_list)
    if state.number != 0:
        problems.insert(0, f"telegram {state.number} is selected; PNU 915/916 change only in telegram 0 "
                           "(run 'akdctl telegram set 0' first)")
    if problems and not force:
        raise UsageError("telegram mapping refused, nothing was written:\n  - " + "\n  - ".join(problems),
                         details={"problems": problems})
    for problem in problems:
        message(f"akdctl: warning: --force: {problem}")
    from akdctl.cli.consent import gate_write
    from akdctl.drive.gate import classify_pnu

    gate_write(app, [classify_pnu(915, "PZD setpoint assignment"), classify_pnu(916, "PZD actual value assignment")])
    state = map_free(channel, wanted_set, wanted_act)
    data = {"target": app.target.display, **state.to_json()}
    app.emit(data, lambda: _state_doc("telegram 0 mapped", app.target.display, data))
