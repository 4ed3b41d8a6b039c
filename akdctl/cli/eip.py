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


def _gate_parameter(app: Any, ref: Any) -> None:
    """Consent before a Parameter-object write that can power or move the axis (the one write gate)."""
    from akdctl.cli.consent import gate_write
    from akdctl.drive.gate import classify_cip
    from akdctl.protocol import cip

    gate_write(app, [classify_cip(cip.PARAMETER, ref.instance, 1, ref.name or "")])


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
def param_set(name: str, value: str) -> None:
    """Write a parameter: its type and length are read first, floats travel x1000.

    \b
    Examples:
      akdctl -T eip://192.168.0.20 -y eip param set DRV.OPMODE 2
    """
    from akdctl.drive import eip_params

    ref = eip_params.resolve(name)
    app = get_app()
    channel = _channel(app)
    _gate_parameter(app, ref)
    result = eip_params.write(channel, ref, value)
    app.emit({"target": app.target.display, **result},
             lambda: Doc(f"parameter {ref.name or ref.instance} written", app.target.display)
             .kv("value", value).kv("bytes", result["written"]))


@param.command("run")
@click.argument("name", metavar="NAME|INSTANCE")
def param_run(name: str) -> None:
    """Run a command parameter (a 1-byte write of attribute 1), e.g. HOME.MOVE.

    \b
    Examples:
      akdctl -T eip://192.168.0.20 -y eip param run HOME.MOVE
    """
    from akdctl.drive import eip_params

    ref = eip_params.resolve(name)
    app = get_app()
    channel = _channel(app)
    _gate_parameter(app, ref)
    result = eip_params.run_command(channel, ref)
    app.emit({"target": app.target.display, **result}, f"{ref.name or ref.instance}: command executed")


IO_TYPES = {"position": 0x01, "torque": 0x05, "move": 0x06, "jog": 0x07, "velocity": 0x08}


@eip.command("io")
@click.argument("kind", type=click.Choice(list(IO_TYPES)), metavar="TYPE")
@click.argument("value", type=int)
@click.option("--velocity", type=int, default=None, help="move: velocity in EIP.PROFUNIT units per second.")
@click.option("--accel", type=int, default=0, help="move/jog: acceleration (EIP.PROFUNIT units/s², 0: drive's).")
@click.option("--decel", type=int, default=0, help="move/jog: deceleration (0: drive's).")
@click.option("--relative", is_flag=True, help="position/move: VALUE is relative to the current position.")
@click.option("--for", "hold", type=click.FloatRange(0.05, 3600), default=None, metavar="SECONDS",
              help="jog/velocity/torque: keep the connection (and the motion) this long, then close it.")
@click.option("--rpi", type=click.FloatRange(10, 10000), default=20.0, show_default=True, metavar="MS",
              help="Requested packet interval (the AKD needs >= 10 ms, >= 20 ms beside WorkBench).")
@click.option("--port", "io_port", type=click.IntRange(1, 65535), default=2222, show_default=True,
              help="The drive's UDP I/O port.")
@click.option("--local-port", type=click.IntRange(0, 65535), default=0, show_default=True,
              help="Our UDP port for T->O data (0: any free port).")
def io(kind: str, value: int, velocity: int | None, accel: int, decel: int, relative: bool, hold: float | None,
       rpi: float, io_port: int, local_port: int) -> None:
    """Run ONE command through the I/O assemblies over a class-1 connection akdctl opens itself.

    Explicit opt-in: a PLC normally owns this connection (akdctl refuses if one does). akdctl runs
    the Load/Start -> Load Complete handshake, waits for the move (or --for), then closes the
    connection - and the drive disables the axis when the connection ends (the Enable bit drops).
    VALUE is in EIP.POSUNIT units (position, move), EIP.PROFUNIT units/s (jog, velocity) or mA (torque).

    \b
    Examples:
      akdctl -T eip://192.168.0.20 -y eip io move 10000 --velocity 2000
      akdctl -T eip://192.168.0.20 -y eip io jog 500 --for 2
    """
    from akdctl.cli.consent import require_consent
    from akdctl.drive.axis.cip import CipAxis
    from akdctl.drive.motion_plan import check_executed_limits
    from akdctl.drive.polling import pause_unless_stopped
    from akdctl.drive.eip_io import run_command
    from akdctl.protocol import akd_assembly as asm
    from akdctl.transport.eip_io import IoConnection

    app = get_app()
    timed = kind in ("jog", "velocity", "torque")
    if timed and hold is None:
        raise UsageError(f"eip io {kind} needs --for SECONDS, so the motion is bounded")
    if kind == "move" and not velocity:
        raise UsageError("eip io move needs --velocity (EIP.PROFUNIT units per second)")
    channel = _channel(app)
    axis = CipAxis(channel, timeout=app.options.timeout, target=app.target.display)
    posunit, profunit = axis.units()
    speed = value if kind in ("jog", "velocity") else (velocity or 0)
    # The same limit rules as every planned motion, on the raw values this command sends.
    end_rev = None
    if kind in ("position", "move"):
        status = axis.read_status()
        if relative:
            end_rev = None if status.position_rev is None else status.position_rev + value / posunit
        else:
            end_rev = value / posunit
        if end_rev is None and app.connection.profile is not None and app.connection.profile.limits.get("travel"):
            from akdctl.errors import SafetyRefusal

            raise SafetyRefusal("refusing: the profile limits travel but this link cannot read the position")
    check_executed_limits(app.connection, rpm=speed * 60.0 / profunit if speed else None,
                          acc_rpm_s=max(accel, decel) * 60.0 / profunit if (accel or decel) else None,
                          end_rev=end_rev, executed_by="the I/O assembly")
    require_consent(app, f"run an I/O {kind} command ({value}, command type 0x{IO_TYPES[kind]:02X}) over a "
                    "class-1 connection akdctl opens; when the connection ends the drive sees Enable drop and "
                    "disables the axis")
    direction = asm.CTL_DIRECTION if kind in ("jog", "velocity") and value >= 0 else 0   # velocity mode only [M-12]
    control = asm.CTL_ENABLE | (asm.CTL_RELATIVE if relative else 0) | direction
    command = asm.Command(control=control, command_type=IO_TYPES[kind],
                          data=value if kind in ("position", "velocity", "torque") else 0,
                          position=value if kind == "move" else 0,
                          velocity=(velocity or 0) if kind == "move" else abs(value) if kind == "jog" else 0,
                          acceleration=accel, deceleration=decel)
    session = app.connection.transport().message_link
    from akdctl.cli.signals import stop_signals
    from akdctl.errors import Interrupted

    # The connection closes on every way out (Forward_Close; the drive drops Enable and disables the axis),
    # also on SIGINT/SIGTERM/SIGHUP: they only set a flag that the waits below check.
    with stop_signals() as stop, IoConnection(session, app.target.host, rpi_ms=rpi, port=io_port,
                                              local_port=local_port, timeout=app.options.timeout,
                                              tracer=app.options.tracer) as conn:
        result = run_command(conn, command, timeout=app.options.timeout)
        if timed:
            pause_unless_stopped(hold, stop)  # type: ignore[arg-type]
            final = conn.wait_input(lambda r: True, "a response", app.options.timeout)
        else:
            final = conn.wait_input(lambda r: stop() or (bool(r.status1 & asm.ST1_IN_POSITION)
                                                         and not r.status1 & asm.ST1_IN_MOTION), "In Position",
                                    timeout=max(app.options.timeout, 60.0))
        if stop():
            raise Interrupted(f"interrupted during the I/O {kind} command; the connection is closed, so the drive "
                              "disables the axis")
        stats = conn.stats
    data = {"target": app.target.display, "type": kind, "command_type": IO_TYPES[kind], "value": value,
            "sent": [b.hex(" ") for b in result.sent], "responses": [b.hex(" ") for b in result.seen],
            "final": final.encode().hex(" "), "actual_position": final.actual_position,
            "actual_velocity": final.actual_velocity, "produced": stats.produced, "consumed": stats.consumed,
            "connection": "closed (the drive disables the axis)"}

    def human() -> Doc:
        doc = Doc(f"I/O {kind} command", app.target.display)
        for n, raw in enumerate(result.sent, 1):
            doc.kv(f"C{n}", raw[:8].hex(" "))
        for n, raw in enumerate(result.seen, 1):
            doc.kv(f"R{n}", raw[:8].hex(" "))
        doc.kv("actual position", final.actual_position).kv("actual velocity", final.actual_velocity)
        doc.kv("connection", "closed; the drive disables the axis")
        return doc

    app.emit(data, human)
