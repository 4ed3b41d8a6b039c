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

import itertools
import socket
import time
from typing import TYPE_CHECKING

from akdctl.errors import CommError, MalformedReply, NoAnswer, UsageError
from akdctl.protocol import cip, enip
from akdctl.protocol.errors import CodecError
from akdctl.links import Deadline, MessageLink
from akdctl.transport.base import LinkOptions, Transport
from akdctl.transport.tcp_stream import TcpStream

if TYPE_CHECKING:
    from akdctl.transport.target import Target

class EnipSession(MessageLink):
    """One encapsulation session on TCP. Not thread-safe (one CLI invocation, one caller).

    Per request: one packet packed by the codec, one send, usually one receive that holds the whole reply
    (bytes past the reply stay for the next read). The socket waits are :mod:`akdctl.transport.tcp_stream`'s:
    no receive outlasts the deadline, and no timeout is set per request.
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
        self.stream = self._connect()

    @property
    def sock(self) -> socket.socket:
        """The session's socket (tests wrap it to count its system calls)."""
        return self.stream.sock

    @sock.setter
    def sock(self, sock: socket.socket) -> None:
        self.stream.sock = sock

    def _connect(self) -> TcpStream:
        host, port, label, timeout = self.host, self.port, self.label, self.options.timeout
        try:
            stream = TcpStream.connect(host, port, timeout)
        except socket.timeout:
            raise NoAnswer(f"{label}: no answer from {host}:{port} within {timeout:g} s (TCP connect)") from None
        except (socket.gaierror, UnicodeError) as exc:
            raise UsageError(f"{label}: cannot resolve host {host!r} ({exc})") from None
        except OSError as exc:
            raise CommError(f"{label}: cannot connect to {host}:{port} ({exc.strerror or exc})") from None
        self._rest = b""
        ends = stream.local_and_remote()
        if ends is None:
            stream.close()
            raise CommError(f"{label}: the connection to {host}:{port} closed at once")
        self.local, self.remote = ends
        return stream

    def _fresh_session(self, what: "str | cip.Request", deadline: Deadline) -> None:
        """A new TCP connection and session after the old stream lost its framing: the next request (a stop
        above all) is still delivered. The old session's state on the target ends with its connection."""
        self.stream.close()
        self._confused = False
        self.session = 0
        self.stream = self._connect()
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

    def _recv(self, what: "str | cip.Request", deadline: Deadline, partial: bool) -> bytes:
        """The next bytes of the stream within the deadline. ``partial``: a packet has begun (a timeout then
        leaves the stream mid-packet, so the session is confused)."""
        try:
            chunk = self.stream.recv(deadline.at, 4096)
        except OSError as exc:
            self._confused = True
            raise CommError(f"{self.label}: connection failed during {_name(what)} "
                            f"({exc.strerror or exc})") from None
        return self._checked(chunk, what, deadline, partial)

    def _checked(self, chunk: bytes | None, what: "str | cip.Request", deadline: Deadline, partial: bool) -> bytes:
        """A receive's bytes, or the error its None (nothing by the deadline) or b"" (closed) means."""
        if chunk:
            return chunk
        if chunk is None:
            self._confused = self._confused or partial
            raise NoAnswer(f"{self.label}: no answer to {_name(what)} within {deadline.describe()}")
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
        stream = self.stream
        if not self._rest:   # the usual request: sent, and the first segment of its reply read, in one call
            try:
                chunk = stream.request(raw, deadline.at, 4096)
            except socket.timeout:
                self._confused = True  # part of the request may be on the wire
                raise NoAnswer(f"{self.label}: could not send {_name(what)} within {deadline.describe()}") from None
            except OSError as exc:
                self._confused = True
                raise CommError(f"{self.label}: connection failed during {_name(what)} "
                                f"({exc.strerror or exc})") from None
            self._rest = self._checked(chunk, what, deadline, False)
        else:
            self._send(raw, what, deadline)
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

    def _send(self, raw: bytes, what: "str | cip.Request", deadline: Deadline) -> None:
        """Send a packet while bytes of an earlier reply wait to be read."""
        try:
            self.stream.send(raw)
        except socket.timeout:
            self._confused = True  # part of the request may be on the wire
            raise NoAnswer(f"{self.label}: could not send {_name(what)} within {deadline.describe()}") from None
        except OSError as exc:
            self._confused = True
            raise CommError(f"{self.label}: cannot send {_name(what)} ({exc.strerror or exc})") from None

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
                self.stream.send_last(raw, min(self.options.timeout, 1.0))
        except OSError:
            pass
        finally:
            self.session = 0
            self.stream.close()


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
