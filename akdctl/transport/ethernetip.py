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
from typing import TYPE_CHECKING

from akdctl.errors import CommError, MalformedReply, NoAnswer, UsageError
from akdctl.protocol import cip, enip
from akdctl.protocol.errors import CodecError
from akdctl.links import Deadline, MessageLink
from akdctl.transport.base import LinkOptions, Transport

if TYPE_CHECKING:
    from akdctl.transport.target import Target

class EnipSession(MessageLink):
    """One encapsulation session on TCP. Not thread-safe (one CLI invocation, one caller)."""

    def __init__(self, host: str, port: int, options: LinkOptions, label: str) -> None:
        self.options = options
        self.label = label
        self.session = 0
        self._context = itertools.count(1)
        self._last_context = 0      # the newest sender context sent: smaller ones are our own late replies
        self._confused = False      # the stream lost its framing (a reply cut off by the deadline): reconnect
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
        self.local = sock.getsockname()[:2]
        self.remote = sock.getpeername()[:2]
        return sock

    def _fresh_session(self, what: str, deadline: Deadline) -> None:
        """A new TCP connection and session after the old stream lost its framing: the next request (a stop
        above all) is still delivered. The old session's state on the target ends with its connection."""
        with contextlib.suppress(OSError):
            self.sock.close()
        self._confused = False
        self.session = 0
        self.sock = self._connect()
        reply = self._exchange(enip.REGISTER_SESSION, enip.register_session_data(),
                               f"RegisterSession (a fresh session for {what})", deadline)
        if reply.status != 0 or reply.session == 0:
            self._confused = True
            raise CommError(f"{self.label}: the target refuses a fresh session (status 0x{reply.status:08X})")
        self.session = reply.session

    # ---------------------------------------------------------------- framing
    def _trace(self, direction: str, data: bytes, note: str) -> None:
        if not self.options.tracer.active:  # tracing off costs one attribute test per frame, no dict, no tuple
            return
        src, dst = (self.local, self.remote) if direction == "tx" else (self.remote, self.local)
        self.options.tracer.frame(direction, "enip", data, note=note,  # type: ignore[arg-type]
                                  meta={"proto": "tcp", "src": src, "dst": dst})

    def _recv_exact(self, size: int, what: str, deadline: Deadline, whole: bool = True) -> bytes:
        """``size`` bytes; ``whole`` False for the rest of a packet whose header was read (a timeout there
        leaves the stream mid-packet, so the session is confused)."""
        data = bytearray()
        while len(data) < size:
            self.sock.settimeout(max(0.001, deadline.remaining()))
            try:
                chunk = self.sock.recv(size - len(data))
            except socket.timeout:
                self._confused = self._confused or bool(data) or not whole  # a packet cut in two
                raise NoAnswer(f"{self.label}: no answer to {what} within {deadline.describe()}") from None
            except OSError as exc:
                self._confused = True
                raise CommError(f"{self.label}: connection failed during {what} ({exc.strerror or exc})") from None
            if not chunk:
                self._confused = True
                raise CommError(f"{self.label}: the target closed the connection during {what}"
                                + (f" after {len(data)} of {size} bytes" if data else ""))
            data += chunk
        return bytes(data)

    def exchange(self, command: int, data: bytes, what: str) -> enip.Packet:
        """Send one encapsulation packet and return the reply that matches it (one deadline for both:
        TCP repeats for us, so the request is sent once)."""
        with self.options.budget.request(attempts=1) as deadline:
            return self._exchange(command, data, what, deadline)

    def _exchange(self, command: int, data: bytes, what: str, deadline: Deadline) -> enip.Packet:
        if self._confused and command != enip.REGISTER_SESSION:
            self._fresh_session(what, deadline)
        number = next(self._context)
        self._last_context = number
        context = struct.pack("<Q", number)
        packet = enip.Packet(command, data, self.session, 0, context)
        raw = packet.encode()
        self._trace("tx", raw, what)
        self.sock.settimeout(max(0.001, deadline.remaining()))
        try:
            self.sock.sendall(raw)
        except socket.timeout:
            self._confused = True  # part of the request may be on the wire
            raise NoAnswer(f"{self.label}: could not send {what} within {deadline.describe()}") from None
        except OSError as exc:
            self._confused = True
            raise CommError(f"{self.label}: cannot send {what} ({exc.strerror or exc})") from None
        while True:
            head_raw = self._recv_exact(enip.HEADER_SIZE, what, deadline)
            try:
                head = enip.decode_header(head_raw)
            except CodecError as exc:
                self._confused = True
                raise MalformedReply(f"{self.label}: malformed encapsulation header in the reply to {what}: "
                                     f"{exc}") from None
            if head.length > enip.MAX_DATA:
                self._confused = True
                raise MalformedReply(f"{self.label}: reply to {what} announces {head.length} bytes")
            body = self._recv_exact(head.length, what, deadline, whole=False) if head.length else b""
            if head.context != context:
                earlier = struct.unpack("<Q", head.context)[0]
                if 0 < earlier < number:
                    # The reply to one of our own earlier requests that came after its deadline: the sender
                    # context exists for telling it apart. Dropped; the conversation goes on.
                    self.late_replies += 1
                    self._trace("rx", head_raw + body, f"late reply to request {earlier} (discarded)")
                    continue
                self._trace("rx", head_raw + body, what)
                self._confused = True
                if head.command != command:
                    raise MalformedReply(f"{self.label}: reply to {what} is a {enip.command_name(head.command)} "
                                         "packet")
                raise MalformedReply(f"{self.label}: reply to {what} carries a sender context akdctl never sent")
            self._trace("rx", head_raw + body, what)
            break
        if head.command != command:
            raise MalformedReply(f"{self.label}: reply to {what} is a {enip.command_name(head.command)} packet")
        if command != enip.REGISTER_SESSION and head.status == 0 and head.session != self.session:
            raise MalformedReply(f"{self.label}: reply to {what} names session 0x{head.session:08X}, "
                                 f"ours is 0x{self.session:08X}")
        return enip.Packet(head.command, body, head.session, head.status, head.context, head.options)

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
        from akdctl.catalog.texts import enip_status_text

        what = f"{req.name} {_path_label(req.path)}"
        rr = enip.unconnected(req.encode())
        rr = enip.RRData(rr.items + tuple(extra_items), rr.timeout, rr.interface)
        reply = self.exchange(enip.SEND_RR_DATA, rr.encode(), what)
        if reply.status != 0:
            raise CommError(f"{self.label}: the target refused {what} at the encapsulation layer: "
                            f"{enip_status_text(reply.status)}", code=reply.status)
        try:
            response = cip.Response.decode(enip.unconnected_message(enip.RRData.decode(reply.data)))
        except CodecError as exc:
            raise MalformedReply(f"{self.label}: malformed reply to {what}: {exc}") from None
        if response.service != req.service:
            raise MalformedReply(f"{self.label}: reply to {what} answers service 0x{response.service:02X}")
        return response

    def close(self) -> None:
        try:
            if self.session:
                raw = enip.Packet(enip.UNREGISTER_SESSION, b"", self.session).encode()
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
    import time

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
