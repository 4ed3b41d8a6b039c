"""Reading a drive's faults completely, consistently and decoded, over PNUs or objects.

Why this module: a support engineer gets one dump from the field and has to
trust it. So:

* **PROFIdrive** (manual 5.14, SPEC-NOTES 14): read PNU 944 (with ZSW1), then
  the whole fault buffer PNU 947, then PNU 944 again; if the counter moved, a
  new fault situation arrived mid-read and the read is repeated (bounded).
  Situation 0 = active faults, situations 1..7 = acknowledged, newest first.
* **CiA 301 / CoE / CANopen** (SPEC-NOTES 21): 0x1001 error register, 0x1003
  pre-defined error field (EMCY codes → AKD F/n numbers through the fault
  table), 0x2001/0x2000 the AKD's current faults and warnings, 0x2012/0x2013
  its fault history with time stamps, the statusword, and the emergencies the
  object channel received. There is no counter, so the dump re-reads the
  newest entries at the end and repeats when they changed.

Every number is decoded through :mod:`akdctl.catalog.faults`; a number the
table does not know is reported as unknown, never an error. A section the
drive refuses (an SDO abort, a negative PNU response) is recorded in the dump
with the drive's words; only a broken link raises.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from akdctl.catalog import faults as catalog
from akdctl.errors import AkdError, CommError, DriveFault, UsageError
from akdctl.profiles.statusword import SW_FAULT, SW_WARNING, ZSW1_FAULT, ZSW1_WARNING

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel
    from akdctl.channels.base import ParameterChannel
    from akdctl.connection import Connection
    from akdctl.drive.operation import WritePlan

MAX_ATTEMPTS = 5  # consistent-read attempts before reporting an inconsistent dump
PNU_FAULT_COUNTER = 944
PNU_FAULT_BUFFER = 947
PNU_ZSW1 = 2
SITUATION_SIZE = 8


# ---------------------------------------------------------------------------- decoding
@dataclass(frozen=True)
class FaultEntry:
    """One decoded fault/warning number as it appears in a buffer or history."""

    number: int
    code: str
    name: str
    kind: str  # "fault", "warning" or "unknown"
    emcy: int | None = None
    time: int | None = None  # history time stamp (drive seconds), where the source has one

    @property
    def known(self) -> bool:
        return self.kind != "unknown"

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {"number": self.number, "code": self.code, "name": self.name, "kind": self.kind}
        if self.emcy is not None:
            data["emcy"] = f"0x{self.emcy:04X}"
        if self.time is not None:
            data["time"] = self.time
        return data

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> "FaultEntry":
        emcy = data.get("emcy")
        return cls(int(data["number"]), str(data["code"]), str(data["name"]), str(data["kind"]),
                   int(emcy, 16) if isinstance(emcy, str) else emcy, data.get("time"))


def decode_number(number: int, *, warning: bool = False, time: int | None = None) -> FaultEntry:
    """A bare AKD number (PNU 947, 0x2001, 0x2012; 0x2000 with ``warning``) → entry; unknown stays visible."""
    fault = catalog.by_number(number, warning=warning)
    if fault is None:
        prefix = "n" if warning else "F"
        what = "warning" if warning else "fault"
        return FaultEntry(number, f"{prefix}{number}?", f"unknown {what} {number} (not in the AKD table)", "unknown",
                          None, time)
    return FaultEntry(number, fault.code, fault.name, fault.kind, fault.emcy, time)


def decode_error_field(value: int) -> dict[str, Any]:
    """One 0x1003 entry: EMCY code (low 16 bits) and manufacturer info (high 16 bits) → candidates.

    Several AKD faults share an EMCY code; when the upper half carries one of their
    numbers (the simulator puts it there; real AKD contents are not verified) the
    match is narrowed to that fault.
    """
    code, extra = value & 0xFFFF, (value >> 16) & 0xFFFF
    candidates = catalog.by_emcy(code)
    narrowed = [f for f in candidates if f.number is not None and f.number == extra]
    chosen = narrowed or candidates
    return {
        "raw": f"0x{value:08X}",
        "emcy": f"0x{code:04X}",
        "additional": extra,
        "faults": [f.code or "-" for f in chosen],
        "text": "; ".join(f.describe() for f in chosen) if chosen else f"unknown emergency 0x{code:04X}",
        "known": bool(chosen),
    }


def decode_emergency(emcy: Any) -> dict[str, Any]:
    """An :class:`~akdctl.protocol.emcy.Emergency` received on the link, in words."""
    from akdctl.catalog.texts import error_register_text

    data = bytes(emcy.data)
    number = struct.unpack_from("<H", data)[0] if len(data) >= 2 else 0
    candidates = catalog.by_emcy(emcy.error_code)
    narrowed = [f for f in candidates if f.number == number] or candidates
    return {
        "emcy": f"0x{emcy.error_code:04X}",
        "register": emcy.error_register,
        "register_text": error_register_text(emcy.error_register),
        "data": data.hex(),
        "faults": [f.code or "-" for f in narrowed],
        "text": catalog.emcy_text(emcy.error_code) if emcy.error_code == 0 or not narrowed
        else "; ".join(f.describe() for f in narrowed),
    }


# ---------------------------------------------------------------------------- PROFIdrive
@dataclass
class ProfidriveFaults:
    """The PROFIdrive view: counter, active situation, acknowledged situations, ZSW1 bits."""

    counter: int
    active: list[FaultEntry]
    acknowledged: list[dict[str, Any]]  # {"situation": k, "faults": [FaultEntry]}
    zsw1: int | None
    attempts: int
    consistent: bool
    raw: list[int] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {
            "fault_message_counter": self.counter,
            "consistent": self.consistent,
            "attempts": self.attempts,
            "zsw1": self.zsw1,
            "fault_present": bool(self.zsw1 & ZSW1_FAULT) if self.zsw1 is not None else bool(self.active),
            "warning_present": bool(self.zsw1 & ZSW1_WARNING) if self.zsw1 is not None else None,
            "active": [e.to_json() for e in self.active],
            "acknowledged": [{"situation": s["situation"], "faults": [e.to_json() for e in s["faults"]]}
                             for s in self.acknowledged],
            "buffer": self.raw,
        }


def split_buffer(values: list[int]) -> tuple[list[FaultEntry], list[dict[str, Any]]]:
    """PNU 947 elements → (active faults, acknowledged situations newest first); zeros are empty slots."""
    situations = [values[i : i + SITUATION_SIZE] for i in range(0, len(values), SITUATION_SIZE)]
    active: list[FaultEntry] = []
    acknowledged: list[dict[str, Any]] = []
    for index, numbers in enumerate(situations):
        entries = [decode_number(n) for n in numbers if n]
        if index == 0:
            active = entries
        elif entries:
            acknowledged.append({"situation": index, "faults": entries})
    return active, acknowledged


def _read_one(channel: "ParameterChannel", specs: list[Any]) -> list[Any]:
    from akdctl.drive.values import pnu_refused, read_pnus

    readings = read_pnus(channel, specs)
    for reading in readings:
        if not reading.ok and reading.spec.pnu != PNU_ZSW1:
            raise pnu_refused(reading, "read")
    return readings


def read_profidrive_faults(channel: "ParameterChannel", *, max_attempts: int = MAX_ATTEMPTS) -> ProfidriveFaults:
    """944 (+ ZSW1), 947, 944 again; repeat while the counter moved (at most ``max_attempts`` times)."""
    from akdctl.drive.values import pnu_spec

    counter_spec, zsw1_spec, buffer_spec = pnu_spec(PNU_FAULT_COUNTER), pnu_spec(PNU_ZSW1), pnu_spec(PNU_FAULT_BUFFER)
    attempt = 0
    while True:
        attempt += 1
        before, zsw1 = _read_one(channel, [counter_spec, zsw1_spec])
        (buffer,) = _read_one(channel, [buffer_spec])
        (after,) = _read_one(channel, [counter_spec])
        consistent = before.values == after.values
        if consistent or attempt >= max_attempts:
            break
    values = [int(v) for v in (buffer.values or [])]
    active, acknowledged = split_buffer(values)
    return ProfidriveFaults(
        counter=int((after.values or [0])[0]),
        active=active,
        acknowledged=acknowledged,
        zsw1=int(zsw1.values[0]) if zsw1.ok and zsw1.values else None,
        attempts=attempt,
        consistent=consistent,
        raw=values,
    )


# ---------------------------------------------------------------------------- CiA 301 / AKD objects
@dataclass
class CanopenFaults:
    """The object view: error register, error field, current faults/warnings, history, emergencies."""

    error_register: int | None = None
    error_field: list[dict[str, Any]] = field(default_factory=list)
    faults: list[FaultEntry] = field(default_factory=list)
    warnings: list[FaultEntry] = field(default_factory=list)
    history: list[FaultEntry] = field(default_factory=list)
    statusword: int | None = None
    emergencies: list[dict[str, Any]] = field(default_factory=list)
    errors: dict[str, str] = field(default_factory=dict)  # section -> the drive's refusal
    attempts: int = 1
    consistent: bool = True

    def to_json(self) -> dict[str, Any]:
        from akdctl.catalog.texts import error_register_text

        return {
            "error_register": self.error_register,
            "error_register_text": error_register_text(self.error_register) if self.error_register is not None
            else None,
            "statusword": self.statusword,
            "fault_present": bool(self.statusword & SW_FAULT) if self.statusword is not None else bool(self.faults),
            "warning_present": bool(self.statusword & SW_WARNING) if self.statusword is not None
            else bool(self.warnings),
            "faults": [e.to_json() for e in self.faults],
            "warnings": [e.to_json() for e in self.warnings],
            "error_history": self.error_field,
            "fault_history": [e.to_json() for e in self.history],
            "emergencies": self.emergencies,
            "consistent": self.consistent,
            "attempts": self.attempts,
            "errors": self.errors,
        }


def _upload_int(channel: "ObjectChannel", index: int, sub: int) -> int:
    """One integer object, typed by the catalogue (drive/values.py)."""
    from akdctl.drive.values import read_object

    return int(read_object(channel, index, sub))


def _section(result: CanopenFaults, name: str, func: Any) -> Any:
    """Run one section; a drive refusal is recorded, a link failure propagates."""
    try:
        return func()
    except CommError:
        raise
    except AkdError as exc:
        result.errors[name] = exc.message
        return None


def _read_list(channel: "ObjectChannel", index: int, limit: int, *, stop_at_zero: bool) -> list[int]:
    """Sub 1..n of an array object; n from sub 0 (bounded by ``limit``); optionally stop at the first 0."""
    count = min(_upload_int(channel, index, 0), limit)
    values = []
    for sub in range(1, count + 1):
        value = _upload_int(channel, index, sub)
        if value == 0 and stop_at_zero:
            break
        values.append(value)
    return values


def _marker(channel: "ObjectChannel") -> tuple[Any, ...]:
    """What changes whenever a new fault or emergency is recorded (newest entries and counts)."""
    out: list[Any] = []
    for index, sub in ((0x1003, 0), (0x1003, 1), (0x2012, 1), (0x2013, 1)):
        try:
            out.append(_upload_int(channel, index, sub))
        except CommError:
            raise
        except AkdError:
            out.append(None)
    return tuple(out)


def _read_canopen_once(channel: "ObjectChannel") -> CanopenFaults:
    result = CanopenFaults()
    result.error_register = _section(result, "0x1001", lambda: _upload_int(channel, 0x1001, 0))
    result.statusword = _section(result, "0x6041", lambda: _upload_int(channel, 0x6041, 0))
    field_values = _section(result, "0x1003", lambda: _read_list(channel, 0x1003, 254, stop_at_zero=False))
    result.error_field = [decode_error_field(v) for v in field_values or []]
    faults = _section(result, "0x2001", lambda: _read_list(channel, 0x2001, 32, stop_at_zero=False))
    result.faults = [decode_number(n) for n in faults or [] if n]
    warnings = _section(result, "0x2000", lambda: _read_list(channel, 0x2000, 32, stop_at_zero=False))
    result.warnings = [decode_number(n, warning=True) for n in warnings or [] if n]
    numbers = _section(result, "0x2012", lambda: _read_list(channel, 0x2012, 254, stop_at_zero=True)) or []
    times: list[int] = []
    if numbers:
        times = _section(result, "0x2013", lambda: [_upload_int(channel, 0x2013, s)
                                                    for s in range(1, len(numbers) + 1)]) or []
    result.history = [decode_number(n, time=times[i] if i < len(times) else None) for i, n in enumerate(numbers)]
    return result


def read_canopen_faults(channel: "ObjectChannel", *, max_attempts: int = MAX_ATTEMPTS) -> CanopenFaults:
    """Read every fault object; repeat while the newest entries changed during the read (bounded)."""
    attempt = 0
    while True:
        attempt += 1
        before = _marker(channel)
        result = _read_canopen_once(channel)
        after = _marker(channel)
        if before == after or attempt >= max_attempts:
            break
    result.attempts = attempt
    result.consistent = before == after
    result.emergencies = [decode_emergency(e) for e in channel.take_emergencies()]
    return result


# ---------------------------------------------------------------------------- whole dump
def _sources(conn: "Connection") -> list[str]:
    """Which views to read: the one ``?drive=``/profile selects, else every channel the target offers."""
    if conn.has_commands:
        return ["akd"]  # the AKD's own DRV.FAULTS / DRV.WARNINGS (issue 24, read_akd_faults)
    if conn.has_registers:
        return ["modbus"]  # DRV.FAULT1 by its register (issue 24, read_modbus_faults)
    has_pnu, has_obj = conn.has_parameters, conn.has_objects
    chosen = conn.drive_profile
    if chosen == "profidrive" and has_pnu:
        return ["profidrive"]
    if chosen == "cia402" and has_obj:
        return ["canopen"]
    return [name for name, ok in (("profidrive", has_pnu), ("canopen", has_obj)) if ok]


def dump(conn: "Connection") -> dict[str, Any]:
    """The whole fault dump of the target as JSON-able data (the ``fault dump`` document)."""
    data: dict[str, Any] = {"target": conn.target.display}
    sources = _sources(conn)
    if not sources:
        raise UsageError(f"target {conn.target.display} offers neither PNU nor object access; no fault dump possible")
    for source in sources:
        try:
            if source == "akd":
                data["akd"] = read_akd_faults(conn)
            elif source == "modbus":
                data["modbus"] = read_modbus_faults(conn)
            elif source == "profidrive":
                data["profidrive"] = read_profidrive_faults(conn.parameters()).to_json()
            else:
                data["canopen"] = read_canopen_faults(conn.objects()).to_json()
        except CommError:
            raise
        except AkdError as exc:
            data[source] = {"error": exc.message}
    return data


def summary(data: dict[str, Any]) -> dict[str, Any]:
    """Active faults/warnings of a dump, merged over its views (for status lines and exit decisions)."""
    codes: list[str] = []
    warnings: list[str] = []
    pd, co = data.get("profidrive") or {}, data.get("canopen") or data.get("akd") or data.get("modbus") or {}
    for entry in pd.get("active", []) + co.get("faults", []):
        if entry["code"] not in codes:
            codes.append(entry["code"])
    for entry in co.get("warnings", []):
        if entry["code"] not in warnings:
            warnings.append(entry["code"])
    fault_present = any(v.get("fault_present") for v in (pd, co) if v and "error" not in v)
    warning_present = any(v.get("warning_present") for v in (pd, co) if v and "error" not in v)
    return {"faults": codes, "warnings": warnings, "fault_present": fault_present or bool(codes),
            "warning_present": bool(warning_present) or bool(warnings)}


# ---------------------------------------------------------------------------- acknowledge / clear
def _ack_path(conn: "Connection") -> str:
    sources = _sources(conn)
    if not sources:
        raise UsageError(f"target {conn.target.display} offers neither PNU nor object access")
    return sources[0]


def acknowledge(conn: "Connection") -> dict[str, Any]:
    """Acknowledge the drive's faults; raise :class:`DriveFault` if a fault remains active.

    The edge itself is the motion layer's ``Axis.acknowledge_faults`` (one implementation
    for every command); this adds the before/after dumps so the user sees what was cleared.
    """
    path = _ack_path(conn)
    before = dump(conn)
    active_before = summary(before)["faults"]
    if not summary(before)["fault_present"]:
        return {"target": conn.target.display, "acknowledged": [], "still_active": [], "fault_present": False,
                "via": path, "note": "no active fault: nothing was written"}
    conn.axis().acknowledge_faults()  # the one acknowledge (STW1 / controlword bit 7 edge)
    after = dump(conn)
    remaining = summary(after)["faults"]
    result = {"target": conn.target.display, "acknowledged": active_before, "still_active": remaining,
              "fault_present": summary(after)["fault_present"], "via": path}
    if summary(after)["fault_present"]:
        exc = DriveFault(
            f"fault still active after acknowledge: {', '.join(remaining) or 'see fault dump'} "
            "(its cause persists; remove it, then acknowledge again)",
            details=result,
        )
        raise exc
    return result


def plan_clear_history(conn: "Connection") -> "WritePlan":
    """``fault clear-history`` as a plan: 0x1003:0 = 0 (CiA 301: writing 0 to sub-index 0 empties the predefined
    error field); never gated, it powers nothing. PROFIdrive offers no way to clear PNU 947: refused (exit 2)."""
    from akdctl.drive.operation import PlannedWrite, WritePlan

    if not conn.has_objects or conn.drive_profile == "profidrive":
        raise UsageError(
            f"target {conn.target.display}: the PROFIdrive fault buffer (PNU 947) cannot be cleared over the "
            "parameter channel; acknowledged situations drop out after 8 new ones"
        )
    return WritePlan("fault clear-history", conn.target.display,
                     [PlannedWrite("0x1003:0 (error history, number of errors)", b"\x00", "0 (clear)")],
                     notes=["only 0x1003 is written; the AKD's fault history (0x2012/0x2013) is not touched"],
                     enabled=None, verify=True)


def clear_history(conn: "Connection", plan: "WritePlan") -> dict[str, Any]:
    """Run :func:`plan_clear_history`'s write, then read how many entries are left."""
    conn.objects().download(0x1003, 0, plan.writes[0].raw)
    remaining = _upload_int(conn.objects(), 0x1003, 0)
    return {"target": conn.target.display, "cleared": "0x1003", "entries_left": remaining}


def read_akd_faults(conn: "Connection") -> dict[str, Any]:
    """Active faults and warnings over the AKD's command channel (``DRV.FAULTS``/``DRV.WARNINGS`` lines
    ``<number>: <text>.``; "No faults active" when none), decoded by the one fault table (issue 24)."""
    from akdctl.drive.axis.akd_ascii import _numbers

    link = conn.commands()
    faults = [decode_number(n).to_json() for n in _numbers(link.command("DRV.FAULTS"))]
    try:
        warnings = [decode_number(n, warning=True).to_json() for n in _numbers(link.command("DRV.WARNINGS"))]
    except AkdError:
        warnings = []
    return {"faults": faults, "warnings": warnings, "fault_present": bool(faults), "warning_present": bool(warnings)}


def read_modbus_faults(conn: "Connection") -> dict[str, Any]:
    """The first active fault over Modbus: DRV.FAULT1 (n 478, register 954 [V]); the other slots and the warnings
    have no published register, so the dump says so (issue 24)."""
    from akdctl.drive import names

    number = int(names.read(conn, names.resolve("DRV.FAULT1")).value)
    faults = [decode_number(number).to_json()] if number else []
    return {"faults": faults, "warnings": [], "fault_present": bool(faults), "warning_present": False,
            "note": "only DRV.FAULT1 has a published Modbus register; more faults may be active"}


# ---------------------------------------------------------------------------- acknowledge as a write plan
#: What an acknowledge writes on each path: the profile's one fault-reset edge (Axis.acknowledge_faults).
_ACK_WRITES = {
    "profidrive": ("PNU 1 (STW1)", "bit 7 (fault acknowledge) low, high, low: one rising edge, power bits off "
                                   "(SPEC-NOTES 7)"),
    "canopen": ("0x6040:0 (Controlword)", "0x0000, 0x0080 (fault reset), 0x0000: one rising edge of bit 7"),
}


class AckRequest:
    """``fault ack``: nothing to choose; the target and its profile decide the path."""

    __slots__ = ()


def plan(conn: "Connection", request: AckRequest | None = None) -> "WritePlan":
    """Reads the fault state; the acknowledge edge is the plan's one write (none when no fault is active).

    The write carries no gate verdict on purpose: an acknowledge only takes power away (README "Safety
    model"; akdctl/drive/gate.py), so it never asks for consent nor waits for the axis's owner.
    """
    from akdctl.drive.operation import PlannedWrite, WritePlan

    path = _ack_path(conn)
    active = summary(dump(conn))
    address, display = _ACK_WRITES.get(path, (path, "fault reset"))
    writes = [PlannedWrite(address, None, display)] if active["fault_present"] else []
    notes = [f"active: {', '.join(active['faults']) or 'a fault (see fault dump)'}" if active["fault_present"]
             else "no active fault: nothing to acknowledge"]
    return WritePlan("fault ack", conn.target.display, writes, notes=notes,
                     data={"path": path, "active": active["faults"]})


def execute(conn: "Connection", plan: "WritePlan") -> dict[str, Any]:
    """Send the acknowledge edge (when the plan has it) and read the faults again (DriveFault if one stays)."""
    if not plan.writes:
        return {"target": conn.target.display, "acknowledged": [], "still_active": [], "fault_present": False,
                "via": plan.data["path"], "note": "no active fault: nothing was written"}
    return acknowledge(conn)
