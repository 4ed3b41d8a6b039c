"""The simulator's PROFINET face: a PNIO CM responder on UDP in front of ``SimDrive.handle_bmp``.

It answers what a supervisor tool needs from a PROFINET AKD: Connect of a
Device Access AR (other AR types are refused with the status a real device
sends), Write/Read record 47 (and 0xB02E) on the configured API/slot/subslot,
Read Implicit of I&M0, Release, and the AR's activity timeout. A processing
delay makes the device answer "busy" (0xB5) the way a real parameter manager
does while it works, so clients must poll. Fault injection drops, duplicates
or delays every Nth datagram so clients' retransmission and stale-reply
handling are exercised over a real socket. Requests are recognised by activity
UUID + sequence number: a repeated request gets the kept reply again and is
never applied twice; a request older than the activity's last answered call is
discarded, as a DCE/RPC CL server does (:meth:`ProfinetFace._activity`).
"""

from __future__ import annotations

import contextlib
import heapq
import itertools
import os
import select
import socket
import time
import uuid
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

from akdctl.errors import CommError, UsageError
from akdctl.protocol import dcerpc, pnio, pnio_record
from akdctl.protocol.errors import CodecError
from akdctl.protocol.pnio import (
    BT_READ_REQ,
    BT_WRITE_REQ,
    INDEX_PROFIDRIVE,
    INDEX_PROFIDRIVE_ALT,
    OK,
    OP_READ,
    OP_READ_IMPLICIT,
    OP_WRITE,
)
from akdctl.sim.errors import RecordRefused
from akdctl.sim.face import Face, FaceOption, request_failed
from akdctl.sim.inject_spec import extra_number, parse_every_nth
from akdctl.sim.refusals import RefusalReport
from akdctl.sim.memo import remember

DEFAULT_ADDRESS = "127.0.0.1:34964"
_PARAMETER_INDICES = frozenset((INDEX_PROFIDRIVE, INDEX_PROFIDRIVE_ALT))  # the parameter channel's records
MAX_RECORD = 240
MAX_ARS = 4  # ARs the device holds at once (the AKD's number is not documented [I])
ACTIVITIES_KEPT = 512  # activities whose last reply the face keeps for retransmissions (sim/memo.remember)
_SEQUENCES, _HALF = 0xFFFFFFFF, 0x80000000  # the 32-bit sequence number space; its older half of any number
_CALLS_KEPT = 64  # shapes of plain record calls a face keeps (_learn): a client's poll repeats two
_SPLIT_BY_DREP, _DREP_BYTE = pnio_record.CALL_PARTS_BY_DREP, pnio_record.DREP_BYTE
_SHORT = pnio_record.CallTooShort
EXPIRY_TICK_S = 0.05  # timed-out ARs are looked for at most this often (with datagrams coming in)
IDLE_WAKE_S = 0.2  # the loop wakes this often without datagrams (AR timeouts, stop)
_NEVER = float("inf")


def _timeval(seconds: float) -> bytes:
    """A ``struct timeval`` for SO_RCVTIMEO (the C library's layout: two longs)."""
    import struct

    whole = int(seconds)
    return struct.pack("ll", whole, int((seconds - whole) * 1e6))


class BmpHandler(Protocol):
    def handle_bmp(self, request: bytes) -> bytes: ...


# ---------------------------------------------------------------- options

@dataclass(frozen=True)
class Injection:
    """Every ``drop``-th, ``dup``-th, ``delay``-th datagram the face sends is lost,
    sent twice, or sent ``delay_s`` late; every ``rxdrop``-th datagram received is ignored."""

    drop: int = 0
    dup: int = 0
    delay: int = 0
    delay_s: float = 0.0
    rxdrop: int = 0

    @classmethod
    def parse(cls, text: str | None) -> "Injection":
        option = "--pn-inject"
        found = parse_every_nth(text, option, {"drop": "", "dup": "", "delay": "SECONDS", "rxdrop": ""})
        every = {kind: n for kind, (n, _) in found.items()}
        return cls(**every, delay_s=extra_number(found, "delay", 0.5, option))


def parse_address(text: str, default_port: int = pnio.PNIO_PORT, option: str = "--profinet") -> tuple[str, int]:
    """HOST[:PORT] of a face option (port 0: any free port); shared by the faces that listen on IP."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = text, str(default_port)
    try:
        number = int(port)
        if not 0 <= number <= 65535:
            raise ValueError
    except ValueError:
        raise UsageError(f"{option} {text!r}: expected HOST:PORT, e.g. 127.0.0.1:{default_port}") from None
    return host.strip("[]") or "127.0.0.1", number


OPTIONS = (
    FaceOption("--profinet", "profinet", flag_value=DEFAULT_ADDRESS, metavar="[ADDR]",
               help=f"Serve the drive over PROFINET record data (PNIO RPC on UDP), default {DEFAULT_ADDRESS}."),
    FaceOption("--pn-delay", "pn_delay", type=float, default=0.0, show_default=True, metavar="SECONDS",
               help="Parameter manager processing time; reads answer 'busy' (0xB5) until it has passed."),
    FaceOption("--pn-inject", "pn_inject", metavar="SPEC",
               help="Fault injection: drop=N,dup=N,delay=N:SECONDS,rxdrop=N acts on every Nth datagram."),
    FaceOption("--pn-slot", "pn_slot", type=int, default=1, show_default=True, help="Slot of the parameter channel."),
    FaceOption("--pn-subslot", "pn_subslot", type=int, default=1, show_default=True,
               help="Subslot of the parameter channel."),
    FaceOption("--pn-api", "pn_api", type=str, default="0x3A00", show_default=True,
               help="API of the parameter channel."),
    FaceOption("--pn-fragment", "pn_fragment", type=int, default=0, metavar="BYTES",
               help="Split response bodies into DCE/RPC fragments of this many bytes (0: only when needed)."),
    FaceOption("--pn-refuse-ar", "pn_refuse_ar", is_flag=True, default=False,
               help="Refuse every AR (as a device that does not allow supervisor/device-access ARs)."),
    FaceOption("--pn-ars", "pn_ars", type=int, range=(1, 64), default=MAX_ARS, show_default=True, metavar="N",
               help="ARs the device holds at once; one more Connect is refused 'out of AR resources'."),
    FaceOption("--pn-ar-timeout", "pn_ar_timeout", type=float, metavar="SECONDS",
               help="Drop an AR after this many seconds without a request (default: the client's activity "
                    "timeout factor x 100 ms, as a device does)."),
    FaceOption("--pn-station", "pn_station", default="akd-sim", show_default=True,
               help="PROFINET station name (NameOfStation) the simulated device reports."),
    FaceOption("--dcp", "dcp_iface", metavar="IFNAME",
               help="Also answer DCP identify/set/signal on this interface (raw socket, needs root)."),
)


def from_options(drive: Any, **kwargs: Any) -> "ProfinetFace | None":
    address = kwargs.get("profinet")
    if address is None:
        return None
    host, port = parse_address(address)
    try:
        api = int(str(kwargs.get("pn_api") or "0x3A00"), 0)
    except ValueError:
        raise UsageError(f"--pn-api {kwargs.get('pn_api')!r} is not a number") from None
    return ProfinetFace(
        drive, host, port,
        delay=float(kwargs.get("pn_delay") or 0.0),
        injection=Injection.parse(kwargs.get("pn_inject")),
        slot=int(kwargs.get("pn_slot", 1)), subslot=int(kwargs.get("pn_subslot", 1)), api=api,
        fragment=int(kwargs.get("pn_fragment") or 0), refuse_ar=bool(kwargs.get("pn_refuse_ar")),
        station_name=str(kwargs.get("pn_station") or "akd-sim"), dcp_iface=kwargs.get("dcp_iface"),
        max_ars=int(kwargs.get("pn_ars") or MAX_ARS), ar_timeout=_ar_timeout(kwargs.get("pn_ar_timeout")),
    )


def _ar_timeout(value: Any) -> float | None:
    if value is None:
        return None
    if not 0 < float(value) <= 3600:
        raise UsageError(f"--pn-ar-timeout {value}: give seconds greater than 0 and at most 3600")
    return float(value)


# ---------------------------------------------------------------- refusals, reported once per cause

#: How many AR holders a refusal line names (the rest are counted): a device with 64 ARs must not print 64.
REPORTED_HOLDERS = 3


# ---------------------------------------------------------------- AR state

@dataclass
class _AR:
    ar_uuid: uuid.UUID
    session_key: int
    timeout: float
    peer: tuple[str, int]
    last_activity: float
    station: str = ""  # the CM initiator's station name (who holds this AR)
    # the parameter manager's one response slot: (ready at monotonic time, response bytes)
    pending: tuple[float, bytes] | None = None


@dataclass
class FaceStats:
    received: int = 0
    sent: int = 0
    dropped: int = 0
    duplicated: int = 0
    delayed: int = 0
    replayed: int = 0          # requests answered again with their kept reply
    bmp_requests: int = 0      # requests handed to the parameter manager (each at most once)
    busy_answers: int = 0      # reads/writes answered 0xB5 while the parameter manager worked
    ars_timed_out: int = 0
    log: list[str] = field(default_factory=list)


def _read_identity(drive: BmpHandler) -> tuple[int, int]:
    """Vendor and device ID from the drive's own PNU 964, so every face reports one identity."""
    from akdctl.protocol import bmp

    request = bmp.ParameterRequest(1, bmp.REQ_READ, 1, (bmp.ParameterAddress(964, 0, 2),))  # PNU 964[0..1]
    try:
        response = bmp.decode_response(drive.handle_bmp(bmp.encode_request(request)), request)
        result = response.results[0] if response.results else None
        if isinstance(result, bmp.ParameterValue) and len(result.values) >= 2:
            return int(result.values[0]), int(result.values[1])
    except Exception:  # noqa: BLE001 - any failure of the simulated model falls back to defaults
        pass
    return 0x0100, 0x0001


class ProfinetFace(Face):
    """PNIO CM responder (device side) on one UDP socket, run by one thread."""

    def __init__(self, drive: BmpHandler, host: str = "127.0.0.1", port: int = pnio.PNIO_PORT, *,
                 delay: float = 0.0, injection: Injection | None = None, slot: int = 1, subslot: int = 1,
                 api: int = pnio.API_PROFIDRIVE, fragment: int = 0, refuse_ar: bool = False,
                 station_name: str = "akd-sim", dcp_iface: str | None = None,
                 mac: bytes = b"\x02\x00\x00\x00\xAD\x01", max_ars: int = MAX_ARS,
                 ar_timeout: float | None = None) -> None:
        super().__init__()
        self.drive = drive
        self.host, self.port = host, port
        self.delay = max(0.0, delay)
        self.injection = injection or Injection()
        inj = self.injection
        self._plain_tx = not (inj.drop or inj.dup or inj.delay)  # nothing injected on sending: no count kept
        self.slot, self.subslot, self.api = slot, subslot, api
        self.fragment = fragment
        self.refuse_ar = refuse_ar
        self.refusals = RefusalReport("profinet")  # one line per cause (sim/refusals.py)
        self.station_name = station_name
        self.dcp_iface = dcp_iface
        self.max_ars = max_ars
        self.ar_timeout = ar_timeout  # None: each AR's own activity timeout, as the client asked
        self.mac = mac
        self.stats = FaceStats()
        self.vendor_id, self.device_id = 0x0100, 0x0001
        self._boot_time = int(time.time()) & 0xFFFFFFFF
        self._ars: dict[bytes, _AR] = {}  # by the AR UUID's 16 bytes (as a record header carries it)
        # activity bytes -> [the sequence number of its last answered call, that call's reply frames] (_activity)
        self._last: dict[bytes, list[Any]] = {}
        self._short_way = not fragment  # plain record calls answered in one pass (_datagram); fragments: never
        self._calls: dict[bytes, tuple[Any, ...]] = {}  # plain record calls' shapes as the one pass needs them (_learn)
        self._address = pnio_record.record_address(api, slot, subslot)  # as record_call_fields gives it
        self._rxdrop = self.injection.rxdrop
        self._scheduled: list[tuple[float, int, bytes, tuple[str, int]]] = []
        self._tie = itertools.count()
        self._tx_count = 0
        self._sock: socket.socket | None = None
        self._wake_r, self._wake_w = -1, -1
        self._dcp: Any = None

    # ------------------------------------------------------------- lifecycle (Face: start, stop)
    def open(self) -> None:
        self.vendor_id, self.device_id = _read_identity(self.drive)
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.bind((self.host, self.port))
        except OSError as exc:
            sock.close()
            raise UsageError(f"--profinet {self.host}:{self.port}: cannot listen there ({exc.strerror})") from None
        self._sock = sock
        self.host, self.port = sock.getsockname()[:2]  # the ready line names what was bound (port 0 -> real)
        self._wake_r, self._wake_w = os.pipe()
        self.spawn(self._run, "pn-face")
        if self.dcp_iface:
            from akdctl.sim.dcp_responder import DcpResponder

            self._dcp = DcpResponder(self, self.dcp_iface)
            self._dcp.start()

    def interrupt(self) -> None:
        if self._wake_w >= 0:
            os.write(self._wake_w, b"x")
        if self._sock is not None:
            with contextlib.suppress(OSError):  # wakes the blocking receive (Linux, also unconnected UDP)
                self._sock.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        self.refusals.flush()
        if self._dcp is not None:
            self._dcp.stop()
            self._dcp = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                os.close(fd)
        self._wake_r = self._wake_w = -1

    @property
    def boot_time(self) -> int:
        """The server boot time every reply carries (DCE/RPC CL header)."""
        return self._boot_time

    @boot_time.setter
    def boot_time(self, value: int) -> None:
        """A new boot time: the memo of call shapes is forgotten, since its reply templates carry the old one."""
        self._boot_time = value
        self._calls.clear()

    def describe(self) -> str:
        text = f"profinet udp {self.host}:{self.port}"
        if self.dcp_iface:
            text += f" (dcp on {self.dcp_iface})"
        return text

    # ------------------------------------------------------------- loop
    def _run(self) -> None:
        """One blocking receive per datagram: the kernel's receive timeout (SO_RCVTIMEO, IDLE_WAKE_S) wakes the
        loop for the ARs' timeouts and the stop flag, :meth:`interrupt` shuts the socket down to wake it at once.
        Only while delayed sends (fault injection) are due does it wait in poll() for the earliest of them."""
        sock = self._sock
        assert sock is not None
        poller = select.poll()  # registered once: a select() per datagram rebuilds its lists and fd sets
        sock_fd = sock.fileno()
        poller.register(sock_fd, select.POLLIN)
        poller.register(self._wake_r, select.POLLIN)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, _timeval(IDLE_WAKE_S))
        # recvfrom_into one kept buffer of the largest datagram: the one pass of _datagrams reads a plain record
        # call's parts from it and copies nothing else (recvfrom made and shrank a 64 KiB bytes object per datagram,
        # issue 29); every other way gets the datagram's bytes. An IPv4 peer is already the (host, port) pair the
        # face keeps, an IPv6 one is cut to it.
        buffer = bytearray(65535)
        receive, stop = sock.recvfrom_into, self._stop
        v6 = sock.family == socket.AF_INET6
        next_expiry = 0.0
        # The stop flag is looked at whenever the loop did not just receive a datagram (stop() shuts the socket
        # down, so the next receive returns at once) and at each expiry tick (at most every EXPIRY_TICK_S under
        # traffic), not per datagram: Event.is_set is a Python call.
        while not stop.is_set():
            if self._scheduled:
                wait = max(0.0, min(EXPIRY_TICK_S, self._scheduled[0][0] - time.monotonic()))
                ready = poller.poll(wait * 1000.0)
                self._send_due()
                if not any(fd == sock_fd for fd, _event in ready):
                    next_expiry = self._maybe_expire(next_expiry)
                    continue
            try:
                size, peer = receive(buffer)
            except OSError:  # the receive timeout (EAGAIN), or the socket shut down/closed by stop()
                next_expiry = self._maybe_expire(next_expiry)
                continue
            if peer is None:
                continue  # woken by interrupt(): the loop condition decides
            expiry = self._datagrams(buffer, size, peer[:2] if v6 else peer, receive, v6, next_expiry)
            if expiry is None:
                return  # stopped
            next_expiry = expiry

    def _maybe_expire(self, next_expiry: float) -> float:
        """Drop timed-out ARs at most every EXPIRY_TICK_S (an idle face: every IDLE_WAKE_S, as before)."""
        now = time.monotonic()
        if now < next_expiry:
            return next_expiry
        self._expire_ars()
        return now + EXPIRY_TICK_S

    def _send_due(self) -> None:
        now = time.monotonic()
        while self._scheduled and self._scheduled[0][0] <= now:
            _, _, data, peer = heapq.heappop(self._scheduled)
            self._raw_send(data, peer)

    def _expire_ars(self) -> None:
        now = time.monotonic()
        for key, ar in list(self._ars.items()):
            if now - ar.last_activity > ar.timeout:
                del self._ars[key]
                self.stats.ars_timed_out += 1

    def _raw_send(self, data: bytes, peer: tuple[str, int]) -> None:
        if self._sock is None:
            return
        try:
            self._sock.sendto(data, peer)
            self.stats.sent += 1
        except OSError:
            pass

    def _send(self, data: bytes, peer: tuple[str, int]) -> None:
        """Send one datagram through the fault injector."""
        self._tx_count += 1
        n, inj = self._tx_count, self.injection
        if not (inj.drop or inj.delay or inj.dup):
            self._raw_send(data, peer)
            return
        if inj.drop and n % inj.drop == 0:
            self.stats.dropped += 1
            return
        if inj.delay and n % inj.delay == 0:
            self.stats.delayed += 1
            heapq.heappush(self._scheduled, (time.monotonic() + inj.delay_s, next(self._tie), data, peer))
            return
        self._raw_send(data, peer)
        if inj.dup and n % inj.dup == 0:
            self.stats.duplicated += 1
            self._raw_send(data, peer)

    # ------------------------------------------------------------- requests
    def _datagram(self, data: bytes, peer: tuple[str, int]) -> None:
        """One datagram, answered as the face's loop answers it (:meth:`_datagrams`; no expiry tick: it never
        comes)."""
        self._datagrams(data, len(data), peer, None, False, _NEVER)

    def _datagrams(self, data: bytes | bytearray, size: int, peer: tuple[str, int], receive: Any, v6: bool,
                   next_expiry: float) -> float | None:
        """Answer the datagram of ``size`` bytes at the start of ``data`` from ``peer``; with ``receive`` (the socket's
        recvfrom_into, ``data`` its buffer), go on with the datagrams that follow at once, while no send is
        scheduled, and return the next expiry tick (None: the face was stopped).

        A plain record call (:func:`pnio_record.record_call_fields`) is answered here in one pass when it is a
        retransmission, a Write that reaches the parameter manager or a Read that collects its response -- what
        :meth:`_record_call` does for them, without a RecordCall or a PnioStatus; every other datagram, and every
        other case of one (nothing done, nothing counted yet), goes to :meth:`_general`, which answers it with the
        same checks (tests/test_sim_faces.py holds both ways equal).

        Why one frame for every datagram of a burst, and the face's own memo of shapes (:attr:`_calls`,
        :meth:`_learn`): a PNU read is two datagrams, and a Python call per datagram, the face's attributes looked up
        again for each and a call to the codec for the fields and another for the reply were a measurable share of
        what the simulator spends on it (issue 29). The memo's key is the codec's (``pnio_record.CALL_PARTS``), so
        what a shape answers is what the codec says of it. The clock is read once per datagram."""
        stats, calls, ars = self.stats, self._calls, self._ars
        rxdrop, short_way, plain_tx, monotonic = self._rxdrop, self._short_way, self._plain_tx, time.monotonic
        handle_bmp, delay = self.drive.handle_bmp, self.delay
        sock, scheduled, split = self._sock, self._scheduled, _SPLIT_BY_DREP
        direct = plain_tx and sock is not None  # replies sent by sendto here (_raw_send's steps)
        half, sequences = _HALF, _SEQUENCES
        while True:
            now = monotonic()
            if now >= next_expiry:  # _maybe_expire's test: false for most datagrams
                if self._stop.is_set():
                    return None
                next_expiry = self._maybe_expire(next_expiry)
            try:
                stats.received += 1
                if rxdrop and stats.received % rxdrop == 0:
                    stats.dropped += 1
                    call = frame = None
                elif short_way:
                    frame = None
                    try:  # (a kept buffer is never too short: a shape's least length tells a short datagram)
                        head, sequence, middle, record_sequence, tail = split[data[_DREP_BYTE]](data)
                    except _SHORT:  # too short to be a plain record call
                        head = None
                    else:
                        try:  # the shape kept for the tail, then the rest of its key compared (_learn says why)
                            kept_head, kept_middle, least, last, write, ar_id, length, template, reads = calls[tail]
                        except KeyError:
                            kept_head = None
                        if kept_head != head or kept_middle != middle or size < least:
                            call = self._learn(bytes(data[:size]), head, middle, tail)
                            if call is None:
                                head = None
                            else:
                                kept_head, kept_middle, least, last, write, ar_id, length, template, reads = call
                    if head is None:
                        self._general(bytes(data[:size]), peer)
                    else:
                        try:  # how far the call is past the activity's last one (_older's rule, in one step)
                            ahead = (sequence - last[0]) & sequences
                        except TypeError:  # no call of the activity answered yet: this one is new
                            ahead = 1
                        if not ahead:  # a retransmission of the activity's last call: its reply again
                            stats.replayed += 1
                            self._replay(last[1], peer)
                        elif ahead > half:
                            pass  # older than the activity's last call: discarded (_activity)
                        else:
                            ar = ars.get(ar_id)  # (None for a shape the one pass does not serve: no AR)
                            if ar is not None:
                                pending = ar.pending
                                if write:
                                    if pending is None or pending[0] <= now:
                                        ar.last_activity = now
                                        stats.bmp_requests += 1
                                        try:
                                            (request,) = length(data)  # the record data (write_data_reader)
                                            response = handle_bmp(request)
                                        except Exception as exc:  # noqa: BLE001 - answered as _write answers it
                                            frame = self._write_failed(bytes(data[:size]), head[_DREP_BYTE] >> 4 == 1,
                                                                       exc)
                                        else:
                                            ar.pending = (now + delay, response)
                                            pack, rhead, rmiddle, rtail = template
                                            frame = pack(rhead, sequence, rmiddle, record_sequence, rtail)
                                elif pending is not None and pending[0] <= now:
                                    ar.last_activity = now
                                    ar.pending = None
                                    record = pending[1]
                                    kept = len(record)
                                    if kept > length:  # the most the client takes (usually it fits)
                                        record, kept = record[:length], length
                                    template = reads.get(kept)
                                    if template is None:
                                        template = reads[kept] = pnio_record.ok_template_booted(
                                            bytes(data[:size]), kept, self._boot_time)
                                    pack, rhead, rmiddle, rtail = template
                                    frame = pack(rhead, sequence, rmiddle, record_sequence, rtail, record)
                            if frame is None:
                                self._general(bytes(data[:size]), peer)
                else:
                    frame = None
                    self._general(bytes(data[:size]), peer)
                if frame is not None:
                    last[0] = sequence  # _remember's steps, inline: the reply kept (a single frame as itself)
                    last[1] = frame
                    if direct:  # _raw_send's steps, inline
                        try:
                            sock.sendto(frame, peer)
                            stats.sent += 1
                        except OSError:
                            pass
                    elif not plain_tx:
                        self._send(frame, peer)
            except Exception as exc:  # noqa: BLE001 - nothing a request does may end the face
                if receive is None:
                    raise
                request_failed("profinet", exc)
            if receive is None or scheduled:
                return next_expiry
            try:
                size, peer = receive(data)
            except OSError:  # the receive timeout (EAGAIN), or the socket shut down/closed by stop()
                return self._maybe_expire(next_expiry)
            if peer is None:
                return next_expiry  # woken by interrupt(): the loop's condition decides
            if v6:
                peer = peer[:2]

    def _replay(self, cached: bytes | list[bytes], peer: tuple[str, int]) -> None:
        """Send a kept reply again: one frame (the one pass keeps it as itself) or the frames of a list."""
        for frame in (cached,) if type(cached) is bytes else cached:
            self._send(frame, peer)

    def _learn(self, data: bytes, head: bytes, middle: bytes, tail: bytes) -> tuple[Any, ...] | None:
        """What :meth:`_datagrams` keeps of a plain record call's shape (None: not one, the general path answers):
        the shape's key as the codec splits it (``head``, ``middle``; ``tail`` is the memo's key), the least datagram
        length it holds for, the activity's last call (:meth:`_activity`), whether it is a Write, the AR UUID's bytes
        if the one pass may serve it here, else None (this face's API/slot/subslot and a parameter record, and a
        Write's record length within 1..MAX_RECORD: what :meth:`_write`/:meth:`_read` check after the AR), a Write's
        record data reader (``pnio_record.write_data_reader``) or the most a Read takes, a Write's OK reply template
        and a Read's by record length (``pnio_record.ok_template``).

        Why the memo is keyed by the tail (the record header from its AR UUID on) and the head and middle compared:
        a dict lookup hashes its whole key, and the 134 bytes of the codec's key cost more to join and hash than
        the two comparisons; the AR UUID in the tail tells one client's calls from another's, its record length a
        Write from a Read. Two shapes with one tail (a Write of as many bytes as its Read takes) take turns in the
        memo: each learnt again (correct, only slower)."""
        fields = pnio_record.record_call_fields(data)
        if fields is None:
            return None
        _little, activity, opnum, ar_id, address, index, length, least, _replies = fields[0]
        write = opnum == OP_WRITE
        served = address == self._address and index in _PARAMETER_INDICES and (not write or 0 < length <= MAX_RECORD)
        return remember(self._calls, tail, (head, middle, least, self._activity(activity), write,
                                            ar_id if served else None,
                                            pnio_record.write_data_reader(length) if write else length,
                                            pnio_record.ok_template_booted(data, None, self._boot_time)
                                            if write else None, {}), _CALLS_KEPT)

    def _general(self, data: bytes, peer: tuple[str, int]) -> None:
        """Every datagram the one pass of :meth:`_datagram` does not answer: the plain record calls' second short way
        (:meth:`_record_call`), else the general decoders."""
        stats = self.stats
        plain = pnio_record.plain_record_call(data) if not self.fragment else None
        if plain is not None:
            little, sequence, opnum, req = plain
            self._record_call(data, peer, little, sequence, opnum, req)
            return
        try:
            view = dcerpc.view_packet(data)  # the header's fields, its UUIDs left as wire bytes
        except CodecError:
            return      # not DCE/RPC: a real device ignores it too
        activity, sequence = data[40:56], view.sequence  # the activity UUID's bytes and the sequence number
        if view.ptype == dcerpc.PT_PING:
            last = self._last.get(activity)
            if last is not None and last[0] == sequence:
                self._replay(last[1], peer)
            elif last is None or not _older(last[0], sequence):
                self._send(pnio_record.reply_head(data, view.little, dcerpc.PT_NOCALL, self.boot_time, 0), peer)
            return      # a ping of a call older than the activity's last one: discarded (_activity)
        if view.ptype != dcerpc.PT_REQUEST:
            return      # acks, facks, stray responses
        last = self._last.get(activity)
        if last is not None:
            if last[0] == sequence:
                stats.replayed += 1
                self._replay(last[1], peer)
                return
            if _older(last[0], sequence):
                return  # older than the activity's last call: discarded (_activity)
        if view.is_fragment:
            reject = _nca(0x1C010003, view.little)
            head = pnio_record.reply_head(data, view.little, dcerpc.PT_REJECT, self.boot_time, len(reject))
            self._send(head + reject, peer)
            return      # our requests are small; fragmented requests are not needed by any client we serve
        if data[24:40] != pnio_record.DEVICE_INTERFACE_WIRE[view.little]:
            reject = _nca(0x1C010003, view.little)
            frames = [pnio_record.reply_head(data, view.little, dcerpc.PT_REJECT, self.boot_time, len(reject)) + reject]
        else:
            try:
                status, blocks = self._call(view, peer)
            except CodecError:
                status, blocks = pnio.PnioStatus(0x81, 0x81, 0x3F, 0x00), b""   # argument length invalid
            except Exception as exc:  # noqa: BLE001 - answered with an error status, the face goes on
                request_failed("profinet", exc)
                status, blocks = _failure_status(view.opnum, exc), b""
            body = pnio.encode_response_args(status, blocks, little=view.little)
            if self.fragment:
                reply = self._reply_header(dcerpc.decode_packet(data).header, dcerpc.PT_RESPONSE)
                frames = dcerpc.fragment_body(reply, body, self.fragment)
            else:
                head = pnio_record.reply_head(data, view.little, dcerpc.PT_RESPONSE, self.boot_time, len(body))
                frames = [head + body]
        self._remember(activity, sequence, frames)
        for frame in frames:
            self._send(frame, peer)

    def _activity(self, activity: bytes) -> list[Any]:
        """The activity's last call: [its sequence number, its reply frames] ([None, None] before any), made on first
        use and kept among the ACTIVITIES_KEPT (sim/memo.remember; the shapes that hold theirs are forgotten with them).

        Why one call per activity and not a memo of every recent (activity, sequence): DCE/RPC CL allows one call in
        progress per activity, so a client retransmits only its latest call, and a request whose sequence number is
        below the activity's current one is discarded by the server (MS-RPCE 3.2.3.5.4 REQUEST: "If N is less than
        the activity ID element's lowest-allowed-sequence number, the server MUST discard the packet"; a new call
        raises that number to its own; 3.2.3.5.5 PING likewise). What an AKD does there is not documented [I]: the
        face follows the protocol. Keeping the last reply is a store into this list, where a memo by (activity,
        sequence) built, hashed and evicted a key per datagram (issue 29)."""
        last = self._last.get(activity)
        if last is None:
            if len(self._last) >= ACTIVITIES_KEPT:
                self._calls.clear()  # shapes hold their activity's list: forgotten with it
            last = remember(self._last, activity, [None, None], ACTIVITIES_KEPT)
        return last

    def _remember(self, activity: bytes, sequence: int, frames: bytes | list[bytes]) -> None:
        """Keep a reply for retransmissions of its call, the activity's last (:meth:`_activity`). :meth:`_datagrams`
        does these steps inline for the replies of its one pass (tests/test_sim_faces.py holds the two ways equal)."""
        last = self._activity(activity)
        last[0], last[1] = sequence, frames

    def _write_failed(self, data: bytes, little: bool, exc: Exception) -> bytes:
        """The reply to a plain Write whose request the parameter manager refused or failed on (as :meth:`_write`)."""
        plain = pnio_record.plain_record_call(data)
        assert plain is not None  # record_call_fields accepted it: so does plain_record_call (the same checks)
        req = plain[3]
        if isinstance(exc, RecordRefused):  # a request no base-mode response can answer (docs/fidelity.md F1)
            status = pnio.rw_error(True, exc.code1)
        else:  # the parameter manager failed: a record error, not silence
            request_failed("profinet", exc)
            status = _failure_status(OP_WRITE, exc)
        return pnio_record.pack_record_response(data, little, self.boot_time, *pnio_record.write_res(req, status))

    def _record_call(self, data: bytes, peer: tuple[str, int], little: bool, sequence: int, opnum: int,
                     req: pnio_record.RecordCall) -> None:
        """A plain Write or Read record request (:func:`pnio_record.plain_record_call`): what the general path does for
        it, without building a header view or calling the argument decoders; the response packed in one step
        (:func:`pnio_record.pack_record_response`)."""
        activity = data[40:56]
        last = self._last.get(activity)
        if last is not None:
            if last[0] == sequence:
                self.stats.replayed += 1
                self._replay(last[1], peer)
                return
            if _older(last[0], sequence):
                return  # older than the activity's last call: discarded (_activity)
        try:
            status, blocks = self._write(req) if opnum == OP_WRITE else self._read(req, implicit=False)
        except CodecError:
            status, blocks = pnio.PnioStatus(0x81, 0x81, 0x3F, 0x00), b""   # argument length invalid
        except Exception as exc:  # noqa: BLE001 - answered with an error status, the face goes on
            request_failed("profinet", exc)
            status, blocks = _failure_status(opnum, exc), b""
        frame = pnio_record.pack_record_response(data, little, self.boot_time, status, blocks)
        self._remember(activity, sequence, frame)
        if self._plain_tx:
            self._raw_send(frame, peer)
        else:
            self._send(frame, peer)

    def _reply_header(self, head: dcerpc.RpcHeader, ptype: int) -> dcerpc.RpcHeader:
        """The reply's header as an object (the fragmenting path); ``pnio_record.reply_head`` writes the same
        bytes."""
        return replace(head, ptype=ptype, flags1=dcerpc.FLAG_NOFACK if ptype == dcerpc.PT_RESPONSE else 0,
                       flags2=0, server_boot=self.boot_time, fragment=0, body_length=0)

    def _call(self, view: dcerpc.RpcView, peer: tuple[str, int]) -> tuple[pnio.PnioStatus, bytes]:
        _args_max, blocks = pnio.decode_request_args(view.body, view.little)
        opnum = view.opnum
        if opnum == OP_WRITE:
            return self._write(pnio_record.record_request(blocks, BT_WRITE_REQ))
        if opnum == OP_READ or opnum == OP_READ_IMPLICIT:
            return self._read(pnio_record.record_request(blocks, BT_READ_REQ), implicit=opnum == OP_READ_IMPLICIT)
        if opnum == pnio.OP_CONNECT:
            return self._connect(blocks, peer)
        if opnum == pnio.OP_RELEASE:
            return self._release(blocks)
        return pnio.PnioStatus(0x81, 0x81, 0x3C, 0x00), b""       # unknown opnum

    def _connect(self, blocks: bytes, peer: tuple[str, int]) -> tuple[pnio.PnioStatus, bytes]:
        found = pnio.split_blocks(blocks)
        ar_blocks = [b for b in found if b.type == pnio.BT_AR_REQ]
        if len(ar_blocks) != 1:
            return pnio.PnioStatus(0xDB, 0x81, 0x40, 0x00), b""
        req = pnio.ARBlockReq.from_block(ar_blocks[0])
        if self.refuse_ar or req.ar_type != pnio.AR_TYPE_IOSAR or len(found) != 1:
            return pnio.PnioStatus(*pnio.AR_TYPE_REFUSED), b""
        if not req.device_access or not req.properties & pnio.AR_PROP_STATE_ACTIVE:
            return pnio.PnioStatus(*pnio.AR_PROPERTIES_REFUSED), b""
        if not 1 <= req.timeout_factor <= 1000:
            return pnio.PnioStatus(0xDB, 0x81, 0x01, 0x0A), b""
        if req.ar_uuid.bytes not in self._ars and len(self._ars) >= self.max_ars:
            self._report_full(peer)
            return pnio.PnioStatus(*pnio.OUT_OF_AR_RESOURCES), b""
        timeout = self.ar_timeout if self.ar_timeout is not None else req.timeout_factor * 0.1
        station = req.station_name.decode("ascii", "replace")
        self._ars[req.ar_uuid.bytes] = _AR(req.ar_uuid, req.session_key, timeout, peer, time.monotonic(), station)
        res = pnio.ARBlockRes(req.ar_type, req.ar_uuid, req.session_key, self.mac)
        return pnio.OK, res.encode()

    def _report_full(self, peer: tuple[str, int]) -> None:
        """Name the ARs holding every slot: the refused client cannot learn it from the device (PROFINET has no
        field for it), the person running the simulator can. Through :class:`RefusalReport`: one line per cause,
        repeats counted (issue 23.16: a client retrying in a loop wrote 853 KB in 4 minutes)."""
        now = time.monotonic()
        ars = list(self._ars.values())
        holders = "; ".join(
            f"AR {ar.ar_uuid} of {ar.station or '?'} at {ar.peer[0]}:{ar.peer[1]}, idle {now - ar.last_activity:.1f} s, "
            f"dropped in {max(0.0, ar.timeout - (now - ar.last_activity)):.1f} s without a request"
            for ar in ars[:REPORTED_HOLDERS])
        if len(ars) > REPORTED_HOLDERS:
            holders += f"; and {len(ars) - REPORTED_HOLDERS} more"
        text = f"Connect from {peer[0]}:{peer[1]} refused, out of AR resources ({len(ars)} held: {holders})"
        if self.refusals.refused("out of AR resources", text):
            self.stats.log.append(text)

    def _release(self, blocks: bytes) -> tuple[pnio.PnioStatus, bytes]:
        rel = pnio.ReleaseBlock.decode(blocks)
        ar = self._ars.get(rel.ar_uuid.bytes)
        if ar is None or ar.session_key != rel.session_key:
            return pnio.PnioStatus(0xDC, 0x81, 0x3D, 0x00), b""        # CM state conflict: no such AR
        del self._ars[rel.ar_uuid.bytes]
        return pnio.OK, replace(rel, command=pnio.CONTROL_DONE, response=True).encode()

    def _address_error(self, req: pnio_record.RecordCall, write: bool) -> pnio.PnioStatus | None:
        if req.api != self.api:
            return pnio.rw_error(write, 0xB4)
        if req.slot != self.slot or req.subslot != self.subslot:
            return pnio.rw_error(write, 0xB2)
        if req.index != INDEX_PROFIDRIVE and req.index != INDEX_PROFIDRIVE_ALT:
            return pnio.rw_error(write, 0xB0)
        return None

    def _ar_for(self, ar_uuid: bytes) -> _AR | None:
        ar = self._ars.get(ar_uuid)
        if ar is not None:
            ar.last_activity = time.monotonic()
        return ar

    def _write(self, req: pnio_record.RecordCall) -> tuple[pnio.PnioStatus, bytes]:
        ar = self._ars.get(req.ar)
        if ar is None:
            return pnio_record.write_res(req, pnio.rw_error(True, 0xB6))                  # no such AR: access denied
        ar.last_activity = now = time.monotonic()
        if req.api != self.api or req.slot != self.slot or req.subslot != self.subslot or \
                (req.index != INDEX_PROFIDRIVE and req.index != INDEX_PROFIDRIVE_ALT):
            return pnio_record.write_res(req, self._address_error(req, True) or OK)
        if not 0 < len(req.data) <= MAX_RECORD:
            return pnio_record.write_res(req, pnio.rw_error(True, 0xB1))
        if ar.pending is not None and ar.pending[0] > now:
            self.stats.busy_answers += 1
            return pnio_record.write_res(req, pnio.rw_error(True, 0xB5))  # still working on the last request
        self.stats.bmp_requests += 1
        try:
            response = self.drive.handle_bmp(req.data)
        except RecordRefused as exc:  # a request no base-mode response can answer (docs/fidelity.md F1)
            return pnio_record.write_res(req, pnio.rw_error(True, exc.code1))
        except Exception as exc:  # noqa: BLE001 - the parameter manager failed: a record error, not silence
            request_failed("profinet", exc)
            return pnio_record.write_res(req, _failure_status(OP_WRITE, exc))
        ar.pending = (now + self.delay, response)
        return pnio_record.write_res(req, OK)

    def _read(self, req: pnio_record.RecordCall, implicit: bool) -> tuple[pnio.PnioStatus, bytes]:
        if req.index == pnio.INDEX_IM0:
            if req.slot not in (0, self.slot):
                return pnio.rw_error(False, 0xB2), b""
            if not implicit and self._ar_for(req.ar) is None:
                return pnio.rw_error(False, 0xB6), b""
            return pnio_record.read_res(req, self.im0().encode()[: max(0, req.length)])
        if implicit:
            # the parameter channel lives in the AR: Read Implicit cannot reach it
            return pnio.rw_error(False, 0xB6), b""
        ar = self._ars.get(req.ar)
        if ar is None:
            return pnio.rw_error(False, 0xB6), b""
        ar.last_activity = now = time.monotonic()
        if req.index == pnio.INDEX_KEEPALIVE:
            return pnio_record.read_res(req, b"")
        if req.api != self.api or req.slot != self.slot or req.subslot != self.subslot or \
                (req.index != INDEX_PROFIDRIVE and req.index != INDEX_PROFIDRIVE_ALT):
            return self._address_error(req, write=False) or OK, b""
        if ar.pending is None:
            return pnio.rw_error(False, 0xA0), b""          # nothing was asked: read error
        ready_at, response = ar.pending
        if ready_at > now:
            self.stats.busy_answers += 1
            return pnio.rw_error(False, 0xB5), b""          # busy: come back later
        ar.pending = None
        return pnio_record.read_res(req, response[: max(0, req.length)])

    def im0(self) -> pnio.IM0:
        from akdctl.sim import identity  # the drive's one identity record (issue 23.8)

        major, minor, patch, _ = identity.firmware_numbers()
        return pnio.IM0(vendor_id=self.vendor_id, order_id=identity.ORDER_CODE, serial_number=str(identity.serial_of(self.drive)),
                        hardware_revision=identity.hardware_revision_number(), sw_revision=("V", major, minor, patch),
                        revision_counter=0,
                        profile_id=pnio.API_PROFIDRIVE, profile_specific_type=1, im_version=(1, 1), im_supported=0)


def _failure_status(opnum: int, exc: Exception) -> pnio.PnioStatus:
    """The status for a request the device failed to carry out: a record access gets "resource busy" (0xC2, the
    client retries) while the drive is locked by another process, else "resource unavailable" (0xC3); any other
    call a CMRPC state conflict."""
    if opnum in (pnio.OP_READ, pnio.OP_WRITE, pnio.OP_READ_IMPLICIT):
        return pnio.rw_error(opnum == pnio.OP_WRITE, 0xC2 if isinstance(exc, CommError) else 0xC3)
    return pnio.PnioStatus(0x81, 0x81, 0x40, 0x06)


def _older(last: int | None, sequence: int) -> bool:
    """Whether ``sequence`` is below ``last`` (the activity's last answered call; None: none yet) in the 32-bit
    sequence space, which wraps: the half of it below ``last`` is older."""
    return last is not None and 0 < (last - sequence) & _SEQUENCES < _HALF


def _nca(status: int, little: bool) -> bytes:
    """A reject body: one NCA status code in the sender's byte order."""
    return status.to_bytes(4, "little" if little else "big")
