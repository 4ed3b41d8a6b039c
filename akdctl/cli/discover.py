"""``akdctl discover``: find the drives of a line on every transport given, one table, an inventory file.

Why one command over the four ``scan`` commands: a machine builder wants the line, not a bus -- which drives are
there, on which transport, who they are (vendor, model, firmware, serial), and an inventory file to run
``--inventory`` commands on. Each source reuses the transport's own discovery (DCP identify, ListIdentity, the
EtherCAT master's scan, CANopen's node scan) and each drive found is then identified through its target with the
one identity reader (:mod:`akdctl.drive.identity`), several at once. akdctl never broadcasts unless told: with
no source option, only the simulator's named drives are listed.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import AkdError, UsageError
from akdctl.protocol.record import Record

#: Drives identified at once (each its own connection; real links are slow, the simulator is quick).
IDENTIFY_AT_ONCE = 8


class Found(Record):
    """One drive a source found: how to reach it (``target``), what the source already knew, and its identity."""

    __slots__ = ("transport", "target", "name", "alias", "identity", "error", "same_as", "identified")

    def __init__(self, transport: str, target: str, name: str = "", alias: str = "",
                 identity: dict[str, Any] | None = None, error: str = "") -> None:
        self.transport = transport
        self.target = target
        self.name = name
        self.alias = alias
        self.identity = dict(identity or {})
        self.error = error
        self.same_as = ""  # the target of the first entry reporting the same serial number
        self.identified = False  # the source's scan already read the identity (a bus: one master, no reopening)

    @property
    def key(self) -> str:
        serial = self.identity.get("serial")
        return f"serial:{serial}" if serial not in (None, "") else ""

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {"transport": self.transport, "target": self.target, "name": self.name,
                                "alias": self.alias, "key": self.key or None, **self.identity}
        if self.error:
            data["error"] = self.error
        if self.same_as:
            data["same_drive_as"] = self.same_as
        return data


def _sim_drives() -> list[Found]:
    from akdctl.sim.drive import state_dir

    directory = state_dir()
    names = sorted({p.name[4:-5] for p in directory.glob("sim-*.json")} |
                   {p.name[4:-5] for p in directory.glob("sim-*.lock")}) if directory.is_dir() else []
    return [Found("sim", "sim" if n == "default" else f"sim://{n}", name=n) for n in names]


def _eip(hosts: tuple[str, ...], iface: str | None, options: Any) -> list[Found]:
    from akdctl.transport.ethernetip import list_identity

    found: list[Found] = []
    asks: list[tuple[str, int, Any]] = []
    for host in hosts:
        name, _, port = host.partition(":")
        asks.append((name, int(port) if port else 44818, None))
    if iface:
        from akdctl.cli.eip import _interface_addresses

        own, address = _interface_addresses(iface)
        asks.append((address, 44818, own))
    for address, port, own in asks:
        answers = list_identity(address, port, options, broadcast_from=own) if own else list_identity(address, port, options)
        if not answers:
            found.append(Found("eip", f"eip://{address}:{port}",
                               error=f"no ListIdentity answer within {options.timeout:g} s"))
        for host, ident in answers:
            target = f"eip://{host}" + ("" if port == 44818 else f":{port}")
            found.append(Found("eip", target, name=str(getattr(ident, "product_name", "") or ""),
                               identity={"serial": getattr(ident, "serial", None)}))
    return found


def _pn_hosts(hosts: tuple[str, ...]) -> list[Found]:
    return [Found("pn", f"pn://{host}") for host in hosts]


def _pn_iface(iface: str, timeout: float) -> list[Found]:
    from akdctl.cli.pn import _client

    with _client(iface) as client:
        stations = client.identify(timeout=timeout)
    return [Found("pn", f"pn://{s.ip}", name=s.name or "", alias=s.name or "") for s in stations if s.ip]


def parse_stations(text: str) -> list[int]:
    """``1001-1016``, ``1001,1003`` -> station addresses (1..65535, at most 256 of them)."""
    numbers: set[int] = set()
    for part in text.split(","):
        low, dash, high = part.strip().partition("-")
        try:
            first = int(low, 0)
            last = int(high, 0) if dash else first
        except ValueError:
            raise UsageError(f"--stations {text!r}: {part.strip()!r} is not a station address or range") from None
        if not 1 <= first <= last <= 0xFFFF:
            raise UsageError(f"--stations {text!r}: station addresses are 1..65535, low to high")
        numbers.update(range(first, last + 1))
        if len(numbers) > 256:
            raise UsageError(f"--stations {text!r}: at most 256 stations per discover")
    return sorted(numbers)


def _ecat_udp(gateways: tuple[str, ...], stations: str) -> list[Found]:
    numbers = parse_stations(stations)
    return [Found("ecat-udp", f"ecat-udp://{gw}/{n}", alias=str(n)) for gw in gateways for n in numbers]


def _bus_found(transport: str, target: str, name: str, alias: str, vendor: int | None, product: int | None,
               revision: int | None, serial: int | None, firmware: str | None = None) -> Found:
    from akdctl.catalog.texts import CANOPEN_VENDORS

    identity: dict[str, Any] = {"vendor": CANOPEN_VENDORS.get(vendor) if vendor is not None else None,
                                "model": name or (f"product 0x{product:08X}" if product is not None else None),
                                "revision": revision, "serial": str(serial) if serial is not None else None,
                                "firmware": firmware}
    found = Found(transport, target, name=name, alias=alias,
                  identity={k: v for k, v in identity.items() if v not in (None, "")})
    found.identified = True
    return found


def _can(buses: tuple[str, ...], nodes: str, app: Any) -> list[Found]:
    """The nodes on each CANopen bus (``INTERFACE/CHANNEL``), by the transport's own scan (0x1018 of each)."""
    from akdctl.cli.can import parse_nodes
    from akdctl.cli.context import AppContext
    from akdctl.transport.canopen_bus import CanopenTransport

    wanted = parse_nodes(nodes)
    found: list[Found] = []
    for spec in buses:
        bus, _, query = spec.partition("?")
        query = f"?{query}" if query else ""
        if bus.count("/") != 1:
            raise UsageError(f"--can {spec!r}: INTERFACE/CHANNEL[?OPTIONS], e.g. socketcan/can0")
        probe = AppContext(target_text=f"can://{bus}/{wanted[0]}{query}", timeout=app.timeout, retries=app.retries)
        try:
            transport = probe.transport()
            assert isinstance(transport, CanopenTransport)
            for node in transport.scan(wanted):
                found.append(_bus_found("can", f"can://{bus}/{node.node}{query}", node.device_name or "", str(node.node),
                                        node.vendor_id, node.product_code, node.revision, node.serial))
        finally:
            probe.close()
    return found


def _ecat(interfaces: tuple[str, ...], app: Any) -> list[Found]:
    """The slaves on each raw EtherCAT interface, by akdctl's master (identity from each slave's SII)."""
    from akdctl.cli.context import AppContext
    from akdctl.transport.ethercat_raw import EthercatRawTransport

    found: list[Found] = []
    for interface in interfaces:
        probe = AppContext(target_text=f"ecat://{interface}", timeout=app.timeout, retries=app.retries)
        transport = probe.connection.new_transport()
        assert isinstance(transport, EthercatRawTransport)
        try:
            transport.open_bus()
            assert transport.master is not None
            for slave in transport.master.scan(with_sii=True):
                sii = slave.sii
                found.append(_bus_found("ecat", f"ecat://{interface}/{slave.position}", sii.name if sii else "",
                                        f"0x{slave.station:04X}", sii.vendor_id if sii else None,
                                        sii.product_code if sii else None, sii.revision if sii else None,
                                        sii.serial if sii else None))
        finally:
            transport.close()
            probe.close()
    return found


def _identify(found: Found, timeout: float, retries: int | None) -> Found:
    """Who the drive at ``found.target`` is, through the one identity reader; a silent target is kept with its
    error (discover lists what it asked and what answered)."""
    if found.error or found.identified:
        return found
    from akdctl.cli.context import AppContext
    from akdctl.drive.identity import read_identity, summary

    app = AppContext(target_text=found.target, timeout=timeout, retries=retries if retries is not None else 0)
    try:
        identity = summary(read_identity(app.connection))
        found.identity = {**{k: v for k, v in found.identity.items() if v not in (None, "")}, **identity}
    except AkdError as exc:
        found.error = exc.message
    finally:
        app.close()
    return found


@click.command("discover")
@click.option("--sim", "with_sim", is_flag=True, help="The simulator's named drives (the default with no source).")
@click.option("--eip", "eip_hosts", multiple=True, metavar="HOST[:PORT]", help="Ask HOST by ListIdentity (repeatable).")
@click.option("--eip-iface", metavar="IFNAME", help="Broadcast ListIdentity on this interface.")
@click.option("--pn", "pn_hosts", multiple=True, metavar="HOST[:PORT]", help="Identify the PROFINET drive at HOST (repeatable).")
@click.option("--pn-iface", metavar="IFNAME", help="DCP identify on this interface (needs CAP_NET_RAW).")
@click.option("--ecat-udp", "gateways", multiple=True, metavar="HOST[:PORT]",
              help="Ask the stations of this ETG.8200 mailbox gateway (repeatable; see --stations).")
@click.option("--stations", default="1001-1008", show_default=True, metavar="RANGE",
              help="With --ecat-udp: station addresses to ask, e.g. 1001-1016.")
@click.option("--can", "can_buses", multiple=True, metavar="INTERFACE/CHANNEL",
              help="Scan this CANopen bus for nodes (repeatable; see --nodes).")
@click.option("--nodes", default="1-127", show_default=True, metavar="RANGE", help="With --can: node ids to ask.")
@click.option("--ecat", "ecat_ifaces", multiple=True, metavar="IFNAME",
              help="Scan the EtherCAT slaves on this raw interface as the master (needs CAP_NET_RAW).")
@click.option("--write-inventory", "inventory_path", metavar="FILE", type=click.Path(dir_okay=False),
              help="Write the drives that answered as an inventory file (TOML) for --inventory.")
@click.option("--tag", "tags", multiple=True, metavar="TAG", help="Tag every drive of the written inventory (repeatable).")
def discover(with_sim: bool, eip_hosts: tuple[str, ...], eip_iface: str | None, pn_hosts: tuple[str, ...],
             pn_iface: str | None, gateways: tuple[str, ...], stations: str, can_buses: tuple[str, ...], nodes: str,
             ecat_ifaces: tuple[str, ...], inventory_path: str | None, tags: tuple[str, ...]) -> None:
    """Find drives on every transport given: one table of transport, target, vendor, model, firmware, serial,
    name and alias; --write-inventory writes the line's inventory.

    With no source option only the simulator's named drives are listed: akdctl never scans a network unasked.

    \b
    Examples:
      akdctl discover
      akdctl discover --eip 192.168.0.20 --pn 192.168.0.21 --write-inventory line3.toml --tag line3
      akdctl discover --ecat-udp 127.0.0.1:34980 --stations 1001-1016 --json
      akdctl discover --can socketcan/can0 --nodes 1-16 --ecat eth1
    """
    from akdctl.drive import inventory

    app = get_app()
    options = app.options
    sources = bool(eip_hosts or eip_iface or pn_hosts or pn_iface or gateways or can_buses or ecat_ifaces)
    if inventory_path:
        from pathlib import Path

        from akdctl.io.atomic import require_directory

        require_directory(Path(inventory_path))  # refused before anything is asked
    for tag in tags:
        if not inventory._NAME.fullmatch(tag):
            raise UsageError(f"--tag {tag!r}: letters, digits, '.', '_' or '-'")
    candidates: list[Found] = []
    if pn_hosts:
        candidates += _pn_hosts(pn_hosts)
    if pn_iface:
        candidates += _pn_iface(pn_iface, options.timeout)
    if gateways:
        candidates += _ecat_udp(gateways, stations)
    if eip_hosts or eip_iface:
        candidates += _eip(eip_hosts, eip_iface, options)
    if ecat_ifaces:
        candidates += _ecat(ecat_ifaces, app)
    if can_buses:
        candidates += _can(can_buses, nodes, app)
    if with_sim or not sources:  # last: a simulated drive served on a face is listed by its network target
        candidates += _sim_drives()
    with ThreadPoolExecutor(max_workers=IDENTIFY_AT_ONCE) as pool:
        found = list(pool.map(lambda f: _identify(f, options.timeout, app.retries), candidates))
    answered = [f for f in found if not f.error]
    silent = [f for f in found if f.error]
    _mark_same_drives(answered)
    if inventory_path:
        taken: set[str] = set()
        drives = [inventory.LineDrive(inventory.unique_name(f.name or _name_from(f), taken), f.target,
                                      f.key or None, tags) for f in answered if not f.same_as]
        if not drives:
            raise UsageError("no drive answered: no inventory written")
        inventory.write(inventory_path, inventory.dump(drives, comment="written by akdctl discover"))
    data = {"drives": [f.to_json() for f in answered], "silent": [f.to_json() for f in silent],
            "inventory": inventory_path}

    def human() -> Doc:
        doc = Doc(f"drives found: {len(answered)}", "discover")
        doc.table(["transport", "target", "vendor", "model", "firmware", "serial", "name", "alias"],
                  [[f.transport, f.target, f.identity.get("vendor", ""), f.identity.get("model", ""),
                    f.identity.get("firmware", ""), f.identity.get("serial", ""), f.name,
                    f.alias or (f"same drive as {f.same_as}" if f.same_as else "")] for f in answered])
        if silent and (not gateways or app.verbose):
            for f in silent:
                doc.line(f"{f.target}: {f.error}")
        elif silent:
            doc.line(f"{len(silent)} address(es) did not answer (-v lists them)")
        if inventory_path:
            doc.line(f"inventory written: {inventory_path} ({sum(1 for f in answered if not f.same_as)} drive(s))")
        return doc

    app.emit(data, human)


def _name_from(found: Found) -> str:
    if found.transport == "ecat-udp":
        return f"station-{found.alias}"
    return found.target.split("://", 1)[-1].replace(":", "-").replace("/", "-")


def _mark_same_drives(found: list[Found]) -> None:
    """Two targets reporting one serial number are one drive reached twice (by two transports, or a name and
    an address): the first keeps the inventory entry, the others are listed as the same drive (an inventory
    holds one entry per drive)."""
    first: dict[str, Found] = {}
    for f in found:
        if f.key and f.key in first:
            f.same_as = first[f.key].target
        elif f.key:
            first[f.key] = f


__all__ = ["discover"]
