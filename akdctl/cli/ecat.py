"""``akdctl ecat scan|state|sii|reg|alias``: EtherCAT bus-level commands on an ``ecat://IFNAME[/POS]`` target.

These talk to the slave controllers, not to the drive's object dictionary, so
they need akdctl as the master (``ecat://``); through a gateway (``ecat-udp://``)
only the master itself could answer them. ``scan`` changes nothing but the
station addresses; ``state`` with no argument only reads; the writing ones
(``sii write``, ``reg write``, ``alias N``) plan, ask consent and execute through
``drive/`` (:mod:`akdctl.drive.ecat_registers`, :mod:`akdctl.drive.alias`).
``ecat foe`` and ``ecat pdo`` live in cli/ecat_foe.py and cli/ecat_pdo.py.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.consent import consent_plan, render_dry_run
from akdctl.cli.ecat_common import parse_int, read_user_file, write_user_file
from akdctl.cli.output import Doc
from akdctl.errors import UsageError

if TYPE_CHECKING:
    from akdctl.transport.ethercat_raw import EthercatRawTransport


def _bus() -> "EthercatRawTransport":
    """The raw transport with the bus counted and addressed, registered for closing at exit."""
    from akdctl.transport.ethercat_raw import EthercatRawTransport

    app = get_app()
    target = app.target
    if target.scheme != "ecat":
        raise UsageError(f"'ecat' commands need akdctl as the EtherCAT master: use a target ecat://IFNAME[/POSITION] "
                         f"(got {target.display})")
    transport = app.connection.new_transport()
    assert isinstance(transport, EthercatRawTransport)
    app._cleanups.append(transport.close)  # noqa: SLF001 - the context closes what commands open
    try:
        transport.open_bus()
    except Exception:
        transport.close()
        raise
    return transport


@click.group()
def ecat() -> None:
    """EtherCAT: scan slaves, read or change the AL state, read the SII (target ecat://IFNAME[/POSITION]).

    \b
    Examples:
      akdctl -T ecat://eth1 ecat scan
      akdctl -T ecat://eth1/0 ecat state PREOP
    """


@ecat.command("scan")
@click.option("--iface", metavar="IFNAME", help="Scan the EtherCAT segment on this interface (instead of -T ecat://IFNAME).")
def scan(iface: str | None) -> None:
    """List the slaves: position, station address, identity from the SII, AL state.

    What to scan, as every scan command: the target (-T ecat://IFNAME), or --iface IFNAME.

    \b
    Examples:
      akdctl -T ecat://eth1 ecat scan
      akdctl ecat scan --iface eth1
    """
    app = get_app()
    if iface is not None:
        from akdctl.transport.registry import parse_target

        app._target = parse_target(f"ecat://{iface}", "--iface")  # noqa: SLF001 - the scan's one target
    transport = _bus()
    assert transport.master is not None
    slaves = transport.master.scan(with_sii=True)
    data = []
    for s in slaves:
        sii = s.sii
        data.append({
            "position": s.position, "station": s.station,
            "vendor_id": sii.vendor_id if sii else None, "product_code": sii.product_code if sii else None,
            "revision": sii.revision if sii else None, "serial": sii.serial if sii else None,
            "name": sii.name if sii else "", "al_state": s.state_text, "al_status": s.al_status,
            "al_status_code": s.al_code, "akd": bool(sii and sii.is_akd),
        })
    doc = Doc(f"EtherCAT slaves on {transport.master.ifname}", app.target.display)
    doc.table(["pos", "station", "vendor", "product", "rev", "serial", "name", "AL state", "AKD"],
              [[d["position"], f"0x{d['station']:04X}", _hex(d["vendor_id"]), _hex(d["product_code"]),
                _hex(d["revision"]), d["serial"], d["name"], d["al_state"], "yes" if d["akd"] else "no"] for d in data])
    app.emit({"target": app.target.display, "slaves": data}, doc)


def _hex(value: int | None) -> str:
    return "" if value is None else f"0x{value:08X}"


@ecat.command("state")
@click.argument("state", required=False,
                type=click.Choice(["INIT", "PREOP", "BOOT", "SAFEOP", "OP"], case_sensitive=False))
@click.option("--dry-run", is_flag=True, help="Show the AL Control requests STATE takes from here; request none.")
def state(state: str | None, dry_run: bool) -> None:
    """Show the slave's AL state, or request STATE (stepping through PRE-OP and SAFE-OP).

    BOOT is entered from INIT with the SII's bootstrap mailbox (only FoE works there); leaving BOOT restarts the
    drive and waits until it answers again (up to 50 s).

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat state
      akdctl -T ecat://eth1/0 ecat state OP
      akdctl -T ecat://eth1/0 ecat state BOOT
    """
    from akdctl.protocol import ethercat as ec

    app = get_app()
    transport = _bus()
    master, slave = transport.master, transport.slave
    assert master is not None and slave is not None
    if state is None:
        status, code = master.al_status(slave.station)
    else:
        from akdctl.cli.consent import consent_plan, render_dry_run
        from akdctl.drive import ecat_state

        plan = ecat_state.plan(transport, app.target.display, state)
        if dry_run:
            return render_dry_run(app, plan)
        consent_plan(app, plan)   # never gated: shows the plan's notes (BOOT, the restart on leaving it)
        status, code = ecat_state.execute(transport, plan)
        slave = transport.slave
        assert slave is not None
    from akdctl.catalog.texts import al_status_line, al_status_text

    text = al_status_line(status, code)
    app.emit({"target": app.target.display, "position": slave.position, "station": slave.station,
              "al_state": ec.al_state_name(status), "al_status": status, "al_status_code": code,
              "al_status_text": al_status_text(code)},
             Doc(f"AL state of slave {slave.position} (station 0x{slave.station:04X})", app.target.display)
             .kv("state", text))


@ecat.group("sii", invoke_without_command=True)
@click.option("--raw", is_flag=True, help="Show the EEPROM bytes as a hex dump instead of decoding them.")
@click.pass_context
def sii(ctx: click.Context, raw: bool) -> None:
    """Read and decode the slave's SII EEPROM (identity, mailboxes, sync managers, PDOs); 'read'/'write' copy it.

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat sii
      akdctl -T ecat://eth1/0 ecat sii --raw
      akdctl -T ecat://eth1/0 ecat sii read -o akd.hex
    """
    if ctx.invoked_subcommand is not None:
        return
    app = get_app()
    transport = _bus()
    master, slave = transport.master, transport.slave
    assert master is not None and slave is not None
    image, data = master.read_sii(slave.station, full=True)
    title = f"SII of slave {slave.position} (station 0x{slave.station:04X})"
    if raw:
        doc = Doc(title, app.target.display)
        for off in range(0, len(data), 16):
            doc.line(f"{off:04X}: {data[off:off + 16].hex(' ')}")
        app.emit({"target": app.target.display, "hex": data.hex()}, doc)
        return
    info = image.to_json()
    doc = Doc(title, app.target.display)
    doc.kv("name", info["name"]).kv("order", info["order"]).kv("firmware", info["firmware"])
    doc.kv("vendor", f"0x{image.vendor_id:08X}").kv("product", f"0x{image.product_code:08X}")
    doc.kv("revision", f"0x{image.revision:08X}").kv("serial", image.serial).kv("AKD", "yes" if image.is_akd else "no")
    doc.kv("mailbox", f"out 0x{image.std_rx_offset:04X}/{image.std_rx_size}  in 0x{image.std_tx_offset:04X}/"
                      f"{image.std_tx_size}  protocols {', '.join(image.protocol_names) or 'none'}")
    doc.table(["SM", "start", "length", "control", "type"],
              [[i, f"0x{s.start:04X}", s.length, f"0x{s.control:02X}", s.type_name]
               for i, s in enumerate(image.sync_managers)])
    pdos = [("Tx", p) for p in image.tx_pdos] + [("Rx", p) for p in image.rx_pdos]
    doc.table(["dir", "PDO", "SM", "entries"],
              [[d, f"0x{p.index:04X}", p.sm, ", ".join(f"{e.index:04X}:{e.subindex:02X}/{e.bit_length}"
                                                        for e in p.entries)] for d, p in pdos])
    app.emit({"target": app.target.display, **info}, doc)


# ---------------------------------------------------------------------- SII files, registers, alias

@sii.command("read")
@click.option("-o", "--output", "output", required=True, type=click.Path(dir_okay=False),
              help="File to write; Intel HEX when it ends in .hex/.ihex or with --format ihex, else raw binary.")
@click.option("--format", "fmt", type=click.Choice(["auto", "bin", "ihex"]), default="auto", show_default=True,
              help="File format.")
def sii_read(output: str, fmt: str) -> None:
    """Copy the slave's whole SII (up to its end marker) into a file, raw binary or Intel HEX.

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat sii read -o akd.bin
      akdctl -T ecat://eth1/0 ecat sii read -o akd.hex
    """
    from akdctl.drive.ecat_registers import read_sii
    from akdctl.protocol.sii import encode_ihex

    app = get_app()
    data = read_sii(app.connection)
    ihex = fmt == "ihex" or (fmt == "auto" and output.lower().endswith((".hex", ".ihex")))
    write_user_file(output, encode_ihex(data).encode("ascii") if ihex else data)
    app.emit({"target": app.target.display, "bytes": len(data), "output": output, "format": "ihex" if ihex else "bin"},
             Doc("SII read", app.target.display).kv("bytes", len(data)).kv("written to", output)
             .kv("format", "Intel HEX" if ihex else "raw binary"))


def _load_sii_file(path: str, fmt: str) -> bytes:
    from akdctl.protocol.errors import CodecError
    from akdctl.protocol.sii import decode_ihex

    data = read_user_file(path, 0x20000)
    ihex = fmt == "ihex" or (fmt == "auto" and data[:1] == b":")
    if not ihex:
        return data
    try:
        return decode_ihex(data.decode("ascii"))
    except (CodecError, UnicodeDecodeError) as exc:
        raise UsageError(f"{path}: {exc}") from None


@sii.command("write")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--format", "fmt", type=click.Choice(["auto", "bin", "ihex"]), default="auto", show_default=True,
              help="File format (auto: Intel HEX when the file starts with ':').")
@click.option("--fix-crc", is_flag=True, help="Set word 7's CRC from words 0-6 instead of refusing a wrong one.")
@click.option("--force", is_flag=True, help="Write an image made for another vendor/product.")
@click.option("--dry-run", is_flag=True, help="Show the words that would change; write nothing.")
def sii_write(file: str, fmt: str, fix_crc: bool, force: bool, dry_run: bool) -> None:
    """Write an SII image (raw binary or Intel HEX) to the slave's EEPROM, word by word, and verify it.

    The CRC in word 7 must match words 0-6 (or --fix-crc); consent required.

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat sii write akd.bin --dry-run
      akdctl -T ecat://eth1/0 -y ecat sii write akd.hex
    """
    from akdctl.drive import ecat_registers as regs

    app = get_app()
    plan = regs.plan_sii_write(app.connection, _load_sii_file(file, fmt), file, fix_crc, force)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)
    result = regs.execute_sii_write(app.connection, plan)
    app.emit(result, Doc("SII write", app.target.display).kv("words written", result["words_written"])
             .kv("verified", "yes").line("the slave loads words 0-7 at its next power-on"))


@ecat.group("reg")
def reg() -> None:
    """Read or write ESC registers of the slave (as IgH's reg_read/reg_write; target ecat://IFNAME[/POS]).

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat reg read 0x0130 6
      akdctl -T ecat://eth1/0 -y ecat reg write 0x0204 0x0000 --size 2
    """


@reg.command("read")
@click.argument("address")
@click.argument("size", required=False, default="2")
def reg_read(address: str, size: str) -> None:
    """Read SIZE bytes (default 2) at register ADDRESS; shown as bytes and as a little-endian number.

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat reg read 0x0012
      akdctl -T ecat://eth1/0 ecat reg read 0x0800 16
    """
    from akdctl.drive.ecat_registers import read_registers

    app = get_app()
    addr, n = parse_int(address, "register address"), parse_int(size, "size")
    data = read_registers(app.connection, addr, n)
    value = int.from_bytes(data, "little") if n <= 8 else None
    doc = Doc(f"register 0x{addr:04X} ({n} byte{'s' if n != 1 else ''})", app.target.display)
    doc.kv("bytes", data.hex(" "))
    if value is not None:
        doc.kv("value", f"{value} (0x{value:0{2 * n}X})")
    app.emit({"target": app.target.display, "address": addr, "size": n, "hex": data.hex(), "value": value}, doc)


@reg.command("write")
@click.argument("address")
@click.argument("value")
@click.option("--size", type=click.IntRange(1, 8), default=None,
              help="Bytes of VALUE as a little-endian number (default: the smallest of 1/2/4/8 that holds it).")
@click.option("--hex", "as_hex", is_flag=True, help="VALUE is raw bytes in hex (e.g. 0102ff), any length.")
@click.option("--force", is_flag=True, help="Write AL control, watchdog, station-address or EEPROM registers too.")
@click.option("--dry-run", is_flag=True, help="Show what would be written; write nothing.")
def reg_write(address: str, value: str, size: int | None, as_hex: bool, force: bool, dry_run: bool) -> None:
    """Write VALUE at register ADDRESS (consent); AL control, watchdog and similar registers need --force.

    \b
    Examples:
      akdctl -T ecat://eth1/0 -y ecat reg write 0x0204 0 --size 2
      akdctl -T ecat://eth1/0 ecat reg write 0x0F80 --hex 01020304 --dry-run
    """
    from akdctl.drive import ecat_registers as regs

    app = get_app()
    addr = parse_int(address, "register address")
    if as_hex:
        try:
            data = bytes.fromhex(value)
        except ValueError:
            raise UsageError(f"--hex value {value!r} is not hex bytes") from None
    else:
        number = parse_int(value, "value")
        n = size or next((k for k in (1, 2, 4, 8) if 0 <= number < 1 << (8 * k)), 0)
        if n == 0 or not 0 <= number < 1 << (8 * n):
            raise UsageError(f"value {value} does not fit {size or 8} unsigned byte(s)")
        data = number.to_bytes(n, "little")
    plan = regs.plan_register_write(app.connection, addr, data, force)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)
    result = regs.execute_register_write(app.connection, plan)
    app.emit(result, Doc(f"register 0x{addr:04X}", app.target.display).kv("before", plan.data["before"].hex(" "))
             .kv("written", data.hex(" ")).kv("read back", bytes.fromhex(result["read_back"]).hex(" ")))


@ecat.command("alias")
@click.argument("alias", required=False)
@click.option("--via", type=click.Choice(["sii", "coe"]), default="sii", show_default=True,
              help="sii: SII word 4 + CRC (any slave; the AKD saves all RAM parameters); coe: FBUS.PARAM03 (0x36E7).")
@click.option("--dry-run", is_flag=True, help="Show what would be written; write nothing.")
def alias(alias: str | None, via: str, dry_run: bool) -> None:
    """Show the station alias (register 0x0012, SII word 4 + CRC, FBUS.PARAM03, FBUS.PARAM05 bit 5), or set it.

    A new alias reaches register 0x0012 at the drive's next power cycle.

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat alias
      akdctl -T ecat://eth1/0 -y ecat alias 1001
      akdctl -T ecat://eth1/0 -y ecat alias 7 --via coe
    """
    from akdctl.drive import alias as op

    app = get_app()
    if alias is None:
        info = op.read(app.connection)
        app.emit(info, _alias_doc("station alias", info))
        return
    plan = op.plan(app.connection, parse_int(alias, "alias"), via)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)  # shows the plan's notes: the power cycle, and DRV.NVSAVE on an SII word 4 write
    result = op.execute(app.connection, plan)
    doc = _alias_doc(f"station alias set to {result['alias']} ({via})", result["after"])
    doc.line("power-cycle the drive: the master sees the new alias in register 0x0012 after that"
             if result["power_cycle_needed"] else "register 0x0012 already shows it")
    app.emit(result, doc)


def _alias_doc(title: str, info: dict[str, Any]) -> Doc:
    doc = Doc(title, get_app().target.display)
    doc.kv("register 0x0012", info["register_0x0012"])
    crc = "CRC ok" if info["sii_crc_ok"] else f"CRC WRONG (expected 0x{info['sii_crc_expected']:02X})"
    doc.kv("SII word 4", f"{info['sii_word4']} ({crc})")
    doc.kv("FBUS.PARAM03", "unreadable" if info["fbus_param03"] is None else info["fbus_param03"])
    bit5 = info["fbus_param05_bit5"]
    doc.kv("FBUS.PARAM05 bit 5", "unreadable" if bit5 is None else int(bit5))
    doc.kv("alias taken from", info["effective_source"])
    if info["pending_power_cycle"]:
        doc.line("register 0x0012 and the stored alias differ: a power cycle of the drive applies it")
    return doc


def _register() -> None:
    """The subgroups that live in modules of their own (one job each), loaded with this one."""
    from akdctl.cli.ecat_foe import foe_group
    from akdctl.cli.ecat_pdo import ecat_pdo

    ecat.add_command(foe_group, "foe")
    ecat.add_command(ecat_pdo, "pdo")


_register()
