"""The power-stage states of the simulated AKD, shared by both word machines.

Why a module of its own: an AKD has one power stage. PROFIdrive (STW1/ZSW1,
S1..S5) and CiA 402 (controlword/statusword) are two views of the same state,
so the simulator keeps one state, named as CiA 402 names it, and each word
machine renders it in its own words.
"""

from __future__ import annotations

SOD, READY, SWITCHED_ON, ENABLED, QUICK_STOP, FAULT_REACTION, FAULT = (
    "switch_on_disabled", "ready", "switched_on", "enabled", "quick_stop", "fault_reaction", "fault")

#: CiA 402 statusword state bits (0x4F mask) of each state.
CIA_WORD = {SOD: 0x40, READY: 0x21, SWITCHED_ON: 0x23, ENABLED: 0x27, QUICK_STOP: 0x07,
            FAULT_REACTION: 0x0F, FAULT: 0x08}
#: The PROFIdrive state (PROFIdrive general state machine, SPEC-NOTES 6) of each state; ENABLED while an
#: OFF1 ramp runs is S5 too (:func:`profidrive_state`).
PD_STATE = {SOD: "S1", READY: "S2", SWITCHED_ON: "S3", ENABLED: "S4", QUICK_STOP: "S5",
            FAULT_REACTION: "S1", FAULT: "S1"}
#: ZSW1 bits 0-2 and 6 of each PROFIdrive state (PDRV V4 general state diagram): S5 "switching off" shows
#: ready to switch on and ready to operate, not operation enabled, for OFF1 (ramp stop) and OFF3 (quick stop).
ZSW1_STATE_BITS = {"S1": 0x40, "S2": 0x01, "S3": 0x03, "S4": 0x07, "S5": 0x03}


def profidrive_state(state: str, stopping_to: str | None) -> str:
    """S1..S5 of the one power stage: ENABLED ramping down after OFF1 (``stopping_to`` READY) is S5
    "switching off", as the quick stop (OFF3) is; docs/fidelity.md F2."""
    if state == ENABLED and stopping_to == READY:
        return "S5"
    return PD_STATE[state]
#: States in which the power stage drives the motor.
POWERED = (ENABLED, QUICK_STOP, FAULT_REACTION)
