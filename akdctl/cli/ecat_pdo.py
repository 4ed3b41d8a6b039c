"""``akdctl ecat pdo watch``: cyclic process data with akdctl as the master, shown live.

Why apart from cli/ecat.py: a live view (redrawn table, or a line a second when piped) is its own job; the
operation and its rules are :mod:`akdctl.drive.ecat_pdo_watch`.
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.consent import consent_plan, render_dry_run
from akdctl.cli.ecat_common import parse_int
from akdctl.cli.output import Doc
from akdctl.errors import UsageError


@click.group("pdo")
def ecat_pdo() -> None:
    """Cyclic process data with akdctl as the master (target ecat://IFNAME[/POS]).

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat pdo watch --for 5
    """


def _parse_out(text: str) -> tuple[tuple[int, int], int]:
    where, sep, value = text.partition("=")
    if not sep:
        raise UsageError(f"--out {text!r}: write INDEX[:SUB]=VALUE, e.g. 0x6040:0=15")
    index_text, _, sub_text = where.strip().partition(":")
    return (parse_int(index_text, "object index"), parse_int(sub_text or "0", "sub-index")), parse_int(value.strip(), "value")


@ecat_pdo.command("watch")
@click.option("--for", "duration", default=10.0, type=click.FloatRange(0.05, 86400), show_default=True,
              help="Seconds to stay in OP.")
@click.option("--period", default=0.01, type=click.FloatRange(0.001, 1.0), show_default=True,
              help="Cycle time in seconds (the slave's SM watchdog is 100 ms by default).")
@click.option("--out", "outs", multiple=True, metavar="INDEX[:SUB]=VALUE",
              help="An RxPDO value to write every cycle instead of 0 (needs --yes / consent).")
@click.option("--dry-run", is_flag=True, help="Show the mapping and the outputs that would go out; change nothing.")
def pdo_watch(duration: float, period: float, outs: tuple[str, ...], dry_run: bool) -> None:
    """Take the slave to OP with its current mapping and show the TxPDO values and the working counter live.

    Outputs are all 0 (controlword 0) unless --out values are given (consent). A working-counter drop ends
    with exit 3, a slave leaving OP with exit 1; the slave is left in PRE-OP.

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat pdo watch --for 5
      akdctl -T ecat://eth1/0 -y ecat pdo watch --out 0x6040:0=6
    """
    from akdctl.drive import ecat_pdo_watch as op

    app = get_app()
    outputs = dict(_parse_out(text) for text in outs)
    plan = op.plan(app.connection, outputs)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)  # every output given with --out needs consent (drive/ecat_pdo_watch.plan)
    with _LiveView(app.json) as view:
        result = op.execute(app.connection, plan, duration, period, view.show)
    doc = Doc("process data (last cycle)", app.target.display)
    doc.table(["object", "name", "value"], [[v["address"], v["name"], v["shown"]] for v in result["inputs"]])
    doc.kv("cycles", f"{result['cycles']} in {result['seconds']} s, working counter {result['expected_wkc']} each")
    app.emit(result, doc)


class _LiveView:
    """TxPDO values and WKC redrawn in place on a terminal (stderr); a plain line a second when piped."""

    def __init__(self, quiet: bool) -> None:
        import sys

        self.quiet, self.stream = quiet, sys.stderr
        self.terminal = not quiet and self.stream.isatty()
        self._live: Any = None
        self._last = 0.0

    def __enter__(self) -> "_LiveView":
        if self.terminal:
            from rich.live import Live

            from akdctl.cli.output import console

            self._live = Live(console=console(stderr=True), transient=True, auto_refresh=False)
            self._live.start()
        return self

    def show(self, values: list[dict[str, Any]], wkc: int, expected: int, cycle: int) -> None:
        import time

        mark = "" if wkc == expected else f" (expected {expected}!)"
        if self._live is not None:
            from rich.table import Table

            table = Table(title=f"cycle {cycle}  WKC {wkc}{mark}")
            for col in ("object", "name", "value"):
                table.add_column(col)
            for v in values:
                table.add_row(v["address"], v["name"], v["shown"])
            self._live.update(table, refresh=True)
            return
        now = time.monotonic()
        if not self.quiet and (now - self._last >= 1.0 or wkc != expected):
            self._last = now
            text = ", ".join(f"{v['name']} {v['shown']}" for v in values)
            self.stream.write(f"akdctl: cycle {cycle} WKC {wkc}{mark}: {text}\n")
            self.stream.flush()

    def __exit__(self, *exc: object) -> None:
        if self._live is not None:
            self._live.stop()
