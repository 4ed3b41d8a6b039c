"""``akdctl eip``: EtherNet/IP discovery (ListIdentity) and AKD parameters through the Parameter object."""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import UsageError


@click.group()
def eip() -> None:
    """EtherNet/IP: find drives (ListIdentity), AKD parameters by the Parameter object 0x0F."""


def _broadcast_address(iface: str) -> str:
    """The IPv4 broadcast address of ``iface`` (SIOCGIFBRDADDR)."""
    import fcntl
    import socket
    import struct

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        raw = fcntl.ioctl(sock.fileno(), 0x8919, struct.pack("256s", iface.encode()[:15]))
    except OSError as exc:
        raise UsageError(f"--iface {iface}: no IPv4 broadcast address ({exc.strerror})") from None
    finally:
        sock.close()
    return socket.inet_ntoa(raw[20:24])


@eip.command("scan")
@click.argument("host", required=False)
@click.option("--iface", metavar="IFNAME", help="Broadcast ListIdentity on this interface (never done by default).")
@click.option("--port", type=click.IntRange(1, 65535), default=44818, show_default=True, help="UDP port.")
@click.option("--wait", type=click.FloatRange(0.05, 60), default=None, metavar="SECONDS",
              help="How long to collect answers (default: --timeout).")
def scan(host: str | None, iface: str | None, port: int, wait: float | None) -> None:
    """ListIdentity: unicast to HOST, or broadcast on --iface IFNAME."""
    from akdctl.catalog.texts import cip_vendor_name
    from akdctl.transport.ethernetip import list_identity

    if (host is None) == (iface is None):
        raise UsageError("give a HOST to ask, or --iface IFNAME to broadcast on (akdctl never broadcasts by default)")
    app = get_app()
    address = host if host is not None else _broadcast_address(iface)  # type: ignore[arg-type]
    found = list_identity(address, port, app.options, broadcast=iface is not None, wait=wait)
    rows = [{"address": peer, **ident.to_json(), "vendor_name": cip_vendor_name(ident.vendor)} for peer, ident in found]

    def human() -> Doc:
        doc = Doc("EtherNet/IP devices (ListIdentity)", address)
        doc.table(["address", "vendor", "device type", "product code", "revision", "serial", "name"],
                  [[r["address"], r["vendor_name"], r["device_type"], r["product_code"], r["revision"],
                    f"0x{r['serial']:08X}", r["product_name"]] for r in rows])
        if not rows:
            doc.kv("found", "nothing answered")
        return doc

    app.emit({"query": address, "devices": rows}, human)


@eip.group("param")
def param() -> None:
    """AKD parameters by the Parameter object 0x0F (instance = parameter number)."""


def _channel(app: Any) -> Any:
    from akdctl.cli.cip import attributes

    return attributes(app)


@param.command("get")
@click.argument("name", metavar="NAME|INSTANCE")
def param_get(name: str) -> None:
    """Read a parameter's value, type and length (attributes 1, 5, 6)."""
    from akdctl.drive import eip_params

    ref = eip_params.resolve(name)
    app = get_app()
    result = eip_params.read(_channel(app), ref)
    app.emit({"target": app.target.display, **result},
             lambda: Doc(f"parameter {ref.name or ref.instance}", app.target.display)
             .kv("instance", ref.instance).kv("type", result["type"]).kv("length", result["length"])
             .kv("value", result["value"]).kv("raw", result["raw"]))


@param.command("set")
@click.argument("name", metavar="NAME|INSTANCE")
@click.argument("value", metavar="VALUE")
def param_set(name: str, value: str) -> None:
    """Write a parameter: its type and length are read first, floats travel x1000."""
    from akdctl.drive import eip_params

    ref = eip_params.resolve(name)
    app = get_app()
    result = eip_params.write(_channel(app), ref, value)
    app.emit({"target": app.target.display, **result},
             lambda: Doc(f"parameter {ref.name or ref.instance} written", app.target.display)
             .kv("value", value).kv("bytes", result["written"]))


@param.command("run")
@click.argument("name", metavar="NAME|INSTANCE")
def param_run(name: str) -> None:
    """Run a command parameter (a 1-byte write of attribute 1), e.g. HOME.MOVE."""
    from akdctl.drive import eip_params

    ref = eip_params.resolve(name)
    if ref.name == "HOME.MOVE":
        raise UsageError("HOME.MOVE moves the axis: use 'akdctl home' (consent, limits, stop on error)")
    app = get_app()
    result = eip_params.run_command(_channel(app), ref)
    app.emit({"target": app.target.display, **result}, f"{ref.name or ref.instance}: command executed")
