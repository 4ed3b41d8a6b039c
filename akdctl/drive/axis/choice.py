"""Which axis profile an invocation uses, decided without connecting when the registry knows.
"""


from __future__ import annotations

from typing import TYPE_CHECKING

from akdctl.drive.axis.base import Axis
from akdctl.profiles.vocabulary import DriveProfile

if TYPE_CHECKING:
    from akdctl.connection import Connection


def profile_name(conn: "Connection") -> str:
    """The axis profile of this invocation (:attr:`Connection.axis_profile`: the chosen one, else the
    CIP Position Controller on an EtherNet/IP target, PROFIdrive where parameters are offered, else
    CiA 402; decided without connecting when the registry knows the scheme)."""
    return conn.axis_profile.value


def axis_class(conn: "Connection") -> type[Axis]:
    """The Axis subclass of this invocation's profile (the planner reads its scales before connecting)."""
    chosen = conn.axis_profile
    if chosen is DriveProfile.CIP:
        from akdctl.drive.axis.cip import CipAxis

        return CipAxis
    if chosen is DriveProfile.AKD:
        from akdctl.drive.axis.akd_ascii import AkdAsciiAxis

        return AkdAsciiAxis
    if chosen is DriveProfile.PROFIDRIVE:  # each profile's module is imported only when chosen (cold start)
        from akdctl.drive.axis.profidrive import ProfidriveAxis

        return ProfidriveAxis
    from akdctl.drive.axis.cia402 import Cia402Axis

    return Cia402Axis


def open_axis(conn: "Connection") -> Axis:
    """The axis of this connection (:attr:`Connection.axis_profile` chooses the profile)."""
    chosen = conn.axis_profile
    timeout = conn.options.timeout
    target = conn.target.display
    axis: Axis
    if chosen is DriveProfile.CIP:
        from akdctl.drive.axis.cip import CipAxis

        axis = CipAxis(conn.cip(), timeout=timeout, target=target)
    elif chosen is DriveProfile.AKD:
        from akdctl.drive.axis.akd_ascii import AkdAsciiAxis

        axis = AkdAsciiAxis(conn.commands(), timeout=timeout, target=target)
    elif chosen is DriveProfile.PROFIDRIVE:
        from akdctl.drive.axis.profidrive import ProfidriveAxis

        axis = ProfidriveAxis(conn.parameters(), conn.objects() if conn.has_objects else None,
                              timeout=timeout, target=target)
    else:
        from akdctl.drive.axis.cia402 import Cia402Axis

        axis = Cia402Axis(conn.objects(), conn.al_state, timeout=timeout, target=target)
    axis.time_scale_source = lambda: conn.time_scale
    return axis
