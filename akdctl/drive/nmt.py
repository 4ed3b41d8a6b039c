"""CANopen NMT commands as write plans (``akdctl can nmt``): plan -> consent -> execute, like every writing command.

Why ``start`` passes the gate: NMT start puts a node into OPERATIONAL, the one state in which it acts on the RPDOs on
the bus (CiA 301: PDO communication only in OPERATIONAL). If a PLC or another master sends the drive's controlword
and set points, the drive follows them from that moment, so the command is a path that can power or move the axis:
it needs consent and owns the axis like any gated write. ``stop``, ``preop`` and the two resets only take the
node's process data away (a reset also restarts the node, its power stage off): never gated, like ``disable``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from akdctl.drive.gate import NMT_START, Gated
from akdctl.drive.operation import PlannedWrite, WritePlan
from akdctl.errors import CheckFailed, UsageError

if TYPE_CHECKING:
    from akdctl.connection import Connection
    from akdctl.transport.canopen_bus import CanopenTransport

#: The NMT state each command leaves a node in (CiA 301's NMT state machine; both resets end in PRE-OPERATIONAL
#: after the boot-up message).
EXPECTED_STATE = {
    "start": "OPERATIONAL",
    "stop": "STOPPED",
    "preop": "PRE-OPERATIONAL",
    "reset": "PRE-OPERATIONAL",
    "reset-comm": "PRE-OPERATIONAL",
}
_RESTARTS = {"reset": "a reset node restarts its application: power stage off, parameters as last saved (DRV.NVSAVE)",
             "reset-comm": "a reset node restarts its communication: PDO and heartbeat settings as last saved"}


@dataclass(frozen=True)
class NmtRequest:
    """One NMT command: ``node`` None is the target's node, 0 every node on the bus; ``wait`` confirms the new
    state from the heartbeat or by node guarding (not possible for every node at once)."""

    command: str
    node: int | None = None
    wait: bool = True


def bus(conn: "Connection") -> "CanopenTransport":
    """The CANopen transport of a ``can://`` target; a UsageError on any other."""
    from akdctl.transport.canopen_bus import CanopenTransport

    if conn.target.scheme != "can":
        raise UsageError(f"'akdctl can' commands need a can://INTERFACE/CHANNEL/NODE target; the target is "
                         f"{conn.target.display}")
    transport = conn.transport()
    if not isinstance(transport, CanopenTransport):
        raise UsageError(f"target {conn.target.display} is not a CANopen transport")
    return transport


def plan(conn: "Connection", request: NmtRequest) -> WritePlan:
    """The NMT command as one planned write (the command specifier and node id of CiA 301's NMT frame, COB-ID 0);
    nothing is sent."""
    from akdctl.transport.canopen_bus import NMT_COMMANDS

    if request.command not in EXPECTED_STATE:
        raise UsageError(f"unknown NMT command {request.command!r}; use one of {', '.join(EXPECTED_STATE)}")
    if request.node is not None and not 0 <= request.node <= 127:   # before the bus is opened
        raise UsageError(f"NODE {request.node} is outside 1..127 (0 or 'all' = every node)")
    node = bus(conn).node_id if request.node is None else request.node
    who = "every node" if node == 0 else f"node {node}"
    address = f"NMT {request.command} ({who})"
    gated = Gated(address, NMT_START) if request.command == "start" else None
    code = NMT_COMMANDS[request.command]
    notes = [_RESTARTS[request.command]] if request.command in _RESTARTS else []
    confirm = request.wait and node != 0
    if node == 0:
        notes.append("every node on the bus gets it; no node's new state is confirmed")
    return WritePlan(f"can nmt {request.command}", conn.target.display,
                     [PlannedWrite(address, bytes((code, node)), f"0x{code:02X} to {who}", gated)],
                     notes=notes, enabled=None, verify=confirm,
                     data={"command": request.command, "node": node, "expected": EXPECTED_STATE[request.command]})


def execute(conn: "Connection", plan: WritePlan) -> dict[str, Any]:
    """Send the command; with ``plan.verify`` wait for the node's new state. The result names the state seen
    (None: not confirmed); :func:`check` then compares it with the state expected."""
    command, node, expected = plan.data["command"], plan.data["node"], plan.data["expected"]
    transport = bus(conn)
    transport.nmt(command, node)
    state = transport.nmt_state(node, fresh=True, expect=expected) if plan.verify else None
    return {"target": plan.target, "node": node or "all", "command": command, "nmt_state": state,
            "expected": expected}


def check(result: dict[str, Any]) -> None:
    """CheckFailed (exit 5) when the node reported another state than the command leaves it in."""
    state, expected = result["nmt_state"], result["expected"]
    if state is not None and state != expected:
        raise CheckFailed(f"node {result['node']} reports {state} after NMT {result['command']} (expected {expected})")
