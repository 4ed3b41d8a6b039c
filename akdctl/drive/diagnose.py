"""Why won't it enable, why did it stop: every cause the drive exposes on the transport at hand, ranked.

Why one module: the answer lives in many places (the axis status and its faults and warnings, DRV.DISSOURCES as
CoE 0x3443, the EtherCAT AL state, the cycle time 0x60C2 against the mapping, the operation mode, the limit switch
inputs 0x60FD, the homed bit), each readable only on some transports. :func:`diagnose` reads what the target
offers, records what it could not read (a cause it cannot see is not a cause it can rule out), and names each
finding in words with its remedy, most likely first. Only reads: nothing is written.

Sources: DISSOURCES bits from reference/akd-ascii-channel.md ([G1] bits 0-5, [A1] bits 6-10: the AKD-C and
fieldbus bits come from a third-party tool's table, not a Kollmorgen manual); STO as fault F602 / warning n602
(catalog/data/faults.csv); SPEC-NOTES 23 (an SDO controlword has no effect while 0x6040 is mapped in OP);
0x60FD bits 0/1 negative/positive limit switch (CiA 402).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akdctl.errors import AkdError, CommError

if TYPE_CHECKING:
    from akdctl.connection import Connection

#: DRV.DISSOURCES bit -> (what, remedy, blocking). Bit 0 is the ordinary "disabled by software" state.
DISSOURCES: dict[int, tuple[str, str, bool]] = {
    0: ("software disable (DRV.DIS, or the fieldbus has not enabled the drive)",
        "enable it: akdctl enable (or the PLC's enable sequence)", False),
    1: ("a fault disables the drive", "remove the fault's cause, then akdctl fault ack", True),
    2: ("hardware enable input is low",
        "apply the hardware enable signal (the digital input the drive uses as enable) and check its wiring", True),
    3: ("in-rush relay not closed (DC bus not charged)", "check the mains supply and the bus voltage", True),
    4: ("the drive is still initialising", "wait for the drive to finish booting, then try again", True),
    5: ("a controlled stop from a digital input is active", "release the controlled-stop input", True),
    6: ("the fieldbus requested the disable (SynqNet / EtherNet/IP)",
        "set the Enable bit in the PLC's command assembly or release the fieldbus' disable", True),
    7: ("AKD-C requested the disable", "see the AKD-C's state", True),
    8: ("AKD-C pre-charge not complete", "wait for the AKD-C pre-charge", True),
    9: ("an unknown disable source", "read DRV.DISSOURCES in WorkBench", True),
    10: ("AKD-C firmware download in progress", "wait until the download has ended", True),
}
#: CiA 402 0x60FD digital inputs: bit -> what.
LIMIT_BITS = {0: "negative limit switch active", 1: "positive limit switch active"}
#: Ranks: lower first. A fault outranks everything; a soft reason last.
RANK = {"fault": 10, "sto": 12, "dissource": 20, "al": 25, "controlword-pdo": 27, "cycle": 30, "mode": 35,
        "quick-stop": 38, "limit": 40, "homed": 50, "warning": 60, "disabled": 70}


class Finder:
    """Collects causes and what could not be read."""

    def __init__(self) -> None:
        self.causes: list[dict[str, Any]] = []
        self.unread: dict[str, str] = {}
        self.read: list[str] = []

    def add(self, kind: str, text: str, remedy: str, *, blocking: bool = True, evidence: str = "",
            rank: int | None = None) -> None:
        self.causes.append({"cause": kind, "blocking": blocking, "text": text, "remedy": remedy,
                            "evidence": evidence, "rank": RANK.get(kind, 90) if rank is None else rank})

    def attempt(self, name: str, func: Any) -> Any:
        """One source; a refusal or a missing channel is recorded, a silent drive ends everything (CommError)."""
        try:
            value = func()
        except CommError:
            raise
        except AkdError as exc:
            self.unread[name] = exc.message
            return None
        self.read.append(name)
        return value


def _fault_remedy(code: str) -> str:
    from akdctl.catalog import faults as catalog

    fault = catalog.by_code(code)
    if fault is None:
        return "see the drive's fault text (DRV.FAULTS), then akdctl fault ack"
    return (fault.remedy or catalog.where_to_look(fault)) + "; then akdctl fault ack"


def _status_causes(f: Finder, status: Any, want_mode: str | None) -> None:
    from akdctl.catalog import faults as catalog

    sto = False
    for item in status.faults:
        code = str(item.get("code") or item.get("number"))
        fault = catalog.by_code(code)
        if fault is not None and fault.number == 602:
            sto = True
            f.add("sto", "safe torque off (STO) input is low: F602", _fault_remedy(code), evidence=f"fault {code}")
        else:
            f.add("fault", f"fault {code} active: {item.get('text') or (fault.name if fault else '')}".strip(),
                  _fault_remedy(code), evidence=f"fault {code}")
    for item in status.warnings:
        code = str(item.get("code") or item.get("number"))
        fault = catalog.by_code(code)
        if fault is not None and fault.number == 602 and not sto:
            f.add("sto", "safe torque off (STO) input is low: warning n602 (the drive will not enable)",
                  "bring the STO input high (check the safety circuit) before enabling", evidence=f"warning {code}")
        else:
            f.add("warning", f"warning {code}: {item.get('text') or (fault.name if fault else '')}".strip(),
                  fault.remedy if fault is not None and fault.remedy else "see the warning's cause", blocking=False,
                  evidence=f"warning {code}")
    if status.fault and not status.faults:
        f.add("fault", "the drive reports a fault but names none here", "run akdctl fault dump, then akdctl fault ack",
              evidence=f"status word 0x{status.word:04X}")
    if "quick stop" in str(status.state_text).lower():
        f.add("quick-stop", "quick stop is active", "akdctl disable, then akdctl enable",
              evidence=str(status.state_text))
    if want_mode is not None and status.mode_text and want_mode.lower() not in str(status.mode_text).lower():
        f.add("mode", f"operation mode is {status.mode_text}, not {want_mode}",
              "select the mode the command needs (the motion commands switch it; a PLC sets it in its cycle)",
              evidence=f"mode {status.mode}")
    if status.homed is False:
        f.add("homed", "the axis is not homed: absolute moves are refused", "akdctl home", blocking=False,
              evidence="homed bit clear")
    if status.enabled or status.fault:
        return
    f.add("disabled", f"the drive is {status.state_text}", "akdctl enable", blocking=False,
          evidence=f"state {status.state}")


def _dissource_causes(f: Finder, value: int) -> None:
    if value & 1:  # bit 0 says the same as the state, in the drive's words: one line, not two
        f.causes = [c for c in f.causes if c["cause"] != "disabled"]
    for bit, (text, remedy, blocking) in DISSOURCES.items():
        if value >> bit & 1:
            if bit == 1 and any(c["cause"] in ("fault", "sto") for c in f.causes):
                continue  # the fault is named already, with its own remedy
            f.add("dissource" if blocking else "disabled", text, remedy, blocking=blocking,
                  evidence=f"DRV.DISSOURCES (0x3443) = 0x{value:04X}, bit {bit}")
    unknown = value & ~((1 << 11) - 1)
    if unknown:
        f.add("dissource", f"DRV.DISSOURCES bits 0x{unknown:04X} this tool has no words for",
              "read DRV.DISSOURCES in WorkBench", evidence=f"0x3443 = 0x{value:04X}")


def _object(conn: Connection, index: int, sub: int = 0) -> int:
    from akdctl.catalog import objects as catalog
    from akdctl.drive.values import decode

    data = conn.objects().upload(index, sub)
    entry = catalog.lookup(index, sub)
    if entry is None:
        return int.from_bytes(bytes(data), "little")
    return int(decode(entry.short_type, data))


def _coe_causes(f: Finder, conn: Connection) -> None:
    value = f.attempt("DRV.DISSOURCES (0x3443)", lambda: _object(conn, 0x3443))
    if value is not None:
        _dissource_causes(f, value)
    inputs = f.attempt("digital inputs (0x60FD)", lambda: _object(conn, 0x60FD))
    if inputs is not None:
        for bit, text in LIMIT_BITS.items():
            if inputs >> bit & 1:
                f.add("limit", text, "move away from the switch in the other direction (jog), or check the switch",
                      evidence=f"0x60FD = 0x{inputs:08X}, bit {bit}")


def _ethercat_causes(f: Finder, conn: Connection) -> None:
    """AL state, the controlword mapped in OP (SPEC-NOTES 23) and the cycle time against the mapping."""
    from akdctl.drive.pdo import al_state_of, read_mapping
    from akdctl.profiles.units import cycle_time_problem

    al = f.attempt("EtherCAT AL state", lambda: al_state_of(conn))
    if al is None:
        f.unread.setdefault("EtherCAT AL state", "this transport does not report it (an ETG.8200 gateway carries "
                                                 "mailboxes only); the AL state and status code are not ruled out")
        return
    f.read.append(f"AL state {al}")
    if "ERR" in al:
        from akdctl.catalog.texts import al_status_text

        code = _al_status_code(conn)
        said = (f"AL status code 0x{code:04X}: {al_status_text(code)}" if code is not None
                else "the AL status code is not readable over this transport")
        f.add("al", f"EtherCAT AL state {al}: the drive refused a state change or left the requested one ({said})",
              "correct what the code names (sync manager, cycle, mapping), then request the state again "
              "(akdctl ecat state ...), which acknowledges the error", evidence=f"AL state {al}"
              + (f", 0x0134 = 0x{code:04X}" if code is not None else ""))
    mapping = f.attempt("PDO mapping", lambda: read_mapping(conn.objects()))
    if not mapping:
        return
    rx = mapping.get("rx")
    rx_objects = {e.index for _, entries in rx.pdos for e in entries} if rx is not None else set()
    if al == "OP" and 0x6040 in rx_objects:
        f.add("controlword-pdo", "the controlword 0x6040 is mapped in the active RxPDO and the drive is in OP: "
              "the EtherCAT master's process data enables and disables it, not an SDO (SPEC-NOTES 23)",
              "enable through the master (its PLC program), or drop to SAFE-OP/PRE-OP to use akdctl enable",
              evidence="0x6040 in the RxPDO, AL state OP")
    units = f.attempt("cycle time (0x60C2)", lambda: (_object(conn, 0x60C2, 1), _object(conn, 0x60C2, 2)))
    if units is not None:
        problem = cycle_time_problem(units[0], units[1])
        if problem is not None:
            from akdctl.catalog.texts import cycle_time_text

            f.add("cycle", f"cycle time 0x60C2 = {units[0]}e{units[1]} s: {cycle_time_text(problem, *units)}",
                  "set 0x60C2 to the master's cycle (a multiple of 62.5 µs, at least 250 µs)",
                  evidence=f"0x60C2:1 = {units[0]}, 0x60C2:2 = {units[1]}")
    mode = f.attempt("operation mode (0x6061)", lambda: _object(conn, 0x6061))
    needs = {8: (0x607A, "cyclic synchronous position needs 0x607A"),
             9: (0x60FF, "cyclic synchronous velocity needs 0x60FF"),
             7: (0x60C1, "interpolated position needs 0x60C1")}
    if mode in needs and al in ("SAFEOP", "OP") and needs[mode][0] not in rx_objects:
        f.add("cycle", f"{needs[mode][1]} in the RxPDO, and it is not mapped: the drive gets no cyclic set points "
                       "(F706 'fieldbus cyclic set points missing')",
              "map the set point the mode needs (akdctl pdo map) or choose the mode the mapping serves",
              evidence=f"mode {mode}, RxPDO objects {sorted(f'0x{i:04X}' for i in rx_objects)}")


def _al_status_code(conn: Connection) -> int | None:
    """The AL status code (register 0x0134), read through the raw master's register access (``ecat reg read``'s
    one path); None where the target gives no register access (an ETG.8200 gateway, SOEM)."""
    if conn.target.scheme != "ecat":
        return None
    from akdctl.drive.ecat_registers import read_registers

    try:
        return int.from_bytes(read_registers(conn, 0x0134, 2), "little")
    except AkdError:
        return None


def _profidrive_causes(f: Finder, conn: Connection) -> None:
    from akdctl.catalog.pnus import pnu_table
    from akdctl.drive.values import PnuSpec, read_pnus

    table = pnu_table()
    specs = [PnuSpec(n, 0, 1, table[n]) for n in (1, 930) if n in table]
    readings = f.attempt("STW1 and operating mode (PNU 1, 930)", lambda: read_pnus(conn.parameters(), specs))
    for r in readings or []:
        data = r.to_json()
        values = data.get("values") or []
        if data.get("pnu") == 1 and values and not int(values[0]) & 0x400:
            f.add("mode", "STW1 bit 10 'control by PLC' is clear: the drive ignores the rest of the control word",
                  "set STW1 bit 10 (akdctl enable does; a PLC must in every cycle)", blocking=False,
                  evidence=f"STW1 = 0x{int(values[0]):04X}")


def _eip_causes(f: Finder, conn: Connection) -> None:
    """eip://: the fault numbers CIP offers (drive/eip_faults.py); what it does not offer is listed as not read."""
    from akdctl.drive import eip_faults

    eip = f.attempt("EtherNet/IP faults (0x24/1/5, DRV.FAULT1)", lambda: eip_faults.read(conn))
    if eip is None:
        return
    named = [e for e in eip["active"] if e.get("code")]
    if named:
        f.causes = [c for c in f.causes if not (c["cause"] == "fault" and "names none" in c["text"])]
    for entry in named:
        f.add("fault", f"fault {entry['code']} active: {entry['name']}", _fault_remedy(entry["code"]).replace(
              "; then akdctl fault ack", "; then acknowledge from the PLC or WorkBench (no CIP path)"),
              evidence=f"DRV.FAULT1 = {entry['number']} (0x0F/{eip_faults.FAULT1_INSTANCE}, inferred instance)")
    for what, why in eip["not_offered"].items():
        if what != "acknowledge":
            f.unread[what] = why
    f.unread.update({f"eip {k}": v for k, v in eip["errors"].items()})


def diagnose(conn: Connection, *, want_mode: str | None = None) -> dict[str, Any]:
    """Every cause found (``causes``, most likely first, blocking ones before the rest), what was read and what
    could not be read. Raises only when the drive does not answer at all."""
    f = Finder()
    status = f.attempt("axis status", lambda: conn.axis().read_status())
    if status is not None:
        _status_causes(f, status, want_mode)
    if conn.has_objects:
        _coe_causes(f, conn)
        if conn.target.scheme in ("sim", "ecat", "ecat-udp", "ecat+soem"):
            _ethercat_causes(f, conn)
    if conn.has_parameters and conn.drive_profile != "cia402":
        _profidrive_causes(f, conn)
    if conn.has_cip and not conn.has_objects and not conn.has_parameters:
        _eip_causes(f, conn)
    causes = sorted(f.causes, key=lambda c: (not c["blocking"], c["rank"]))
    blocking = [c for c in causes if c["blocking"]]
    if status is not None and status.enabled and not blocking:
        verdict = "enabled; nothing stops it"
    elif blocking:
        verdict = f"{len(blocking)} cause(s) keep it from running; first: {blocking[0]['text']}"
    elif status is not None:
        verdict = "nothing blocks enabling: it is only disabled (akdctl enable)"
    else:
        verdict = "the drive's state could not be read"
    return {"target": conn.target.display, "enabled": None if status is None else status.enabled,
            "state": None if status is None else status.state_text, "verdict": verdict, "causes": causes,
            "read": f.read, "not_read": f.unread}
