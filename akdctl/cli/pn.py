"""``akdctl pn scan|set-name|set-ip|blink``: PROFINET DCP on a local network interface.

These talk to the network, not to one target: ``--iface`` names the card the
drives are on. DEVICE is a MAC address (``00:1b:..``) or a station name.
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc

IFACE = click.option("--iface", "-i", required=True, metavar="IFNAME",
                     help="Network interface the PROFINET devices are on (e.g. eth0).")


def _client(iface: str):  # type: ignore[no-untyped-def]
    from akdctl.transport.dcp import DcpClient

    app = get_app()
    return DcpClient(iface, timeout=app.options.timeout, tracer=app.options.tracer)


def _hex(value: int | None) -> str:
    return "" if value is None else f"0x{value:04X}"


@click.group()
def pn() -> None:
    """PROFINET: scan for devices (DCP), name, address and blink them.

    \b
    Examples:
      akdctl pn scan --iface eth1
      akdctl pn blink --iface eth1 akd-axis1
    """


@pn.command("scan")
@IFACE
@click.option("--wait", type=click.FloatRange(min=0.1, max=60), default=None, metavar="SECONDS",
              help="How long to collect answers (default: the --timeout).")
def scan(iface: str, wait: float | None) -> None:
    """List the PROFINET devices on IFNAME: station name, IP, MAC, vendor/device ID, role.

    \b
    Examples:
      akdctl pn scan --iface eth1
      akdctl pn scan --iface eth1 --wait 3 --json
    """
    with _client(iface) as client:
        stations = client.identify(timeout=wait)
    app = get_app()
    rows = [[s.name or "(no name)", s.ip, s.mac, _hex(s.vendor_id), _hex(s.device_id), s.role_text, s.family]
            for s in stations]
    doc = Doc(f"PROFINET devices on {iface}", iface)
    if rows:
        doc.table(["station name", "IP", "MAC", "vendor", "device", "role", "type"], rows)
    else:
        doc.line("no device answered DCP identify")
    app.emit({"interface": iface, "devices": [s.to_json() for s in stations]}, doc)


DRY_RUN = click.option("--dry-run", is_flag=True,
                       help="Find the device and show what it holds and would hold; send no Set.")


def _set(iface: str, plan_of: Any, render: Any, dry_run: bool) -> None:
    """plan -> consent (notes) -> execute -> render: the one path of both DCP Set commands (drive/dcp_settings)."""
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import dcp_settings

    app = get_app()
    plan = plan_of(lambda: _client(iface))
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)
    result = dcp_settings.execute(lambda: _client(iface), plan)
    app.emit(result, render(result))


@pn.command("set-name")
@IFACE
@click.argument("device")
@click.argument("name")
@click.option("--temporary", is_flag=True, help="Keep the name only until the device restarts.")
@DRY_RUN
def set_name(iface: str, device: str, name: str, temporary: bool, dry_run: bool) -> None:
    """Give DEVICE (MAC or current station name) the station name NAME.

    \b
    Examples:
      akdctl pn set-name --iface eth1 00:23:1b:00:00:01 akd-axis1
      akdctl pn set-name --iface eth1 akd-axis1 akd-axis2 --dry-run
    """
    from akdctl.drive import dcp_settings

    _set(iface, lambda open_client: dcp_settings.plan_name(open_client, device, name, permanent=not temporary),
         lambda r: f"{r['mac']}: station name set to {r['name']!r}" + ("" if r["permanent"] else " (temporary)"),
         dry_run)


@pn.command("set-ip")
@IFACE
@click.argument("device")
@click.argument("ip")
@click.option("--netmask", default="255.255.255.0", show_default=True)
@click.option("--gateway", default="0.0.0.0", show_default=True)
@click.option("--temporary", is_flag=True, help="Keep the address only until the device restarts.")
@DRY_RUN
def set_ip(iface: str, device: str, ip: str, netmask: str, gateway: str, temporary: bool, dry_run: bool) -> None:
    """Give DEVICE (MAC or station name) the IPv4 address IP.

    \b
    Examples:
      akdctl pn set-ip --iface eth1 akd-axis1 192.168.0.10 --netmask 255.255.255.0
    """
    from akdctl.drive import dcp_settings

    _set(iface, lambda open_client: dcp_settings.plan_ip(open_client, device, ip, netmask, gateway,
                                                         permanent=not temporary),
         lambda r: f"{r['mac']}: IP set to {r['ip']}/{r['netmask']} via {r['gateway']}"
         + ("" if r["permanent"] else " (temporary)"), dry_run)


@pn.command("blink")
@IFACE
@click.argument("device")
def blink(iface: str, device: str) -> None:
    """Flash DEVICE's LED (DCP signal) so you can find it in the cabinet.

    \b
    Examples:
      akdctl pn blink --iface eth1 akd-axis1
    """
    from akdctl.protocol import dcp
    from akdctl.transport.dcp import find_station

    with _client(iface) as client:
        station = find_station(client, device)
        client.blink(dcp.mac_bytes(station.mac))
    get_app().emit({"mac": station.mac, "name": station.name, "blink": True},
                   f"{station.mac} ({station.name or 'no name'}): LED flashing")
