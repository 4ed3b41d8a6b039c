"""Status and control words in words: PROFIdrive STW1/ZSW1 and CiA 402 controlword/statusword.

Why one module: ``status`` prints every bit by name, the axis decides what the
drive is doing from the same words, and the simulator builds them bit by bit.
Keeping the bit numbers and the state decoding here means the three can never
disagree. Bit meanings come from the PROFINET manual 5.4/5.5 (general, velocity
mode, position mode) and the EtherCAT manual 5.4 / CiA 402 (statusword states,
mode-specific bits for profile position and homing).
"""

from __future__ import annotations

from akdctl.protocol.record import Record

# ---------------------------------------------------------------- PROFIdrive STW1 (PNU 1)
STW1_ON = 1 << 0
STW1_NO_COAST_STOP = 1 << 1
STW1_NO_QUICK_STOP = 1 << 2
STW1_ENABLE_OPERATION = 1 << 3
STW1_BIT4 = 1 << 4  # velocity: enable ramp generator; position: do not reject traversing task
STW1_BIT5 = 1 << 5  # velocity: unfreeze ramp generator; position: no intermediate stop
STW1_BIT6 = 1 << 6  # velocity: enable set point; position: activate traversing task (edge)
STW1_FAULT_ACK = 1 << 7
STW1_JOG1 = 1 << 8
STW1_JOG2 = 1 << 9
STW1_CONTROL_BY_PLC = 1 << 10
STW1_START_HOMING = 1 << 11

#: The S7 sample's enable sequence (PROFINET manual 6.1.4; SPEC-NOTES 6: ends in S4).
S7_ENABLE_SEQUENCE = (0x0400, 0x0406, 0x040E, 0x040F)
#: The velocity-mode telegram 1 example (PROFINET manual 5.9).
TELEGRAM1_ENABLE_SEQUENCE = (0x0470, 0x0476, 0x0477, 0x047F)

# ---------------------------------------------------------------- PROFIdrive ZSW1 (PNU 2)
ZSW1_READY_TO_SWITCH_ON = 1 << 0
ZSW1_READY_TO_OPERATE = 1 << 1
ZSW1_OPERATION_ENABLED = 1 << 2
ZSW1_FAULT = 1 << 3
ZSW1_NO_COAST_STOP = 1 << 4
ZSW1_NO_QUICK_STOP = 1 << 5
ZSW1_SWITCHING_ON_INHIBITED = 1 << 6
ZSW1_WARNING = 1 << 7
ZSW1_BIT8 = 1 << 8  # velocity error within range / following error in range
ZSW1_CONTROL_REQUESTED = 1 << 9
ZSW1_BIT10 = 1 << 10  # target velocity reached / target position reached
ZSW1_HOME_POSITION_SET = 1 << 11
ZSW1_TASK_ACK = 1 << 12
ZSW1_DRIVE_STOPPED = 1 << 13

_ZSW1_GENERAL = {
    0: "ready to switch on",
    1: "ready to operate",
    2: "operation enabled",
    3: "fault present",
    4: "coast stop not activated",
    5: "quick stop not activated",
    6: "switching on inhibited",
    7: "warning present",
    9: "control requested by the master",
}
_ZSW1_VELOCITY = {8: "velocity error within range", 10: "target velocity reached"}
_ZSW1_POSITION = {
    8: "following error in range",
    10: "target position reached",
    11: "home position set",
    12: "traversing task acknowledged",
    13: "drive stopped",
}
_STW1_GENERAL = {
    0: "ON (OFF1 inactive)",
    1: "no coast stop (OFF2 inactive)",
    2: "no quick stop (OFF3 inactive)",
    3: "enable operation",
    7: "fault acknowledge",
    8: "jog 1",
    9: "jog 2",
    10: "control by PLC",
}
_STW1_VELOCITY = {4: "enable ramp generator", 5: "unfreeze ramp generator", 6: "enable set point"}
_STW1_POSITION = {4: "do not reject traversing task", 5: "no intermediate stop", 6: "activate traversing task",
                  11: "start homing procedure"}

# ---------------------------------------------------------------- CiA 402 controlword (0x6040)
CW_SWITCH_ON = 1 << 0
CW_ENABLE_VOLTAGE = 1 << 1
CW_QUICK_STOP = 1 << 2  # 0 = quick stop
CW_ENABLE_OPERATION = 1 << 3
CW_NEW_SETPOINT = 1 << 4  # pp: new set-point; homing: start homing
CW_CHANGE_IMMEDIATELY = 1 << 5
CW_RELATIVE = 1 << 6
CW_FAULT_RESET = 1 << 7
CW_HALT = 1 << 8

CW_SHUTDOWN = 0x0006
CW_SWITCH_ON_CMD = 0x0007
CW_ENABLE_OPERATION_CMD = 0x000F
CW_DISABLE_VOLTAGE = 0x0000
CW_QUICK_STOP_CMD = 0x0002
CW_DISABLE_OPERATION = 0x0007

# ---------------------------------------------------------------- CiA 402 statusword (0x6041)
SW_READY_TO_SWITCH_ON = 1 << 0
SW_SWITCHED_ON = 1 << 1
SW_OPERATION_ENABLED = 1 << 2
SW_FAULT = 1 << 3
SW_VOLTAGE_ENABLED = 1 << 4
SW_QUICK_STOP = 1 << 5  # 0 = quick stop active
SW_SWITCH_ON_DISABLED = 1 << 6
SW_WARNING = 1 << 7
SW_REMOTE = 1 << 9
SW_TARGET_REACHED = 1 << 10
SW_INTERNAL_LIMIT = 1 << 11
SW_BIT12 = 1 << 12  # pp: set-point acknowledge; homing: homing attained
SW_BIT13 = 1 << 13  # pp: following error; homing: homing error

_SW_GENERAL = {
    0: "ready to switch on",
    1: "switched on",
    2: "operation enabled",
    3: "fault",
    4: "voltage enabled",
    5: "quick stop not active",
    6: "switch on disabled",
    7: "warning",
    8: "manufacturer specific (STO on AKD, unverified)",
    9: "remote",
    10: "target reached",
    11: "internal limit active",
}
_SW_MODE = {
    1: {12: "set-point acknowledge", 13: "following error"},
    6: {12: "homing attained", 13: "homing error"},
    7: {12: "ip mode active", 13: "following error"},
    8: {12: "drive follows the target position", 13: "following error"},
}

#: CiA 402 modes of operation (0x6060/0x6061, SPEC-NOTES 20).
CIA402_MODES = {1: "profile position", 3: "profile velocity", 4: "profile torque", 6: "homing",
                7: "interpolated position", 8: "cyclic synchronous position"}


def drive_modes_word(modes: tuple[int, ...] | list[int]) -> int:
    """0x6502 "supported drive modes" (CiA 402): bit n-1 set for each standard mode n in 1..10
    (bit 0 pp, 2 pv, 3 tq, 5 hm, 6 ip, 7 csp; bits 16-31 are manufacturer specific)."""
    return sum(1 << (mode - 1) for mode in set(modes) if 1 <= mode <= 10)


def drive_modes_of_word(word: int) -> list[int]:
    """The standard modes (1..10) a 0x6502 value lists."""
    return [mode for mode in range(1, 11) if word >> (mode - 1) & 1]


#: PROFIdrive operating modes (PNU 930 = DRV.OPMODE).
PROFIDRIVE_MODES = {0: "torque", 1: "velocity", 2: "position"}

# PROFIdrive general state machine (SPEC-NOTES 6).
PD_STATES = {
    "S1": "switching on inhibited",
    "S2": "ready for switching on",
    "S3": "switched on",
    "S4": "operation",
    "S5": "switching off",
}


class Bit(Record):
    """One bit of a word: number, meaning, and whether it is set (JSON through :meth:`to_json`)."""

    __slots__ = ("number", "name", "set")

    def __init__(self, number: int, name: str, set: bool) -> None:  # noqa: A002
        self.number = number
        self.name = name
        self.set = set


    def to_json(self) -> dict[str, object]:
        return {"bit": self.number, "name": self.name, "set": self.set}


def _bits(word: int, names: dict[int, str], width: int = 16) -> list[Bit]:
    return [Bit(n, names.get(n, "reserved / device specific"), bool(word >> n & 1)) for n in range(width)]


def zsw1_bits(word: int, opmode: int | None) -> list[Bit]:
    """ZSW1 bit by bit in words; the mode-specific bits per PNU 930 (2 = position, else velocity)."""
    names = dict(_ZSW1_GENERAL)
    names.update(_ZSW1_POSITION if opmode == 2 else _ZSW1_VELOCITY)
    return _bits(word, names)


def stw1_bits(word: int, opmode: int | None) -> list[Bit]:
    names = dict(_STW1_GENERAL)
    names.update(_STW1_POSITION if opmode == 2 else _STW1_VELOCITY)
    return _bits(word, names)


def statusword_bits(word: int, mode: int | None) -> list[Bit]:
    """The CiA 402 statusword bit by bit; bits 12/13 named per the mode of operation display."""
    names = dict(_SW_GENERAL)
    names.update(_SW_MODE.get(mode or 0, {}))
    return _bits(word, names)


def profidrive_state(zsw1: int, stw1: int | None = None) -> str:
    """The general state machine state (S1..S5) a ZSW1 (and the STW1 it answers) shows.

    S1: switching on inhibited (bit 6), or a fault (bit 3: the drive returns to S1
    after the acknowledge, SPEC-NOTES 7). S2: ready to switch on only. S3: also ready
    to operate. S4: operation enabled. S5 "switching off" (PDRV general state diagram:
    bits 0 and 1 set, bit 2 clear) runs for OFF3 (quick stop: bit 5 clear) and for
    OFF1 (ramp stop): S3 and the OFF1 ramp show the same ZSW1, so STW1 bit 0 tells
    them apart — with ON cleared a drive in S3 is in S2 at once (docs/fidelity.md F2).
    A ZSW1 with bit 2 set and bit 5 clear (older simulator, other drives) is S5 too.
    """
    if zsw1 & ZSW1_FAULT or zsw1 & ZSW1_SWITCHING_ON_INHIBITED:
        return "S1"
    if zsw1 & ZSW1_OPERATION_ENABLED:
        if not zsw1 & ZSW1_NO_QUICK_STOP:
            return "S5"
        return "S4"
    if zsw1 & ZSW1_READY_TO_OPERATE:
        if not zsw1 & ZSW1_NO_QUICK_STOP or (stw1 is not None and not stw1 & STW1_ON):
            return "S5"
        return "S3"
    if zsw1 & ZSW1_READY_TO_SWITCH_ON:
        return "S2"
    return "S1"


def cia402_state(statusword: int) -> str:
    """Decode the CiA 402 state from the statusword (EtherCAT manual 5.4.3 masks)."""
    low = statusword & 0x6F
    if statusword & 0x4F == 0x00:
        return "not ready to switch on"
    if statusword & 0x4F == 0x40:
        return "switch on disabled"
    if statusword & 0x4F == 0x08:
        return "fault"
    if statusword & 0x4F == 0x0F:
        return "fault reaction active"
    if low == 0x21:
        return "ready to switch on"
    if low == 0x23:
        return "switched on"
    if low == 0x27:
        return "operation enabled"
    if low == 0x07:
        return "quick stop active"
    return f"unknown (0x{statusword:04X})"


def set_names(bits: list[Bit]) -> list[str]:
    """The names of the bits that are set (a compact human summary)."""
    return [b.name for b in bits if b.set]
