"""Faults over ``eip://``: what an AKD offers to explicit messaging, read and named, and what it does not offer.

Why a module of its own: an EtherNet/IP target has neither the PROFIdrive fault buffer (PNU 947) nor the CoE
objects (0x1001, 0x2001 ...), so :func:`akdctl.drive.faults.dump` has nothing to read there. What the AKD does
expose over CIP (reference/ethernetip.md 1.8, 1.9):

* Position Controller Supervisor 0x24, instance 1, attribute 5 "General Fault" (BOOL) - [I]: there is no public
  AKD table for 0x24; the attribute comes from the ODVA profile as Moog and Yaskawa implement it;
* DRV.FAULT1 through the Parameter object 0x0F, instance 478 - [I]: 478 is DRV.FAULT1's id in the EIP.RSPMAP
  table [M-34] and "looks like" its Parameter-object instance; no source states it. A drive that answers
  "object does not exist" there is reported as such, never guessed around. DRV.FAULT2.. and DRV.WARNING1.. have
  no known instance: they are listed as not offered;
* the homed state and warnings: only in the class-1 I/O response assembly (status word 1 "Homed", motion status
  "home finished"), which akdctl does not open for a read (it would take the I/O connection from the PLC).

Every [I] source is named as such in the dump (``sources``), so a reader knows which facts are inferred.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akdctl.errors import CipRefused, CommError, MalformedReply

if TYPE_CHECKING:
    from akdctl.connection import Connection

SUPERVISOR = 0x24
PARAMETER = 0x0F
#: Parameter-object instance of DRV.FAULT1 [I] (see the module's docstring).
FAULT1_INSTANCE = 478
#: CIP general statuses meaning "this drive has no such thing" (not a failure of the request).
_ABSENT = (0x05, 0x08, 0x14, 0x16)

SOURCES = {
    "general_fault": "0x24/1/5 General Fault [I: ODVA profile as Moog/Yaskawa implement it; no public AKD table]",
    "fault1": f"DRV.FAULT1 = Parameter object 0x0F/{FAULT1_INSTANCE}/1 [I: its EIP.RSPMAP id, M-34]",
}
NOT_OFFERED = {
    "fault history": "the AKD keeps no fault history readable over CIP explicit messaging",
    "DRV.FAULT2..10, DRV.WARNING1..3": "no cited Parameter-object instance (a guess would read another parameter)",
    "homed, warnings": "only in the class-1 I/O response assembly (status word 1, motion status), which belongs to "
                       "the PLC's I/O connection; akdctl does not open it for a read",
    "acknowledge": "DRV.CLRFAULTS has no cited Parameter-object instance: acknowledge from the PLC, WorkBench or a "
                   "fieldbus with a fault-reset bit",
}


def _absent(exc: CipRefused) -> bool:
    return getattr(exc, "code", None) in _ABSENT


def _fault_entry(number: int) -> dict[str, Any]:
    from akdctl.catalog import faults as catalog

    fault = catalog.by_number(number)
    return {"number": number, "code": fault.code if fault else f"F{number}",
            "name": fault.name if fault else "not in the AKD fault table",
            "kind": fault.kind if fault else "fault"}


def read(conn: Connection) -> dict[str, Any]:
    """The ``eip`` view of a fault dump: general fault, DRV.FAULT1 and what the target does not offer."""
    channel = conn.cip()
    out: dict[str, Any] = {"fault_present": None, "warning_present": None, "active": [], "sources": {},
                           "not_offered": dict(NOT_OFFERED), "errors": {}}
    try:
        raw = channel.get(SUPERVISOR, 1, 5)
        out["fault_present"] = bool(raw[:1] and raw[0])
        out["sources"]["general_fault"] = SOURCES["general_fault"]
    except CommError:
        raise
    except CipRefused as exc:
        out["errors"]["general_fault"] = exc.message if not _absent(exc) else "not offered by this drive"
    try:
        raw = channel.get(PARAMETER, FAULT1_INSTANCE, 1)
        if not 1 <= len(raw) <= 4:
            raise MalformedReply(f"DRV.FAULT1 (0x0F/{FAULT1_INSTANCE}/1) answered {len(raw)} bytes")
        number = int.from_bytes(raw, "little")
        out["sources"]["fault1"] = SOURCES["fault1"]
        out["fault1"] = number
        if number:
            out["active"].append(_fault_entry(number))
            if out["fault_present"] is None:
                out["fault_present"] = True
    except CommError:
        raise
    except CipRefused as exc:
        out["errors"]["fault1"] = (exc.message if not _absent(exc)
                                   else f"DRV.FAULT1 is not at Parameter-object instance {FAULT1_INSTANCE} on this "
                                        "drive (that instance was inferred)")
    except MalformedReply as exc:
        out["errors"]["fault1"] = exc.message
    if out["fault_present"] and not out["active"]:
        out["active"].append({"number": None, "code": None, "name": "a fault is present (its number is not readable "
                              "over this transport)", "kind": "fault"})
    return out


def dump(conn: Connection) -> dict[str, Any]:
    """The fault dump document of an ``eip://`` target (same top-level shape as :func:`drive.faults.dump`)."""
    return {"target": conn.target.display, "eip": read(conn)}
