"""``akdctl diagnose``: why won't it enable, why did it stop: the causes the drive exposes, ranked, with remedies.

Thin: :func:`akdctl.drive.diagnose.diagnose` reads and decides; this module renders. Nothing is written.
"""

from __future__ import annotations

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc


@click.command()
@click.option("--mode", "want_mode", type=click.Choice(["position", "velocity", "torque", "homing"]), default=None,
              help="The operation mode you mean to run in: a drive in another mode is named as a cause.")
def diagnose(want_mode: str | None) -> None:
    """Name every cause that keeps the axis from enabling or moving, most likely first, each with its remedy.

    Reads (never writes) what the target exposes: the state, faults and warnings,
    STO, DRV.DISSOURCES (CoE 0x3443), the limit switch inputs, the EtherCAT AL state,
    the controlword mapped in OP, the cycle time and the mode against the mapping,
    STW1's control-by-PLC bit, the homed bit. What a transport cannot read is listed
    as not read: such a cause is not ruled out. Exit 0 whatever it finds (scripts read
    --json: causes[].blocking).

    \b
    Examples:
      akdctl diagnose
      akdctl -T ecat-udp://10.0.0.5/1001 diagnose --json
      akdctl -T 'sim?drive=cia402' diagnose --mode position
    """
    from akdctl.drive.diagnose import diagnose as run

    app = get_app()
    result = run(app.connection, want_mode=want_mode)

    def human() -> Doc:
        doc = Doc("diagnosis", app.target.display)
        doc.kv("state", result["state"] or "unknown").kv("verdict", result["verdict"])
        rows = [[i + 1, "blocks" if c["blocking"] else "note", c["text"], c["remedy"], c["evidence"]]
                for i, c in enumerate(result["causes"])]
        if rows:
            doc.table(["#", "", "cause", "remedy", "evidence"], rows, title="causes, most likely first")
        for name, why in result["not_read"].items():
            doc.kv(f"not read: {name}", why)
        return doc

    app.emit(result, human)
