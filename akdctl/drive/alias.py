"""The EtherCAT configured station alias: read all four places it lives, and change it (``ecat alias``).

Why one module for the four: on an AKD the alias the master sees in register 0x0012 comes from SII word 4 at
power-on (ESC datasheet; reference foe-alias-recorder.md B), the drive keeps it as FBUS.PARAM03 (CoE 0x36E7,
seed 001 5.14), and FBUS.PARAM05 bit 5 decides whether FBUS.PARAM03 or the rotary switches win. A technician
asking "why does the master still see the old alias" needs all four side by side, and a rule for which wins
written once (:func:`effective`).

Writing (plan -> consent -> execute, :mod:`akdctl.drive.operation`):

* ``via="sii"`` (default; works for any slave, IgH's and SOEM's way): SII word 4 = N, then word 7's low byte =
  CRC-8 of words 0-6 (high byte kept), both read back with the CRC checked. On the AKD "an EEPROM emulation write
  access to the Configured Station Alias address forces the AKD to store the drive parameters automatically
  using the DRV.NVSAVE command" (seed 001 5.14): every RAM parameter is saved -- the consent says so.
* ``via="coe"``: FBUS.PARAM03 (0x36E7) = N, read back. Whether SII word 4 and 0x0012 follow without a power
  cycle is not known [I]; the plan says a power cycle is needed either way.
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING, Any

from akdctl.drive.gate import Gated
from akdctl.drive.operation import PlannedWrite, WritePlan, check_readback
from akdctl.errors import AkdError, CommError, UsageError

if TYPE_CHECKING:
    from akdctl.connection import Connection

PARAM03 = 0x36E7  # FBUS.PARAM03: configured station alias
PARAM05 = 0x36E9  # FBUS.PARAM05: bit 5 chooses FBUS.PARAM03 over the rotary switches

SAVES_ALL = Gated("SII word 4 (station alias)",
                  "the AKD saves all its RAM parameters (DRV.NVSAVE) on this write, seed 001 5.14")
CHANGES_ALIAS = Gated("0x36E7:0 (FBUS.PARAM03)", "changes the drive's station alias at the next power cycle")


def raw_bus(conn: "Connection") -> Any:
    """The raw master's transport (open, slave in PRE-OP or higher); the alias needs SII and register access."""
    from akdctl.drive.ecat_registers import raw_bus as registers_bus

    return registers_bus(conn, "'ecat alias' needs")


def require_position(conn: "Connection", transport: Any) -> None:
    """With more than one slave on the line, a write needs the position spelled out (IgH asks --force)."""
    count = transport.master.count_slaves()
    if count > 1 and not conn.target.path_parts:
        raise UsageError(f"{count} slaves answer on {transport.master.ifname}: name the one to change with its "
                         f"position (ecat://{transport.master.ifname}/POS); nothing was written")


def sii_words(transport: Any) -> list[int]:
    """SII words 0-7 (the ESC configuration area) of the target's slave."""
    raw = transport.master.read_sii_bytes(transport.slave.station, 0, 16)
    return list(struct.unpack("<8H", raw))


def crc_of(words: list[int]) -> int:
    from akdctl.protocol.sii import crc8

    return crc8(struct.pack("<7H", *words[:7]))


def effective(param03: int | None, bit5: bool | None) -> str:
    """Which source the AKD takes its alias from, in words (seed 001 5.14, FBUS.PARAM05 bit 5)."""
    if param03 is None or bit5 is None:
        return "unknown (FBUS.PARAM03/FBUS.PARAM05 not readable)"
    if bit5:
        return ("FBUS.PARAM03" if param03 else "the rotary switches (FBUS.PARAM03 is 0)") + " (FBUS.PARAM05 bit 5 = 1)"
    return ("the rotary switches if they are not 0, else FBUS.PARAM03 "
            f"({param03}) (FBUS.PARAM05 bit 5 = 0; the switches cannot be read over EtherCAT here)")


def _u32(conn: "Connection", index: int) -> int | None:
    try:
        return int.from_bytes(conn.objects().upload(index, 0)[:4], "little")
    except CommError:
        raise
    except AkdError:
        return None


def read(conn: "Connection") -> dict[str, Any]:
    """Register 0x0012, SII word 4 with its CRC check, FBUS.PARAM03, FBUS.PARAM05 bit 5 and which wins."""
    from akdctl.protocol import ethercat as ec

    transport = raw_bus(conn)
    master, slave = transport.master, transport.slave
    register = struct.unpack("<H", master.fprd(slave.station, ec.REG_STATION_ALIAS, 2))[0]
    words = sii_words(transport)
    crc = crc_of(words)
    param03, param05 = _u32(conn, PARAM03), _u32(conn, PARAM05)
    bit5 = None if param05 is None else bool(param05 & 0x20)
    return {"target": conn.target.display, "position": slave.position, "station": slave.station,
            "register_0x0012": register, "sii_word4": words[4], "sii_word7": words[7],
            "sii_crc_ok": (words[7] & 0xFF) == crc, "sii_crc_expected": crc,
            "fbus_param03": param03, "fbus_param05": param05, "fbus_param05_bit5": bit5,
            "effective_source": effective(param03, bit5),
            "pending_power_cycle": register != words[4] or (param03 is not None and param03 != words[4])}


def plan(conn: "Connection", alias: int, via: str = "sii") -> WritePlan:
    if not 0 <= alias <= 0xFFFF:
        raise UsageError(f"station alias {alias} is out of range 0..65535")
    if via not in ("sii", "coe"):
        raise UsageError(f"--via {via!r}: use sii or coe")
    transport = raw_bus(conn)
    require_position(conn, transport)
    now = read(conn)
    notes = ["the master sees the new alias in register 0x0012 only after a power cycle of the drive"]
    if via == "sii":
        words = sii_words(transport)
        if (words[7] & 0xFF) != crc_of(words):
            notes.append(f"the SII's CRC is wrong now (0x{words[7] & 0xFF:02X}, expected 0x{crc_of(words):02X}); "
                         "this write sets it right")
        new = list(words)
        new[4] = alias
        word7 = (words[7] & 0xFF00) | crc_of(new)
        writes = [PlannedWrite("SII word 4 (configured station alias)", alias, f"{alias} (0x{alias:04X})", SAVES_ALL),
                  PlannedWrite("SII word 7 (CRC of words 0-6)", word7, f"0x{word7:04X} (CRC 0x{word7 & 0xFF:02X})")]
        notes.append("the AKD saves all RAM parameters (DRV.NVSAVE) when its SII word 4 is written: unsaved "
                     "changes become permanent")
        data = {"words": new, "word7": word7}
    else:
        writes = [PlannedWrite("0x36E7:0 (FBUS.PARAM03)", alias, str(alias), CHANGES_ALIAS)]
        notes.append("FBUS.PARAM03 is a RAM parameter: save it (DRV.NVSAVE, 0x1010:1) to keep it over a power cycle")
        data = {}
    return WritePlan(f"ecat alias ({via})", conn.target.display, writes, verify=True,
                     preconditions=[f"slave at position {now['position']}, alias now: register {now['register_0x0012']}, "
                                    f"SII word 4 {now['sii_word4']}, FBUS.PARAM03 {now['fbus_param03']}"],
                     notes=notes, enabled=None, data={"alias": alias, "via": via, "before": now, **data})


def execute(conn: "Connection", plan: WritePlan) -> dict[str, Any]:
    alias, via = plan.data["alias"], plan.data["via"]
    transport = raw_bus(conn)
    if via == "sii":
        station = transport.slave.station
        transport.master.write_eeprom(station, 4, alias)
        transport.master.write_eeprom(station, 7, plan.data["word7"])
        back = sii_words(transport)
        check_readback([("SII word 4", alias, back[4]), ("SII word 7", plan.data["word7"], back[7]),
                        ("SII CRC (word 7 low byte)", crc_of(back), back[7] & 0xFF)])
    else:
        conn.objects().download(PARAM03, 0, alias.to_bytes(4, "little"))
        check_readback([("0x36E7:0 (FBUS.PARAM03)", alias, _u32(conn, PARAM03))])
    after = read(conn)
    return {"alias": alias, "via": via, "before": plan.data["before"], "after": after,
            "power_cycle_needed": after["register_0x0012"] != alias}
