"""``akdctl ecat scan|state|sii``: EtherCAT bus-level commands on an ``ecat://IFNAME[/POS]`` target.

These talk to the slave controllers, not to the drive's object dictionary, so
they need akdctl as the master (``ecat://``); through a gateway (``ecat-udp://``)
only the master itself could answer them. ``scan`` changes nothing but the
station addresses; ``state`` with no argument only reads.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import click

from akdctl.cli.context import get_app
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
@click.argument("state", required=False, type=click.Choice(["INIT", "PREOP", "SAFEOP", "OP"], case_sensitive=False))
def state(state: str | None) -> None:
    """Show the slave's AL state, or request STATE (stepping through PRE-OP and SAFE-OP).

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat state
      akdctl -T ecat://eth1/0 ecat state OP
    """
    from akdctl.protocol import ethercat as ec

    app = get_app()
    transport = _bus()
    master, slave = transport.master, transport.slave
    assert master is not None and slave is not None
    if state is not None:
        wanted = ec.parse_al_state(state)
        current = slave.al_status & 0x0F
        if wanted == ec.AlState.INIT or wanted < current:
            master.request_state(slave.station, wanted)
        else:
            if current in (ec.AlState.INIT, ec.AlState.BOOT) or slave.al_status & ec.AL_ERROR_FLAG:
                transport.open_mailbox()  # INIT -> PRE-OP with SM0/SM1 from the SII
            for step in (ec.AlState.SAFEOP, ec.AlState.OP):
                if step <= wanted and master.al_status(slave.station)[0] & 0x0F < step:
                    master.request_state(slave.station, step)
    status, code = master.al_status(slave.station)
    text = ec.describe_al(status, code)
    app.emit({"target": app.target.display, "position": slave.position, "station": slave.station,
              "al_state": ec.al_state_name(status), "al_status": status, "al_status_code": code,
              "al_status_text": ec.al_status_text(code)},
             Doc(f"AL state of slave {slave.position} (station 0x{slave.station:04X})", app.target.display)
             .kv("state", text))


@ecat.command("sii")
@click.option("--raw", is_flag=True, help="Show the EEPROM bytes as a hex dump instead of decoding them.")
def sii(raw: bool) -> None:
    """Read and decode the slave's SII EEPROM (identity, mailboxes, sync managers, PDOs).

    \b
    Examples:
      akdctl -T ecat://eth1/0 ecat sii
      akdctl -T ecat://eth1/0 ecat sii --raw
    """
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
