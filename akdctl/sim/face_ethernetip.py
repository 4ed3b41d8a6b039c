"""The simulator's EtherNet/IP face: encapsulation on TCP (and ListIdentity on UDP) 44818, class-1 I/O on UDP.

Sessions: RegisterSession hands out a handle; SendRRData carries UCMM requests (Null address item
plus unconnected data item, no route path) to the CIP objects of :mod:`akdctl.sim.cip_device`, and
Connection Manager requests (Forward_Open / Large_Forward_Open / Forward_Close) open and close
the one class-1 I/O connection (exclusive owner: a second originator gets "ownership conflict").
I/O runs on one UDP socket: consumed command assemblies go through the seed's Load/Start ->
Load Complete handshake, the response assembly is produced every T->O RPI, and a connection that
stops consuming for its timeout (RPI x multiplier) is closed, which drops Enable (the axis is
disabled) as on the drive.

Why the face answers rather than crashes: every per-request error becomes the status the protocol
has for it (an encapsulation status, a CIP general status); only a header that cannot be framed
(its length cannot be trusted) ends the TCP connection. Fault injection (``--eip-inject``) drops,
delays or answers requests with an error status, or closes the connection mid-request.
"""

from __future__ import annotations

import os
import select
import socket
import struct
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from akdctl.errors import UsageError
from akdctl.protocol import akd_assembly as asm
from akdctl.protocol import cip, enip
from akdctl.protocol.errors import CodecError
from akdctl.sim.cip_device import CipDevice, IdentitySettings
from akdctl.sim.face import Face, FaceOption, request_failed
from akdctl.sim.inject_spec import extra_number, parse_every_nth

DEFAULT_ADDRESS = "127.0.0.1:44818"
MIN_RPI_US = 10000                      # "10ms or greater" [M-11]
IDLE_TIMEOUT_S = 120.0                  # a silent TCP client is dropped after this (encapsulation inactivity)


@dataclass(frozen=True)
class Injection:
    """Every ``drop``-th request gets no answer, every ``delay``-th is answered ``delay_s`` late, every
    ``close``-th closes the TCP connection instead of answering, every ``status``-th explicit request is
    answered with CIP general status ``status_code``."""

    drop: int = 0
    delay: int = 0
    delay_s: float = 0.0
    close: int = 0
    status: int = 0
    status_code: int = cip.DEVICE_STATE_CONFLICT

    @classmethod
    def parse(cls, text: str | None) -> "Injection":
        option = "--eip-inject"
        found = parse_every_nth(text, option, {"drop": "", "delay": "SECONDS", "close": "", "status": "CODE"})
        every = {kind: n for kind, (n, _) in found.items()}
        return cls(**every, delay_s=extra_number(found, "delay", 0.5, option),
                   status_code=int(extra_number(found, "status", cip.DEVICE_STATE_CONFLICT, option, integer=True,
                                                low=1, high=0xFF)))

    def hits(self, every: int, count: int) -> bool:
        return every > 0 and count % every == 0


OPTIONS = (
    FaceOption("--ethernetip", "ethernetip", flag_value=DEFAULT_ADDRESS, metavar="[ADDR]",
               help=f"Serve the drive over EtherNet/IP (encapsulation on TCP, ListIdentity on UDP), "
                    f"default {DEFAULT_ADDRESS}."),
    FaceOption("--eip-io-port", "eip_io_port", type=int, range=(0, 65535), default=enip.IO_PORT, show_default=True,
               help="UDP port for class-1 I/O (0: any free port)."),
    FaceOption("--eip-inject", "eip_inject", metavar="SPEC",
               help="Fault injection: drop=N,delay=N:SECONDS,close=N,status=N:CODE acts on every Nth request."),
    FaceOption("--eip-identity", "eip_identity", metavar="SPEC",
               help="Identity: vendor=N,device_type=N,product_code=N,revision=M.m,serial=N,name=TEXT."),
    FaceOption("--eip-refuse-session", "eip_refuse_session", is_flag=True,
               help="Refuse every RegisterSession (as a target out of sessions)."),
)


def from_options(drive: Any, **kwargs: Any) -> "EthernetIpFace | None":
    address = kwargs.get("ethernetip")
    if address is None:
        return None
    from akdctl.sim.face_profinet import parse_address

    host, port = parse_address(address, enip.TCP_PORT, "--ethernetip")
    return EthernetIpFace(drive, host, port, io_port=int(kwargs.get("eip_io_port", enip.IO_PORT)),
                          injection=Injection.parse(kwargs.get("eip_inject")),
                          identity=IdentitySettings.parse(kwargs.get("eip_identity")),
                          refuse_session=bool(kwargs.get("eip_refuse_session")))


@dataclass
class IoConnection:
    ot_id: int
    to_id: int
    triad: cip.ConnectionTriad
    peer: tuple[str, int]
    to_rpi_s: float
    timeout_s: float
    last_consumed: float
    next_produce: float = 0.0
    sequence: int = 0
    produced: int = 0
    consumed: int = 0
    idle: int = 0                      # consumed packets with the Run bit clear (not applied)
    last_command: bytes = bytes(asm.ASSEMBLY_SIZE)


@dataclass
class FaceStats:
    sessions: int = 0
    requests: int = 0
    dropped: int = 0
    delayed: int = 0
    closed: int = 0
    io_opened: int = 0
    io_closed: int = 0
    io_timeouts: int = 0
    log: list[str] = field(default_factory=list)


class EthernetIpFace(Face):
    """TCP 44818 + UDP 44818 (ListIdentity) + UDP I/O, each served by threads of this object."""

    def __init__(self, drive: Any, host: str = "127.0.0.1", port: int = enip.TCP_PORT, *, io_port: int = enip.IO_PORT,
                 injection: Injection | None = None, identity: IdentitySettings | None = None,
                 refuse_session: bool = False) -> None:
        self.host, self.port, self.io_port = host, port, io_port
        self.injection = injection or Injection()
        self.refuse_session = refuse_session
        self.device = CipDevice(drive, identity, (host, port))
        self.stats = FaceStats()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._clients: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._sessions: set[int] = set()
        self._counter = 0
        self.io: IoConnection | None = None
        self.tcp: socket.socket | None = None
        self.udp: socket.socket | None = None
        self.io_sock: socket.socket | None = None

    # ------------------------------------------------------------- lifecycle
    def start(self) -> None:
        try:
            self.tcp = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self.tcp.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self.tcp.bind((self.host, self.port))
            self.tcp.listen(8)
            self.port = self.tcp.getsockname()[1]
            self.device.address = (self.host, self.port)
            self.udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.udp.bind((self.host, self.port))
            self.io_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.io_sock.bind((self.host, self.io_port))
            self.io_port = self.io_sock.getsockname()[1]
        except OSError as exc:
            self.stop()
            raise UsageError(f"--ethernetip {self.host}:{self.port}: cannot listen ({exc.strerror})") from None
        for name, target in (("eip-accept", self._accept_loop), ("eip-udp", self._udp_loop),
                             ("eip-io", self._io_loop)):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self) -> None:
        self._stop.set()
        if self.io is not None:
            self._close_io("face stopped")
        for sock in (self.tcp, self.udp, self.io_sock):
            if sock is not None:
                try:
                    sock.close()
                except OSError:
                    pass
        with self._lock:
            clients = list(self._clients)
        for client in clients:
            try:
                client.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
        for thread in self._threads:
            thread.join(timeout=2)

    def describe(self) -> str:
        return f"ethernetip {self.host}:{self.port} (class-1 I/O on udp {self.host}:{self.io_port})"

    # ------------------------------------------------------------- TCP
    def _accept_loop(self) -> None:
        assert self.tcp is not None
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self.tcp], [], [], 0.2)
                if not ready:
                    continue
                client, peer = self.tcp.accept()
            except OSError:
                return
            with self._lock:
                self._clients.add(client)
            thread = threading.Thread(target=self._serve_client, args=(client, peer), name="eip-client", daemon=True)
            thread.start()
            self._threads = [t for t in self._threads if t.is_alive()] + [thread]

    def _serve_client(self, client: socket.socket, peer: tuple[str, int]) -> None:
        sessions: set[int] = set()
        try:
            client.settimeout(IDLE_TIMEOUT_S)
            while not self._stop.is_set():
                head = _recv_exact(client, enip.HEADER_SIZE)
                if head is None:
                    return
                header = enip.decode_header(head)
                body = _recv_exact(client, header.length) if header.length else b""
                if body is None:
                    return
                try:
                    reply = self._handle_tcp(header, body, sessions, peer)
                except Exception as exc:  # noqa: BLE001 - answered with an encapsulation error, the session goes on
                    request_failed("ethernetip", exc)
                    reply = enip.Packet(header.command, b"", header.session, enip.STATUS_NO_MEMORY,
                                        header.context).encode()
                if reply is _CLOSE:
                    return
                if reply is not None:
                    client.sendall(reply)  # type: ignore[arg-type]
        except (OSError, CodecError):
            return
        finally:
            with self._lock:
                self._clients.discard(client)
                self._sessions -= sessions
            try:
                client.close()
            except OSError:
                pass

    def _handle_tcp(self, header: enip.Header, body: bytes, sessions: set[int],
                    peer: tuple[str, int]) -> bytes | object | None:
        with self._lock:            # one count across client threads: injection hits every Nth request
            self.stats.requests += 1
            self._counter += 1
            count = self._counter
        inj = self.injection
        if inj.hits(inj.close, count):
            self.stats.closed += 1
            return _CLOSE
        if inj.hits(inj.drop, count):
            self.stats.dropped += 1
            return None
        if inj.hits(inj.delay, count):
            self.stats.delayed += 1
            time.sleep(inj.delay_s)

        def reply(data: bytes = b"", status: int = enip.STATUS_SUCCESS, session: int = header.session) -> bytes:
            return enip.Packet(header.command, data if status == 0 else b"", session, status, header.context).encode()

        command = header.command
        if command == enip.NOP:
            return None
        if command == enip.LIST_IDENTITY:
            return reply(self._list_identity())
        if command == enip.LIST_SERVICES:
            return reply(enip.encode_cpf([enip.Item(enip.ITEM_LIST_SERVICES,
                                                    struct.pack("<HH", 1, 0x0120) + b"Communications\0\0")]))
        if command == enip.REGISTER_SESSION:
            try:
                version, _ = enip.decode_register_session(body)
            except CodecError:
                return reply(status=enip.STATUS_INCORRECT_DATA, session=0)
            if version != enip.PROTOCOL_VERSION:
                return enip.Packet(command, enip.register_session_data(), 0, enip.STATUS_UNSUPPORTED_PROTOCOL,
                                   header.context).encode()
            if self.refuse_session or sessions:
                return reply(status=enip.STATUS_INVALID_COMMAND if sessions else enip.STATUS_NO_MEMORY, session=0)
            handle = int.from_bytes(os.urandom(4), "little") | 1
            sessions.add(handle)
            with self._lock:
                self._sessions.add(handle)
            self.stats.sessions += 1
            return enip.Packet(command, enip.register_session_data(), handle, 0, header.context).encode()
        if command == enip.UNREGISTER_SESSION:
            return _CLOSE
        if command not in (enip.SEND_RR_DATA, enip.SEND_UNIT_DATA):
            return reply(status=enip.STATUS_INVALID_COMMAND)
        if header.session not in sessions:
            return reply(status=enip.STATUS_INVALID_SESSION)
        if command == enip.SEND_UNIT_DATA:
            return reply(status=enip.STATUS_INVALID_COMMAND)    # no class-3 connections (not in the AKD manual)
        try:
            rr = enip.RRData.decode(body)
            message = enip.unconnected_message(rr)
        except CodecError:
            return reply(status=enip.STATUS_INCORRECT_DATA)
        if inj.hits(inj.status, count):
            answer = cip.Response(message[0] & 0x7F if message else 0, inj.status_code).encode()
        else:
            answer = self._message(message, rr, peer)
        return reply(enip.unconnected(answer).encode())

    def _list_identity(self) -> bytes:
        attrs = self.device.identity_attributes()
        ident = enip.Identity(attrs.vendor, attrs.device_type, attrs.product_code, attrs.revision, attrs.status,
                              attrs.serial, attrs.product_name, 0x03,
                              enip.SockAddr(self.host if self.host != "0.0.0.0" else "0.0.0.0", self.port))
        return enip.list_identity_reply(ident)

    def _message(self, message: bytes, rr: enip.RRData, peer: tuple[str, int]) -> bytes:
        try:
            req = cip.Request.decode(message)
            path = cip.decode_path(req.path)
        except CodecError:
            return self.device.handle(message)
        if path.class_id != cip.CONNECTION_MANAGER:
            return self.device.handle(message)
        try:
            if req.service in (cip.FORWARD_OPEN, cip.LARGE_FORWARD_OPEN):
                return self._forward_open(req, rr, peer)
            if req.service == cip.FORWARD_CLOSE:
                return self._forward_close(req)
        except CodecError:
            return cip.Response(req.service, cip.NOT_ENOUGH_DATA).encode()
        return cip.Response(req.service, cip.SERVICE_NOT_SUPPORTED).encode()

    # ------------------------------------------------------------- Connection Manager
    def _forward_open(self, req: cip.Request, rr: enip.RRData, peer: tuple[str, int]) -> bytes:
        large = req.service == cip.LARGE_FORWARD_OPEN
        fo = cip.ForwardOpen.decode(req.data, large=large)
        failure = cip.ConnectionFailure(fo.serial, fo.vendor, fo.originator_serial)

        def fail(ext: int) -> bytes:
            return cip.Response(req.service, cip.CONNECTION_FAILURE, (ext,), failure.encode()).encode()

        try:
            path = cip.decode_path(fo.path)
        except CodecError:
            return fail(cip.EXT_INVALID_CONSUMING_PATH)
        key = path.key
        ident = self.device.identity
        if key is not None:
            if (key.vendor and key.vendor != ident.vendor) or (key.product_code and key.product_code != ident.product_code):
                return fail(0x0114)
            if key.device_type and key.device_type != ident.device_type:
                return fail(0x0115)
            if key.major & 0x7F and (key.major & 0x7F, key.minor) != tuple(ident.revision):
                return fail(0x0116)
        if fo.transport & 0x0F != 1:
            return fail(0x0103)                          # only class 1 (no class-3 in the AKD manual)
        if path.class_id != cip.ASSEMBLY or path.instance != asm.CONFIG_INSTANCE:
            return fail(cip.EXT_INVALID_CONFIGURATION_PATH)
        if path.points != (asm.OUTPUT_INSTANCE, asm.INPUT_INSTANCE):
            return fail(cip.EXT_INVALID_CONSUMING_PATH if not path.points or path.points[0] != asm.OUTPUT_INSTANCE
                        else cip.EXT_INVALID_PRODUCING_PATH)
        if fo.ot_params.size != asm.ASSEMBLY_SIZE + 6:
            return fail(cip.EXT_INVALID_OT_SIZE)
        if fo.to_params.size != asm.ASSEMBLY_SIZE + 2:
            return fail(cip.EXT_INVALID_TO_SIZE)
        if fo.ot_rpi_us < MIN_RPI_US or fo.to_rpi_us < MIN_RPI_US:
            return fail(cip.EXT_RPI_NOT_SUPPORTED)
        triad = cip.ConnectionTriad(fo.serial, fo.vendor, fo.originator_serial)
        with self._lock:
            if self.io is not None:
                return fail(cip.EXT_CONNECTION_IN_USE if self.io.triad == triad else cip.EXT_OWNERSHIP_CONFLICT)
            sockaddr = rr.item(enip.ITEM_SOCKADDR_T2O)
            port = enip.SockAddr.decode(sockaddr.data).port if sockaddr is not None else enip.IO_PORT
            ot_id = int.from_bytes(os.urandom(4), "little") | 1
            now = time.monotonic()
            timeout = fo.ot_rpi_us / 1e6 * (4 << min(fo.timeout_multiplier, 7))
            self.io = IoConnection(ot_id, fo.to_connection_id, triad, (peer[0], port), fo.to_rpi_us / 1e6,
                                   timeout, now, now)
            self.stats.io_opened += 1
        reply = cip.ForwardOpenReply(ot_id, fo.to_connection_id, fo.serial, fo.vendor, fo.originator_serial,
                                     fo.ot_rpi_us, fo.to_rpi_us)
        return cip.Response(req.service, cip.SUCCESS, (), reply.encode()).encode()

    def _forward_close(self, req: cip.Request) -> bytes:
        fc = cip.ForwardClose.decode(req.data)
        with self._lock:
            io = self.io
            if io is None or io.triad != fc.triad:
                failure = cip.ConnectionFailure(fc.serial, fc.vendor, fc.originator_serial)
                return cip.Response(req.service, cip.CONNECTION_FAILURE, (cip.EXT_CONNECTION_NOT_FOUND,),
                                    failure.encode()).encode()
        self._close_io("Forward_Close")
        return cip.Response(req.service, cip.SUCCESS, (),
                            cip.ForwardCloseReply(fc.serial, fc.vendor, fc.originator_serial).encode()).encode()

    def _close_io(self, why: str) -> None:
        with self._lock:
            io, self.io = self.io, None
        if io is not None:
            self.stats.io_closed += 1
            self.stats.log.append(f"I/O connection closed: {why}")
            self.device.io_closed()

    # ------------------------------------------------------------- UDP
    def _udp_loop(self) -> None:
        assert self.udp is not None
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([self.udp], [], [], 0.2)
                if not ready:
                    continue
                data, peer = self.udp.recvfrom(2048)
            except OSError:
                return
            try:
                packet = enip.decode_packet(data)
            except CodecError:
                continue
            if packet.command == enip.LIST_IDENTITY:
                try:
                    answer = enip.Packet(enip.LIST_IDENTITY, self._list_identity(), 0, 0, packet.context).encode()
                    self.udp.sendto(answer, peer)
                except OSError:
                    pass
                except Exception as exc:  # noqa: BLE001 - no answer this time; the face goes on
                    request_failed("ethernetip", exc)

    def _io_loop(self) -> None:
        assert self.io_sock is not None
        while not self._stop.is_set():
            io = self.io
            now = time.monotonic()
            wait = 0.05 if io is None else max(0.0, min(0.05, io.next_produce - now))
            try:
                ready, _, _ = select.select([self.io_sock], [], [], wait)
            except (OSError, ValueError):
                return
            if ready:
                try:
                    data, peer = self.io_sock.recvfrom(2048)
                except OSError:
                    return
                self._consume(data)
            io = self.io
            if io is None:
                continue
            now = time.monotonic()
            if now - io.last_consumed > io.timeout_s:
                self.stats.io_timeouts += 1
                self._close_io("consumer timeout")
                continue
            if now >= io.next_produce:
                try:
                    self._produce(io)
                except Exception as exc:  # noqa: BLE001 - this production is lost (the originator sees a gap)
                    request_failed("ethernetip", exc)
                io.next_produce = max(io.next_produce + io.to_rpi_s, now)

    def _consume(self, data: bytes) -> None:
        io = self.io
        try:
            packet = enip.IoPacket.decode(data)
            if io is None or packet.connection_id != io.ot_id:
                return
            run, command = enip.split_run_idle(packet.data)
        except CodecError:
            return
        io.last_consumed = time.monotonic()   # Idle data keeps the connection alive (it is a valid packet)
        io.consumed += 1
        if not run:
            # CIP's 32-bit run/idle header: data sent with the Run bit clear (Idle) is not applied. The AKD documents no idle behaviour
            # of its own [I]; the simulated drive takes it as the data-less command (Enable = 0), what a closed
            # connection leaves, so a PLC in program mode neither enables nor keeps moving the axis.
            io.last_command = bytes(asm.ASSEMBLY_SIZE)
            io.idle += 1
        elif len(command) == asm.ASSEMBLY_SIZE:
            io.last_command = command

    def _produce(self, io: IoConnection) -> None:
        response = self.device.io_cycle(io.last_command)
        io.sequence = (io.sequence + 1) & 0xFFFFFFFF
        packet = enip.IoPacket(io.to_id, io.sequence, io.sequence & 0xFFFF, response).encode()
        try:
            assert self.io_sock is not None
            self.io_sock.sendto(packet, io.peer)
            io.produced += 1
        except OSError:
            pass


_CLOSE = object()


def _recv_exact(sock: socket.socket, size: int) -> bytes | None:
    data = bytearray()
    while len(data) < size:
        chunk = sock.recv(size - len(data))
        if not chunk:
            return None
        data += chunk
    return bytes(data)
