"""A TCP connection to a drive whose every receive ends by a given time, with as few system calls as that allows:
the one place the TCP transports (``akd://``, ``mb://``, ``eip://``) and the UDP clients of ``pn://`` and
``ecat-udp://`` wait on a socket.

Why a module of its own: a request/response client on loopback spends most of its CPU in system calls, and
Python's socket timeout costs two per receive (``poll(2)`` then ``recv(2)``) plus one per ``settimeout``. On
Linux the kernel's own receive timeout (``SO_RCVTIMEO`` on a blocking socket) bounds a receive in the one
``recv(2)``. Two rules make that safe and cheap, and they live here only:

* **never past the deadline**: the kernel's timer may end a wait up to an eighth of it (plus a tick) late, so the
  timeout is set to end that much early (:func:`early`); a wait it ended before the deadline resumes with
  Python's precise (polled) timeout for the rest. A receive therefore returns ``None`` no later than the deadline
  (tests/test_late_replies.py saw a 30 ms overshoot without this);
* **no system call per request**: the timeout is set again only when the wanted one moves out of a window
  :data:`SLACK` wide below it (never above: that would end after the deadline). A command's requests each get
  what their fresh deadline has, which differs by microseconds, so a command sets it once.

Elsewhere Python's timeout is used under the same window rule. Sends are bounded once, at connect, by the
command's timeout (``SO_SNDTIMEO``): a request is a few bytes into an empty send buffer.

Errors are left as they are (``OSError``, ``socket.timeout``): each transport words them for its drive.
"""

from __future__ import annotations

import os
import socket
import struct
import sys
import time
from collections.abc import Callable
from typing import Any, TypeVar

_R = TypeVar("_R")

#: How much earlier than wanted a socket timeout may end and still be kept (the wait then resumes for the rest):
#: a wait within this below the one set costs no system call.
SLACK = 0.01
#: The shortest timeout set: 0 would mean "wait forever"; a wait with no time left still looks once.
MIN_WAIT = 0.001
#: The kernel's timeouts are a ``struct timeval`` here (two C longs); elsewhere Python's timeout is used.
KERNEL_TIMEOUTS = sys.platform.startswith("linux")
_TIMEVAL = struct.Struct("@ll")   # the OS's struct timeval (seconds, microseconds), not a wire layout
_monotonic = time.monotonic
_read, _write = os.read, os.write


def _timeval(seconds: float) -> bytes:
    micros = max(1000, int(seconds * 1e6))   # 0 would mean "wait forever"
    return _TIMEVAL.pack(micros // 1_000_000, micros % 1_000_000)


def early(left: float) -> float:
    """What kernel receive timeout ends a wait before ``left`` s have passed: the kernel may end it up to an eighth
    late, plus a tick (10 ms at HZ=100)."""
    return left * 0.875 - 0.01


class BoundedSocket:
    """One connected socket whose every receive ends by a given time (the rules above). One caller at a time.

    Stream or datagram: :class:`TcpStream` adds what TCP needs; ``pn://``'s DCE/RPC client uses this for its UDP
    socket (:meth:`recv_into`), ``ecat-udp://``'s gateway link too (:meth:`recv`: one datagram each).
    """

    __slots__ = ("sock", "_wait", "_polled", "_armed")

    def __init__(self, sock: socket.socket, send_timeout: float) -> None:
        self.sock = sock
        self._wait = -1.0     # the receive timeout set on the socket (-1: none yet)
        self._polled = True   # Python's polled timeout is on (elsewhere than Linux: always)
        self._armed = -1.0    # the whole wait the receive timeout is set for (see _arm); -1: none
        if KERNEL_TIMEOUTS:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, _timeval(send_timeout))
        sock.settimeout(send_timeout)

    def _bound(self, left: float, precise: bool) -> None:
        """Bound the next receive by ``left`` s: the kernel's timeout ending early, kept while within the
        window; Python's exact one when ``precise`` or too little is left for the kernel's."""
        self._armed = -1.0   # any new bound: a remembered wait is checked again (_arm)
        if KERNEL_TIMEOUTS:
            wait = left * 0.875 - 0.01   # early(left), inline: the hot path
            if precise or wait < MIN_WAIT:
                self._polled = True
                self._wait = -1.0
                self.sock.settimeout(left)
                return
            current = self._wait
            if self._polled:
                self._polled = False
                self.sock.settimeout(None)   # blocking: recv(2) alone, bounded by SO_RCVTIMEO
                current = -1.0
            if current > wait or current < wait - SLACK:
                self._wait = wait = max(MIN_WAIT, wait - SLACK / 2)
                self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, _timeval(wait))
            return
        current = self._wait
        if current > left or current < left - SLACK:
            self._wait = wait = max(MIN_WAIT, left - SLACK / 2)
            self.sock.settimeout(wait)

    def recv(self, at: float, size: int = 65536) -> bytes | None:
        """What arrives before the monotonic time ``at`` (at most ``size`` bytes); ``None`` when nothing did by
        then, ``b""`` when the peer closed the connection. Other failures raise ``OSError``. With no time left it
        still looks once (a millisecond) at what is already there."""
        left = at - _monotonic()
        if self._polled or not self._wait <= left * 0.875 - 0.01 <= self._wait + SLACK:
            # _bound's window test inline, as in request(): a wait the timeout set still fits costs no call
            self._bound(left if left > MIN_WAIT else MIN_WAIT, False)
        try:
            return self.sock.recv(size)
        except (BlockingIOError, socket.timeout):   # SO_RCVTIMEO expired (EAGAIN) / Python's timeout
            return self._rest(at, size)

    def request(self, data: bytes, at: float, size: int = 4096) -> bytes | None:
        """Send all of ``data``, then :meth:`recv` what arrives before ``at``: a request and the first segment of
        its reply in one call (the hot path of a request/response client). ``size`` bounds that first receive only:
        a longer reply comes through :meth:`recv`."""
        left = at - _monotonic()
        if self._polled or not self._wait <= left * 0.875 - 0.01 <= self._wait + SLACK:
            # _bound's window test inline (the hot path of a kernel-bounded socket): the timeout set ends within
            # SLACK before early(left), never after it
            self._bound(left if left > MIN_WAIT else MIN_WAIT, False)
        sock = self.sock
        try:
            sock.sendall(data)
        except BlockingIOError:   # SO_SNDTIMEO expired
            raise socket.timeout("send timed out") from None
        try:
            return sock.recv(size)
        except (BlockingIOError, socket.timeout):   # SO_RCVTIMEO expired (EAGAIN) / Python's timeout
            return self._rest(at, size)

    def _arm(self, at: float, wait: float) -> bool:
        """Bound the socket for a request that starts now and may wait ``wait`` s (``at`` is now + ``wait``: a lone
        request's whole timeout or its first attempt's share, :meth:`akdctl.links.Budget.lone`), and remember ``wait``
        when the timeout set is within the window for a whole one: such a request always waits the same, so whether
        the timeout suits it depends on ``wait`` alone, and the caller skips this call (no clock read, no float
        arithmetic) while ``wait == self._armed``; any new bound forgets it. False when Python's polled timeout
        bounds the socket (too little left for the kernel's): the caller then uses the socket's own calls.
        The one rule for :meth:`TcpStream.request` and :meth:`DatagramSocket.exchange`."""
        left = at - _monotonic()
        if self._polled or not self._wait <= left * 0.875 - 0.01 <= self._wait + SLACK:
            self._bound(left if left > MIN_WAIT else MIN_WAIT, False)   # the window test inline, as in request()
            if self._polled:
                return False
        if wait > 0.0:
            wanted = wait * 0.875 - 0.01   # early(wait)
            if wanted - SLACK <= self._wait <= wanted:
                self._armed = wait
        return True

    def _rest(self, at: float, size: int) -> bytes | None:
        """After a timeout: None at the deadline, or what arrives in the rest of the wait."""
        return self._rest_of(at, self.sock.recv, size)

    def _rest_of(self, at: float, receive: Callable[[Any], _R], argument: Any) -> _R | None:
        """``receive(argument)`` in the rest of the wait after the kernel's timeout ended it early (it is set
        short): with Python's exact timeout; None at the deadline. The one rule for :meth:`recv` and
        :meth:`recv_into`."""
        while True:
            left = at - _monotonic()
            if left <= 0.0:
                return None
            self._bound(left, True)
            try:
                return receive(argument)
            except (BlockingIOError, socket.timeout):
                continue

    def recv_into(self, at: float, buffer: bytearray) -> int | None:
        """Receive one datagram into ``buffer`` if one arrives before the monotonic time ``at``: its length, or
        ``None`` when none did by then. Unlike :meth:`recv` it does not look when no time is left (the caller's
        wait is over). Other failures raise ``OSError``.

        The timeout set is kept while it is anywhere from half to all of what the wait wants (not only within
        :data:`SLACK`): a datagram client's waits are shares of a request's time that differ by the moments the
        thread was not running, and a timeout that ends early only costs the rest's wait when no datagram comes."""
        left = at - _monotonic()
        if left <= 0.0:
            return None
        wanted = left * 0.875 - 0.01  # early(left), inline: the hot path
        if self._polled or not wanted * 0.5 <= self._wait <= wanted:
            self._bound(left, False)
        try:
            return self.sock.recv_into(buffer)
        except (BlockingIOError, socket.timeout):   # SO_RCVTIMEO expired (EAGAIN) / Python's timeout
            return self._rest_of(at, self.sock.recv_into, buffer)

    def send(self, data: bytes) -> None:
        """All of ``data``; ``socket.timeout`` when the send buffer stayed full for the command's timeout."""
        try:
            self.sock.sendall(data)
        except BlockingIOError:   # SO_SNDTIMEO expired
            raise socket.timeout("send timed out") from None

    def send_last(self, data: bytes, wait: float) -> None:
        """A last send before closing (a goodbye such as UnRegisterSession), bounded by ``wait`` s whatever the
        receive waits left set; errors as :meth:`send`."""
        self._polled = True
        self._wait = -1.0
        self._armed = -1.0
        self.sock.settimeout(wait)
        self.sock.sendall(data)

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


class _DescriptorSocket(BoundedSocket):
    """A :class:`BoundedSocket` whose fast requests write and read its descriptor, kept from connect until
    :meth:`close` (which forgets it: a later request fails as on a closed socket, EBADF, never on a descriptor
    number reused). What :class:`DatagramSocket` and :class:`TcpStream` share."""

    __slots__ = ("_fd",)

    def __init__(self, sock: socket.socket, send_timeout: float) -> None:
        super().__init__(sock, send_timeout)
        self._fd = sock.fileno()

    def close(self) -> None:
        self._armed = -1.0
        self._fd = -1
        BoundedSocket.close(self)


class DatagramSocket(_DescriptorSocket):
    """One connected UDP socket of a request/response client (``ecat-udp://``'s gateway link). One caller at a time.

    :meth:`exchange` is a request in one call: the datagram out and the first datagram back, through the descriptor
    while the kernel's timeouts bound the socket, as :meth:`TcpStream.request` does (``write(2)``/``read(2)`` on a
    connected datagram socket are ``send``/``recv`` without flags: one datagram each way).
    """

    __slots__ = ()

    def exchange(self, data: bytes, at: float, size: int = 4096, wait: float = -2.0) -> bytes | None:
        """Send the datagram ``data``, then :meth:`recv` the first datagram that arrives before ``at`` (None when
        none did). A failed send raises :class:`SendFailed` (the send's errno and text; a refusal stays
        ``ConnectionRefusedError``), so the caller words it apart from a failed receive (plain ``OSError``).
        ``wait``: a request that starts now and ends at ``at`` = now + ``wait`` (:meth:`BoundedSocket._arm`: while the
        timeout set suits such a wait, the request is the two system calls with no clock read)."""
        if wait != self._armed and not self._arm(at, wait):
            return self._exchange_polled(data, at, size)   # Python's timeout: the socket's own calls
        fd = self._fd
        try:
            _write(fd, data)
        except ConnectionRefusedError:
            raise
        except OSError as exc:   # (BlockingIOError: SO_SNDTIMEO expired)
            raise SendFailed(exc.errno, exc.strerror) from None
        try:
            return _read(fd, size)
        except BlockingIOError:   # SO_RCVTIMEO expired (EAGAIN), early by design: the rest of the wait
            return self._rest(at, size)

    def _exchange_polled(self, data: bytes, at: float, size: int) -> bytes | None:
        try:
            self.sock.send(data)
        except ConnectionRefusedError:
            raise
        except OSError as exc:
            raise SendFailed(exc.errno, exc.strerror) from None
        try:
            return self.sock.recv(size)
        except (BlockingIOError, socket.timeout):
            return self._rest(at, size)


class SendFailed(OSError):
    """:meth:`DatagramSocket.exchange` could not send its datagram (errno and text of the send's failure)."""


class TcpStream(_DescriptorSocket):
    """One connected TCP socket (TCP_NODELAY: a request is one segment, sent at once). One caller at a time; the
    fast requests go through the descriptor (:class:`_DescriptorSocket`).
    """

    __slots__ = ()

    def __init__(self, sock: socket.socket, send_timeout: float) -> None:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        super().__init__(sock, send_timeout)

    def request(self, data: bytes, at: float, size: int = 4096, wait: float = -2.0) -> bytes | None:
        """:meth:`BoundedSocket.request`, with the same system calls made through the descriptor while the
        kernel's timeouts bound the socket (``write(2)``/``read(2)`` on a socket are ``send``/``recv`` without
        flags): ``os.write``/``os.read`` skip the socket methods' argument parsing, about a tenth of a request's
        user-space instructions on loopback. The descriptor is the one kept at connect until :meth:`close`.

        ``wait``: a request that starts now and may wait ``wait`` s (``at`` is now + ``wait``: a lone request's whole
        timeout, :meth:`akdctl.links.Budget.lone`). Such a request always waits the same, so whether the socket's
        receive timeout suits it (the window rule) depends on ``wait`` alone: checked once, remembered, and
        forgotten whenever the timeout is set again (:meth:`BoundedSocket._arm`). While it holds, the request is the
        two system calls with no clock read and no float arithmetic."""
        if wait != self._armed and not self._arm(at, wait):
            return BoundedSocket.request(self, data, at, size)   # Python's timeout: the socket's own calls
        fd = self._fd
        try:
            sent = _write(fd, data)
        except BlockingIOError:   # SO_SNDTIMEO expired
            raise socket.timeout("send timed out") from None
        if sent != len(data):   # a send buffer that filled up part way: the rest as sendall sends it
            self.send(data[sent:])
        try:
            return _read(fd, size)
        except BlockingIOError:   # SO_RCVTIMEO expired (EAGAIN), early by design: the rest of the wait
            return self._rest(at, size)

    @classmethod
    def connect(cls, host: str, port: int, timeout: float) -> "TcpStream":
        """Connect within ``timeout`` s (``socket.create_connection``'s errors as they are)."""
        sock = socket.create_connection((host, port), timeout=timeout)
        try:
            return cls(sock, timeout)
        except OSError:
            sock.close()
            raise


__all__ = ["BoundedSocket", "DatagramSocket", "SendFailed", "TcpStream", "SLACK", "MIN_WAIT", "KERNEL_TIMEOUTS", "early"]
