"""``pn set-name`` and ``pn set-ip`` as write plans: the device found by DCP Identify, what it holds now and what it
will hold, before the DCP Set is sent (``--dry-run`` shows it; PROFINET DCP, IEC 61158-6-10).

Why a plan: a station name or address is how a PROFINET controller finds its device, so renaming the wrong one (a
typo in a MAC, two drives with one name) takes a running line's drive from its PLC. The plan names the device that
answered and its present name and address, so a dry run shows which device changes. Never gated: a name or address
powers and moves nothing (a device that loses its controller stops its process data).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akdctl.drive.operation import PlannedWrite, WritePlan

if TYPE_CHECKING:
    from akdctl.transport.dcp import DcpClient

#: Opens a DCP client on the interface (a raw socket): called only after the request's own checks, so a bad name
#: or address is a usage error even where the socket could not be opened.
OpenClient = Callable[[], "DcpClient"]

_KEPT = {True: "permanent: the device keeps it over a restart",
         False: "temporary: the device forgets it when it restarts"}


def _station(open_client: OpenClient, device: str) -> tuple[Any, str]:
    """The device that answers DCP Identify as ``device``, and the interface it answered on."""
    from akdctl.transport.dcp import find_station

    with open_client() as client:
        return find_station(client, device), client.iface


def plan_name(open_client: OpenClient, device: str, name: str, permanent: bool) -> WritePlan:
    """The new station ``name`` of ``device`` (a MAC or the present name); the name is checked, the device found."""
    from akdctl.errors import UsageError
    from akdctl.protocol import dcp

    if not dcp.valid_station_name(name):
        raise UsageError(f"{name!r} is not a valid PROFINET station name (lower-case letters, digits and '-', "
                         "dot-separated labels of at most 63 characters)")
    station, iface = _station(open_client, device)
    return WritePlan("pn set-name", iface,
                     [PlannedWrite(f"{station.mac} station name", name, f"{name!r} (now {station.name or 'none'!r})")],
                     preconditions=[f"{station.mac} answered DCP Identify on {iface}"],
                     notes=[_KEPT[permanent]], enabled=None,
                     data={"mac": station.mac, "name": name, "permanent": permanent})


def plan_ip(open_client: OpenClient, device: str, ip: str, netmask: str, gateway: str,
            permanent: bool) -> WritePlan:
    """The new IPv4 setting of ``device``; each address is checked, the device found."""
    import ipaddress

    from akdctl.errors import UsageError

    try:
        for value in (ip, netmask, gateway):
            ipaddress.IPv4Address(value)
    except ValueError as exc:
        raise UsageError(f"bad IPv4 setting: {exc}") from None
    station, iface = _station(open_client, device)
    now = f"now {station.ip or 'none'}"
    return WritePlan("pn set-ip", iface,
                     [PlannedWrite(f"{station.mac} ({station.name or 'no name'}) IP suite", (ip, netmask, gateway),
                                   f"{ip}/{netmask} via {gateway} ({now})")],
                     preconditions=[f"{station.mac} answered DCP Identify on {iface}"],
                     notes=[_KEPT[permanent]], enabled=None,
                     data={"mac": station.mac, "name": station.name, "ip": ip, "netmask": netmask,
                           "gateway": gateway, "permanent": permanent})


def execute(open_client: OpenClient, plan: WritePlan) -> dict[str, Any]:
    """Send the plan's DCP Set (the device acknowledges it; a refusal is the client's error)."""
    from akdctl.protocol import dcp

    data = plan.data
    mac = dcp.mac_bytes(data["mac"])
    with open_client() as client:
        if plan.operation == "pn set-name":
            client.set_name(mac, data["name"], permanent=data["permanent"])
            return {"mac": data["mac"], "name": data["name"], "permanent": data["permanent"]}
        client.set_ip(mac, data["ip"], data["netmask"], data["gateway"], permanent=data["permanent"])
    return {"mac": data["mac"], "ip": data["ip"], "netmask": data["netmask"], "gateway": data["gateway"],
            "permanent": data["permanent"]}
