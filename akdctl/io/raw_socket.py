"""One way to open a raw Ethernet (AF_PACKET) socket for one EtherType on one interface.

Why here: the raw EtherCAT master, the simulated EtherCAT slave, the DCP client and
the simulated DCP responder all need the same socket and the same one-line advice
when the process lacks CAP_NET_RAW; written once, the advice cannot drift.
"""

from __future__ import annotations

import socket

from akdctl.errors import UsageError

#: What to do when raw sockets are refused (the same advice for every user of raw sockets).
CAP_HINT = "run as root or `setcap cap_net_raw+ep $(readlink -f $(which python3))`"


#: Linux ``SOL_PACKET`` / ``PACKET_IGNORE_OUTGOING`` (4.20+; not every Python names them).
_SOL_PACKET = 263
_PACKET_IGNORE_OUTGOING = 23


def open_raw_socket(ifname: str, ethertype: int, who: str, *, ignore_outgoing: bool = False) -> socket.socket:
    """An AF_PACKET socket bound to ``ifname`` receiving ``ethertype``, or a one-line :class:`UsageError`.

    ``who`` names the user-facing thing that wanted the socket (``ecat://eth0``,
    ``--ethercat-raw veth0``): it starts every error message. ``ignore_outgoing`` asks the kernel
    not to hand the socket its own frames back (a master would read and drop each one; older
    kernels ignore the request and the caller's own filter does the work).
    """
    try:
        sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ethertype))
    except PermissionError:
        raise UsageError(f"{who} needs CAP_NET_RAW: {CAP_HINT}") from None
    except (OSError, AttributeError) as exc:
        raise UsageError(f"{who}: raw sockets are not available on this system ({exc})") from None
    if ignore_outgoing:
        try:
            sock.setsockopt(_SOL_PACKET, _PACKET_IGNORE_OUTGOING, 1)
        except OSError:
            pass
    try:
        sock.bind((ifname, 0))
    except OSError as exc:
        sock.close()
        raise UsageError(f"{who}: cannot use interface {ifname!r}: {exc.strerror}") from None
    return sock
