"""``akdctl eip``: EtherNet/IP discovery (ListIdentity) and AKD parameters through the Parameter object."""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import UsageError


@click.group()
def eip() -> None:
    """EtherNet/IP: find drives (ListIdentity), AKD parameters by the Parameter object 0x0F.

    \b
    Examples:
      akdctl eip scan 192.168.0.20
      akdctl -T eip://192.168.0.20 eip param get DRV.OPMODE
    """


def _interface_addresses(iface: str) -> tuple[str, str]:
    """(IPv4 address, IPv4 broadcast address) of ``iface`` (SIOCGIFADDR, SIOCGIFBRDADDR).

    The scan binds to the interface's own address, so the broadcast leaves by that interface only.
    """
    import fcntl
    import socket
    import struct

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        request = struct.pack("256s", iface.encode()[:15])
        own = fcntl.ioctl(sock.fileno(), 0x8915, request)
        broadcast = fcntl.ioctl(sock.fileno(), 0x8919, request)
    except OSError as exc:
        raise UsageError(f"--iface {iface}: no IPv4 address/broadcast address ({exc.strerror})") from None
    finally:
        sock.close()
    return socket.inet_ntoa(own[20:24]), socket.inet_ntoa(broadcast[20:24])


@eip.command("scan")
@click.argument("host", required=False)
@click.option("--iface", metavar="IFNAME", help="Broadcast ListIdentity on this interface (never done by default).")
@click.option("--port", type=click.IntRange(1, 65535), default=44818, show_default=True, help="UDP port.")
@click.option("--wait", type=click.FloatRange(0.05, 60), default=None, metavar="SECONDS",
              help="How long to collect answers (default: --timeout).")
def scan(host: str | None, iface: str | None, port: int, wait: float | None) -> None:
    """ListIdentity: unicast to the target (-T eip://HOST) or HOST, or broadcast on --iface IFNAME.

    What to scan, as every scan command: the target, or --iface IFNAME to broadcast on a link (never by default).

    \b
    Examples:
      akdctl -T eip://192.168.0.20 eip scan
      akdctl eip scan 192.168.0.20
      akdctl eip scan --iface eth1
    """
    from akdctl.catalog.texts import cip_vendor_name
    from akdctl.transport.ethernetip import list_identity

    app = get_app()
    if host is not None and iface is not None:
        raise UsageError("give a HOST or --iface IFNAME, not both")
    if host is None and iface is None:
        if app.target.scheme != "eip":
            raise UsageError("give the target (-T eip://HOST), a HOST to ask, or --iface IFNAME to broadcast on "
                             "(akdctl never broadcasts by default)")
        host = app.target.host
        if app.target.port:
            port = app.target.port
    if host is not None:
        address = host
        found = list_identity(host, port, app.options, wait=wait)
    else:
        own, address = _interface_addresses(iface)  # type: ignore[arg-type]
        found = list_identity(address, port, app.options, broadcast_from=own, wait=wait)
    rows = [{**ident.to_json(), "address": peer, "vendor_name": cip_vendor_name(ident.vendor)} for peer, ident in found]

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
    """AKD parameters by the Parameter object 0x0F (instance = parameter number).

    \b
    Examples:
      akdctl -T eip://192.168.0.20 eip param get DRV.OPMODE
    """


def _channel(app: Any) -> Any:
    from akdctl.cli.cip import attributes

    return attributes(app)


@param.command("get")
@click.argument("name", metavar="NAME|INSTANCE")
def param_get(name: str) -> None:
    """Read a parameter's value, type and length (attributes 1, 5, 6).

    \b
    Examples:
      akdctl -T eip://192.168.0.20 eip param get DRV.OPMODE
    """
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
@click.option("--dry-run", is_flag=True, help="Print what would be written and whether it needs consent; write nothing.")
def param_set(name: str, value: str, dry_run: bool) -> None:
    """Write a parameter: its type and length are read first, floats travel x1000.

    \b
    Examples:
      akdctl -T eip://192.168.0.20 -y eip param set DRV.OPMODE 2
      akdctl -T eip://192.168.0.20 eip param set EIP.PROFUNIT 65536 --dry-run
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import eip_params

    ref = eip_params.resolve(name)
    request = eip_params.parameter_request(ref, value)
    app = get_app()
    _channel(app)  # a target without CIP is refused before anything else
    plan = eip_params.plan(app.connection, request)  # plan -> consent -> execute (drive/eip_params.py)
    if dry_run:
        render_dry_run(app, plan)
        return
    consent_plan(app, plan)
    eip_params.execute(app.connection, plan)
    result = {"instance": ref.instance, "name": ref.name, "written": plan.data["bytes"].hex(),
              "value": plan.data["value"], "length": plan.data["length"]}
    app.emit({"target": app.target.display, **result},
             lambda: Doc(f"parameter {ref.name or ref.instance} written", app.target.display)
             .kv("value", value).kv("bytes", result["written"]))


@param.command("run")
@click.argument("name", metavar="NAME|INSTANCE")
@click.option("--dry-run", is_flag=True, help="Show the plan (the write, whether it needs consent); write nothing.")
def param_run(name: str, dry_run: bool) -> None:
    """Run a command parameter (a 1-byte write of attribute 1), e.g. HOME.MOVE.

    \b
    Examples:
      akdctl -T eip://192.168.0.20 -y eip param run HOME.MOVE
      akdctl -T eip://192.168.0.20 eip param run HOME.MOVE --dry-run
    """
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import eip_params

    ref = eip_params.resolve(name)
    app = get_app()
    _channel(app)  # a target without CIP is refused before anything else
    plan = eip_params.plan_command(app.connection, ref)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)
    eip_params.execute(app.connection, plan)
    app.emit({"target": app.target.display, "instance": ref.instance, "name": ref.name, "executed": True},
             f"{ref.name or ref.instance}: command executed")


IO_KINDS = ("position", "torque", "move", "jog", "velocity")   # drive/eip_io.IO_TYPES, listed without its import


@eip.command("io")
@click.argument("kind", type=click.Choice(list(IO_KINDS)), metavar="TYPE")
@click.argument("value", type=int)
@click.option("--velocity", type=int, default=None, help="move: velocity in EIP.PROFUNIT units per second.")
@click.option("--accel", type=int, default=0, help="move/jog: acceleration (EIP.PROFUNIT units/s², 0: drive's).")
@click.option("--decel", type=int, default=0, help="move/jog: deceleration (0: drive's).")
@click.option("--relative", is_flag=True, help="position/move: VALUE is relative to the current position.")
@click.option("--for", "hold", type=str, default=None, metavar="DURATION",
              help="jog/velocity/torque: keep the motion this long (e.g. 2, 2s, 500ms; at most 60 s and the "
                   "profile's max_jog_duration), stop it, then close the connection.")
@click.option("--rpi", type=click.FloatRange(10, 10000), default=20.0, show_default=True, metavar="MS",
              help="Requested packet interval (the AKD needs >= 10 ms, >= 20 ms beside WorkBench); at most "
                   "125 ms, so a dead tool leaves the axis running at most 0.5 s.")
@click.option("--port", "io_port", type=click.IntRange(1, 65535), default=2222, show_default=True,
              help="The drive's UDP I/O port.")
@click.option("--local-port", type=click.IntRange(0, 65535), default=0, show_default=True,
              help="Our UDP port for T->O data (0: any free port).")
@click.option("--dry-run", is_flag=True, help="Show the plan (after reading the drive's units); send nothing.")
def io(kind: str, value: int, velocity: int | None, accel: int, decel: int, relative: bool, hold: str | None,
       rpi: float, io_port: int, local_port: int, dry_run: bool) -> None:
    """Run ONE command through the I/O assemblies over a class-1 connection akdctl opens itself.

    Explicit opt-in: a PLC normally owns this connection (akdctl refuses if one does). The command passes
    the motion planner's limits (config profile, 60 s for a timed motion); akdctl runs the Load/Start ->
    Load Complete handshake, waits for the move (or --for, then a smooth stop to standstill), then closes
    the connection - and the drive disables the axis when the connection ends (the Enable bit drops).
    The connection's timeout (RPI x multiplier) is kept within 0.5 s, so a killed akdctl leaves the axis
    running at most that long. VALUE is in EIP.POSUNIT units (position, move), EIP.PROFUNIT units/s (jog,
    velocity) or mA (torque).

    \b
    Examples:
      akdctl -T eip://192.168.0.20 -y eip io move 10000 --velocity 2000
      akdctl -T eip://192.168.0.20 -y eip io jog 500 --for 2s
    """
    from akdctl.cli.consent import render_dry_run, require_consent
    from akdctl.cli.parsing import parse_duration
    from akdctl.cli.signals import stop_signals
    from akdctl.drive import eip_io

    app = get_app()
    request = eip_io.IoRequest(kind, value, velocity, accel, decel, relative,
                               None if hold is None else parse_duration(hold, "--for"), rpi, io_port, local_port)
    accepted = eip_io.plan(app.connection, request)
    if dry_run:
        return render_dry_run(app, accepted)
    require_consent(app, accepted.consent_text)  # motion: always asked (drive/eip_io.IoPlan)
    # SIGINT/SIGTERM/SIGHUP only set a flag the waits check: the axis is stopped and watched to standstill
    # before the connection closes (drive/eip_io.execute).
    with stop_signals() as stop:
        data = eip_io.execute(app.connection, accepted, stop)

    def human() -> Doc:
        doc = Doc(f"I/O {kind} command", app.target.display)
        for n, raw in enumerate(data["sent"], 1):
            doc.kv(f"C{n}", raw[:23])
        for n, raw in enumerate(data["responses"], 1):
            doc.kv(f"R{n}", raw[:23])
        doc.kv("actual position", data["actual_position"]).kv("actual velocity", data["actual_velocity"])
        doc.kv("connection", "closed; the drive disables the axis")
        return doc

    app.emit(data, human)
