"""``ecat state STATE`` as a write plan: the AL Control requests the master will make, from the state the slave is
in now (ETG.1000.6's state machine: up one step at a time through PRE-OP and SAFE-OP, down with one request; BOOT
only from INIT, and leaving BOOT restarts the drive).

Why a plan: the stepping rule lived in the command; ``--dry-run`` now shows the steps before any is taken. Never
gated: a state change powers nothing, and in OP the slave's outputs are what a master cycles (``ecat pdo watch``
sends zeros unless told otherwise, with consent).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from akdctl.drive.operation import PlannedWrite, WritePlan
from akdctl.protocol import ethercat as ec

if TYPE_CHECKING:
    from akdctl.transport.ethercat_raw import EthercatRawTransport

#: How long leaving BOOT may take: the drive takes its new firmware and restarts.
LEAVE_BOOT_S = 50.0
_CONTROL = "AL Control (0x0120)"


def _step(state: ec.AlState, words: str) -> PlannedWrite:
    return PlannedWrite(_CONTROL, int(state), f"{ec.al_state_name(int(state))}{words}", None)


def plan(transport: "EthercatRawTransport", target: str, wanted_text: str) -> WritePlan:
    """The requests that take the slave from its present AL state to ``wanted_text`` (INIT, PREOP, BOOT, SAFEOP,
    OP); reads the AL status, writes nothing."""
    wanted = ec.parse_al_state(wanted_text)
    slave = transport.slave
    assert slave is not None
    status = slave.al_status
    current = status & 0x0F
    steps: list[tuple[str, PlannedWrite]] = []
    notes: list[str] = []
    if current == ec.AlState.BOOT and wanted != ec.AlState.BOOT:
        steps.append(("leave-boot", _step(ec.AlState.INIT, " (leaving BOOT: the drive restarts)")))
        notes.append(f"the drive restarts on leaving BOOT; akdctl waits up to {LEAVE_BOOT_S:g} s for it to answer")
        current = ec.AlState.INIT
    if wanted == ec.AlState.BOOT:
        if current != ec.AlState.BOOT:
            steps.append(("enter-boot", _step(ec.AlState.BOOT,
                                              " (via INIT, the SII's bootstrap mailbox in SM0/SM1)")))
        notes.append("in BOOT only FoE works (firmware download); 'ecat state INIT' leaves it")
    elif wanted == ec.AlState.INIT or wanted < current:
        steps.append(("request", _step(wanted, "")))
    else:
        if current == ec.AlState.INIT or status & ec.AL_ERROR_FLAG:
            steps.append(("open-mailbox", _step(ec.AlState.PREOP,
                                                " (via INIT, SM0/SM1 from the SII)")))
            current = ec.AlState.PREOP
        for state in (ec.AlState.SAFEOP, ec.AlState.OP):
            if state <= wanted and current < state:
                steps.append(("request", _step(state, "")))
    return WritePlan("ecat state", target, [write for _, write in steps],
                     preconditions=[f"slave {slave.position} (station 0x{slave.station:04X}) in "
                                    f"{ec.al_state_name(status)}"],
                     notes=notes, enabled=None, data={"steps": [kind for kind, _ in steps]})


def execute(transport: "EthercatRawTransport", plan: WritePlan) -> tuple[int, int]:
    """Make the plan's requests in order; returns the AL status and status code read at the end."""
    master = transport.master
    assert master is not None
    for kind, write in zip(plan.data["steps"], plan.writes):
        slave = transport.slave
        assert slave is not None
        if kind == "leave-boot":
            transport.leave_boot(LEAVE_BOOT_S)   # BOOT goes to INIT only, and the drive restarts
        elif kind == "enter-boot":
            transport.enter_boot()
        elif kind == "open-mailbox":
            transport.open_mailbox()             # INIT -> PRE-OP with SM0/SM1 from the SII
        elif write.raw in (ec.AlState.SAFEOP, ec.AlState.OP) and \
                master.al_status(slave.station)[0] & 0x0F >= write.raw:
            continue                             # already there (the mailbox step may have brought it)
        else:
            master.request_state(slave.station, ec.AlState(write.raw))
    slave = transport.slave
    assert slave is not None
    return master.al_status(slave.station)


__all__ = ["LEAVE_BOOT_S", "execute", "plan"]
