"""``akdctl can scan|nmt``: CANopen network management on a ``can://`` target.

``scan`` finds the nodes on the target's bus (the NODE part of the target is
not used); ``nmt`` sends a CiA 301 NMT command and confirms the new state from
the node's heartbeat or, if it sends none, by node guarding.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.drive.nmt import EXPECTED_STATE
from akdctl.errors import UsageError

if TYPE_CHECKING:
    from akdctl.transport.canopen_bus import CanopenTransport


def _can_transport() -> "CanopenTransport":
    from akdctl.drive.nmt import bus

    return bus(get_app().connection)


def parse_nodes(text: str) -> list[int]:
    """``1-127``, ``1,3,10-12`` -> sorted node ids; UsageError outside 1..127."""
    nodes: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        low, dash, high = part.partition("-")
        try:
            first = int(low, 0)
            last = int(high, 0) if dash else first
        except ValueError:
            raise UsageError(f"--nodes {text!r}: {part!r} is not a node id or range (e.g. 1-127 or 1,3,5-9)") from None
        if not (1 <= first <= 127 and 1 <= last <= 127 and first <= last):
            raise UsageError(f"--nodes {text!r}: node ids are 1..127")
        nodes.update(range(first, last + 1))
    if not nodes:
        raise UsageError(f"--nodes {text!r}: no node ids")
    return sorted(nodes)


def _hex(value: int | None, width: int = 8) -> str:
    return "" if value is None else f"0x{value:0{width}X}"


@click.group()
def can() -> None:
    """CANopen network management (needs a can://INTERFACE/CHANNEL/NODE target).

    \b
    Examples:
      akdctl -T can://socketcan/can0/1 can scan
      akdctl -T can://socketcan/can0/1 can nmt start
    """


@can.command("scan")
@click.option("--nodes", "nodes_text", default="1-127", show_default=True, metavar="RANGE",
              help="Node ids to ask, e.g. 1-127 or 1,3,5-9.")
@click.option("--wait", type=click.FloatRange(min=0.05, max=60), default=None, metavar="SECONDS",
              help="How long to listen for answers (default: the --timeout).")
def scan(nodes_text: str, wait: float | None) -> None:
    """List the nodes that answer: identity (0x1018), device type, name and NMT state.

    \b
    Examples:
      akdctl -T can://socketcan/can0/1 can scan --nodes 1-10
    """
    app = get_app()
    nodes = parse_nodes(nodes_text)
    transport = _can_transport()
    found = transport.scan(nodes, wait=wait)
    data = {"target": app.target.display, "bus": transport.config.describe(), "nodes": [n.to_json() for n in found]}

    def human() -> Doc:
        doc = Doc(f"CANopen nodes on {transport.config.describe()}", app.target.display)
        if not found:
            doc.line("no node answered")
            return doc
        rows = [[n.node, n.state or "?", _hex(n.vendor_id), _hex(n.product_code), _hex(n.revision),
                 n.serial if n.serial is not None else "", _hex(n.device_type), n.device_name or ""] for n in found]
        doc.table(["node", "NMT state", "vendor", "product", "revision", "serial", "device type", "name"], rows)
        return doc

    app.emit(data, human)


@can.command("nmt")
@click.argument("command", type=click.Choice(sorted(EXPECTED_STATE)))
@click.argument("node", required=False, metavar="[NODE|all]")
@click.option("--no-wait", is_flag=True, help="Do not wait for the node to confirm its new state.")
@click.option("--dry-run", is_flag=True, help="Show the plan (the NMT frame, consent, notes); send nothing.")
def nmt(command: str, node: str | None, no_wait: bool, dry_run: bool) -> None:
    """Send an NMT command (start, stop, preop, reset, reset-comm) to NODE (default: the target's node).

    NODE 'all' (or 0) addresses every node; then no state is confirmed.
    The new state is confirmed from the heartbeat or by node guarding (exit 3 if
    the node stays silent, 5 if it reports another state). 'start' needs consent
    (-y): in OPERATIONAL the node acts on the RPDOs a master sends.

    \b
    Examples:
      akdctl -T can://socketcan/can0/1 can nmt preop
      akdctl -T can://socketcan/can0/1 -y can nmt start
      akdctl -T can://pcan/PCAN_USBBUS1/1 can nmt reset all
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import nmt as op

    app = get_app()
    if node is None:
        node_id = None
    elif node.lower() == "all":
        node_id = 0
    else:
        try:
            node_id = int(node, 0)
        except ValueError:
            raise UsageError(f"NODE {node!r} is not a node id (1..127) or 'all'") from None
    plan = op.plan(app.connection, op.NmtRequest(command, node_id, wait=not no_wait))
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)
    result = op.execute(app.connection, plan)
    who = "all nodes" if result["node"] == "all" else f"node {result['node']}"
    app.emit(result, Doc(f"NMT {command} sent to {who}", app.target.display)
             .kv("NMT state", result["nmt_state"] or "(not confirmed)"))
    op.check(result)


from akdctl.cli.can_monitor import monitor as _monitor  # noqa: E402 - registered last: `can monitor`

can.add_command(_monitor)
