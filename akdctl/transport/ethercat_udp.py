"""``ecat-udp://HOST[:34980]/STATION``: CoE through a running master's ETG.8200
mailbox gateway.

The gateway forwards a mailbox (wrapped in an EtherCAT header of type 5) to the
slave with the given station address and sends the slave's reply back to us.
Gateways answer nothing when a request fails or times out inside the master,
so every wait here is bounded; the SDO client above
(:mod:`akdctl.channels.coe_sdo`) repeats reads, never writes, and matches
replies on their content and, where the gateway echoes it, the mailbox counter
(:mod:`akdctl.channels.reply_filter`: masters may rewrite the counter).

Target query options: ``mailbox=N`` the slave's mailbox size in bytes
(default 512, the AKD ESI default; a real AKD reports 1024 - larger objects are
then segmented, never refused).
"""

from __future__ import annotations

import socket
import time
from typing import Literal

from akdctl.errors import CommError, UsageError
from akdctl.links import MailboxLink
from akdctl.protocol.gateway_sdo import UploadFrames
from akdctl.protocol.mailbox import MailboxError, unwrap_gateway, wrap_gateway
from akdctl.transport.base import LinkOptions, Transport
from akdctl.transport.target import Target
from akdctl.transport.tcp_stream import DatagramSocket, SendFailed
from akdctl.transport.trace import Tracer

DEFAULT_PORT = 34980
DEFAULT_MAILBOX = 512
#: How many ignored datagrams (foreign station, not a gateway datagram) a receive reads past its end before it
#: reports silence: what was already queued is still looked at, a peer that never stops sending holds it no longer.
_LATE_LOOKS = 64


class GatewayMailboxLink(MailboxLink):
    """A :class:`MailboxLink` over one connected UDP socket to a gateway.

    It traces each datagram (layer ``ecat-gw``: the 2-byte gateway header and the
    mailbox as it is), so the mailbox layer is not traced a second time.
    """

    traced_on_wire = True

    def __init__(self, host: str, port: int, station: int, tracer: Tracer, mailbox_size: int = DEFAULT_MAILBOX,
                 timeout: float = 2.0) -> None:
        self.host, self.port, self.station = host, port, station
        self.mailbox_address = station
        self.tracer = tracer
        self.mailbox_size = mailbox_size
        self._address = station.to_bytes(2, "little")
        self.sent = 0       # datagrams sent
        self.received = 0   # datagrams handed up: the mailboxes receive returned, the datagrams quick_request did
        try:
            infos = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        except socket.gaierror as exc:
            raise CommError(f"cannot resolve EtherCAT gateway host {host!r}: {exc.strerror}") from None
        family, _, _, _, addr = infos[0]
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.connect(addr)
        except OSError as exc:
            sock.close()
            raise CommError(f"cannot reach EtherCAT gateway {host}:{port}: {exc.strerror}") from None
        self.sock: socket.socket | None = sock
        try:
            # every receive ends by its wait's end, in one recv(2) where the kernel can bound it (tcp_stream: the
            # rule pn:// waits by too); sends bounded by the command's timeout
            self.stream = DatagramSocket(sock, timeout)
        except OSError as exc:
            sock.close()
            raise CommError(f"cannot use the socket to EtherCAT gateway {host}:{port}: {exc.strerror}") from None
        self._local = sock.getsockname()[:2]
        self._remote = addr[:2]

    def _meta(self, direction: str) -> dict[str, object]:
        src, dst = (self._local, self._remote) if direction == "tx" else (self._remote, self._local)
        return {"proto": "udp", "src": src, "dst": dst}

    def send(self, mailbox: bytes) -> None:
        sock = self.sock
        if sock is None:
            raise self._closed()
        if mailbox[2] | mailbox[3] << 8 != self.station:  # the mailbox names the gateway's station (the channel
            mailbox = mailbox[:2] + self._address + mailbox[4:]  # writes it)
        try:
            datagram = wrap_gateway(mailbox)
        except MailboxError as exc:
            raise CommError(f"cannot send to EtherCAT gateway {self.host}:{self.port}: {exc}") from None
        if self.tracer.active:
            self.tracer.frame("tx", "ecat-gw", datagram, note=f"gateway -> station {self.station}",
                              meta=self._meta("tx"))
        try:
            sock.send(datagram)
        except ConnectionRefusedError:
            raise self._refused() from None
        except OSError as exc:
            raise CommError(f"cannot send to EtherCAT gateway {self.host}:{self.port}: {exc.strerror}") from None
        self.sent += 1

    def receive(self, timeout: float) -> bytes | None:
        sock = self.sock
        if sock is None:
            raise self._closed()
        stream = self.stream
        at = time.monotonic() + timeout
        late = 0
        while True:
            # at least one look, even with no time left (timeout 0: take what is already there); past the end, the
            # datagrams ignored below are read on only while the next one is already there, and so many at most
            try:
                data = stream.recv(at, 4096)
            except ConnectionRefusedError:
                raise self._refused() from None
            except OSError as exc:
                raise CommError(f"EtherCAT gateway {self.host}:{self.port}: {exc.strerror}") from None
            if data is None:
                return None
            mailbox = self.frame_mailbox(data)
            if mailbox is not None:
                self.received += 1
                return mailbox
            if time.monotonic() >= at and (late := late + 1) > _LATE_LOOKS:
                return None

    def frame_mailbox(self, frame: bytes) -> bytes | None:
        """The mailbox in a gateway datagram (traced as received), or None for one a receive reads past (traced
        as ignored): not a gateway datagram, or from another station (address 0: the gateway's own answer)."""
        tracer = self.tracer
        try:
            mailbox = unwrap_gateway(frame)
        except MailboxError as exc:
            if tracer.active:
                tracer.frame("rx", "ecat-gw", frame, note=f"ignored: {exc}", meta=self._meta("rx"))
            return None
        address = mailbox[2] | mailbox[3] << 8
        if address != self.station and address:
            if tracer.active:
                tracer.frame("rx", "ecat-gw", frame, note=f"ignored: from station {address}", meta=self._meta("rx"))
            return None
        if tracer.active:
            tracer.frame("rx", "ecat-gw", frame, note=f"gateway <- station {address}", meta=self._meta("rx"))
        return mailbox

    # --- the poll's quick way (MailboxLink.quick_frames): whole datagrams, pre-encoded by the codec ---------------

    quick_frames = True

    def upload_frames(self, index: int, subindex: int) -> UploadFrames:
        return UploadFrames(self.station, index, subindex)

    def quick_request(self, frame: bytes, at: float, wait: float) -> bytes | None | Literal[False]:
        """Send a datagram of :meth:`upload_frames` and return the first datagram received before ``at``, untouched:
        the SDO client checks it whole and hands anything else to :meth:`frame_mailbox`. Declined (False, nothing
        sent) while tracing: the general path traces every datagram with what it made of it."""
        if self.tracer.active:
            return False
        if self.sock is None:
            raise self._closed()
        try:
            data = self.stream.exchange(frame, at, 4096, wait)
        except ConnectionRefusedError:
            raise self._refused() from None
        except SendFailed as exc:
            raise CommError(f"cannot send to EtherCAT gateway {self.host}:{self.port}: {exc.strerror}") from None
        except OSError as exc:
            self.sent += 1
            raise CommError(f"EtherCAT gateway {self.host}:{self.port}: {exc.strerror}") from None
        self.sent += 1
        if data is not None:
            self.received += 1
        return data

    def _refused(self) -> CommError:
        """ICMP port unreachable came back (ECONNREFUSED on the connected socket): no gateway listens there,
        and the request bounced before reaching any drive, so failing now loses nothing."""
        return CommError(f"no answer from an EtherCAT gateway: nothing listens on UDP port {self.port} of {self.host} "
                         "(ICMP port unreachable); is the master's mailbox gateway enabled on that port?")

    @staticmethod
    def _closed() -> CommError:
        return CommError("the EtherCAT gateway link is closed")

    def close(self) -> None:
        if self.sock is not None:
            self.stream.close()   # closes the socket and forgets its descriptor (DatagramSocket.exchange writes to it)
            self.sock = None


class EthercatUdpTransport(Transport):
    """Object channel (CoE SDO) to one slave behind an ETG.8200 gateway."""

    scheme = "ecat-udp"

    def __init__(self, target: Target, options: LinkOptions) -> None:
        super().__init__(target, options)
        self.link: GatewayMailboxLink | None = None

    @property
    def station(self) -> int:
        parts = self.target.path_parts
        try:
            station = int(parts[0], 0)
        except (IndexError, ValueError):
            raise UsageError(f"malformed target {self.target.raw!r}: expected ecat-udp://HOST[:PORT]/STATION") from None
        if not 0 <= station <= 0xFFFF:
            raise UsageError(f"target {self.target.raw!r}: station address {station} is outside 0..65535")
        return station

    def open(self) -> None:
        mailbox = self.target.query_int("mailbox", DEFAULT_MAILBOX)
        if not 16 <= mailbox <= 2040:
            raise UsageError(f"target {self.target.raw!r}: mailbox={mailbox} is outside 16..2040 bytes")
        self.link = self.mailbox_link = GatewayMailboxLink(self.target.host, self.target.port or DEFAULT_PORT,
                                                           self.station, self.options.tracer, mailbox,
                                                           self.options.timeout)

    def close(self) -> None:
        if self.link is not None:
            self.link.close()
            self.link = None
        self.mailbox_link = None
