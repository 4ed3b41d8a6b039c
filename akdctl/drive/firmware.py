"""Firmware download over EtherCAT (FoE in BOOT): ``ecat foe write`` and ``firmware update`` plan and run here.

Why here and in this shape (plan -> consent -> execute, :mod:`akdctl.drive.operation`): the AKD EtherCAT manual
(seed 001 4.6.3) names FoE as the only firmware path over the bus, and a download interrupted or started on a
powered axis is the most dangerous service job there is (KDN "AKD Backup FPGA FAQ": an interrupted download can
leave the drive on its backup image, older ones releasing the brake; reference foe-alias-recorder.md A6). So
:func:`plan` reads, before anything changes: the identity and firmware, the power stage (refused while powered),
the AL state, and checks the file; :func:`execute` then runs exactly the plan:

    INIT -> SM0/SM1 = bootstrap mailbox from the SII -> BOOT -> FoE write (BUSY handled, packet numbers
    checked) -> INIT (the drive takes the file and restarts) -> wait until it answers -> identity and firmware

[I] The sequence is SOEM's firm_update sample and IgH's documented use (reference A2/A4/A6); the AKD's own
file-name convention, password and restart time are not public ([—] in the reference): the name defaults to the
file's base name (IgH's rule), the password to 0.

The header check: the AKD firmware file format is not public either, so a file is refused only when it is
empty, too large, or recognisably something else (an archive, an executable, a document, text) -- never
"verified" as AKD firmware. The JSON document says so (``header_check``).
"""

from __future__ import annotations

import os
import time
from typing import TYPE_CHECKING, Any

from akdctl.drive.gate import Gated
from akdctl.drive.operation import PlannedWrite, WritePlan
from akdctl.errors import AkdError, CommError, SafetyRefusal, UsageError

if TYPE_CHECKING:
    from akdctl.channels.foe_client import Progress
    from akdctl.connection import Connection

#: Largest file accepted, bytes [I]: AKD firmware images are a few MB; 32 MiB leaves room and bounds memory.
MAX_FIRMWARE_BYTES = 32 * 1024 * 1024
#: Seconds the drive may take to answer again after BOOT -> INIT: the AKD ESI's back-to-INIT timeout (50 s).
RESTART_TIMEOUT = 50.0
#: Per-packet FoE timeout, seconds: the AKD ESI's mailbox request/response timeout (3000 ms).
PACKET_TIMEOUT = 3.0

#: Leading bytes of formats a firmware file is not, with their names (the check can only exclude).
_NOT_FIRMWARE = (
    (b"PK\x03\x04", "a ZIP archive (unpack it first)"), (b"\x1f\x8b", "a gzip archive (unpack it first)"),
    (b"7z\xbc\xaf", "a 7-Zip archive"), (b"Rar!", "a RAR archive"), (b"\x7fELF", "an ELF executable"),
    (b"MZ", "a Windows executable"), (b"%PDF", "a PDF document"), (b"\xd4\xc3\xb2\xa1", "a pcap capture"),
    (b"\x0a\x0d\x0d\x0a", "a pcapng capture"), (b"{", "a JSON document"), (b"<?xml", "an XML document"),
)

RESTARTS = Gated("a firmware file", "the drive leaves operation, takes the file in BOOT and restarts with it")


class FirmwareRequest:
    """What the caller asks: the file's bytes and path, the name on the slave, the password."""

    def __init__(self, path: str, data: bytes, name: str | None = None, password: int = 0,
                 restart_timeout: float = RESTART_TIMEOUT) -> None:
        self.path, self.data, self.password, self.restart_timeout = path, data, password, restart_timeout
        self.name = name if name is not None else os.path.basename(path)


def check_file(data: bytes, name: str, path: str) -> str:
    """The file's verdict in words, or UsageError (exit 2) when it cannot be a firmware image."""
    if not data:
        raise UsageError(f"{path}: the file is empty; nothing to download")
    if len(data) > MAX_FIRMWARE_BYTES:
        raise UsageError(f"{path}: {len(data)} bytes is more than the {MAX_FIRMWARE_BYTES} a firmware file may have")
    for magic, what in _NOT_FIRMWARE:
        if data.startswith(magic):
            raise UsageError(f"{path} is {what}, not a firmware image; nothing was written")
    head = data[:4096]
    if all(32 <= b < 127 or b in (9, 10, 13) for b in head):
        raise UsageError(f"{path} is a text file, not a firmware image; nothing was written")
    if not name or len(name.encode("latin-1", "replace")) > 255 or any(c in name for c in "\0/\\"):
        raise UsageError(f"FoE file name {name!r} is not usable: 1..255 characters, no '/', '\\\\' or NUL")
    return "not a known other format (the AKD firmware format is not public: no header to verify)"


def _need_bus(conn: "Connection") -> Any:
    transport = conn.transport()
    if getattr(transport, "scheme", "") not in ("ecat", "ecat+soem"):
        raise UsageError(f"a firmware download needs akdctl as the EtherCAT master (target ecat://IFNAME[/POS] or "
                         f"ecat+soem://IFNAME[/POS]); {conn.target.display} cannot put the drive in BOOT")
    return transport


def drive_state(conn: "Connection") -> dict[str, Any]:
    """Identity, firmware and power stage as the drive reports them now (CoE 0x1018, 0x1008-0x100A, 0x6041)."""
    from akdctl.drive.identity import read_identity

    identity = read_identity(conn, pnus=False, im0=False).get("canopen", {})
    try:
        sw = int.from_bytes(conn.objects().upload(0x6041, 0)[:2], "little")
    except CommError:
        raise
    except AkdError:
        sw = None
    powered = None if sw is None else ((sw & 0x6F) in (0x27, 0x07) or (sw & 0x4F) == 0x0F)
    transport = conn.transport()
    al = transport.al_state() if hasattr(transport, "al_state") else None
    return {"identity": identity, "firmware": identity.get("software_version"), "statusword": sw,
            "powered": powered, "al_state": al}


def plan(conn: "Connection", request: FirmwareRequest, operation: str = "firmware update") -> WritePlan:
    """Check the file, read the drive; refuse a powered drive (exit 4) before anything changes."""
    verdict = check_file(request.data, request.name, request.path)
    _need_bus(conn)
    before = drive_state(conn)
    if before["powered"] is not False:
        why = ("its power stage is on" if before["powered"] else "its power stage cannot be read (statusword 0x6041)")
        raise SafetyRefusal(f"refusing the firmware download: {why}; disable the drive first "
                            "('akdctl disable'), the download restarts it")
    size = len(request.data)
    writes = [
        PlannedWrite("AL control 0x0120", "INIT", "INIT, then SM0/SM1 = the SII's bootstrap mailbox"),
        PlannedWrite("AL control 0x0120", "BOOT", "BOOT (bootstrap: only FoE)", RESTARTS),
        PlannedWrite(f"FoE file {request.name!r}", size, f"{size} bytes, password {request.password}"),
        PlannedWrite("AL control 0x0120", "INIT", "INIT: the drive takes the file and restarts"),
    ]
    return WritePlan(
        operation, conn.target.display, writes,
        preconditions=[f"drive disabled (statusword 0x{before['statusword']:04X})",
                       f"EtherCAT state {before['al_state'] or 'unknown'}"],
        notes=[f"file {request.path}: {verdict}",
               f"firmware now {before['firmware'] or 'unknown'}",
               f"then waits up to {request.restart_timeout:g} s for the drive to answer again",
               "an interrupted download can leave the drive on its backup firmware: keep power and cable in place"],
        enabled=False,
        data={"request": request, "before": before, "header_check": verdict})


def execute(conn: "Connection", plan: WritePlan, progress: "Progress | None" = None) -> dict[str, Any]:
    """Run the plan; the result document (before, download, restart, after, verdict)."""
    request: FirmwareRequest = plan.data["request"]
    transport = _need_bus(conn)
    started = time.monotonic()
    transfer = write_in_boot(transport, request, progress)
    restart_s = transfer.pop("restart_s")
    transport.open_mailbox()
    if getattr(transport, "scheme", "") == "ecat+soem":
        channel = conn.objects()
        if hasattr(channel, "slave"):  # the restarted slave, for the reads after
            channel.slave = transport.sdo_client.slave
    after = drive_state(conn)
    before = plan.data["before"]
    same = (before["identity"].get("serial") is not None
            and before["identity"].get("serial") == after["identity"].get("serial")
            and before["identity"].get("product_code") == after["identity"].get("product_code"))
    changed = before["firmware"] != after["firmware"]
    verdict = (f"downloaded {len(request.data)} bytes as {request.name!r}; the drive restarted in {restart_s:.1f} s; "
               f"firmware {before['firmware'] or '?'} -> {after['firmware'] or '?'}"
               + ("" if changed else " (unchanged: the drive kept its firmware)"))
    return {"target": conn.target.display, "file": request.path, "name": request.name, "bytes": len(request.data),
            "header_check": plan.data["header_check"], "before": before, "after": after, "download": transfer,
            "restart_s": round(restart_s, 3), "same_drive": same, "firmware_changed": changed,
            "seconds": round(time.monotonic() - started, 3), "verdict": verdict}


def write_in_boot(transport: Any, request: FirmwareRequest, progress: "Progress | None" = None) -> dict[str, Any]:
    """BOOT, FoE write, INIT and the wait for the restart -- on the raw master or on SOEM. If the transfer fails,
    the slave is still sent to INIT (a known state) before the error goes up."""
    from akdctl.channels.foe_client import FoeClient

    timeout = max(PACKET_TIMEOUT, float(getattr(transport.options, "timeout", 0) or 0))
    if getattr(transport, "scheme", "") == "ecat+soem":
        return transport.foe_write_in_boot(request.name, request.data, request.password, timeout,
                                           request.restart_timeout, progress)
    link = transport.enter_boot()
    client = FoeClient(link, link.sm0.length, timeout, who=f"slave {transport.position}")
    try:
        packets = client.write(request.name, request.data, request.password, progress)
    except BaseException:
        try:
            transport.leave_boot(request.restart_timeout)
        except AkdError:
            pass
        raise
    restart_s = transport.leave_boot(request.restart_timeout)
    return {"packets": packets, "packet_bytes": client.chunk, "busy": client.busy_count, "restart_s": restart_s}
