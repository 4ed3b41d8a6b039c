"""ESC register and SII EEPROM access for service work: ``ecat reg read|write``, ``ecat sii read|write``.

Why guarded here and not in the CLI: a register write can change the AL state (0x0120 AL control), stop the
watchdogs that bring an axis to a stop when the master dies (0x0400-0x0443), or cut the master off its slave
(0x0010 station address, 0x0500 EEPROM ownership); an SII write with a wrong CRC leaves the ESC unconfigured at
the next power-on. Those rules live once, in :func:`plan_register_write` and :func:`plan_sii_write`, which the
CLI and any later caller (recipe, shell) use (plan -> consent -> execute, :mod:`akdctl.drive.operation`).
IgH's ``reg_write``/``sii_write`` have no such guard; SOEM's eepromtool writes whatever it is given.
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING, Any

from akdctl.drive.gate import Gated
from akdctl.drive.operation import PlannedWrite, WritePlan, check_readback
from akdctl.errors import SafetyRefusal, UsageError

if TYPE_CHECKING:
    from akdctl.connection import Connection

ESC_SPACE = 0x10000
MAX_ACCESS = 1486  # bytes one datagram carries

#: Registers a write is refused for unless forced: (first, last, why).
GUARDED = (
    (0x0010, 0x0011, "the configured station address: the master would lose its slave"),
    (0x0120, 0x0121, "AL control: changes the slave's AL state (and what the drive does)"),
    (0x0400, 0x0443, "the watchdogs that stop the drive when the master stops sending"),
    (0x0500, 0x050F, "the SII EEPROM interface: use 'ecat sii write'"),
)

REGISTER_WRITE = Gated("ESC register", "a register write changes the slave controller directly, bypassing the drive")
SII_WRITE = Gated("SII EEPROM", "rewrites the slave's identity and configuration; wrong content leaves it "
                                "unusable after the next power-on (and the AKD saves its RAM parameters on word 4)")


def check_range(address: int, size: int) -> None:
    if not 1 <= size <= MAX_ACCESS:
        raise UsageError(f"size {size} is out of range 1..{MAX_ACCESS} (one datagram)")
    if not 0 <= address < ESC_SPACE or address + size > ESC_SPACE:
        raise UsageError(f"register 0x{address:X}+{size} lies outside the ESC's 64 KiB address space (0x0000-0xFFFF)")


def guarded(address: int, size: int) -> list[str]:
    """The reasons a write to [address, address+size) touches a guarded register (empty: none)."""
    return [f"0x{lo:04X}-0x{hi:04X} {why}" for lo, hi, why in GUARDED if address <= hi and lo < address + size]


def raw_bus(conn: "Connection", what: str = "register and SII access need") -> Any:
    """The raw master's transport: the one way to the slave's registers and SII (``ecat reg``, ``ecat sii``,
    ``ecat alias``); a UsageError naming ``what`` needs it on any other target."""
    if conn.target.scheme != "ecat":
        raise UsageError(f"{what} akdctl as the EtherCAT master (target ecat://IFNAME[/POS]); "
                         f"{conn.target.display} gives no access to the slave's registers and SII")
    return conn.transport()


def read_registers(conn: "Connection", address: int, size: int) -> bytes:
    check_range(address, size)
    transport = raw_bus(conn)
    return bytes(transport.master.fprd(transport.slave.station, address, size))


def plan_register_write(conn: "Connection", address: int, data: bytes, force: bool = False) -> WritePlan:
    check_range(address, len(data))
    transport = raw_bus(conn)
    reasons = guarded(address, len(data))
    if reasons and not force:
        raise SafetyRefusal(f"refusing to write register 0x{address:04X}: it is " + "; ".join(reasons)
                            + " (--force writes it anyway); nothing was written")
    before = bytes(transport.master.fprd(transport.slave.station, address, len(data)))
    return WritePlan("ecat reg write", conn.target.display,
                     [PlannedWrite(f"register 0x{address:04X}", data, data.hex(" "), REGISTER_WRITE)],
                     preconditions=[f"slave at position {transport.slave.position} (station "
                                    f"0x{transport.slave.station:04X}), now {before.hex(' ')}"],
                     notes=[f"forced past: {r}" for r in reasons], verify=False,
                     data={"address": address, "data": data, "before": before})


def execute_register_write(conn: "Connection", plan: WritePlan) -> dict[str, Any]:
    """Write, then read back and report it (a register may legitimately read back otherwise: status bits,
    read-only bytes; the read-back is shown, not compared)."""
    transport = raw_bus(conn)
    address, data = plan.data["address"], plan.data["data"]
    transport.master.fpwr(transport.slave.station, address, data)
    back = bytes(transport.master.fprd(transport.slave.station, address, len(data)))
    return {"target": conn.target.display, "address": address, "written": data.hex(), "before": plan.data["before"].hex(),
            "read_back": back.hex(), "same": back == data}


# ---------------------------------------------------------------------- SII
def read_sii(conn: "Connection") -> bytes:
    transport = raw_bus(conn)
    return transport.master.read_sii(transport.slave.station, full=True)[1]


def plan_sii_write(conn: "Connection", raw: bytes, path: str, fix_crc: bool = False,
                   force: bool = False) -> WritePlan:
    """Check the image (decodes, CRC right or fixed on request, same vendor/product as the slave unless forced);
    the words that differ from the slave's are the writes, each read back."""
    from akdctl.protocol.errors import CodecError
    from akdctl.protocol.sii import crc8, parse_sii

    if len(raw) < 128 or len(raw) % 2:
        raise UsageError(f"{path}: an SII image is an even number of bytes, at least 128 (got {len(raw)})")
    if len(raw) > 0x4000:
        raise UsageError(f"{path}: {len(raw)} bytes is larger than an SII EEPROM akdctl writes (16 KiB)")
    image = bytearray(raw)
    crc = crc8(bytes(image[:14]))
    notes = []
    if image[14] != crc:
        if not fix_crc:
            raise UsageError(f"{path}: the SII CRC (word 7 low byte) is 0x{image[14]:02X}, words 0-6 give 0x{crc:02X}; "
                             "the ESC would refuse its configuration at power-on (--fix-crc sets it); nothing was written")
        notes.append(f"CRC set to 0x{crc:02X} (the file had 0x{image[14]:02X})")
        image[14] = crc
    try:
        new = parse_sii(bytes(image))
    except CodecError as exc:
        raise UsageError(f"{path}: not an SII image: {exc}; nothing was written") from None
    transport = raw_bus(conn)
    old_raw = transport.master.read_sii(transport.slave.station, full=True)[1]
    old = parse_sii(old_raw)
    if (new.vendor_id, new.product_code) != (old.vendor_id, old.product_code) and not force:
        raise SafetyRefusal(f"{path} is for vendor 0x{new.vendor_id:08X} product 0x{new.product_code:08X}, the slave is "
                            f"vendor 0x{old.vendor_id:08X} product 0x{old.product_code:08X} (--force writes it anyway); "
                            "nothing was written")
    current = old_raw.ljust(len(image), b"\xff")
    changed = [w for w in range(len(image) // 2) if image[2 * w:2 * w + 2] != current[2 * w:2 * w + 2]]
    writes = [PlannedWrite(f"SII word 0x{w:04X}", struct.unpack_from("<H", image, 2 * w)[0],
                           f"0x{struct.unpack_from('<H', image, 2 * w)[0]:04X}", SII_WRITE if i == 0 else None)
              for i, w in enumerate(changed)]
    if not writes:
        notes.append("the slave's SII already holds this image: nothing to write")
    if any(w == 4 for w in changed):
        notes.append("word 4 (station alias) changes: the AKD saves all RAM parameters (DRV.NVSAVE) on that write")
    notes.append("the ESC loads words 0-7 at the next power-on")
    return WritePlan("ecat sii write", conn.target.display, writes, verify=True,
                     preconditions=[f"slave at position {transport.slave.position}: {old.name or 'unnamed'} "
                                    f"serial {old.serial}"],
                     notes=notes, data={"image": bytes(image), "words": changed})


def execute_sii_write(conn: "Connection", plan: WritePlan) -> dict[str, Any]:
    transport = raw_bus(conn)
    image, words = plan.data["image"], plan.data["words"]
    station = transport.slave.station
    for w in words:
        transport.master.write_eeprom(station, w, struct.unpack_from("<H", image, 2 * w)[0])
    back = transport.master.read_sii_bytes(station, 0, len(image))
    check_readback([(f"SII word 0x{w:04X}", image[2 * w:2 * w + 2], back[2 * w:2 * w + 2]) for w in words])
    return {"target": conn.target.display, "words_written": len(words), "bytes": len(image), "verified": True}
