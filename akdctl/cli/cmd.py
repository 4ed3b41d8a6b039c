"""``akdctl cmd LINE``: one line to the AKD's own command channel (akd://), its reply printed.

A passthrough for what akdctl has no command for (``DRV.INFO``, ``MT.LIST``, ``DRV.HELP VL.KP``). Known-safe reads
run at once; anything else -- a write, a command, a keyword akdctl does not know -- passes the one gate and
consent (``drive/names.py`` ``classify_line``), as ``sdo write`` does for raw objects.
"""

from __future__ import annotations

import click

from akdctl.cli.context import get_app


@click.command()
@click.argument("words", nargs=-1, required=True, metavar="LINE")
@click.option("--dry-run", is_flag=True, help="Show whether the line is a safe read or needs consent; send nothing.")
def cmd(words: tuple[str, ...], dry_run: bool) -> None:
    """Send one command line to the AKD's ASCII channel (akd:// targets) and print the reply.

    Reads of known names and reports (DRV.INFO, DRV.FAULTS, MT.LIST ...) run freely; every other
    line needs consent (-y), as it may write, power or move.

    \b
    Examples:
      akdctl -T akd://192.168.0.10 cmd DRV.INFO
      akdctl -T akd://192.168.0.10 -y cmd "DRV.OPMODE 2"
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import names as ops

    app = get_app()
    plan = ops.plan_line(app.connection, " ".join(words))
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)  # a known-safe read has no gated write: nothing is asked
    reply = ops.execute_line(app.connection, plan)
    app.emit({"target": app.target.display, "line": plan.data["line"], "reply": reply}, reply or "(no reply)")
