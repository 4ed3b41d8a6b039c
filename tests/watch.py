"""The test suite's own policy, seen through PEP 578 audit events: which tests start subprocesses (they must be
marked ``slow``) and which in-process sockets aim off the machine (no test may send a packet beyond loopback).

conftest installs the hook once per session and checks after every test; this module only observes and classifies.
"""

from __future__ import annotations

import ipaddress
import socket
import sys


def _is_address(host: str) -> bool:
    try:
        ipaddress.ip_address(host.split("%")[0])
    except ValueError:
        return False
    return True


def _local_host(host: str) -> bool:
    """Whether *host* stays on this machine: a loopback address or ``localhost``; any other name means DNS."""
    return host == "localhost" or (_is_address(host) and ipaddress.ip_address(host.split("%")[0]).is_loopback)


class Watch:
    """What tests do behind their backs, seen through PEP 578 audit events: subprocesses started, and in-process
    sockets aimed off the machine (a non-loopback connect or send, a name lookup, a bind to every interface).

    conftest installs the hook once per session (audit hooks cannot be removed) and checks the lists after every
    test.  Subprocesses are not seen inside; the harness gives them loopback targets or a namespace.
    """

    started: list[str] = []
    off_machine: list[str] = []
    installed = False
    _SOCKET_EVENTS = frozenset({"socket.connect", "socket.sendto", "socket.sendmsg", "socket.bind"})

    @staticmethod
    def classify(event: str, args: tuple) -> str | None:  # type: ignore[type-arg]
        """Why this audit event leaves the machine, or None when it stays on it (or is no network event)."""
        if event in Watch._SOCKET_EVENTS:
            sock, address = args[0], args[1]
            if getattr(sock, "family", None) not in (socket.AF_INET, socket.AF_INET6) or not isinstance(address, tuple):
                return None  # AF_UNIX paths, raw AF_PACKET/AF_CAN links: no IP route out
            host = str(address[0])
            if event == "socket.bind":
                return f"bind to every interface {address}" if host in ("", "0.0.0.0", "::") else None
            return None if _local_host(host) else f"{event} {address}"
        if event == "socket.getaddrinfo" and args[0] is not None:
            host = args[0].decode() if isinstance(args[0], bytes) else str(args[0])
            if not _is_address(host) and not _local_host(host):  # a literal address is parsed, not looked up
                return f"name lookup {host!r}"
        return None

    @classmethod
    def install(cls) -> None:
        if cls.installed:
            return
        cls.installed = True

        def hook(event: str, args: tuple) -> None:  # type: ignore[type-arg]
            if event == "subprocess.Popen":
                cls.started.append(str(args[0]))
            elif event.startswith("socket."):
                why = cls.classify(event, args)
                if why:
                    cls.off_machine.append(why)

        sys.addaudithook(hook)
