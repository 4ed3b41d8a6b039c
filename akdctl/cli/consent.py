"""The one consent for anything that can power or move the axis.

Motion commands, recipes with motion or gated set steps, and gated raw writes
(``pnu set``, ``sdo write``; :mod:`akdctl.drive.gate`) all ask here: a prompt on a
terminal naming the target and what will happen, or ``--yes``; otherwise exit 4
with the reason. Nothing is written to the drive before this returns.
"""

from __future__ import annotations

import sys
from typing import Any

import click

from akdctl.errors import SafetyRefusal


def require_consent(app: Any, action: str) -> None:
    """Return when the user consents to ``action`` on this target; SafetyRefusal (exit 4) otherwise."""
    text = f"{action} on {app.target.display}"
    if app.yes:
        return
    if not sys.stdin.isatty():
        raise SafetyRefusal(f"refusing to {text}: no terminal to ask for consent and --yes was not given; "
                            "nothing was written")
    from akdctl.cli.output import inert

    if not click.confirm(inert(f"About to {text}. Proceed?"), default=False, err=True):
        raise SafetyRefusal(f"not confirmed: {text}; nothing was written")


def gate_write(app: Any, gated: list[Any]) -> None:
    """The write gate for raw write commands: consent when the addresses can power or move the axis
    (:func:`akdctl.drive.gate.check_write`); ``--yes`` counts as given without reading the drive."""
    from akdctl.drive import gate

    gate.check_write(app.connection, gated, lambda action: require_consent(app, action), given=app.yes)
