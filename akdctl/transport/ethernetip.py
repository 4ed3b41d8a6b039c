"""``eip://HOST[:44818]``: CIP explicit messaging to an AKD over an EtherNet/IP encapsulation session.

One TCP connection, one RegisterSession, then unconnected (UCMM) requests: SendRRData with a
Null address item and an unconnected data item, **no Unconnected_Send wrapper and no route path**
(the AKD is not a backplane; reference/ethernetip.md 5). Every wait is bounded: the connect by
the timeout, each request (its send and every receive of its reply) by one deadline of the command's
Budget. A reply must echo our sender context
and session, or it is a malformed reply. ``close`` unregisters the session and closes the socket
on every way out.

The transport offers its session as a *message link* (:class:`akdctl.links.MessageLink`); the
Connection builds the attribute channel (:class:`akdctl.channels.cip.CipAttributes`) over it. Frames
are traced as layer ``enip`` with TCP addresses, so ``--trace`` prints them and ``--pcap`` writes
them as TCP segments that Wireshark's enip/cip dissectors decode.

Query parameters: none yet; the port defaults to 44818.
"""

from __future__ import annotations

import contextlib
import itertools
import socket
import struct
import sys
import time
from typing import TYPE_CHECKING

from akdctl.errors import CommError, MalformedReply, NoAnswer, UsageError
from akdctl.protocol import cip, enip
from akdctl.protocol.errors import CodecError
from akdctl.links import Deadline, MessageLink
from akdctl.transport.base import LinkOptions, Transport

if TYPE_CHECKING:
    from akdctl.transport.target import Target

#: How much earlier than the deadline a socket timeout may end a wait and still be kept (the wait then resumes
#: for the rest): a request whose deadline is within this of the last one's sets no socket timeout at all.
TIMEOUT_SLACK = 0.01
#: Linux bounds a blocking socket's waits itself (SO_RCVTIMEO/SO_SNDTIMEO): each send and receive is then one
#: system call, where Python's own socket timeout polls before each. The kernel's timer wheel may end such a wait
#: up to an eighth of it (plus a tick) late, so it is set to end that much early, and a wait it ended before the
#: deadline resumes with Python's precise (polled) timeout for the rest. Elsewhere Python's timeout does it all.
KERNEL_TIMEOUTS = sys.platform.startswith("linux")
_TIMEVAL = struct.Struct("@ll")  # the OS's struct timeval (seconds, microseconds), not a wire layout
#: What a wait that ran out raises: Python's socket timeout, or EAGAIN from a kernel-bounded blocking socket.
_TIMED_OUT = (socket.timeout, BlockingIOError)


def _kernel_bound(sock: socket.socket, seconds: float) -> None:
    """Bound each of a blocking socket's next sends and receives by ``seconds`` (at least 1 ms: 0 is forever)."""
    micro = max(1000, round(seconds * 1e6))
    timeval = _TIMEVAL.pack(micro // 1_000_000, micro % 1_000_000)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, timeval)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, timeval)


def _early(left: float) -> float:
    """When a kernel-bounded wait must be set to end so that it ends before ``left`` s have passed."""
    return left * 0.875 - 0.01  # a tick: 10 ms at HZ=100


class EnipSession(MessageLink):
    """One encapsulation session on TCP. Not thread-safe (one CLI invocation, one caller).

    Per request: one packet packed by the codec, one send, usually one receive that holds the whole reply
    (bytes past the reply stay for the next read), and no socket timeout set unless the deadline moved by more
    than :data:`TIMEOUT_SLACK` -- each ``settimeout`` is a system call. A socket timeout never outlasts the
    deadline; one that ends a wait early resumes it for what is left.
    """

    def __init__(self, host: str, port: int, options: LinkOptions, label: str) -> None:
        self.options = options
        self.label = label
        self.session = 0
        self._context = itertools.count(1)
        self._confused = False      # the stream lost its framing (a reply cut off by the deadline): reconnect
        self._rest = b""            # bytes read past the last packet (the start of the next one)
        self.host, self.port = host, port
        self.late_replies = 0
        self.sock = self._connect()

    def _connect(self) -> socket.socket:
        host, port, label, timeout = self.host, self.port, self.label, self.options.timeout
        try:
            sock = socket.create_connection((host, port), timeout=timeout)
        except socket.timeout:
            raise NoAnswer(f"{label}: no answer from {host}:{port} within {timeout:g} s (TCP connect)") from None
        except (socket.gaierror, UnicodeError) as exc:
            raise UsageError(f"{label}: cannot resolve host {host!r} ({exc})") from None
        except OSError as exc:
            raise CommError(f"{label}: cannot connect to {host}:{port} ({exc.strerror or exc})") from None
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # a request is one segment: send it now
        sock.settimeout(timeout)
        self._timeout = timeout     # the socket's timeout now (Python's or the kernel's); set only when it changes
        self._polled = True         # Python's (polled) timeout is on
        self._rest = b""
        self.local = sock.getsockname()[:2]
        self.remote = sock.getpeername()[:2]
        return sock

    def _fresh_session(self, what: "str | cip.Request", deadline: Deadline) -> None:
        """A new TCP connection and session after the old stream lost its framing: the next request (a stop
        above all) is still delivered. The old session's state on the target ends with its connection."""
        with contextlib.suppress(OSError):
            self.sock.close()
        self._confused = False
        self.session = 0
        self.sock = self._connect()
        reply = self._exchange(enip.REGISTER_SESSION, enip.register_session_data(),
                               f"RegisterSession (a fresh session for {_name(what)})", deadline)
        if reply.status != 0 or reply.session == 0:
            self._confused = True
            raise CommError(f"{self.label}: the target refuses a fresh session (status 0x{reply.status:08X})")
        self.session = reply.session

    # ---------------------------------------------------------------- framing
    def _trace(self, direction: str, data: bytes, note: str) -> None:
        """Callers test ``tracer.active`` first: with tracing off no note, dict or tuple is built."""
        src, dst = (self.local, self.remote) if direction == "tx" else (self.remote, self.local)
        self.options.tracer.frame(direction, "enip", data, note=note,  # type: ignore[arg-type]
                                  meta={"proto": "tcp", "src": src, "dst": dst})

    def _wait_within(self, deadline: Deadline, precise: bool = False) -> None:
        """Bound the next wait by the deadline. The socket's timeout is kept while it ends within TIMEOUT_SLACK
        before it (no system call); ``precise`` (a kernel-bounded wait ran out early) takes Python's polled
        timeout for the rest."""
        left = max(deadline.at - time.monotonic(), 0.001)  # no time left: a last look at what is already there
        if KERNEL_TIMEOUTS:
            early = _early(left)
            if precise or early < 0.001:
                self._polled = True
                self.sock.settimeout(left)
                return
            current = self._timeout
            if self._polled:
                self._polled = False
                self.sock.settimeout(None)
                current = -1.0
            if current > early or current < early - TIMEOUT_SLACK:
                self._timeout = max(0.001, early - TIMEOUT_SLACK / 2)
                _kernel_bound(self.sock, self._timeout)
            return
        current = self._timeout
        if current > left or current < left - TIMEOUT_SLACK:
            current = self._timeout = max(0.001, left - TIMEOUT_SLACK / 2)
            self.sock.settimeout(current)

    def _recv(self, what: "str | cip.Request", deadline: Deadline, partial: bool) -> bytes:
        """The next bytes of the stream within the deadline. ``partial``: a packet has begun (a timeout then
        leaves the stream mid-packet, so the session is confused)."""
        precise = False
        while True:
            self._wait_within(deadline, precise)
            try:
                chunk = self.sock.recv(4096)
            except _TIMED_OUT:
                if not deadline.expired():
                    precise = True  # the socket's timeout ended before the deadline: wait for the rest
                    continue
                self._confused = self._confused or partial
                raise NoAnswer(f"{self.label}: no answer to {_name(what)} within {deadline.describe()}") from None
            except OSError as exc:
                self._confused = True
                raise CommError(f"{self.label}: connection failed during {_name(what)} "
                                f"({exc.strerror or exc})") from None
            if not chunk:
                self._confused = True
                raise CommError(f"{self.label}: the target closed the connection during {_name(what)}"
                                + (" in the middle of a reply" if partial else ""))
            return chunk

    def _read_packet(self, what: "str | cip.Request", deadline: Deadline) -> tuple[tuple[int, ...], bytes, bytes]:
        """(header fields, command data, the whole packet) of the next packet on the stream."""
        data = self._rest or self._recv(what, deadline, False)
        while len(data) < enip.HEADER_SIZE:
            data += self._recv(what, deadline, True)
        head = enip.unpack_header(data)
        if head[1] > enip.MAX_DATA:
            self._confused = True
            raise MalformedReply(f"{self.label}: reply to {_name(what)} announces {head[1]} bytes")
        end = enip.HEADER_SIZE + head[1]
        while len(data) < end:
            data += self._recv(what, deadline, True)
        if len(data) == end:
            self._rest = b""
            return head, data[enip.HEADER_SIZE:], data
        self._rest = data[end:]
        return head, data[enip.HEADER_SIZE:end], data[:end]

    def exchange(self, command: int, data: bytes, what: str) -> enip.Packet:
        """Send one encapsulation packet and return the reply that matches it (one deadline for both:
        TCP repeats for us, so the request is sent once)."""
        with self.options.budget.request(attempts=1) as deadline:
            return self._exchange(command, data, what, deadline)

    def _exchange(self, command: int, data: bytes, what: str, deadline: Deadline) -> enip.Packet:
        if self._confused and command != enip.REGISTER_SESSION:
            self._fresh_session(what, deadline)
        number = next(self._context)
        head, body = self._round_trip(enip.pack_packet(command, data, self.session, number), command, number, what,
                                      deadline)
        return enip.Packet(head[0], body, head[2], head[3], head[4].to_bytes(8, "little"), head[5])

    def _round_trip(self, raw: bytes, command: int, number: int, what: "str | cip.Request",
                    deadline: Deadline) -> tuple[tuple[int, ...], bytes]:
        """Send one packet (sender context ``number``) and return the header fields and data of its reply."""
        tracer = self.options.tracer
        if tracer.active:
            self._trace("tx", raw, _name(what))
        self._wait_within(deadline)
        try:
            self.sock.sendall(raw)
        except _TIMED_OUT:
            self._confused = True  # part of the request may be on the wire
            raise NoAnswer(f"{self.label}: could not send {_name(what)} within {deadline.describe()}") from None
        except OSError as exc:
            self._confused = True
            raise CommError(f"{self.label}: cannot send {_name(what)} ({exc.strerror or exc})") from None
        while True:
            try:
                head, body, packet = self._read_packet(what, deadline)
            except CodecError as exc:
                self._confused = True
                raise MalformedReply(f"{self.label}: malformed encapsulation header in the reply to {_name(what)}: "
                                     f"{exc}") from None
            context = head[4]
            if context != number:
                if 0 < context < number:
                    # The reply to one of our own earlier requests that came after its deadline: the sender
                    # context exists for telling it apart. Dropped; the conversation goes on.
                    self.late_replies += 1
                    if tracer.active:
                        self._trace("rx", packet, f"late reply to request {context} (discarded)")
                    continue
                if tracer.active:
                    self._trace("rx", packet, _name(what))
                self._confused = True
                if head[0] != command:
                    raise MalformedReply(f"{self.label}: reply to {_name(what)} is a {enip.command_name(head[0])} "
                                         "packet")
                raise MalformedReply(f"{self.label}: reply to {_name(what)} carries a sender context akdctl never "
                                     "sent")
            if tracer.active:
                self._trace("rx", packet, _name(what))
            break
        if head[0] != command:
            raise MalformedReply(f"{self.label}: reply to {_name(what)} is a {enip.command_name(head[0])} packet")
        if command != enip.REGISTER_SESSION and head[3] == 0 and head[2] != self.session:
            raise MalformedReply(f"{self.label}: reply to {_name(what)} names session 0x{head[2]:08X}, "
                                 f"ours is 0x{self.session:08X}")
        return head, body

    # ---------------------------------------------------------------- session
    def register(self) -> None:
        from akdctl.catalog.texts import enip_status_text

        reply = self.exchange(enip.REGISTER_SESSION, enip.register_session_data(), "RegisterSession")
        if reply.status != 0:
            raise CommError(f"{self.label}: the target refuses the session: {enip_status_text(reply.status)}",
                            code=reply.status)
        if reply.session == 0:
            raise MalformedReply(f"{self.label}: RegisterSession reply carries no session handle")
        self.session = reply.session

    def request(self, req: cip.Request, extra_items: tuple[enip.Item, ...] = ()) -> cip.Response:
        """One UCMM request; the CIP reply (any general status) or a link error. ``extra_items``
        (socket-address items) follow the unconnected data item, as a Forward_Open may need."""
        with self.options.budget.request(attempts=1) as deadline:
            if self._confused:
                self._fresh_session(req, deadline)
            number = next(self._context)
            if extra_items:
                rr = enip.unconnected(req.encode())
                raw = enip.pack_packet(enip.SEND_RR_DATA, enip.RRData(rr.items + tuple(extra_items)).encode(),
                                       self.session, number)
            else:
                raw = enip.pack_ucmm(self.session, number, req.encode())
            head, body = self._round_trip(raw, enip.SEND_RR_DATA, number, req, deadline)
        if head[3] != 0:
            from akdctl.catalog.texts import enip_status_text

            raise CommError(f"{self.label}: the target refused {_name(req)} at the encapsulation layer: "
                            f"{enip_status_text(head[3])}", code=head[3])
        try:
            response = cip.decode_response(enip.ucmm_reply_message(body))
        except CodecError as exc:
            raise MalformedReply(f"{self.label}: malformed reply to {_name(req)}: {exc}") from None
        if response.service != req.service:
            raise MalformedReply(f"{self.label}: reply to {_name(req)} answers service 0x{response.service:02X}")
        return response

    def close(self) -> None:
        try:
            if self.session:
                raw = enip.pack_packet(enip.UNREGISTER_SESSION, b"", self.session, 0)
                if self.options.tracer.active:
                    self._trace("tx", raw, "UnRegisterSession")
                self.sock.settimeout(min(self.options.timeout, 1.0))
                self.sock.sendall(raw)
        except OSError:
            pass
        finally:
            self.session = 0
            try:
                self.sock.close()
            except OSError:
                pass


def _name(what: "str | cip.Request") -> str:
    """What a message calls the request: built only when a message or a trace note needs it."""
    if isinstance(what, str):
        return what
    return f"{what.name} {_path_label(what.path)}"


def _path_label(path: bytes) -> str:
    try:
        return cip.decode_path(path).label
    except CodecError:
        return path.hex(" ")


class EthernetIpTransport(Transport):
    """``eip://HOST[:44818]``: one encapsulation session to one AKD."""

    scheme = "eip"

    def __init__(self, target: "Target", options: LinkOptions) -> None:
        super().__init__(target, options)
        self.label = target.display
        self.session: EnipSession | None = None

    def open(self) -> None:
        try:
            self.session = EnipSession(self.target.host, self.target.port or enip.TCP_PORT, self.options, self.label)
            self.session.register()
            self.message_link = self.session
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        if self.session is not None:
            self.session.close()
        self.session = None
        self.message_link = None


def list_identity(host: str, port: int, options: LinkOptions, broadcast_from: str | None = None,
                  wait: float | None = None) -> list[tuple[str, enip.Identity]]:
    """ListIdentity on UDP: unicast to ``host``, or to the broadcast address ``host`` from the interface
    address ``broadcast_from`` (bound to it, so the datagram leaves by that interface only); collects
    replies until ``wait`` (default: the link timeout) has passed."""

    wait = options.timeout if wait is None else wait
    broadcast = broadcast_from is not None
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        if broadcast:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            sock.bind((broadcast_from, 0))
        request = enip.Packet(enip.LIST_IDENTITY, b"", context=b"akdscan\0").encode()
        try:
            sock.sendto(request, (host, port))
        except OSError as exc:
            raise CommError(f"ListIdentity to {host}:{port} failed ({exc.strerror or exc})") from None
        local = sock.getsockname()[:2]
        options.tracer.frame("tx", "enip", request, note="ListIdentity",
                             meta={"proto": "udp", "src": local, "dst": (host, port)})
        found: list[tuple[str, enip.Identity]] = []
        deadline = time.monotonic() + wait
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return found
            sock.settimeout(left)
            try:
                data, peer = sock.recvfrom(4096)
            except socket.timeout:
                return found
            except OSError:
                continue   # ICMP port unreachable on a unicast probe: keep waiting until the deadline
            options.tracer.frame("rx", "enip", data, note="ListIdentity",
                                 meta={"proto": "udp", "src": peer[:2], "dst": local})
            try:
                packet = enip.decode_packet(data)
                if packet.command != enip.LIST_IDENTITY or packet.status != 0:
                    continue
                for ident in enip.decode_list_identity(packet.data):
                    found.append((peer[0], ident))
            except CodecError:
                continue
            if not broadcast and found:
                return found
    finally:
        sock.close()


__all__ = ["EthernetIpTransport", "EnipSession", "list_identity"]
