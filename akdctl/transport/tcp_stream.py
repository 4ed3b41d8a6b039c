"""A TCP connection to a drive whose every receive waits at most a given time, with as few system calls as that
allows: the one place the stream transports (``akd://``, ``mb://``) wait on a socket.

Why a module of its own: a request/response client on loopback spends most of its CPU in system calls, and
Python's socket timeout costs two per receive (``poll(2)`` then ``recv(2)``) plus one per ``settimeout``. On
Linux the kernel's own receive timeout (``SO_RCVTIMEO`` on a blocking socket) bounds a receive in the one
``recv(2)``; it is set again only when the wait asked for differs from the one set by more than :data:`SLACK` of
it (at least :data:`MIN_SLACK`): a request asks for what its deadline has left, which shrinks by microseconds from
one request to the next, so a command's requests set it once.
Elsewhere the same rule drives Python's ``settimeout``. Sends are bounded once, at connect, by the command's
timeout (``SO_SNDTIMEO``): a request is a few bytes into an empty send buffer.

Errors are left as they are (``OSError``, ``socket.timeout``): each transport words them for its drive.
"""

from __future__ import annotations

import socket
import struct
import sys

#: How far a receive may overrun its deadline rather than pay a system call to reset the wait: a share of the wait,
#: and at least MIN_SLACK seconds.
SLACK = 0.01
MIN_SLACK = 0.001
#: The kernel's timeouts are a ``struct timeval`` here (two C longs); elsewhere Python's timeout is used.
_KERNEL_TIMEOUT = sys.platform.startswith("linux")
_TIMEVAL = struct.Struct("@ll")


def _timeval(seconds: float) -> bytes:
    micros = max(1000, int(seconds * 1e6))   # 0 would mean "wait forever"
    return _TIMEVAL.pack(micros // 1_000_000, micros % 1_000_000)


class TcpStream:
    """One connected TCP socket (TCP_NODELAY: a request is one segment, sent at once)."""

    __slots__ = ("sock", "_wait")

    def __init__(self, sock: socket.socket, send_timeout: float) -> None:
        self.sock = sock
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._wait = -1.0   # the receive timeout set on the socket (-1: none yet)
        if _KERNEL_TIMEOUT:
            sock.settimeout(None)   # blocking: recv(2) alone, bounded by SO_RCVTIMEO
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, _timeval(send_timeout))
        else:
            sock.settimeout(send_timeout)

    @classmethod
    def connect(cls, host: str, port: int, timeout: float) -> "TcpStream":
        """Connect within ``timeout`` s (``socket.create_connection``'s errors as they are)."""
        sock = socket.create_connection((host, port), timeout=timeout)
        try:
            return cls(sock, timeout)
        except OSError:
            sock.close()
            raise

    def recv(self, wait: float, size: int = 65536) -> bytes | None:
        """What arrives within ``wait`` s (at most ``size`` bytes); ``None`` when nothing did, ``b""`` when the
        peer closed the connection. Other failures raise ``OSError``."""
        slack = SLACK * wait
        if abs(wait - self._wait) > (slack if slack > MIN_SLACK else MIN_SLACK):
            self._set_wait(wait)
        try:
            return self.sock.recv(size)
        except (BlockingIOError, socket.timeout):   # SO_RCVTIMEO expired (EAGAIN) / Python's timeout
            return None

    def request(self, data: bytes, wait: float, size: int = 65536) -> bytes | None:
        """Send all of ``data``, then :meth:`recv` what arrives within ``wait`` s: a request and the first segment
        of its reply in one call (the hot path of a request/response client)."""
        sock = self.sock
        try:
            sock.sendall(data)
        except BlockingIOError:   # SO_SNDTIMEO expired
            raise socket.timeout("send timed out") from None
        slack = SLACK * wait
        if abs(wait - self._wait) > (slack if slack > MIN_SLACK else MIN_SLACK):
            self._set_wait(wait)
        try:
            return sock.recv(size)
        except (BlockingIOError, socket.timeout):
            return None

    def _set_wait(self, wait: float) -> None:
        self._wait = wait
        if _KERNEL_TIMEOUT:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, _timeval(wait))
        else:
            self.sock.settimeout(max(wait, 0.001))

    def send(self, data: bytes) -> None:
        """All of ``data``; ``socket.timeout`` when the send buffer stayed full for the command's timeout."""
        try:
            self.sock.sendall(data)
        except BlockingIOError:   # SO_SNDTIMEO expired
            raise socket.timeout("send timed out") from None

    def local_and_remote(self) -> tuple[tuple[str, int], tuple[str, int]] | None:
        """(local, remote) addresses for a wire trace, or None once the socket is gone."""
        try:
            return self.sock.getsockname()[:2], self.sock.getpeername()[:2]
        except OSError:
            return None

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass


__all__ = ["TcpStream", "SLACK", "MIN_SLACK"]
