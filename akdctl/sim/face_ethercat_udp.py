"""`akdctl sim serve --ethercat-udp [ADDR]`: an ETG.8200 mailbox gateway in
front of one or more simulated AKDs.

It behaves like the gateway of a running master (TwinCAT, IgH): a UDP datagram
carrying an EtherCAT header of type 5 and a mailbox addressed to a station is
forwarded to that slave, and every mailbox the slave answers with (emergencies
included) goes back to the sender with the station's address. Requests for an
unknown station, malformed datagrams and injected "drops" get no answer at all,
because that is what real gateways do - the client must time out and retry.
"""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Callable
from typing import Any

from akdctl.errors import UsageError
from akdctl.sim.drive import SimDrive
from akdctl.sim.ecat_inject import Injector, failure_reply, mailbox_error_reply, sdo_abort_reply, warm_up
from akdctl.sim.face import Face, FaceOption, request_failed
from akdctl.sim.memo import remember

DEFAULT_ADDR = "127.0.0.1:34980"
DEFAULT_STATION = 1001
#: Datagrams whose mailbox the gateway keeps at once (:meth:`GatewayHandler._learn`); more start the memo over.
MAILBOXES_KEPT = 1024
#: What one receive takes: more than the largest gateway frame (``mailbox.MAX_GATEWAY_DATAGRAM``, 2049 bytes), so
#: none is cut short.
RECEIVE_SIZE = 4096


OPTIONS = (
    FaceOption("--ethercat-udp", "ethercat_udp", flag_value=DEFAULT_ADDR, metavar="[HOST:PORT]",
               help=f"Serve an ETG.8200 EtherCAT mailbox gateway on UDP (default {DEFAULT_ADDR})."),
    FaceOption("--ecat-stations", "ecat_stations", metavar="ADDR=NAME,...",
               help="Gateway station addresses -> simulated drives, e.g. 1001=default,1002=axis2 "
                    f"(default: {DEFAULT_STATION}=the served drive)."),
    FaceOption("--ecat-inject", "ecat_inject", metavar="drop=N,mbxerr=N,abort=N",
               help="Gateway fault injection: lose every N-th reply, answer with a mailbox error or an SDO abort."),
)


def parse_stations(text: str | None, drive: SimDrive) -> dict[int, SimDrive]:
    """``1001=default,1002=axis2`` -> {1001: SimDrive('default'), 1002: SimDrive('axis2')}."""
    if not text:
        return {DEFAULT_STATION: drive}
    stations: dict[int, SimDrive] = {}
    for part in text.split(","):
        addr_text, sep, name = part.strip().partition("=")
        try:
            addr = int(addr_text, 0)
        except ValueError:
            addr = -1
        if not sep or not 1 <= addr <= 0xFFFF or not name.replace("-", "").replace("_", "").isalnum():
            raise UsageError(f"--ecat-stations: {part!r} is not STATION=NAME (station 1..65535, e.g. 1001=default)")
        stations[addr] = drive if name == drive.name else _face_drive(SimDrive(name, drive.directory), drive)
    return stations


def parse_addr(text: str, default_port: int) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, str(default_port)
    try:
        return host or "127.0.0.1", int(port)
    except ValueError:
        raise UsageError(f"bad address {text!r}: expected HOST:PORT") from None


class GatewayHandler:
    """The pure part of the gateway: one datagram in, the datagrams to send back out.

    Kept apart from the socket so tests and benchmarks can drive it directly.
    """

    def __init__(self, stations: dict[int, SimDrive], injector: Injector | None = None) -> None:
        from akdctl.protocol import mailbox
        from akdctl.protocol.errors import CodecError
        from akdctl.sim.mailbox_repeat import MailboxRepeats, counted

        self.stations = stations  # fixed for the handler's life: each drive's handle_mailbox is bound once, here
        self._answers = {address: drive.handle_mailbox for address, drive in stations.items()}
        self.injector = injector or Injector()
        self.repeats = MailboxRepeats()  # a duplicated request datagram is not executed twice (issue 23.14)
        # looked up once here, not imported per datagram
        self._unwrap, self._gateway_header, self._header_size = \
            mailbox.unwrap_gateway, mailbox.gateway_header, mailbox.HEADER_SIZE
        self._headers: dict[int, bytes] = {}  # reply size -> its gateway header (at most 0x7FF sizes)
        self._codec_error = CodecError
        self._counted = counted
        #: datagram -> (its mailbox, station, whether the mailbox has a counter, the station's two bytes, the last
        #: reply framed for it and its frame) (_learn)
        self._mailboxes: dict[bytes, tuple[bytes, int, bool, int, int, list[Any]]] = {}

    def handle(self, datagram: bytes, peer: object = None) -> list[bytes]:
        """The datagrams that answer ``datagram`` (:meth:`serve`'s answer to it alone; a failure raises)."""
        out: list[bytes] = []
        self.serve(datagram, peer, None, lambda frame, _peer: out.append(frame))
        return out

    def serve(self, datagram: bytes, peer: Any, receive: Callable[[int], tuple[bytes, Any]] | None,
              send: Callable[[bytes, Any], object], stopped: Callable[[], bool] = bool) -> None:
        """Answer ``datagram`` from ``peer`` with ``send(frame, peer)``; with ``receive`` (a socket's recvfrom), go
        on with the datagrams it returns until it fails, is woken (no peer) or ``stopped()`` is true.

        The datagram's mailbox goes to its station's drive as it came (``unwrap_gateway`` checked it, once per
        distinct datagram: :meth:`_learn`); each mailbox the drive answers goes back behind the 2-byte header of
        its size (``mailbox.gateway_header``, kept per size) with the station's address in it (the drive's own
        emergencies carry address 0). A send that fails (OSError) is lost, as on a network.

        Why one frame for the datagrams that follow: a Python call per datagram and the gateway's attributes
        looked up again for each were a share of what a served upload cost (issue 29); :meth:`handle` answers
        through this same code."""
        CodecError = self._codec_error  # noqa: N806 - the class, looked up once
        mailboxes, answers, injector = self._mailboxes, self._answers, self.injector
        answer, answer_counted = self.repeats.answer, self.repeats.answer_counted
        headers, header_size = self._headers, self._header_size
        data: bytes | None = datagram
        while True:
            if data is None:
                if receive is None or stopped():
                    return
                try:
                    data, peer = receive(RECEIVE_SIZE)
                except OSError:
                    return
                if peer is None:
                    return  # woken by the face's interrupt(): its loop decides
            datagram = data
            data = None
            try:
                try:
                    mailbox = mailboxes.get(datagram)
                except (TypeError, ValueError):  # not hashable (a bytearray, a writable view): not kept
                    mailbox = None
                if mailbox is None:
                    try:
                        mailbox = self._learn(datagram)
                    except CodecError:
                        continue  # a gateway drops what it cannot parse
                raw, address, has_counter, low, high, framed = mailbox
                handle = answers.get(address)  # the station's drive.handle_mailbox
                if handle is None:
                    continue
                replies: list[bytes] | None = None
                if injector.every:
                    fault = injector.decide()
                    if fault == "drop":
                        continue
                    if fault == "mbxerr":
                        replies = [mailbox_error_reply(raw)]
                    elif fault == "abort" and (abort := sdo_abort_reply(raw)) is not None:
                        replies = [abort]
                if replies is None:
                    try:
                        replies = (answer_counted if has_counter else answer)((peer, address), raw, handle)
                    except CodecError:
                        replies = [mailbox_error_reply(raw, 1)]  # syntax of the mailbox protocol header wrong
                    except Exception as exc:  # noqa: BLE001 - the drive failed: the master gets an abort, not silence
                        request_failed("ethercat-udp", exc)
                        replies = failure_reply(raw)
                for reply in replies:
                    if reply is framed[0]:  # the very bytes framed last for this datagram (kept alive here)
                        frame = framed[1]
                    else:
                        size = len(reply)
                        if size < header_size:
                            continue
                        body = reply
                        if reply[2] != low or reply[3] != high:  # not the station's address (an emergency's is 0)
                            body = reply[:2] + raw[2:4] + reply[4:]
                        try:
                            header = headers[size]
                        except KeyError:
                            try:
                                header = headers[size] = self._gateway_header(size)
                            except CodecError:
                                continue
                        frame = header + body
                        framed[0], framed[1] = reply, frame
                    try:
                        send(frame, peer)
                    except OSError:
                        pass
            except Exception as exc:  # noqa: BLE001 - one bad request must not end the face (a gateway drops it)
                if receive is None:
                    raise
                request_failed("ethercat-udp", exc)

    def _learn(self, datagram: bytes) -> tuple[bytes, int, bool, int, int, list[Any]]:
        """The mailbox in ``datagram``, its station address, whether it carries a counter (``mailbox_repeat.counted``:
        only then can it be a repeat) and the address's two bytes, kept in :attr:`_mailboxes` by the datagram's bytes;
        and ``[reply, frame]``, the last reply :meth:`serve` framed for it with its frame.

        Why: a master polls with the same few datagrams (its counter runs 1..7), and checking and cutting the
        gateway header (``mailbox.unwrap_gateway``) again for each was a share of a served upload (issue 29). What
        is kept is read from the datagram's bytes alone, so the key covers it; a datagram the codec refuses raises
        its error and is not kept. Bounded by :data:`MAILBOXES_KEPT`: many distinct datagrams start it over.

        Why the last frame: the drive answers a poll of an unchanged value with the same reply object (the SDO
        server keeps its answer, ``SdoServer.handle``), and the frame depends on the reply's bytes and this
        datagram's station alone; bytes do not change, and the one kept here is not freed, so the same object is the
        same bytes. Any other reply is framed anew."""
        raw = self._unwrap(datagram)
        mailbox = (raw, raw[2] | raw[3] << 8, self._counted(raw), raw[2], raw[3], [None, None])
        if datagram.__class__ is bytes:
            remember(self._mailboxes, datagram, mailbox, MAILBOXES_KEPT)
        return mailbox


class EthercatUdpFace(Face):
    """A UDP socket served by one thread; ``stop`` closes it and joins."""

    def __init__(self, host: str, port: int, handler: GatewayHandler) -> None:
        super().__init__()
        self.host, self.port = host, port
        self.handler = handler
        self._sock: socket.socket | None = None

    def open(self) -> None:
        for drive in set(self.handler.stations.values()):
            warm_up(drive)
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.bind((self.host, self.port))
        except OSError as exc:
            sock.close()
            raise UsageError(f"--ethercat-udp: cannot listen on {self.host}:{self.port}: {exc.strerror}") from None
        self.host, self.port = sock.getsockname()[:2]  # the ready line names what was bound (port 0 -> real)
        self._sock = sock
        self.spawn(self._serve, "ecat-udp-face")

    def _serve(self) -> None:
        """One blocking receive and one send per request: a socket timeout would add a poll() before each of
        them; :meth:`interrupt` wakes the receive instead (shutdown)."""
        sock = self._sock
        assert sock is not None
        serve, stopped, receive, send = self.handler.serve, self._stop.is_set, sock.recvfrom, sock.sendto
        while not stopped():
            try:
                data, peer = receive(RECEIVE_SIZE)
            except OSError:
                break
            if peer is None:
                continue  # woken by interrupt(): the loop condition decides
            serve(data, peer, receive, send, stopped)  # answers this one and those that follow

    def interrupt(self) -> None:
        """Wake the blocking receive: a shut-down socket returns from it at once (Linux, also unconnected UDP)."""
        if self._sock is not None:
            with contextlib.suppress(OSError):
                self._sock.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def describe(self) -> str:
        stations = ",".join(f"{a}={d.name}" for a, d in sorted(self.handler.stations.items()))
        inject = self.handler.injector.describe()
        extra = f" inject {inject}" if inject != "none" else ""
        return f"ethercat-udp udp {self.host}:{self.port} stations {stations}{extra}"


def from_options(drive: SimDrive, **kwargs: object) -> EthercatUdpFace | None:
    addr = kwargs.get("ethercat_udp")
    if not addr:
        return None
    host, port = parse_addr(str(addr), 34980)
    stations = parse_stations(kwargs.get("ecat_stations") or None, drive)  # type: ignore[arg-type]
    injector = Injector.parse(kwargs.get("ecat_inject") or None, "--ecat-inject")  # type: ignore[arg-type]
    return EthercatUdpFace(host, port, GatewayHandler(stations, injector))


def _face_drive(new: "SimDrive", like: "SimDrive") -> "SimDrive":
    """A further station's drive waits for its state lock as long as the served one (sim serve's face timeout) and
    keeps it between requests as the served one does."""
    new.lock_timeout = like.lock_timeout
    if like.keeps_lock:
        new.serve_faces()
    return new
