"""Which axis profile an invocation uses, decided without connecting when the registry knows.
"""


from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akdctl.drive.axis.base import Axis
from akdctl.drive.axis.cia402 import Cia402Axis
from akdctl.drive.axis.profidrive import ProfidriveAxis
from akdctl.errors import (
    UsageError,
)


def target_channels(conn: Any) -> set[str] | None:
    """The channels ('parameters', 'objects') the target offers, known without connecting; None if unknown."""
    from akdctl.transport.registry import BUILTIN

    spec = BUILTIN.get(conn.target.scheme)
    if spec is None:
        return None
    return {part.strip() for part in spec.channels.split(",")}


def profile_name(conn: Any) -> str:
    """The axis profile of this invocation: ``conn.drive_profile`` if set, else the CIP Position
    Controller on an EtherNet/IP target, PROFIdrive when the target has a parameter channel, else
    CiA 402 (decided without connecting when the registry knows)."""
    chosen = conn.drive_profile
    if chosen is not None:
        return str(chosen)
    channels = target_channels(conn)
    if channels is None:
        return "profidrive" if conn.has_parameters else "cia402"
    if "attributes" in channels:
        return "cip"
    if "commands" in channels:
        return "akd"   # the AKD's own command channel (issue 24)
    if "registers" in channels:   # issue 24: no published register holds the AKD's enable state
        raise UsageError(f"{conn.target.display}: the axis (status, enable, motion) is not offered over Modbus: "
                         "no published AKD register holds its enable state; read 'akdctl param get DRV.MOTIONSTAT "
                         "DRV.FAULT1' here, or use akd://HOST or a fieldbus target")
    return "profidrive" if "parameters" in channels else "cia402"


def axis_class(conn: Any) -> type[Axis]:
    """The Axis subclass of this invocation's profile (the planner reads its scales before connecting)."""
    chosen = profile_name(conn)
    if chosen == "cip":
        from akdctl.drive.axis.cip import CipAxis

        return CipAxis
    if chosen == "akd":
        from akdctl.drive.axis.akd_ascii import AkdAsciiAxis

        return AkdAsciiAxis
    classes: dict[str, type[Axis]] = {"profidrive": ProfidriveAxis, "cia402": Cia402Axis}
    if chosen not in classes:
        raise UsageError(f"unknown drive profile {chosen!r}: use 'profidrive', 'cia402' or 'cip'")
    return classes[chosen]


if TYPE_CHECKING:  # beside its one user, so this hunk stays apart from the module's import block
    from akdctl.connection import Connection


def open_axis(conn: "Connection") -> Axis:
    """The axis of this connection (:func:`profile_name` chooses the profile)."""
    chosen = profile_name(conn)
    timeout = conn.options.timeout
    target = conn.target.display
    axis: Axis
    if chosen == "cip":
        from akdctl.drive.axis.cip import CipAxis

        axis = CipAxis(conn.cip(), timeout=timeout, target=target)
    elif chosen == "akd":
        from akdctl.drive.axis.akd_ascii import AkdAsciiAxis

        axis = AkdAsciiAxis(conn.commands(), timeout=timeout, target=target)
    elif chosen == "profidrive":
        axis = ProfidriveAxis(conn.parameters(), conn.objects() if conn.has_objects else None,
                              timeout=timeout, target=target)
    elif chosen == "cia402":
        axis = Cia402Axis(conn.objects(), conn.transport(), timeout=timeout, target=target)
    else:
        raise UsageError(f"unknown drive profile {chosen!r}: use 'profidrive', 'cia402' or 'cip'")
    transport = conn.transport()
    axis.time_scale_source = lambda: float(getattr(transport, "time_scale", 1.0))
    return axis


