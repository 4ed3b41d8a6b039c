"""AKD parameters by name on every transport: resolve, read, plan -> consent -> execute a write, save.

Why one module: a name means the same parameter whichever way the drive is reached, so the rules that turn a
name into a transport's address and a value into its wire form are written once:

* ``akd://`` (the ASCII service channel) speaks the name itself: ``NAME`` reads, ``NAME value`` writes;
* ``mb://`` reads holding registers ``2(n-1)``, two registers per value, the most significant word first
  (AKD User Guide ch. 22 [V]); floats x1000;
* ``sim``, ``ecat*://`` and ``can://`` upload/download the CoE object with its float scale (catalogue ``scale``;
  ``var`` scales are shown raw and written only with ``raw=True``);
* ``eip://`` reads the Parameter object instance ``n`` (floats x1000, :mod:`akdctl.drive.eip_params`);
* ``pn://`` reaches only names with a PNU (DRV.OPMODE 930, HOME.MODE 1001); anything else is "not reachable over
  PROFINET" naming the transports that reach it.

Writes follow :mod:`akdctl.drive.operation`: :func:`plan` checks names, classes, values and ranges and asks the
gate (:func:`classify`: a CoE-mapped name exactly as its index, commands and the service set points by name),
:func:`execute` writes, reads back and raises one CheckFailed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from akdctl.errors import MalformedReply, UsageError
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.catalog.akd_params import AkdParam
    from akdctl.connection import Connection
    from akdctl.drive.gate import Gated
    from akdctl.drive.operation import WritePlan

ROUTE_WORDS = {"ascii": "the AKD service channel (akd://)", "modbus": "Modbus TCP (mb://)",
               "coe": "CoE/CANopen SDO", "eip": "the EtherNet/IP Parameter object", "pnu": "PROFINET (PNUs)"}

# ---------------------------------------------------------------- names


def resolve(name: str, live: dict[str, Any] | None = None) -> "AkdParam":
    """The catalogue row of ``name`` (case-insensitive); UsageError (exit 2) naming the closest names.
    ``live``: the names the drive reported (:mod:`akdctl.drive.name_discovery`), which override the catalogue."""
    from akdctl.catalog.akd_params import close_matches, lookup

    row = lookup(name)
    if live is not None:
        from akdctl.drive.name_discovery import live_row

        row = live_row(row, name.strip().upper(), live)
    if row is None:
        close = close_matches(name)
        hint = f"; closest: {', '.join(close)}" if close else ""
        raise UsageError(f"unknown AKD parameter {name.strip()!r}{hint} ('akdctl param list' lists the names)",
                         details={"closest": close})
    return row


def expand(patterns: Sequence[str], live: dict[str, Any] | None = None) -> list["AkdParam"]:
    """Names and globs (``VL.*``) to rows, in order, each once; a glob that matches nothing is a UsageError.
    ``live``: the drive's own names (they join the catalogue's and override its addresses)."""
    import fnmatch

    from akdctl.catalog.akd_params import matching

    rows: list[AkdParam] = []
    for pattern in patterns:
        if any(c in pattern for c in "*?["):
            found = matching(pattern)
            if live is not None:
                known = {r.name for r in found}
                extra = [n for n in sorted(live) if n not in known and fnmatch.fnmatchcase(n, pattern.strip().upper())]
                found = [resolve(r.name, live) for r in found] + [resolve(n, live) for n in extra]
            if not found:
                raise UsageError(f"no AKD parameter matches {pattern!r}")
        else:
            found = [resolve(pattern, live)]
        rows += [r for r in found if r not in rows]
    return rows


# ---------------------------------------------------------------- routes


def route(conn: "Connection") -> str:
    """How this connection reaches parameters by name: ascii, modbus, coe, eip or pnu."""
    if conn.has_commands:
        return "ascii"
    if conn.has_registers:
        return "modbus"
    if conn.has_objects:
        return "coe"
    if conn.has_cip:
        return "eip"
    if conn.has_parameters:
        return "pnu"
    raise UsageError(f"target {conn.target.display} offers no way to reach AKD parameters by name")


def alternatives(row: "AkdParam") -> str:
    """The transports that reach ``row``, in words (for 'not reachable' messages)."""
    ways = ["akd://HOST (service channel)"]
    if row.coe is not None:
        ways.append(f"ecat-udp://, ecat://, can:// or sim (CoE 0x{row.coe[0]:04X}:{row.coe[1]})")
    if row.n:
        ways.append(f"eip://HOST (instance {row.n}) or mb://HOST (register {row.modbus})")
    if row.pnu:
        ways.append(f"pn://HOST (PNU {row.pnu})")
    return "; ".join(ways)


def reachable(row: "AkdParam", how: str) -> bool:
    """Whether ``how`` has an address for ``row`` (the service channel reaches every name)."""
    if how == "ascii":
        return True
    if row.kind in ("text",):
        return False
    if how == "coe":
        return row.coe is not None
    if how in ("eip", "modbus"):
        return bool(row.n) and row.kind != "string"
    if how == "pnu":
        return bool(row.pnu)
    return False


def _unreachable(row: "AkdParam", how: str) -> UsageError:
    where = {"pnu": "PROFINET", "coe": "CoE/CANopen", "eip": "EtherNet/IP", "modbus": "Modbus"}.get(how, how)
    return UsageError(f"{row.name} is not reachable over {where}: use {alternatives(row)}",
                      details={"name": row.name, "route": how})


# ---------------------------------------------------------------- reading


class NameReading(Record):
    """One name read: ``value`` (int, float or text), its ``text`` as the drive prints it (with unit), the
    ``raw`` wire value, the ``scale`` applied and the ``address`` used (mutable result; not hashed)."""

    __slots__ = ("row", "value", "text", "unit", "raw", "scale", "route", "address", "note")
    __hash__ = None  # type: ignore[assignment]

    def __init__(self, row: "AkdParam", value: Any, text: str, unit: str, raw: Any, scale: str, route: str,
                 address: str, note: str = "") -> None:
        self.row = row
        self.value = value
        self.text = text
        self.unit = unit
        self.raw = raw
        self.scale = scale
        self.route = route
        self.address = address
        self.note = note

    def to_json(self, raw: bool = False) -> dict[str, Any]:
        data: dict[str, Any] = {"name": self.row.name, "value": self.value, "unit": self.unit or None,
                                "text": self.text}
        if raw:
            data.update(raw=self.raw, scale=self.scale or None, route=self.route, address=self.address)
        if self.note:
            data["note"] = self.note
        return data


def _coe_address(row: "AkdParam") -> str:
    assert row.coe is not None
    return f"0x{row.coe[0]:04X}:{row.coe[1]}"


def read(conn: "Connection", row: "AkdParam", how: str | None = None) -> NameReading:
    """Read one parameter by name over the connection's route (``how``: the route, if already known)."""
    from akdctl.profiles.akd_values import FLOAT_WIRE, format_value, from_fixed

    how = how or route(conn)
    if row.is_command or row.access == "WO":
        raise UsageError(f"{row.name} is a command, not a value; run it with 'akdctl cmd {row.name}'")
    if not reachable(row, how):
        raise _unreachable(row, how)
    if how == "ascii":
        reply = conn.commands().command(row.name)
        return _from_reply(row, reply)
    if how == "coe":
        from akdctl.protocol import datatypes

        data = conn.objects().upload(*row.coe)  # type: ignore[misc]
        ctype = row.coe_type or "u32"
        try:
            raw = datatypes.unpack(ctype, data)
        except datatypes.DataTypeError as exc:
            raise MalformedReply(f"{row.name} ({_coe_address(row)}): {exc}") from None
        if row.kind == "string":
            return NameReading(row, raw, str(raw), "", data.hex(), "", how, _coe_address(row))
        if row.scale == "var":
            return NameReading(row, raw, str(raw), "", raw, "var", how, _coe_address(row),
                               note="raw CoE value: its scale depends on UNIT.*/FBUS.PARAM05")
        factor = row.factor or 1
        value = from_fixed(int(raw), row.kind, factor)  # type: ignore[call-overload]
        return NameReading(row, value, format_value(row.kind, value, row.unit), row.unit, raw, row.scale, how,
                           _coe_address(row))
    if how == "eip":
        from akdctl.drive import eip_params

        ref = eip_params.ParameterRef(row.n, row.name, "float" if row.kind == "float" else "int")  # type: ignore[arg-type]
        got = eip_params.read(conn.cip(), ref)
        value = got["value"]
        return NameReading(row, value, format_value(row.kind, value, row.unit), row.unit, got["raw"],
                           str(FLOAT_WIRE) if row.kind == "float" else "1", how, f"instance {row.n}")
    if how == "modbus":
        words = conn.registers().read_registers(row.modbus, 2)  # type: ignore[arg-type]
        if len(words) != 2:
            raise MalformedReply(f"{row.name}: {len(words)} registers instead of 2")
        raw = (words[0] << 16) | words[1]
        if raw >= 1 << 31 and not row.coe_type.startswith("u"):
            raw -= 1 << 32
        factor = FLOAT_WIRE if row.kind == "float" else 1
        value = from_fixed(raw, row.kind, factor)
        return NameReading(row, value, format_value(row.kind, value, row.unit), row.unit, raw, str(factor), how,
                           f"register {row.modbus}")
    from akdctl.drive.values import pnu_spec, read_pnus
    from akdctl.errors import ParameterRefused

    reading = read_pnus(conn.parameters(), [pnu_spec(row.pnu, count=1)])[0]  # type: ignore[arg-type]
    if not reading.ok:
        raise ParameterRefused(f"drive refused to read {row.name} (PNU {row.pnu}): {reading.error_text}",
                               code=reading.error)
    value = (reading.values or [0])[0]
    return NameReading(row, value, format_value(row.kind, value, row.unit), row.unit, value, "1", how,
                       f"PNU {row.pnu}")


def _from_reply(row: "AkdParam", reply: str) -> NameReading:
    from akdctl.profiles.akd_values import ValueFormError, format_value, parse_text, split_reply

    if row.kind in ("text", "string"):
        return NameReading(row, reply, reply, "", reply, "", "ascii", row.name)
    value_text, unit = split_reply(reply)
    if row.kind == "raw":   # a name only the drive knows: a number when it is one, else its text
        try:
            number = parse_text("float" if "." in value_text else "int", value_text)
        except ValueFormError:
            return NameReading(row, reply, reply, "", reply, "", "ascii", row.name)
        return NameReading(row, number, format_value("float" if isinstance(number, float) else "int", number, unit or ""),
                           unit or "", reply, "", "ascii", row.name)
    try:
        value = parse_text("float" if row.kind == "float" or "." in value_text else "int", value_text)
    except ValueFormError as exc:
        raise MalformedReply(f"{row.name}: the drive answered {reply[:60]!r}, not a value ({exc})") from None
    if row.kind == "float":
        value = float(value)  # type: ignore[arg-type]
    unit = unit if unit is not None else row.unit
    return NameReading(row, value, format_value(row.kind, value, unit), unit, reply, "", "ascii", row.name)


def read_all(conn: "Connection", rows: Sequence["AkdParam"]) -> tuple[list[NameReading], list["AkdParam"]]:
    """Read every row the route reaches: (readings, rows it does not reach)."""
    how = route(conn)
    readings, skipped = [], []
    for row in rows:
        if not row.readable or not reachable(row, how):
            skipped.append(row)
            continue
        readings.append(read(conn, row, how))
    return readings, skipped


# ---------------------------------------------------------------- the gate, by name

#: Names the gate's catalogue rules (catalog/objects.py WRITE_CLASS_RULES, drive/gate.classify_name) do not
#: classify yet, with the class they get here until those rules carry them (one place: move them there).
NAME_FALLBACK: dict[str, str] = {"VL.CMDU": "setpoint", "IL.CMDU": "setpoint", "HOME.SET": "mode",
                                 "DRV.RSTVAR": "mode", "DRV.NVLOAD": "mode"}
#: Commands that only take power away, stop, clear faults or store parameters: never gated (like 'stop',
#: 'disable' and 'fault ack').
HARMLESS_COMMANDS = frozenset({"DRV.DIS", "DRV.STOP", "DRV.CLRFAULTS", "DRV.NVSAVE", "MT.SET", "SD.SAVE"})


def classify(row: "AkdParam") -> "Gated | None":
    """The gate's verdict on writing (or running) ``row``: by its CoE object exactly as ``sdo write`` would
    (:func:`akdctl.drive.gate.classify_object`), else by the gate's classes of AKD names
    (:func:`akdctl.drive.gate.classify_name`); a command neither knows is gated unless it only stops or stores."""
    from akdctl.drive import gate

    if row.coe is not None:
        found = gate.classify_object(row.coe[0], row.coe[1], row.name)
        if found is not None:
            return found
    found = gate.classify_name(row.name)
    if found is not None:
        return found
    if row.name in NAME_FALLBACK:
        return gate.gated_for(row.name, NAME_FALLBACK[row.name])
    if row.is_command and row.name not in HARMLESS_COMMANDS:
        return gate.gated_for(row.name, "motion", "an AKD command akdctl does not know to leave the axis still")
    return None


#: Read-only commands and reports the passthrough runs without consent (besides reading any readable name).
SAFE_REPORTS = frozenset({"DRV.FAULTS", "DRV.WARNINGS", "DRV.INFO", "DRV.VER", "DRV.VERIMAGE", "DRV.LIST",
                          "DRV.HELP", "DRV.HELPALL", "DRV.NVLIST", "DRV.DIFVAR", "DRV.NVCHECK", "DRV.TEMPERATURES",
                          "DRV.LOGICVOLTS", "DRV.ONTIME", "DRV.RUNTIME", "DRV.FAULTHIST", "DRV.ERRORLIST",
                          "MT.LIST", "MT.PARAMS", "DIN.STATES", "DOUT.STATES", "DRV.ACTIVE", "DRV.DISSOURCES"})


def classify_line(line: str) -> "tuple[str, Gated | None]":
    """A passthrough command line: (keyword, gate verdict). A known-safe read runs freely; every other line
    (a write, a command, a name akdctl does not know) is gated."""
    from akdctl.catalog.akd_params import lookup
    from akdctl.drive import gate

    text = line.strip()
    if not text or any(ord(c) < 32 or ord(c) > 126 for c in text):
        raise UsageError("a command line is printable ASCII on one line, e.g. 'DRV.INFO' or 'VL.KP 0.5'")
    keyword, _, argument = text.partition(" ")
    keyword = keyword.upper()
    row = lookup(keyword)
    if keyword in SAFE_REPORTS and (not argument or keyword in ("DRV.HELP", "DRV.LIST", "MT.PARAMS")):
        return keyword, None
    if row is not None and not argument.strip() and row.readable:
        return keyword, None
    if row is not None:
        found = classify(row)
        if found is not None:
            return keyword, found
        if argument.strip() and row.writable:
            return keyword, gate.Gated(text, "a parameter write through the passthrough (use 'param set' to check "
                                             "it first)")
    return keyword, gate.Gated(text, "not a read akdctl knows to be safe")


def drive_enabled(conn: "Connection") -> bool | None:
    """Is the power stage on? DRV.ACTIVE over the service channel, else the axis profile's status."""
    from akdctl.errors import AkdError

    if conn.has_commands:
        try:
            return conn.commands().command("DRV.ACTIVE").strip() not in ("0",)
        except AkdError:
            return None
    if conn.has_registers:
        return None
    from akdctl.drive.gate import drive_enabled as profile_enabled

    return profile_enabled(conn)


# ---------------------------------------------------------------- writing: plan -> consent -> execute


def wire_value(row: "AkdParam", value: Any, how: str, raw: bool = False) -> Any:
    """The value as ``how`` carries it (an int for fieldbuses, the text for the service channel)."""
    from akdctl.profiles.akd_values import FLOAT_WIRE, format_value, to_fixed

    if how == "ascii":
        return format_value(row.kind, value)
    if raw:
        if not isinstance(value, int):
            raise UsageError(f"{row.name}: --raw takes the integer as the fieldbus carries it")
        return value
    if row.kind == "string":
        return value
    if how == "coe":
        if row.scale == "var":
            raise UsageError(f"{row.name}: the scale of CoE {_coe_address(row)} depends on UNIT.*/FBUS.PARAM05; "
                             "give the wire value with --raw, or use akd://HOST")
        return to_fixed(value, row.factor or 1)
    if how in ("eip", "modbus"):
        return to_fixed(value, FLOAT_WIRE if row.kind == "float" else 1)
    return int(value)


def check_value(row: "AkdParam", text: str, raw: bool = False, notes: list[str] | None = None) -> Any:
    """The value a user or file gave for ``row``, parsed and checked against class and published range.

    With ``notes`` (a restore: the values came from a drive) a value outside the published range is noted, not
    refused: the ranges are launch-firmware ones (2009 guide) and the drive itself decides."""
    from akdctl.profiles.akd_values import ValueFormError, parse_text

    if row.is_command:
        raise UsageError(f"{row.name} is a command: run it with 'akdctl cmd {row.name}'")
    if not row.writable:
        raise UsageError(f"{row.name} is read-only ({row.access})")
    try:
        kind = "int" if raw else row.kind if row.kind != "raw" else ("float" if "." in text else "int")
        value = parse_text(kind, text)
    except ValueFormError as exc:
        raise UsageError(f"bad value for {row.name}: {exc}") from None
    if not raw and isinstance(value, (int, float)):
        for bound, ok in ((row.minimum, lambda b: value >= b), (row.maximum, lambda b: value <= b)):
            if bound and not ok(float(bound)):
                words = (f"{value} is outside {row.name}'s published range {row.minimum or '..'} .. "
                         f"{row.maximum or '..'}{' [I]' if row.mark('range') == 'I' else ''}")
                if notes is None:
                    raise UsageError(words)
                notes.append(words + " (from the file; the drive decides)")
                break
    return value


def plan(conn: "Connection", request: Sequence[tuple[str, str]], *, raw: bool = False,
         operation: str = "param set", only_changes: bool = False, skip_unreachable: bool = False,
         live: dict[str, Any] | None = None) -> "WritePlan":
    """Plan writes of ``request`` [(name, value text)]: every name, value and range checked, each write's
    gate verdict attached, the enabled state read when a write is gated only while enabled. ``only_changes``
    (restore) reads each value first and drops the ones already equal; ``skip_unreachable`` (restore across
    transports) leaves names the route cannot reach out, as notes."""
    from akdctl.drive.operation import PlannedWrite, WritePlan
    from akdctl.profiles.akd_values import format_value, same_value

    how = route(conn)
    writes: list[PlannedWrite] = []
    items: list[tuple["AkdParam", Any, Any]] = []
    notes: list[str] = []
    seen: set[str] = set()
    for name, text in request:
        row = resolve(name, live)
        if row.name in seen:
            raise UsageError(f"{row.name} is given twice")
        seen.add(row.name)
        range_notes: list[str] = []   # kept only for a value that is written (a restore leaves equal ones alone)
        value = check_value(row, text, raw, range_notes if only_changes else None)
        if not reachable(row, how):
            if skip_unreachable:
                notes.append(f"{row.name} skipped: not reachable over {ROUTE_WORDS[how]}")
                continue
            raise _unreachable(row, how)
        wire = wire_value(row, value, how, raw)
        if only_changes and same_value(row.kind, read(conn, row, how).value, value):
            continue
        notes += range_notes
        address = row.name if how == "ascii" else f"{row.name} ({_address(row, how)})"
        writes.append(PlannedWrite(address, wire, format_value(row.kind, value, "" if raw else row.unit),
                                   classify(row)))
        items.append((row, value, wire))
        if how != "ascii" and row.mark("scale") == "I" and row.kind == "float" and how == "coe" and not raw:
            notes.append(f"{row.name}: CoE scale x{row.scale} is inferred [I] (the read-back uses the same scale, "
                         "so it cannot confirm it; compare with akd://HOST on a real drive)")
    enabled = drive_enabled(conn) if any(w.gated is not None and w.gated.when_enabled for w in writes) else None
    if writes:
        notes.append("RAM only until 'akdctl param save' (DRV.NVSAVE)")
    return WritePlan(operation, conn.target.display, writes, enabled=enabled, verify=True, notes=notes,
                     data={"route": how, "items": items, "raw": raw})


def _address(row: "AkdParam", how: str) -> str:
    if how == "coe":
        return f"CoE {_coe_address(row)}"
    if how == "eip":
        return f"instance {row.n}"
    if how == "modbus":
        return f"register {row.modbus}"
    if how == "pnu":
        return f"PNU {row.pnu}"
    return row.name


def _write(conn: "Connection", row: "AkdParam", wire: Any, how: str) -> None:
    if how == "ascii":
        conn.commands().command(f"{row.name} {wire}")
    elif how == "coe":
        from akdctl.protocol import datatypes

        try:
            data = datatypes.pack(row.coe_type or "u32", wire)
        except datatypes.DataTypeError as exc:
            raise UsageError(f"{row.name}: {exc}") from None
        conn.objects().download(row.coe[0], row.coe[1], data)  # type: ignore[index]
    elif how == "eip":
        from akdctl.drive import eip_params

        ref = eip_params.ParameterRef(row.n, row.name, "int")  # type: ignore[arg-type]
        eip_params.write(conn.cip(), ref, str(wire))
    elif how == "modbus":
        number = int(wire) & 0xFFFFFFFF
        conn.registers().write_registers(row.modbus, [number >> 16, number & 0xFFFF])  # type: ignore[arg-type]
    else:
        from akdctl.drive.values import pnu_spec, write_pnus
        from akdctl.errors import ParameterRefused

        result = write_pnus(conn.parameters(), [(pnu_spec(row.pnu, count=1), [int(wire)])])[0]  # type: ignore[arg-type]
        if not result.ok:
            raise ParameterRefused(f"drive refused to change {row.name} (PNU {row.pnu}): {result.error_text}",
                                   code=result.error)


def execute(conn: "Connection", plan: "WritePlan") -> list[dict[str, Any]]:
    """Write the plan in order, read every value back over the same route; CheckFailed names differences."""
    from akdctl.drive.operation import check_readback
    from akdctl.profiles.akd_values import format_value, same_value

    how, raw = plan.data["route"], plan.data["raw"]
    done: list[dict[str, Any]] = []
    pairs = []
    for row, value, wire in plan.data["items"]:
        name = row.name
        _write(conn, row, wire, how)
        back = read(conn, row, how)
        got = back.raw if raw and how != "ascii" else back.value
        ok = same_value(row.kind, got, value)
        shown = format_value(row.kind, value)
        pairs.append((name, shown, shown if ok else (back.text if not raw else str(got))))
        done.append({"name": name, "value": value, "wire": wire, "read_back": got, "unit": back.unit or None})
    check_readback(pairs)
    return done


def plan_save(conn: "Connection") -> "WritePlan":
    """DRV.NVSAVE: the service channel's command, CoE 1010h:1 = "save"; other routes name the way."""
    from akdctl.drive.operation import PlannedWrite, WritePlan

    how = route(conn)
    if how not in ("ascii", "coe"):
        raise UsageError(f"saving to non-volatile memory is not reachable over {ROUTE_WORDS[how]}: use "
                         "akd://HOST (DRV.NVSAVE) or a CoE target (1010h:1)")
    address = "DRV.NVSAVE" if how == "ascii" else "DRV.NVSAVE (CoE 0x1010:1)"
    return WritePlan("param save", conn.target.display, [PlannedWrite(address, "save", "save")],
                     notes=["the drive writes its RAM parameters to flash (about 1 s in the background)"],
                     data={"route": how})


def execute_save(conn: "Connection", plan: "WritePlan") -> dict[str, Any]:
    if plan.data["route"] == "ascii":
        conn.commands().command("DRV.NVSAVE")
    else:
        conn.objects().download(0x1010, 1, b"save")
    return {"saved": True, "route": plan.data["route"]}


__all__ = ["NameReading", "resolve", "expand", "route", "read", "read_all", "classify", "classify_line",
           "plan", "execute", "plan_save", "execute_save", "reachable", "alternatives", "drive_enabled"]


def plan_line(conn: "Connection", line: str) -> "WritePlan":
    """The passthrough (``akdctl cmd LINE``) as a plan: a known-safe read is a plan without writes' consent;
    every other line is one gated write (its reason from :func:`classify_line`)."""
    from akdctl.drive.operation import PlannedWrite, WritePlan

    keyword, gated = classify_line(line)
    conn.commands()  # only the service channel carries command lines: UsageError naming akd:// otherwise
    text = line.strip()
    enabled = drive_enabled(conn) if gated is not None and gated.when_enabled else None
    return WritePlan("cmd", conn.target.display, [PlannedWrite(text, text, "(command line)", gated)],
                     enabled=enabled, data={"line": text, "keyword": keyword, "safe": gated is None})


def execute_line(conn: "Connection", plan: "WritePlan") -> str:
    """Send the planned line; the drive's reply (without echo and prompt)."""
    return conn.commands().command(plan.data["line"])
