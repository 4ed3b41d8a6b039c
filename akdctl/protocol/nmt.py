"""CiA 301 NMT: the states a node reports in its heartbeat or node-guarding reply.

Why a module of its own: the ``can://`` transport (``can nmt``, ``can scan``) and the CANopen SDO
channel (an unanswered SDO to a STOPPED node) both name these states, and neither may import the
other; the numbers are protocol facts, so they live with the codecs.
"""

from __future__ import annotations

#: Heartbeat / node-guarding state byte (bit 7, the guarding toggle, removed) -> name.
NMT_STATES: dict[int, str] = {
    0x00: "BOOTUP",
    0x04: "STOPPED",
    0x05: "OPERATIONAL",
    0x7F: "PRE-OPERATIONAL",
}


def state_name(code: int) -> str:
    """Heartbeat state byte -> name; a boot-up (0) means the node is now PRE-OPERATIONAL (CiA 301)."""
    code &= 0x7F
    if code == 0:
        return "PRE-OPERATIONAL"
    return NMT_STATES.get(code, f"UNKNOWN (0x{code:02X})")
