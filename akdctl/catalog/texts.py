"""Human texts for the error codes the three fieldbuses return.

Why one module: every code path that reports a refusal (SDO abort, PROFIdrive error
value, PNIO status of a record access, EtherCAT AL status, mailbox error reply, the
0x1001 error register) needs the same wording, and an unknown code must still produce a
sentence naming the code - never a KeyError reaching the user.

Sources: CiA 301 / ETG.1000.6 abort codes as SOEM (ethercatprint.c) and python-canopen
word them; PROFIdrive V4.2 error values (reference/profidrive_reference.md); PNIO status
codes as IEC 61158-6-10 defines them (names as in rt-labs p-net pnet_api.h); AL status
codes of ETG.1000.6 (names as in SOEM ethercatprint.c).
"""
from __future__ import annotations

__all__ = [
    "SDO_ABORT_TEXTS", "sdo_abort_text",
    "PROFIDRIVE_ERROR_TEXTS", "profidrive_error_text", "profidrive_error_phrase", "profidrive_failure_detail",
    "PROFIDRIVE_SUBINDEX_INFO_ERRORS",
    "RECORD_ERROR_TEXTS", "RECORD_RETRY_CODES", "PNIO_ERROR_CODE_TEXTS", "PNIO_ERROR_DECODE_TEXTS",
    "PNIO_CM_ERROR_CODE1_TEXTS", "pnio_status_text",
    "AL_STATUS_CODE_TEXTS", "AKD_AL_STATUS_CODES", "al_status_text",
    "ERROR_REGISTER_BITS", "error_register_text",
    "MAILBOX_ERROR_TEXTS", "mailbox_error_text",
    "FOE_ERROR_TEXTS", "foe_error_text",
    "CIP_STATUS_TEXTS", "CIP_CM_EXTENDED_TEXTS", "ENIP_STATUS_TEXTS", "cip_status_text", "enip_status_text", "CIP_VENDORS", "cip_vendor_name",
    "CANOPEN_VENDORS", "PI_VENDORS",
]

# --- CoE / CANopen SDO abort codes (CiA 301, ETG.1000.6) --------------------------------

SDO_ABORT_TEXTS: dict[int, str] = {
    0x05030000: "Toggle bit not alternated",
    0x05040000: "SDO protocol timed out",
    0x05040001: "Client/server command specifier not valid or unknown",
    0x05040002: "Invalid block size (block mode only)",
    0x05040003: "Invalid sequence number (block mode only)",
    0x05040004: "CRC error (block mode only)",
    0x05040005: "Out of memory",
    0x06010000: "Unsupported access to an object",
    0x06010001: "Attempt to read a write-only object",
    0x06010002: "Attempt to write a read-only object",
    0x06010003: "Subindex cannot be written, subindex 0 must be 0 for write access",
    0x06010004: "SDO complete access not supported for objects of variable length",
    0x06010005: "Object length exceeds mailbox size",
    0x06010006: "Object mapped to RxPDO, SDO download blocked",
    0x06020000: "Object does not exist in the object dictionary",
    0x06040041: "Object cannot be mapped to the PDO",
    0x06040042: "Number and length of objects to be mapped would exceed PDO length",
    0x06040043: "General parameter incompatibility reason",
    0x06040047: "General internal incompatibility in the device",
    0x06060000: "Access failed due to a hardware error",
    0x06070010: "Data type does not match, length of service parameter does not match",
    0x06070012: "Data type does not match, length of service parameter too high",
    0x06070013: "Data type does not match, length of service parameter too low",
    0x06090011: "Subindex does not exist",
    0x06090030: "Value range of parameter exceeded (write access only)",
    0x06090031: "Value of parameter written too high",
    0x06090032: "Value of parameter written too low",
    0x06090036: "Maximum value is less than minimum value",
    0x060A0023: "Resource not available",
    0x08000000: "General error",
    0x08000020: "Data cannot be transferred or stored to the application",
    0x08000021: "Data cannot be transferred or stored to the application because of local control",
    0x08000022: "Data cannot be transferred or stored to the application because of the present device state",
    0x08000023: "Object dictionary dynamic generation fails or no object dictionary is present",
    0x08000024: "No data available",
}


def sdo_abort_text(code: int) -> str:
    """Text for an SDO abort code; unknown codes name themselves in hex."""
    try:
        code = int(code)
    except (TypeError, ValueError):
        return f"unknown SDO abort code {code!r}"
    text = SDO_ABORT_TEXTS.get(code)
    if text is not None:
        return text
    return f"unknown SDO abort code 0x{code & 0xFFFFFFFF:08X}"


# --- PROFIdrive parameter access error values (PROFIdrive V4.2, error value 1) ---------

PROFIDRIVE_ERROR_TEXTS: dict[int, str] = {
    0x00: "Impermissible parameter number",
    0x01: "Parameter value cannot be changed",
    0x02: "Low or high limit exceeded",
    0x03: "Faulty subindex",
    0x04: "No array",
    0x05: "Incorrect data type",
    0x06: "Setting not permitted (may only be reset)",
    0x07: "Description element cannot be changed",
    0x08: "Reserved (PROFIdrive V2: PPO-Write requested in IR not available)",
    0x09: "No description data available",
    0x0A: "Reserved (PROFIdrive V2: access group wrong)",
    0x0B: "No operation priority (no parameter change rights)",
    0x0C: "Reserved (PROFIdrive V2: wrong password)",
    0x0D: "Reserved (PROFIdrive V2: text cannot be read in cyclic data transfer)",
    0x0E: "Reserved (PROFIdrive V2: name cannot be read in cyclic data transfer)",
    0x0F: "No text array available",
    0x10: "Reserved (PROFIdrive V2: no PPO-Write)",
    0x11: "Request cannot be executed because of operating state",
    0x14: "Value impermissible",
    0x15: "Response too long",
    0x16: "Parameter address impermissible",
    0x17: "Illegal format",
    0x18: "Number of values inconsistent",
    0x19: "Axis/DO nonexistent",
    0x20: "Parameter text element cannot be changed",
    0x21: "Service not supported (invalid request ID)",
    0x22: "Too many parameter requests",
    0x23: "Multi-parameter access not supported",
}

# Error values whose additional information word is the subindex (Siemens G130 table 6-15).
PROFIDRIVE_SUBINDEX_INFO_ERRORS: frozenset[int] = frozenset({0x01, 0x02, 0x03, 0x06, 0x07, 0x14})


def profidrive_error_text(code: int) -> str:
    """Text for a PROFIdrive error value; 0x65..0xFF are manufacturer specific."""
    try:
        code = int(code)
    except (TypeError, ValueError):
        return f"unknown PROFIdrive error {code!r}"
    text = PROFIDRIVE_ERROR_TEXTS.get(code)
    if text is not None:
        return text
    if 0x65 <= code <= 0xFF:
        return f"manufacturer-specific PROFIdrive error 0x{code:02X}"
    return f"unknown PROFIdrive error 0x{code & 0xFFFF:02X}"


def profidrive_error_phrase(code: int) -> str:
    """:func:`profidrive_error_text` as it reads inside a sentence ("drive refused to read PNU 9999:
    impermissible parameter number"): the same words, first letter lower-case."""
    text = profidrive_error_text(code)
    return text[:1].lower() + text[1:]


def profidrive_failure_detail(error: int, additional: int | None = None) -> str:
    """A negative parameter result in words with its codes: "faulty subindex (error 0x03, subindex 99)"."""
    words = f"{profidrive_error_phrase(error)} (error 0x{error:02X}"
    if additional is not None:
        label = "subindex" if error in PROFIDRIVE_SUBINDEX_INFO_ERRORS else "additional info"
        words += f", {label} {additional}"
    return words + ")"


# --- PROFINET PNIOStatus (ErrorCode, ErrorDecode, ErrorCode1, ErrorCode2) --------------

PNIO_ERROR_CODE_TEXTS: dict[int, str] = {
    0x00: "no error",
    0x81: "PNIO error",
    0xCF: "RTA error",
    0xDA: "alarm acknowledge error",
    0xDB: "connect error",
    0xDC: "release error",
    0xDD: "control error",
    0xDE: "read error",
    0xDF: "write error",
}

PNIO_ERROR_DECODE_TEXTS: dict[int, str] = {
    0x00: "no error",
    0x80: "PNIORW",
    0x81: "PNIO",
    0x82: "manufacturer specific",
}

# ErrorCode1 with ErrorDecode 0x80 (PNIORW): the record-access layer's answer.
RECORD_ERROR_TEXTS: dict[int, str] = {
    0xA0: "application: read error",
    0xA1: "application: write error",
    0xA2: "application: module failure",
    0xA3: "application: not specified",
    0xA4: "application: not specified",
    0xA5: "application: not specified",
    0xA6: "application: not specified",
    0xA7: "application: busy",
    0xA8: "application: version conflict",
    0xA9: "application: feature not supported",
    0xB0: "access: invalid index",
    0xB1: "access: write length error",
    0xB2: "access: invalid slot/subslot",
    0xB3: "access: type conflict",
    0xB4: "access: invalid area/API",
    0xB5: "access: state conflict",
    0xB6: "access: access denied",
    0xB7: "access: invalid range",
    0xB8: "access: invalid parameter",
    0xB9: "access: invalid type",
    0xBA: "access: backup",
    0xC0: "resource: read constrain conflict",
    0xC1: "resource: write constrain conflict",
    0xC2: "resource: resource busy",
    0xC3: "resource: resource unavailable",
}
# Record errors after which the same request may simply be repeated (busy, not refused).
RECORD_RETRY_CODES: frozenset[int] = frozenset({0xA7, 0xB5, 0xC2})

# ErrorCode1 with ErrorDecode 0x81 (PNIO): which CM protocol machine or block refused.
PNIO_CM_ERROR_CODE1_TEXTS: dict[int, str] = {
    0x01: "Connect: faulty ARBlockReq",
    0x02: "Connect: faulty IOCRBlockReq",
    0x03: "Connect: faulty ExpectedSubmoduleBlockReq",
    0x04: "Connect: faulty AlarmCRBlockReq",
    0x05: "Connect: faulty PrmServerBlockReq",
    0x06: "Connect: faulty MCRBlockReq",
    0x07: "Connect: faulty ARRPCBlockReq",
    0x08: "Read/Write record: faulty record",
    0x09: "Connect: faulty IRInfoBlock",
    0x0A: "Connect: faulty SRInfoBlock",
    0x0B: "Connect: faulty ARFSUBlock",
    0x0C: "Connect: faulty vendor block",
    0x0D: "Connect: faulty RSInfoBlock",
    0x14: "IODControl: faulty ControlBlockConnect",
    0x15: "IODControl: faulty ControlBlockPlug",
    0x16: "IOXControl: faulty ControlBlockConnect",
    0x17: "IOXControl: faulty ControlBlockPlug",
    0x18: "IODControl: faulty ControlBlockPrmBegin",
    0x19: "IODControl: faulty SubmoduleListBlock",
    0x28: "Release: faulty ReleaseBlock",
    0x3C: "AlarmAck: error",
    0x3D: "CMDEV",
    0x3E: "CMCTL",
    0x3F: "CTLDINA",
    0x40: "CMRPC",
    0x41: "ALPMI",
    0x42: "ALPMR",
    0x43: "LMPM",
    0x44: "MAC",
    0x45: "RPC",
    0x46: "APMR",
    0x47: "APMS",
    0x48: "CPM",
    0x49: "PPM",
    0x4A: "DCPUCS",
    0x4B: "DCPUCR",
    0x4C: "DCPMCS",
    0x4D: "DCPMCR",
    0x4E: "FSPM",
    0xC8: "CMSM",
    0xCA: "CMRDR",
    0xCC: "CMWRR",
    0xCD: "CMIO",
    0xCE: "CMSU",
    0xD0: "CMINA",
    0xD1: "CMPBE",
    0xD2: "CMSRL",
    0xD3: "CMDMC",
    0xFD: "RTA protocol error",
    0xFF: "user specific",
}
# ErrorCode2 for a faulty block (ErrorCode1 0x01..0x0D): index of the offending field.
_BLOCK_FIELD_TEXTS: dict[int, str] = {
    0: "block type", 1: "block length", 2: "block version high", 3: "block version low",
}
_AR_BLOCK_FIELD_TEXTS: dict[int, str] = {4: "AR type not supported"}
_CMRPC_CODE2_TEXTS: dict[int, str] = {
    0x00: "ArgsLength invalid", 0x01: "unknown blocks", 0x02: "IOCR missing", 0x03: "wrong AlarmCRBlock count",
    0x04: "out of AR resources", 0x05: "AR UUID unknown", 0x06: "state conflict",
    0x07: "out of provider, consumer or alarm resources", 0x08: "out of memory",
}


def _pnio_detail(decode: int, code1: int, code2: int) -> str:
    if decode == 0x80:
        text = RECORD_ERROR_TEXTS.get(code1)
        if text is None:
            if 0xAA <= code1 <= 0xAF or 0xBB <= code1 <= 0xBF or 0xC8 <= code1 <= 0xCF:
                text = f"user-specific record error 0x{code1:02X}"
            else:
                text = f"unknown record error 0x{code1:02X}"
        return text
    if decode == 0x81:
        text = PNIO_CM_ERROR_CODE1_TEXTS.get(code1, f"unknown PNIO error 0x{code1:02X}")
        if 0x01 <= code1 <= 0x0D:
            field = _BLOCK_FIELD_TEXTS.get(code2) or (_AR_BLOCK_FIELD_TEXTS.get(code2) if code1 == 0x01 else None)
            text += f", {field}" if field else f", field {code2}"
        elif code1 == 0x40 and code2 in _CMRPC_CODE2_TEXTS:
            text += f": {_CMRPC_CODE2_TEXTS[code2]}"
        return text
    if decode == 0x82:
        return f"manufacturer-specific error 0x{code1:02X}/0x{code2:02X}"
    return f"unknown error decode 0x{decode:02X}"


def pnio_status_text(b0: int, b1: int, b2: int, b3: int) -> str:
    """One line for a PNIOStatus (ErrorCode, ErrorDecode, ErrorCode1, ErrorCode2).

    Always ends with the four bytes in hex, so a support log keeps the raw status.
    """
    try:
        raw = [int(b) & 0xFF for b in (b0, b1, b2, b3)]
    except (TypeError, ValueError):
        return f"malformed PNIO status {(b0, b1, b2, b3)!r}"
    code, decode, code1, code2 = raw
    hexed = " ".join(f"{b:02X}" for b in raw)
    if raw == [0, 0, 0, 0]:
        return f"OK [{hexed}]"
    what = PNIO_ERROR_CODE_TEXTS.get(code, f"error 0x{code:02X}")
    detail = _pnio_detail(decode, code1, code2)
    hint = " (busy, try again)" if decode == 0x80 and code1 in RECORD_RETRY_CODES else ""
    return f"{what}: {detail}{hint} [{hexed}]"


# A Connect refused with "out of AR resources" (DB 81 40 04): what holds the device's ARs and when they come free.
# The device does not say which AR holds a slot; the simulator's face names the holders on its stderr.
PN_OUT_OF_ARS_HINT = (
    "every AR the device offers is held, by other supervisors or controllers, or by a client that ended without "
    "releasing its AR (the device frees that one after the AR's activity timeout); on 'akdctl sim serve' the "
    "server's stderr names the AR holding each slot")


# --- EtherCAT AL status codes (ETG.1000.6) ----------------------------------------------

AL_STATUS_CODE_TEXTS: dict[int, str] = {
    0x0000: "No error",
    0x0001: "Unspecified error",
    0x0002: "No memory",
    0x0003: "Invalid device setup",
    0x0006: "SII/EEPROM information does not match firmware",
    0x0007: "Firmware update not successful",
    0x000E: "License error",
    0x0011: "Invalid requested state change",
    0x0012: "Unknown requested state",
    0x0013: "Bootstrap not supported",
    0x0014: "No valid firmware",
    0x0015: "Invalid mailbox configuration (BOOT)",
    0x0016: "Invalid mailbox configuration (PRE-OP)",
    0x0017: "Invalid sync manager configuration",
    0x0018: "No valid inputs available",
    0x0019: "No valid outputs",
    0x001A: "Synchronization error",
    0x001B: "Sync manager watchdog",
    0x001C: "Invalid sync manager types",
    0x001D: "Invalid output configuration",
    0x001E: "Invalid input configuration",
    0x001F: "Invalid watchdog configuration",
    0x0020: "Slave needs cold start",
    0x0021: "Slave needs INIT",
    0x0022: "Slave needs PRE-OP",
    0x0023: "Slave needs SAFE-OP",
    0x0024: "Invalid input mapping",
    0x0025: "Invalid output mapping",
    0x0026: "Inconsistent settings",
    0x0027: "Free-run not supported",
    0x0028: "Synchronization not supported",
    0x0029: "Free-run needs 3-buffer mode",
    0x002A: "Background watchdog",
    0x002B: "No valid inputs and outputs",
    0x002C: "Fatal sync error",
    0x002D: "No sync error",
    0x002E: "Invalid input FMMU configuration",
    0x0030: "Invalid DC SYNC configuration",
    0x0031: "Invalid DC latch configuration",
    0x0032: "PLL error",
    0x0033: "DC sync IO error",
    0x0034: "DC sync timeout error",
    0x0035: "DC invalid sync cycle time",
    0x0036: "DC invalid SYNC0 cycle time",
    0x0037: "DC invalid SYNC1 cycle time",
    0x0041: "Mailbox AoE error",
    0x0042: "Mailbox EoE error",
    0x0043: "Mailbox CoE error",
    0x0044: "Mailbox FoE error",
    0x0045: "Mailbox SoE error",
    0x004F: "Mailbox VoE error",
    0x0050: "EEPROM no access",
    0x0051: "EEPROM error",
    0x0060: "Slave restarted locally",
    0x0061: "Device identification value updated",
    0x00F0: "Application controller available",
}
# The AL status codes an AKD reports (SPEC-NOTES 22).
AKD_AL_STATUS_CODES: tuple[int, ...] = (0x0000, 0x0011, 0x0017)


def al_status_text(code: int) -> str:
    """Text for an AL status code (register 0x0134); vendor range 0x8000+ named as such."""
    try:
        code = int(code)
    except (TypeError, ValueError):
        return f"unknown AL status code {code!r}"
    text = AL_STATUS_CODE_TEXTS.get(code)
    if text is not None:
        return text
    if 0x8000 <= code <= 0xFFFF:
        return f"vendor-specific AL status code 0x{code:04X}"
    return f"unknown AL status code 0x{code & 0xFFFF:04X}"


# --- EtherCAT cycle time (0x60C2; EtherCAT manual 5.9/5.10, profiles/units.cycle_time_problem) ---------------
CYCLE_TIME_TEXTS: dict[str, str] = {
    "too-short": "below the AKD's minimum cycle time of 250 us (EtherCAT manual 5.10)",
    "off-grid": "not a multiple of 62.5 us, the step FBUS.SAMPLEPERIOD counts in (EtherCAT manual 5.9)",
}


def cycle_time_text(problem: str, units: int, exponent: int) -> str:
    """'cycle time 3 x 10^-4 s is not a multiple of 62.5 us ...' for a cycle_time_problem result."""
    return f"cycle time {units} x 10^{exponent} s is {CYCLE_TIME_TEXTS.get(problem, problem)}"


# --- CiA 301 error register 0x1001 -------------------------------------------------------

ERROR_REGISTER_BITS: dict[int, str] = {
    0: "generic error",
    1: "current",
    2: "voltage",
    3: "temperature",
    4: "communication error (overrun, error state)",
    5: "device profile specific",
    6: "reserved",
    7: "manufacturer specific",
}


def error_register_text(value: int) -> str:
    """The set bits of an error register in words ('no error' for 0)."""
    try:
        value = int(value) & 0xFF
    except (TypeError, ValueError):
        return f"malformed error register {value!r}"
    if value == 0:
        return "no error"
    return ", ".join(text for bit, text in ERROR_REGISTER_BITS.items() if value & (1 << bit))


# --- EtherCAT mailbox error replies (ETG.1000.6, mailbox type 0) ------------------------

MAILBOX_ERROR_TEXTS: dict[int, str] = {
    0x0001: "Syntax of the 6-byte mailbox header is wrong",
    0x0002: "Mailbox protocol not supported",
    0x0003: "Channel field contains a wrong value",
    0x0004: "Mailbox service not supported",
    0x0005: "Invalid mailbox header",
    0x0006: "Length of received mailbox data is too short",
    0x0007: "No more memory in the slave",
    0x0008: "Length of data is inconsistent",
}


def mailbox_error_text(code: int) -> str:
    try:
        code = int(code)
    except (TypeError, ValueError):
        return f"unknown mailbox error {code!r}"
    text = MAILBOX_ERROR_TEXTS.get(code)
    if text is not None:
        return text
    return f"unknown mailbox error 0x{code & 0xFFFF:04X}"


# --- FoE error codes (ETG.1000.6, File access over EtherCAT) -----------------------------

FOE_ERROR_TEXTS: dict[int, str] = {
    0x8000: "Not defined",
    0x8001: "Not found",
    0x8002: "Access denied",
    0x8003: "Disk full",
    0x8004: "Illegal",
    0x8005: "Packet number wrong",
    0x8006: "Already exists",
    0x8007: "No user",
    0x8008: "Bootstrap only",
    0x8009: "Not in bootstrap",
    0x800A: "No rights",
    0x800B: "Program error",
}


def foe_error_text(code: int) -> str:
    try:
        code = int(code)
    except (TypeError, ValueError):
        return f"unknown FoE error {code!r}"
    return FOE_ERROR_TEXTS.get(code, f"FoE error 0x{code:04X}")


# --- CIP general status (CIP Vol. 1 appendix B) and EtherNet/IP ------------------------
# Codes 0x0B-0x20 with the AKD EtherNet/IP manual's own names (seed 002, p. 16, error codes of
# I/O response type 0x14, additional code 0xFF); the rest as CIP Vol. 1 names them.

CIP_STATUS_TEXTS: dict[int, str] = {
    0x00: "success",
    0x01: "connection failure",
    0x02: "resource unavailable",
    0x03: "invalid parameter value",
    0x04: "path segment error",
    0x05: "path destination unknown (class or instance does not exist)",
    0x06: "partial transfer",
    0x07: "connection lost",
    0x08: "service not supported",
    0x09: "invalid attribute value (value out of range)",
    0x0A: "attribute list error",
    0x0B: "already in requested mode/state (ALREADY_IN_STATE)",
    0x0C: "object state conflict (OBJ_STATE_CONFLICT)",
    0x0D: "object already exists (OBJECT_ALREADY_EXISTS)",
    0x0E: "attribute not settable (ATTRIBUTE_NOT_SETTABLE)",
    0x0F: "privilege violation (ACCESS_DENIED)",
    0x10: "device state conflict (DEVICE_STATE_CONFLICT)",
    0x11: "reply data too large (REPLY_DATA_TOO_LARGE)",
    0x12: "fragmentation of a primitive value",
    0x13: "not enough data (NOT_ENOUGH_DATA)",
    0x14: "attribute not supported (ATTRIBUTE_NOT_SUPP)",
    0x15: "too much data (TOO_MUCH_DATA)",
    0x16: "object does not exist (OBJECT_DOES_NOT_EXIST; the AKD manual: class not supported)",
    0x17: "service fragmentation sequence not in progress (FRAGMENTATION_SEQ_ERR)",
    0x18: "no stored attribute data",
    0x19: "store operation failure",
    0x1A: "routing failure, request packet too large",
    0x1B: "routing failure, response packet too large",
    0x1C: "missing attribute list entry data",
    0x1D: "invalid attribute value list",
    0x1E: "embedded service error",
    0x1F: "vendor specific error",
    0x20: "invalid parameter (INVALID_PARAMETER)",
    0x21: "write-once value or medium already written",
    0x22: "invalid reply received",
    0x25: "key failure in path",
    0x26: "path size invalid",
    0x27: "unexpected attribute in list",
    0x28: "invalid member ID",
    0x29: "member not settable",
}

# Connection Manager extended status (general status 0x01), CIP Vol. 1 table 3-5.29.
CIP_CM_EXTENDED_TEXTS: dict[int, str] = {
    0x0100: "connection in use or duplicate Forward_Open",
    0x0103: "transport class and trigger combination not supported",
    0x0106: "ownership conflict (another scanner owns the connection)",
    0x0107: "target connection not found",
    0x0108: "invalid network connection parameter",
    0x0109: "invalid connection size",
    0x0110: "target for connection not configured",
    0x0111: "RPI not supported",
    0x0113: "out of connections",
    0x0114: "vendor ID or product code mismatch",
    0x0115: "device type mismatch",
    0x0116: "revision mismatch",
    0x0117: "invalid produced or consumed application path",
    0x0118: "invalid or inconsistent configuration application path",
    0x0127: "invalid O->T connection size",
    0x0128: "invalid T->O connection size",
    0x0129: "invalid configuration application path",
    0x012A: "invalid consuming application path",
    0x012B: "invalid producing application path",
    0x0203: "connection timed out",
    0x0204: "unconnected request timed out",
    0x0315: "invalid segment in connection path",
}

# EtherNet/IP encapsulation status (CIP Vol. 2 table 2-3.3).
ENIP_STATUS_TEXTS: dict[int, str] = {
    0x0000: "success",
    0x0001: "invalid or unsupported encapsulation command",
    0x0002: "insufficient memory in the target",
    0x0003: "poorly formed or incorrect data",
    0x0064: "invalid session handle",
    0x0065: "invalid length",
    0x0069: "unsupported encapsulation protocol revision",
}


def cip_status_text(status: int, extended: tuple[int, ...] | list[int] = ()) -> str:
    """Words for a CIP general status with its additional status; unknown codes name themselves."""
    text = CIP_STATUS_TEXTS.get(status, f"unknown CIP general status 0x{status:02X}")
    if status == 0x01 and extended:
        ext = extended[0]
        text += f": {CIP_CM_EXTENDED_TEXTS.get(ext, f'extended status 0x{ext:04X}')}"
    elif extended:
        text += " (additional status " + " ".join(f"0x{w:04X}" for w in extended) + ")"
    return f"{text} (0x{status:02X})"


def enip_status_text(status: int) -> str:
    return ENIP_STATUS_TEXTS.get(status, f"unknown encapsulation status 0x{status:08X}") + f" (0x{status:04X})"


# CIP vendor IDs an AKD may report (pycomm3 1.2.16 cip/status_info.py; reference/ethernetip.md 1.2).
CIP_VENDORS: dict[int, str] = {1: "Rockwell Automation/Allen-Bradley", 103: "Pacific Scientific (API Controls Inc.)",
                               452: "Kollmorgen", 503: "Danaher Controls"}


def cip_vendor_name(vendor: int) -> str:
    return CIP_VENDORS.get(vendor, f"vendor {vendor}")


# CANopen/EtherCAT vendor IDs (0x1018:1): the AKD ESI names 0x6A "Kollmorgen" (reference/akd_esi_notes.md).
CANOPEN_VENDORS: dict[int, str] = {0x6A: "Kollmorgen"}
# PROFINET (PI) vendor IDs (PNU 964[0], 975[0], DCP, I&M0): 0x0100 is what the simulator and the project's example
# recipe give the AKD; inferred, not verified against PI's vendor list.
PI_VENDORS: dict[int, str] = {0x0100: "Kollmorgen"}


# FoE error codes beyond ETG.1000.6's first table, from newer Beckhoff SSC versions (reference
# foe-alias-recorder.md A1: 0x800C..0x8010; 0x800F is "no file", the same meaning as 0x8001).
FOE_ERROR_TEXTS.update({
    0x800C: "Invalid checksum",
    0x800D: "Invalid firmware (the hardware does not support it)",
    0x800F: "No file",
    0x8010: "File header missing",
})
