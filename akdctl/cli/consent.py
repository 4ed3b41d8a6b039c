"""The one consent for anything that can power or move the axis, and the axis's one owner.

Motion commands, recipes with motion or gated set steps, and gated raw writes
(``pnu set``, ``sdo write``; :mod:`akdctl.drive.gate`) all ask here: a prompt on a
terminal naming the target and what will happen, or ``--yes``; otherwise exit 4
with the reason. Nothing is written to the drive before this returns.

Whoever passes also *owns the axis* for the rest of the command (:func:`own_axis`):
a second akdctl process that wants to power or move the same target meanwhile is
refused (exit 4) naming the owner's pid and command, so five parallel ``move
--relative 1`` never add up on one axis. The owner is taken before the prompt, so
nobody is asked for a consent that could not be used.
"""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, Any

import click

from akdctl.errors import SafetyRefusal

if TYPE_CHECKING:
    from akdctl.cli.context import AppContext


def require_consent(app: "AppContext", action: str) -> None:
    """Return when the user consents to ``action`` on this target; SafetyRefusal (exit 4) otherwise."""
    refuse_unaskable(app, action)
    own_axis(app)
    ask(f"{action} on {app.target.display}", app.yes)


def refuse_unaskable(app: "AppContext", action: str) -> None:
    """SafetyRefusal (exit 4) when consent to ``action`` on this target can be neither given nor asked: called
    before a plan's notes, so such a refusal is its one line."""
    refuse_without_terminal(f"{action} on {app.target.display}", app.yes)


def refuse_without_terminal(text: str, yes: bool) -> None:
    """SafetyRefusal (exit 4) when consent to ``text`` can be neither given (--yes) nor asked (no terminal)."""
    if not yes and not sys.stdin.isatty():
        raise SafetyRefusal(f"refusing to {text}: no terminal to ask for consent and --yes was not given; "
                            "nothing was written")


def ask(text: str, yes: bool) -> None:
    """The one consent question (``--yes`` answers it): return on yes, SafetyRefusal (exit 4) otherwise.
    Used for one axis here and for a whole line of drives (cli/line.py)."""
    refuse_without_terminal(text, yes)
    if yes:
        return
    from akdctl.cli.output import inert

    if not click.confirm(inert(f"About to {text}. Proceed?"), default=False, err=True):
        raise SafetyRefusal(f"not confirmed: {text}; nothing was written")


def consent_plan(app: "AppContext", plan: Any) -> None:
    """The consent a write plan asks for (:attr:`akdctl.drive.operation.WritePlan.consent_text`), decided by the
    plan alone; a plan with gated writes owns the axis like a motion (also with ``--yes``).

    A plan that cannot be consented to (no terminal, no ``--yes``) is refused first, in its one line. Otherwise its
    notes come before the question, one ``akdctl: note:`` line each on stderr: what the user should know before it
    runs (RAM only until saved, an inferred scale, what ``--force`` let past, a power cycle needed), shown the same
    way by every writing command, whether or not it needs consent."""
    from akdctl.drive.operation import consent_needed

    if not app.yes and plan.needing_consent:
        refuse_unaskable(app, plan.consent_text)
    show_notes(plan)
    if plan.gated and app.yes:
        own_axis(app)
    consent_needed(plan, lambda text: require_consent(app, text), given=app.yes)


def show_notes(plan: Any) -> None:
    """A plan's notes (a write plan's or a motion's), one ``akdctl: note:`` line each on stderr, before it runs."""
    if plan.notes:
        from akdctl.cli.output import message

        for note in plan.notes:
            message(f"akdctl: note: {note}")


def render_dry_run(app: "AppContext", plan: Any, **extra: Any) -> None:
    """``--dry-run``: the plan in words (or its JSON with ``--json``, ``extra`` keys beside it); nothing is
    written. Every writing command's dry run is rendered here; a plan's first line names its target."""
    from akdctl.cli.output import Doc

    lines = plan.lines()
    doc = Doc(f"{lines[0]} (dry run, nothing written)", "")
    for line in lines[1:]:
        doc.line(line)
    app.emit({"target": plan.target, **extra, "dry_run": True, "plan": plan.to_json()}, doc)


def own_axis(app: "AppContext") -> None:
    """Own the target's axis until the command ends (:meth:`akdctl.connection.Connection.own_axis`:
    released when the connection closes, or when the process dies); SafetyRefusal (exit 4) naming the
    owner when another command holds it."""
    from akdctl.io.owner_lock import OwnerBusy

    conn = app.connection
    try:
        conn.own_axis(_command_line())
    except OwnerBusy as busy:
        raise SafetyRefusal(f"refusing: the axis of {app.target.display} is in use by {_owner_text(busy.owner)}; "
                            "wait until it ends, or stop it ('akdctl stop' is never refused); nothing was written",
                            details={"owner": busy.owner}) from None
    except OSError as exc:  # the state directory, not the drive: exit 2 naming the way out (README, issue 23.22)
        from akdctl.errors import UsageError

        where = exc.filename or "the state directory"
        raise UsageError(f"cannot take the axis's owner lock {where} ({exc.strerror or exc}); check that the state "
                         "directory is writable and has free space (set AKDCTL_STATE_DIR to use another); "
                         "nothing was written") from None


def _command_line() -> str:
    import shlex  # here: every command imports this module, few take the owner lock

    return shlex.join(["akdctl", *sys.argv[1:]])


def _owner_text(owner: dict[str, Any]) -> str:
    if "pid" not in owner:
        return "another akdctl command that is just starting or ending"
    since = f", since {time.strftime('%H:%M:%S', time.localtime(owner['since']))}" if "since" in owner else ""
    return f"pid {owner['pid']} ({owner.get('command', 'akdctl')}{since})"
