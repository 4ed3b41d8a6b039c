"""Scheme -> transport registry (the way python-can maps interface names to buses).

Built-in schemes are listed here as *specs* (module and class names as strings),
so parsing a target and listing transports never imports a transport module.
Third-party transports register under the ``akdctl.transports`` entry-point
group (``scheme = "package.module:ClassName"``); they are looked up only for a
scheme that is not built in.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from akdctl.errors import UsageError
from akdctl.transport.target import Target, split_target
from akdctl.profiles.vocabulary import Channel, drive_profile, usable_profiles
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.transport.base import Transport

ENTRY_POINT_GROUP = "akdctl.transports"


def _need_host(target: Target) -> None:
    if not target.host:
        raise UsageError(f"malformed target {target.raw!r}: {target.scheme}:// needs a host, e.g. {target.scheme}://192.168.0.10")


def _check_ecat_udp(target: Target) -> None:
    _need_host(target)
    parts = target.path_parts
    if len(parts) != 1 or not _is_int(parts[0]):
        raise UsageError(f"malformed target {target.raw!r}: expected ecat-udp://HOST[:PORT]/STATION (station address, e.g. 1001)")


def _check_ecat_raw(target: Target) -> None:
    if not target.host:
        raise UsageError(f"malformed target {target.raw!r}: expected {target.scheme}://IFNAME[/POSITION]")
    parts = target.path_parts
    if len(parts) > 1 or (parts and not _is_int(parts[0])):
        raise UsageError(f"malformed target {target.raw!r}: POSITION must be a number (0 = first slave)")


def _check_can(target: Target) -> None:
    # CHANNEL is everything between the first and last "/" (a device path follows "//": can://slcan//dev/ttyACM0/1);
    # can://config/NODE takes interface and channel from python-can's configuration.
    parts = target.path_parts
    need = 1 if target.host in ("config", "default") else 2
    if not target.host or len(parts) < need or not _is_int(parts[-1]):
        raise UsageError(f"malformed target {target.raw!r}: expected can://INTERFACE/CHANNEL/NODE, e.g. can://socketcan/can0/1")
    node = int(parts[-1], 0)
    if not 1 <= node <= 127:
        raise UsageError(f"malformed target {target.raw!r}: CANopen node id {node} is outside 1..127")


def _check_sim(target: Target) -> None:
    name = target.host or "default"
    if not name.replace("-", "").replace("_", "").isalnum():
        raise UsageError(f"malformed target {target.raw!r}: simulator name {name!r} may use letters, digits, - and _")
    if target.path_parts:  # sim://a/b is not the drive 'a': a typo is said, never served from another drive
        raise UsageError(f"malformed target {target.raw!r}: expected sim://NAME (no path after the name)")


def _is_int(text: str) -> bool:
    try:
        int(text, 0)
    except ValueError:
        return False
    return True


class TransportSpec(Record):
    """What the registry knows about a scheme without importing its transport."""

    __slots__ = ("scheme", "module", "cls", "summary", "syntax", "channels", "requires", "check", "extra", "notes",
                 "query")

    def __init__(self, scheme: str, module: str, cls: str, summary: str, syntax: str, channels: frozenset[Channel],
                 requires: tuple[str, ...] = (), check: Callable[[Target], None] | None = None, extra: str = "",
                 notes: tuple[str, ...] = (), query: tuple[str, ...] | None = ()) -> None:
        self.scheme = scheme
        self.module = module
        self.cls = cls
        self.summary = summary
        self.syntax = syntax
        #: What the Connection can build over this transport's links (known without importing it).
        self.channels = channels
        self.requires = requires
        self.check = check
        self.extra = extra
        self.notes = notes
        #: The query keys the transport reads (``drive`` is every target's); None: any key is passed on (can://).
        self.query = query


_PARAMETERS = frozenset({Channel.PARAMETERS})
_OBJECTS = frozenset({Channel.OBJECTS})

BUILTIN: dict[str, TransportSpec] = {
    spec.scheme: spec
    for spec in (
        TransportSpec("sim", "akdctl.transport.sim", "SimTransport",
                      "built-in simulated AKD (state kept between invocations)",
                      "sim | sim://NAME[?drive=profidrive|cia402]", _PARAMETERS | _OBJECTS,
                      check=_check_sim),
        TransportSpec("pn", "akdctl.transport.profinet", "ProfinetTransport",
                      "PROFINET record data: PROFIdrive base-mode parameter access over PNIO DCE/RPC/UDP",
                      "pn://HOST[:34964][?slot=1&subslot=1&api=0x3A00&index=47]", _PARAMETERS,
                      check=_need_host, query=("slot", "subslot", "api", "index", "axis", "vendor", "device",
                                               "instance", "ar_timeout", "iface")),
        TransportSpec("ecat-udp", "akdctl.transport.ethercat_udp", "EthercatUdpTransport",
                      "EtherCAT mailbox (CoE SDO) through a master's ETG.8200 mailbox gateway",
                      "ecat-udp://HOST[:34980]/STATION", _OBJECTS, check=_check_ecat_udp, query=("mailbox",)),
        TransportSpec("ecat", "akdctl.transport.ethercat_raw", "EthercatRawTransport",
                      "EtherCAT: akdctl as master on a raw interface (needs CAP_NET_RAW)",
                      "ecat://IFNAME[/POSITION]", _OBJECTS, check=_check_ecat_raw),
        TransportSpec("ecat+soem", "akdctl.transport.ethercat_soem", "EthercatSoemTransport",
                      "EtherCAT through pysoem (optional extra akdctl[soem])",
                      "ecat+soem://IFNAME[/POSITION]", _OBJECTS, requires=("pysoem",),
                      check=_check_ecat_raw, extra="soem"),
        TransportSpec("can", "akdctl.transport.canopen_bus", "CanopenTransport",
                      "CANopen over any python-can interface (socketcan, slcan, pcan, kvaser, virtual, ...)",
                      "can://INTERFACE/CHANNEL/NODE[?bitrate=500000]", _OBJECTS,
                      requires=("can", "canopen"), check=_check_can, query=None),
        TransportSpec("eip", "akdctl.transport.ethernetip", "EthernetIpTransport",
                      "EtherNet/IP: CIP explicit messaging (UCMM over TCP), Parameter and Position Controller objects",
                      "eip://HOST[:44818]", frozenset({Channel.ATTRIBUTES}), check=_need_host),
        TransportSpec("akd", "akdctl.transport.akd_ascii", "AkdAsciiTransport",
                      "The AKD's ASCII command channel (service port, \"Telnet\"): parameters by name, DRV.* commands",
                      "akd://HOST[:23]", frozenset({Channel.COMMANDS}), check=_need_host),
        TransportSpec("mb", "akdctl.transport.modbus", "ModbusTransport",
                      "Modbus TCP: AKD parameters at holding register 2(n-1)",
                      "mb://HOST[:502][?unit=N]", frozenset({Channel.REGISTERS}), check=_need_host, query=("unit",)),
    )
}


def known_schemes() -> list[str]:
    return sorted(BUILTIN) + sorted(set(_entry_points()) - set(BUILTIN))


def _entry_points() -> dict[str, str]:
    from importlib.metadata import entry_points

    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def parse_target(text: str, source: str = "--target") -> Target:
    """Parse and check a target string; unknown schemes list the known ones."""
    target = split_target(text, source)
    spec = BUILTIN.get(target.scheme)
    if spec is None:
        if target.scheme not in _entry_points():
            raise UsageError(
                f"unknown target scheme {target.scheme!r} in {target.raw!r} (from {source}); "
                f"known schemes: {', '.join(known_schemes())}"
            )
        return target
    _check_query(target, spec)
    _check_drive(target, spec)
    if spec.check is not None:
        spec.check(target)
    return target


#: The query key every target takes: the axis profile motion uses (the Connection reads it).
COMMON_QUERY = ("drive",)


def _check_query(target: Target, spec: TransportSpec) -> None:
    """An unknown query key is a typo the transport would silently ignore (``pn://HOST?slott=2``): refuse it."""
    if spec.query is None:
        return
    known = sorted({*spec.query, *COMMON_QUERY})
    for key in target.query:
        if key not in known:
            import difflib

            close = difflib.get_close_matches(key, known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise UsageError(f"target {target.raw!r}: unknown query key {key!r}{hint}; {spec.scheme}:// takes "
                             f"{', '.join(known)}")


def _check_drive(target: Target, spec: TransportSpec) -> None:
    """``?drive=`` names a profile whose channel this scheme offers (one rule for every scheme)."""
    word = target.query.get("drive")
    if word is None:
        return
    usable = usable_profiles(spec.channels)
    chosen = drive_profile(word)
    if chosen is None or chosen not in usable:
        choices = " or ".join(f"drive={p.value}" for p in usable)
        raise UsageError(f"malformed target {target.raw!r}: drive={word!r}; {spec.scheme}:// speaks {choices}")


def module_available(name: str) -> bool:
    """Whether a third-party module a transport needs (python-can, pysoem) is installed.

    Only for other projects' modules: akdctl's own transports are imported plainly, so a packaging
    slip is an ImportError a test sees (tests/test_registry_wiring.py), not a scheme silently missing."""
    import importlib.util

    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def transport_class(target: Target) -> "type[Transport]":
    """Import and return the transport class for a parsed target."""
    import importlib

    spec = BUILTIN.get(target.scheme)
    if spec is None:
        value = _entry_points().get(target.scheme)
        if value is None:
            raise UsageError(f"unknown target scheme {target.scheme!r}; known schemes: {', '.join(known_schemes())}")
        module_name, _, cls_name = value.partition(":")
    else:
        missing = [m for m in spec.requires if not module_available(m)]
        if missing:
            hint = f" (pip install 'akdctl[{spec.extra}]')" if spec.extra else ""
            raise UsageError(f"{spec.scheme}:// needs the Python module(s) {', '.join(missing)}{hint}")
        module_name, cls_name = spec.module, spec.cls
    cls: type[Transport] = vars(importlib.import_module(module_name))[cls_name]
    return cls
