"""A class-1 I/O connection to an AKD: akdctl as the originator (what a PLC scanner normally is).

Forward_Open (over the explicit session) to the configuration / output / input assemblies
100 / 101 / 102 [101 is inferred, reference/ethernetip.md 1.4], point-to-point both ways, cyclic,
RPI >= 10 ms [M-11]; then one UDP socket produces the command assembly (sequence count + 32-bit
run/idle header + 64 bytes) every O->T RPI from a thread and consumes the response assembly (sequence
count + 64 bytes). ``close`` stops producing and sends Forward_Close; the drive then sees the
Enable bit go away and disables the axis (DRV.DISSOURCES bit 6).

Every wait is bounded; a Forward_Open refused with "ownership conflict" means another scanner owns
the drive, and akdctl refuses to fight it.
"""

from __future__ import annotations

import os
import socket
import threading
import time
from dataclasses import dataclass

from akdctl.errors import CipRefused, CommError, MalformedReply, NoAnswer, SafetyRefusal, UsageError
from akdctl.protocol import akd_assembly as asm
from akdctl.protocol import cip, enip
from akdctl.protocol.errors import CodecError

MIN_RPI_MS = 10.0
ORIGINATOR_VENDOR = 0xFFFF          # "unassigned": akdctl has no ODVA vendor ID
OT_SIZE = asm.ASSEMBLY_SIZE + 6     # sequence count + run/idle header
TO_SIZE = asm.ASSEMBLY_SIZE + 2     # sequence count


@dataclass
class IoStats:
    produced: int = 0
    consumed: int = 0
    stale: int = 0


def _route_source(host: str, port: int) -> str:
    """The local IPv4 address the kernel would send from to ``host`` (a connect of a UDP socket sends nothing)."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.connect((host, port))
        return str(probe.getsockname()[0])
    finally:
        probe.close()


class IoConnection:
    """One exclusive-owner class-1 connection. Use as a context manager."""

    def __init__(self, session: object, host: str, rpi_ms: float = 20.0, port: int = enip.IO_PORT,
                 local_port: int = 0, timeout: float = 2.0, tracer: object = None,
                 timeout_multiplier: int = 2) -> None:
        if rpi_ms < MIN_RPI_MS:
            raise UsageError(f"RPI {rpi_ms:g} ms is below the AKD's minimum of {MIN_RPI_MS:g} ms")
        self.session = session
        self.host, self.port = host, port
        self.rpi_s = rpi_ms / 1000.0
        self.timeout = timeout
        self.tracer = tracer
        self.stats = IoStats()
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            # Bound to the address that routes to the drive (not every interface): the drive's T->O datagrams
            # come to it, and the port is not open towards any other network.
            self.sock.bind((_route_source(host, port), local_port))
            self.sock.connect((host, port))       # only the drive's datagrams; our real address for the trace
        except OSError as exc:
            self.sock.close()
            raise UsageError(f"cannot use the I/O port {local_port} towards {host}:{port} ({exc.strerror})") from None
        self.local = self.sock.getsockname()[:2]
        self.local_port = self.local[1]
        self.serial = int.from_bytes(os.urandom(2), "little")
        self.originator_serial = int.from_bytes(os.urandom(4), "little")
        self.to_id = int.from_bytes(os.urandom(4), "little") | 1
        self.ot_id = 0
        self.output = asm.Command().encode()
        # The Run bit of the run/idle header is set only while a command is meant (set_output): until then, and
        # after idle(), the drive gets Idle data, which CIP says it must not apply.
        self.run = False
        self.timeout_multiplier = timeout_multiplier   # CIP code n: the target times out after RPI x 4 << n
        self._input: tuple[int, bytes] | None = None     # (sequence, data) of the newest response
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._open = False

    # ---------------------------------------------------------------- open / close
    def _path(self) -> bytes:
        return cip.Path(cip.ASSEMBLY, asm.CONFIG_INSTANCE, None, (asm.OUTPUT_INSTANCE, asm.INPUT_INSTANCE)).encode()

    def open(self) -> None:
        from akdctl.catalog.texts import cip_status_text

        rpi_us = round(self.rpi_s * 1e6)
        fo = cip.ForwardOpen(0, self.to_id, self.serial, ORIGINATOR_VENDOR, self.originator_serial, rpi_us,
                             cip.NetParams(OT_SIZE, cip.TYPE_P2P), rpi_us, cip.NetParams(TO_SIZE, cip.TYPE_P2P),
                             self._path(), cip.TRANSPORT_CLASS1_CYCLIC,
                             timeout_multiplier=self.timeout_multiplier)
        request = cip.Request(cip.FORWARD_OPEN, cip.Path(cip.CONNECTION_MANAGER, 1).encode(), fo.encode())
        sockaddr = enip.Item(enip.ITEM_SOCKADDR_T2O, enip.SockAddr("0.0.0.0", self.local_port).encode())
        response = self.session.request(request, extra_items=(sockaddr,))  # type: ignore[attr-defined]
        if not response.ok:
            ext = response.extended[0] if response.extended else None
            if response.status == cip.CONNECTION_FAILURE and ext == cip.EXT_OWNERSHIP_CONFLICT:
                raise SafetyRefusal("refusing: another scanner (a PLC) owns the drive's I/O connection "
                                    "(Forward_Open: ownership conflict); akdctl will not take it over")
            raise CipRefused(f"Forward_Open to assemblies 100/101/102 refused: "
                             f"{cip_status_text(response.status, response.extended)}", code=response.status)
        try:
            reply = cip.ForwardOpenReply.decode(response.data)
        except CodecError as exc:
            raise MalformedReply(f"malformed Forward_Open reply: {exc}") from None
        if reply.to_connection_id != self.to_id or reply.serial != self.serial:
            raise MalformedReply("Forward_Open reply names another connection")
        self.ot_id = reply.ot_connection_id
        self.rpi_s = max(self.rpi_s, reply.ot_api_us / 1e6)
        self._open = True
        self._thread = threading.Thread(target=self._run, name="eip-io", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop producing and Forward_Close (bounded); safe to call twice."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
        self._thread = None
        if self._open:
            self._open = False
            fc = cip.ForwardClose(self.serial, ORIGINATOR_VENDOR, self.originator_serial, self._path())
            try:
                self.session.request(cip.Request(cip.FORWARD_CLOSE,  # type: ignore[attr-defined]
                                                 cip.Path(cip.CONNECTION_MANAGER, 1).encode(), fc.encode()))
            except CommError:
                pass   # the target's connection timeout ends it anyway
        self.sock.close()

    def __enter__(self) -> "IoConnection":
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---------------------------------------------------------------- cyclic exchange
    def _trace(self, direction: str, data: bytes, note: str) -> None:
        if self.tracer is None:
            return
        remote = (self.host, self.port)
        src, dst = (self.local, remote) if direction == "tx" else (remote, self.local)
        self.tracer.frame(direction, "cip-io", data, note=note,  # type: ignore[attr-defined]
                          meta={"proto": "udp", "src": src, "dst": dst})

    def _run(self) -> None:
        sequence = 0
        next_send = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_send:
                sequence = (sequence + 1) & 0xFFFFFFFF
                with self._lock:
                    data = enip.with_run_idle(self.output, run=self.run)
                packet = enip.IoPacket(self.ot_id, sequence, sequence & 0xFFFF, data).encode()
                self._trace("tx", packet, f"O->T seq {sequence}")
                try:
                    self.sock.send(packet)
                    self.stats.produced += 1
                except OSError:
                    pass
                next_send = max(next_send + self.rpi_s, now)
            self.sock.settimeout(max(0.001, min(0.05, next_send - time.monotonic())))
            try:
                raw = self.sock.recv(2048)
            except (socket.timeout, BlockingIOError):
                continue
            except OSError:
                if self._stop.is_set():
                    return
                continue
            try:
                packet_in = enip.IoPacket.decode(raw)
            except CodecError:
                continue
            if packet_in.connection_id != self.to_id or len(packet_in.data) != asm.ASSEMBLY_SIZE:
                self.stats.stale += 1
                continue
            self._trace("rx", raw, f"T->O seq {packet_in.sequence}")
            with self._changed:
                self._input = (packet_in.sequence, packet_in.data)
                self.stats.consumed += 1
                self._changed.notify_all()

    def set_output(self, command: asm.Command, run: bool = True) -> None:
        with self._lock:
            self.output = command.encode()
            self.run = run

    def idle(self) -> None:
        """From now on send Idle (Run bit clear): the drive applies none of the data."""
        with self._lock:
            self.run = False

    @property
    def connection_timeout_s(self) -> float:
        """How long the drive keeps the last command after our last packet (RPI x the timeout multiplier)."""
        return self.rpi_s * (4 << self.timeout_multiplier)

    def wait_input(self, predicate, what: str, timeout: float | None = None) -> asm.Response:  # type: ignore[no-untyped-def]
        """The first response assembly *produced after this call* that satisfies ``predicate``."""
        limit = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        with self._changed:
            seen = self._input[0] if self._input is not None else None
            while True:
                current = self._input
                if current is not None and current[0] != seen:
                    seen = current[0]
                    response = asm.Response.decode(current[1])
                    if predicate(response):
                        return response
                left = deadline - time.monotonic()
                if left <= 0:
                    if current is None:
                        raise NoAnswer(f"no response assembly arrived within {limit:g} s "
                                       f"(UDP {self.host}:{self.port}, our port {self.local_port})")
                    raise NoAnswer(f"the drive did not show {what} within {limit:g} s")
                self._changed.wait(left)
