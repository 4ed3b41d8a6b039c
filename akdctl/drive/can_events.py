"""What a CANopen bus says about its nodes, frame by frame: emergencies, heartbeats, boot-ups, NMT commands.

Why a pure class: ``akdctl can monitor`` reads raw frames from python-can, but the meaning of a frame (COB-ID
function code, the emergency's AKD fault, a node's state change, a heartbeat that stopped coming) is a rule that
must be testable without a bus. :class:`BusWatch` takes ``(time, can_id, data)`` and returns events; the CLI only
feeds it frames and renders what comes back. The clock is the caller's, so a test can step it.

CiA 301 pre-defined connection set: 0x000 NMT command, 0x080+node EMCY, 0x700+node heartbeat / boot-up.
"""

from __future__ import annotations

from typing import Any

from akdctl.protocol.emcy import EMCY_SIZE, decode_emcy
from akdctl.protocol.nmt import state_name

NMT_COMMANDS = {0x01: "start", 0x02: "stop", 0x80: "preop", 0x81: "reset", 0x82: "reset-comm"}
#: A node whose heartbeat period is known is reported lost after this many periods without one.
LOST_AFTER_PERIODS = 3.0
#: A heartbeat period is measured from two heartbeats at least this far apart (a boot-up burst is not a period).
MIN_PERIOD_S = 0.01


def emcy_faults(code: int, data: bytes) -> list[dict[str, Any]]:
    """The AKD faults an emergency code stands for (reference/akd_faults_emcy.csv, SPEC-NOTES 21).

    One code can stand for several AKD faults. The first two manufacturer bytes as a u16 equal to one candidate's
    number narrow it to that one [I]: the simulator sends the AKD number there; whether a real AKD does is not
    verified, so the narrowing only picks among the table's candidates, never invents one.
    """
    from akdctl.catalog import faults as catalog

    found = catalog.by_emcy(code)
    number = int.from_bytes(bytes(data[:2]).ljust(2, b"\0"), "little")
    narrowed = [f for f in found if f.number == number]
    return [{"code": f.code, "number": f.number, "warning": f.is_warning, "text": f.describe()}
            for f in (narrowed or found)]


class NodeState:
    """What the watch knows of one node: its last NMT state, when it last sent a heartbeat, its period."""

    __slots__ = ("last", "lost", "period", "state")

    def __init__(self) -> None:
        self.state: str | None = None
        self.last: float | None = None
        self.period: float | None = None
        self.lost = False


class BusWatch:
    """Frames in, events out (dicts with stable keys: ``time``, ``kind``, ``node`` and the kind's fields).

    *heartbeat_timeout* fixes when a silent node counts as lost; None measures each node's period and allows
    :data:`LOST_AFTER_PERIODS` of them. *nodes* limits the events to those nodes (None: every node).
    """

    def __init__(self, heartbeat_timeout: float | None = None, nodes: set[int] | None = None,
                 every_heartbeat: bool = False) -> None:
        self.heartbeat_timeout = heartbeat_timeout
        self.nodes = nodes
        self.every_heartbeat = every_heartbeat
        self.known: dict[int, NodeState] = {}

    def _wanted(self, node: int) -> bool:
        return self.nodes is None or node in self.nodes

    def frame(self, now: float, can_id: int, data: bytes) -> list[dict[str, Any]]:
        """The events one received frame makes (none for PDOs, SDOs and other traffic)."""
        data = bytes(data)
        function, node = can_id & 0x780, can_id & 0x7F
        if can_id == 0x000 and len(data) >= 2:
            target = data[1]
            if target and not self._wanted(target):
                return []
            return [{"time": now, "kind": "nmt-command", "node": target or "all",
                     "command": NMT_COMMANDS.get(data[0], f"0x{data[0]:02X}")}]
        if not 1 <= node <= 127 or not self._wanted(node):
            return []
        if function == 0x080 and len(data) == EMCY_SIZE:
            emcy = decode_emcy(data)
            return [{"time": now, "kind": "emergency-reset" if emcy.is_reset else "emergency", "node": node,
                     "emcy": f"0x{emcy.error_code:04X}", "error_register": f"0x{emcy.error_register:02X}",
                     "data": emcy.data.hex(), "faults": [] if emcy.is_reset else emcy_faults(emcy.error_code, emcy.data)}]
        if function == 0x700 and len(data) >= 1:
            return self._heartbeat(now, node, data[0] & 0x7F)
        return []

    def _heartbeat(self, now: float, node: int, code: int) -> list[dict[str, Any]]:
        known = self.known.setdefault(node, NodeState())
        events: list[dict[str, Any]] = []
        if code == 0:
            events.append({"time": now, "kind": "boot-up", "node": node})
            known.period = None  # a rebooted node may come back with another producer time
            known.last = None
        elif known.last is not None and now - known.last >= MIN_PERIOD_S and not known.lost:
            known.period = now - known.last if known.period is None else min(known.period, now - known.last)
        if known.lost:
            events.append({"time": now, "kind": "heartbeat-back", "node": node, "silent_s": round(now - (known.last or now), 3)})
            known.lost = False
        state = state_name(code)
        if self.every_heartbeat and code != 0:
            events.append({"time": now, "kind": "heartbeat", "node": node, "state": state})
        if state != known.state:
            events.append({"time": now, "kind": "nmt-state", "node": node, "state": state, "was": known.state})
            known.state = state
        known.last = now
        return events

    def limit(self, node: int) -> float | None:
        """How long node may stay silent before it counts as lost (None: not known yet)."""
        if self.heartbeat_timeout is not None:
            return self.heartbeat_timeout
        known = self.known.get(node)
        if known is None or known.period is None:
            return None
        return known.period * LOST_AFTER_PERIODS

    def tick(self, now: float) -> list[dict[str, Any]]:
        """Heartbeat timeouts: one ``heartbeat-lost`` event per node that went silent (again after it came back)."""
        events = []
        for node, known in sorted(self.known.items()):
            limit = self.limit(node)
            if known.lost or known.last is None or limit is None or now - known.last <= limit:
                continue
            known.lost = True
            events.append({"time": now, "kind": "heartbeat-lost", "node": node, "silent_s": round(now - known.last, 3),
                           "limit_s": round(limit, 3), "last_state": known.state})
        return events


def describe(event: dict[str, Any]) -> str:
    """One line of words for an event (the human view; ``--json`` prints the event itself)."""
    kind, node = event["kind"], event.get("node")
    if kind == "emergency":
        faults = "; ".join(f["text"] for f in event["faults"]) or "no AKD fault has this emergency code"
        return f"node {node}: EMCY {event['emcy']} (register {event['error_register']}): {faults}"
    if kind == "emergency-reset":
        return f"node {node}: EMCY 0x0000 error reset (no fault active)"
    if kind == "boot-up":
        return f"node {node}: boot-up"
    if kind == "nmt-state":
        was = event.get("was")
        return f"node {node}: NMT state {event['state']}" + (f" (was {was})" if was else "")
    if kind == "heartbeat-lost":
        return f"node {node}: heartbeat lost (silent {event['silent_s']:g} s, limit {event['limit_s']:g} s)"
    if kind == "heartbeat-back":
        return f"node {node}: heartbeat back after {event['silent_s']:g} s"
    if kind == "heartbeat":
        return f"node {node}: heartbeat ({event['state']})"
    if kind == "nmt-command":
        return f"NMT command {event['command']} to {'all nodes' if node == 'all' else f'node {node}'}"
    return f"node {node}: {kind}"
