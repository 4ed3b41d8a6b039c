"""``pn://HOST[:34964]``: PROFIdrive parameters over PROFINET record data (PNIO DCE/RPC on UDP).

A supervisor tool needs no PLC configuration: it connects a *Device Access
AR* (AR type 0x0006, DeviceAccess property), writes the PROFIdrive request to
record 47 and reads the response from record 47, polling while the device
answers "busy". The DCE/RPC client is ours, on a plain UDP socket, so that
every failure can be reported in words and every wait is bounded:

* a lost datagram is retransmitted with the same activity UUID and sequence
  number (the device recognises the repeat and answers from its cache);
* a reply is accepted only for our activity and the current sequence number,
  so duplicated or late replies of an earlier call are dropped;
* fragmented responses are reassembled;
* an idle AR is kept alive by harmless reads (index 0xFBFF) before the device's
  activity timeout ends it, and the AR is released on every way out.

Query parameters: ``slot`` (1), ``subslot`` (1), ``api`` (0x3A00), ``index``
(47), ``axis`` (0, the PROFIdrive DO), ``vendor``/``device`` (the PNIO object
UUID's IDs), ``instance`` (1), ``ar_timeout`` (AR activity timeout factor in
100 ms, default 100), ``iface`` (to resolve a station name through DCP).
"""

from __future__ import annotations

import errno
import ipaddress
import socket
import threading
import time
import uuid
from collections.abc import Callable
from typing import TYPE_CHECKING

from akdctl.catalog.texts import pnio_status_text
from akdctl.errors import (
    CommError,
    MalformedReply,
    NoAnswer,
    RecordError,
    UnknownOutcome,
    UsageError,
)
from akdctl.links import Deadline, RecordLink
from akdctl.protocol import dcerpc, pnio
from akdctl.protocol.errors import CodecError
from akdctl.protocol.pnio_call import RecordCalls, plain_response
from akdctl.transport.base import LinkOptions, Transport
from akdctl.transport.tcp_stream import BoundedSocket

if TYPE_CHECKING:
    from akdctl.transport.target import Target

DEFAULT_VENDOR_ID = 0x0100       # the simulator's PNU 964[0]; a real AKD is addressed by its own IDs
DEFAULT_DEVICE_ID = 0x0001
MAX_RECORD = 240
BUSY_BACKOFF = (0.01, 0.1)       # first and longest pause between polls of a busy device
MAX_BODY = 1 << 17               # the most a reassembled response may hold (a record is at most 64 KiB)
RecordReply = tuple["pnio.PnioStatus", bytes]  # a record call's PNIOStatus and record data
NCA_TEXTS = {0x1C010003: "unknown interface (not a PNIO device interface)", 0x1C010002: "operation out of range",
             0x1C010014: "server too busy", 0x1C00001C: "protocol error", 0x1C010013: "unsupported type"}


class Begun:
    """A call whose first attempt :meth:`ProfinetTransport.quick_exchange` sent at ``sent_at`` (``time.monotonic()``)
    without getting the usual answer: ``taken`` is the datagram it received instead (None: none came within the
    attempt's wait, or the send found the host unreachable). :meth:`RpcClient.exchange` goes on from there."""

    __slots__ = ("sent_at", "taken")

    def __init__(self, sent_at: float, taken: bytes | None) -> None:
        self.sent_at = sent_at
        self.taken = taken


class Step:
    """Where :meth:`ProfinetTransport.quick_exchange` left a request: in the Write call (``read_seq`` -1) or the Read
    call (``read_seq``: its record sequence number); ``datagram`` is that call's, ``begun`` where it stands."""

    __slots__ = ("read_seq", "datagram", "begun")

    def __init__(self, read_seq: int, datagram: bytes, begun: Begun) -> None:
        self.read_seq = read_seq
        self.datagram = datagram
        self.begun = begun


class RpcClient:
    """DCE/RPC CL calls to one PNIO device: one activity, sequence numbers, retransmission."""

    def __init__(self, host: str, port: int, options: LinkOptions, object_uuid: uuid.UUID, label: str) -> None:
        self.options = options
        self.object_uuid = object_uuid
        self.label = label
        self.activity = uuid.uuid4()
        self.template = dcerpc.RequestTemplate(object_uuid, pnio.DEVICE_INTERFACE, self.activity)
        self._activity_be, self._activity_le = self.activity.bytes, self.activity.bytes_le
        self.sequence = 0
        self.stale = 0          # replies dropped as duplicates or leftovers of earlier calls
        self._buffer = bytearray(65536)  # one receive buffer: no 64 KiB allocation per datagram
        self.retransmissions = 0
        try:
            infos = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
        except (socket.gaierror, UnicodeError) as exc:
            raise UsageError(f"{label}: cannot resolve host {host!r} ({exc})") from None
        family, _, _, _, address = infos[0]
        self.sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            self.sock.connect(address)
            # every receive ends by its attempt's end, in one recv(2) where the kernel can bound it (tcp_stream)
            self.stream = BoundedSocket(self.sock, options.timeout)
        except OSError as exc:
            self.sock.close()
            raise CommError(f"{label}: cannot reach {host}:{port} ({exc.strerror})") from None
        self.remote = address[:2]
        self.local = self.sock.getsockname()[:2]

    def close(self) -> None:
        self.sock.close()

    def _trace(self, direction: str, data: bytes, note: str) -> None:
        src, dst = (self.local, self.remote) if direction == "tx" else (self.remote, self.local)
        self.options.tracer.frame(direction, "pnio-rpc", data, note=note,  # type: ignore[arg-type]
                                  meta={"proto": "udp", "src": src, "dst": dst})

    def call(self, opnum: int, blocks: bytes, deadline: Deadline | None = None) -> tuple[pnio.PnioStatus, bytes]:
        """One PNIO call within ``deadline`` (default: a request of the command's Budget); returns the
        response's PNIOStatus and blocks. Raises NoAnswer / MalformedReply / CommError (port unreachable)."""
        if deadline is None:
            with self.options.budget.request() as own:
                return self.call(opnum, blocks, own)
        sequence = self.next_sequence()
        return self.exchange(self.template.packet(sequence, opnum, pnio.encode_request_args(blocks)), opnum, deadline)

    def next_sequence(self) -> int:
        """The sequence number of the next call (the datagram passed to :meth:`exchange` must carry it)."""
        self.sequence = sequence = (self.sequence + 1) & 0xFFFFFFFF
        return sequence

    def exchange(self, datagram: bytes, opnum: int, deadline: Deadline,
                 begun: "Begun | None" = None) -> tuple[pnio.PnioStatus, bytes]:
        """Send the datagram of call :attr:`sequence` and wait for its answer within ``deadline`` (see :meth:`call`).

        The same datagram goes out again after each attempt's share of the deadline: the device recognises the
        repeat by activity and sequence number and answers from its cache, so a write is not applied twice.
        The usual reply (our activity, this sequence, one unfragmented response) is read by
        :func:`pnio_call.plain_response`; every other datagram, and every datagram while tracing, by :meth:`_accept`.
        ``begun``: the call's first attempt went out on :meth:`ProfinetTransport.quick_exchange` and did not end it;
        this goes on from there exactly as if it had sent that attempt itself.
        """
        sequence = self.sequence
        tracing = self.options.tracer.active
        reassembler: list[dcerpc.Reassembler] | None = None  # made when the general path first takes a datagram
        attempts = deadline.attempts
        sock, stream, buffer = self.sock, self.stream, self._buffer
        activity_be, activity_le = self._activity_be, self._activity_le
        for sent in range(attempts):
            if begun is not None:  # the first attempt is out (the quick path's): its share counts from when it went
                now = begun.sent_at
                resend_at = now + max(0.0, deadline.at - now) / attempts
                taken, begun = begun.taken, None
                if taken is not None:  # a datagram the quick path did not take: the general path reads it
                    reassembler = []
                    result = self._accept(taken, _opname(opnum), reassembler)
                    if result is not None:
                        return result
                wait = resend_at - time.monotonic()
            else:
                if sent and deadline.expired():
                    break
                if tracing:
                    self._trace("tx", datagram, f"{_opname(opnum)} seq {sequence}"
                                + (" (retransmission)" if sent else ""))
                try:
                    sock.send(datagram)
                except OSError as exc:
                    self._send_failed(exc, opnum)
                if sent:
                    self.retransmissions += 1
                now = time.monotonic()
                resend_at = now + max(0.0, deadline.at - now) / (attempts - sent)  # this attempt's share of the rest
                wait = resend_at - now
            while wait > 0:
                try:
                    size = stream.recv_into(resend_at, buffer)
                except OSError as exc:
                    raise self._receive_failed(exc, opnum) from None
                if size is None:
                    break  # nothing before resend_at: the next attempt
                data = buffer[:size]
                if not tracing:
                    result = plain_response(data, sequence, activity_be, activity_le)
                    if result is not None:
                        return result
                if reassembler is None:
                    reassembler = []  # (a reassembler goes in for the first fragment: responses rarely are)
                result = self._accept(data, _opname(opnum), reassembler)
                if result is not None:
                    return result
                wait = resend_at - time.monotonic()
        raise NoAnswer(f"{self.label}: no answer to PNIO {_opname(opnum)} within {deadline.describe()}")

    def _receive_failed(self, exc: OSError, opnum: int) -> CommError:
        """The error of a receive that failed (other than by its timeout)."""
        if isinstance(exc, ConnectionRefusedError):
            return self._refused(_opname(opnum))
        return CommError(f"{self.label}: receive failed ({exc.strerror})")

    def _send_failed(self, exc: OSError, opnum: int) -> None:
        """A send that failed: nothing listens (refused), or the host cannot be reached now (the attempt's wait
        follows as if the datagram were lost), or the socket failed."""
        if isinstance(exc, ConnectionRefusedError):
            raise self._refused(_opname(opnum)) from None
        if isinstance(exc, BlockingIOError):  # SO_SNDTIMEO (tcp_stream): the send buffer stayed full
            raise CommError(f"{self.label}: cannot send (timed out)") from None
        if exc.errno not in (errno.EHOSTUNREACH, errno.ENETUNREACH):
            raise CommError(f"{self.label}: cannot send ({exc.strerror})") from None

    def _refused(self, name: str) -> CommError:
        """ICMP port unreachable came back (ECONNREFUSED on the connected socket): nothing listens there,
        so waiting out the timeout would only hide that."""
        host, port = self.remote
        return CommError(f"{self.label}: nothing listens on UDP port {port} of {host} (ICMP port unreachable "
                         f"in answer to the PNIO {name}): no PROFINET device there, or the wrong port")

    def _accept(self, data: bytes, name: str,
                reassembler: list[dcerpc.Reassembler]) -> tuple[pnio.PnioStatus, bytes] | None:
        tracing = self.options.tracer.active
        try:
            packet = dcerpc.view_packet(data)
        except CodecError as exc:
            if tracing:
                self._trace("rx", data, f"ignored: {exc}")
            return None
        if packet.sequence != self.sequence or not self.template.is_ours(packet):
            self.stale += 1
            if tracing:
                self._trace("rx", data, f"ignored stale/duplicate {packet.type_name} seq {packet.sequence}")
            return None
        if tracing:
            self._trace("rx", data, f"{name} {packet.type_name} seq {packet.sequence}"
                        + (f" fragment {packet.fragment}" if packet.is_fragment else ""))
        ptype = packet.ptype
        if ptype in (dcerpc.PT_WORKING, dcerpc.PT_NOCALL, dcerpc.PT_FACK, dcerpc.PT_PING):
            return None
        if ptype in (dcerpc.PT_REJECT, dcerpc.PT_FAULT):
            body = packet.body
            code = int.from_bytes(body[:4], "little" if packet.little else "big") if len(body) >= 4 else 0
            text = NCA_TEXTS.get(code, f"status 0x{code:08X}")
            raise MalformedReply(f"{self.label}: the device {packet.type_name}s the PNIO {name} call: {text}", code=code)
        if ptype != dcerpc.PT_RESPONSE:
            return None
        if packet.is_fragment:
            if not reassembler:
                reassembler.append(dcerpc.Reassembler(max_body=MAX_BODY))
            try:
                body = reassembler[0].add(packet)
            except CodecError as exc:
                raise MalformedReply(f"{self.label}: bad fragment in the {name} response: {exc}") from None
            if body is None:
                return None
        else:
            body = packet.body
        try:
            return pnio.decode_response_args(body, packet.little)
        except CodecError as exc:
            raise MalformedReply(f"{self.label}: malformed {name} response: {exc}") from None


class PnioRecordLink(RecordLink):
    """PROFIdrive request bytes through write record + read record in one Device Access AR."""

    max_record = MAX_RECORD

    def __init__(self, transport: "ProfinetTransport") -> None:
        self.t = transport
        self.axis = transport.axis
        self.trace_note = transport.address.describe()

    def exchange(self, request: bytes) -> bytes:
        t = self.t
        if len(request) > MAX_RECORD:
            raise UsageError(f"{t.label}: parameter request of {len(request)} bytes exceeds the record limit "
                             f"of {MAX_RECORD} bytes")
        with t.lock:
            options = t.options
            # The usual request (tracing off, an AR, nothing unanswered before it): ProfinetTransport.quick_exchange
            at = None if options.tracer.active or t._calls is None else options.budget.lone()
            if at is None:
                return self._exchange(request, None, None)
            try:
                step = t.quick_exchange(request, at)
            except BaseException:
                t._last_activity = time.monotonic()
                raise
            if step.__class__ is bytes:
                return step  # type: ignore[return-value]
            return self._exchange(request, at, step)  # type: ignore[arg-type]

    def _exchange(self, request: bytes, at: float | None, step: "Step | None") -> bytes:
        """Write record, then read record, by the general path; ``step``: where :meth:`ProfinetTransport.quick_exchange`
        left the same request (begun at the end time ``at``), to go on from there."""
        t = self.t
        with t.options.budget.request(at=at) as deadline:
            try:
                if step is None or step.read_seq < 0:  # the write is still to do, or to finish
                    if step is None:
                        status = t.write_record(request, deadline)[0]
                    else:
                        status = t._write_outcome(t._need_rpc().exchange(step.datagram, pnio.OP_WRITE, deadline,
                                                                         step.begun))[0]
                    if status.busy:
                        self._until_not_busy(deadline, status, t.write_record, request, "write")
                    status, data = t.read_record(deadline)
                else:
                    reply = t._need_rpc().exchange(step.datagram, pnio.OP_READ, deadline, step.begun)
                    status, data = t._read_reply(t.address, step.read_seq, *reply)
                if status.busy:
                    data = self._until_not_busy(deadline, status, t.read_record, None, "read")
                return data
            except NoAnswer as exc:
                from akdctl.protocol import bmp

                if len(request) > 1 and request[1] == bmp.REQ_CHANGE:
                    raise _unknown_outcome(exc, request) from None
                raise
            finally:
                t._last_activity = time.monotonic()

    def _until_not_busy(self, deadline: Deadline, busy: pnio.PnioStatus, action: Callable[..., RecordReply],
                        request: bytes | None, what: str) -> bytes:
        """Ask again, with a growing pause, while the device answers busy (``busy``: its first answer)."""
        pause = BUSY_BACKOFF[0]
        while True:
            if pause > deadline.remaining():
                raise NoAnswer(f"{self.t.label}: the drive stayed busy for {deadline.total:g} s "
                               f"({what} record: {pnio_status_text(*busy.encode())})", code=busy.value)
            time.sleep(pause)
            pause = min(BUSY_BACKOFF[1], pause * 2)
            try:
                status, data = action(deadline) if request is None else action(request, deadline)
            except NoAnswer:
                # The drive did answer: busy, until the time ran out. Say that, not "no answer" (issue 23.15).
                raise NoAnswer(f"{self.t.label}: the drive stayed busy for {deadline.total:g} s "
                               f"({what} record: {pnio_status_text(*busy.encode())})", code=busy.value) from None
            if not status.busy:
                return data
            busy = status


class ProfinetTransport(Transport):
    """``pn://HOST``: one Device Access AR to one PROFINET AKD."""

    scheme = "pn"

    def __init__(self, target: "Target", options: LinkOptions) -> None:
        super().__init__(target, options)
        q = target.query_int
        self.address = pnio.RecordAddress(api=q("api", pnio.API_PROFIDRIVE), slot=q("slot", 1),
                                          subslot=q("subslot", 1), index=q("index", pnio.INDEX_PROFIDRIVE))
        self.axis = q("axis", 0)
        self.vendor_id = q("vendor", DEFAULT_VENDOR_ID)
        self.device_id = q("device", DEFAULT_DEVICE_ID)
        self.instance = q("instance", 1)
        self.timeout_factor = q("ar_timeout", 100)
        for name, value, low, high in (("slot", self.address.slot, 0, 0x7FFF), ("subslot", self.address.subslot, 0, 0xFFFF),
                                       ("api", self.address.api, 0, 0xFFFFFFFF), ("index", self.address.index, 0, 0xFFFF),
                                       ("axis", self.axis, 0, 254), ("vendor", self.vendor_id, 0, 0xFFFF),
                                       ("device", self.device_id, 0, 0xFFFF), ("instance", self.instance, 0, 0xFFFF),
                                       ("ar_timeout", self.timeout_factor, 1, 1000)):
            if not low <= value <= high:
                raise UsageError(f"target {target.raw!r}: {name}={value} is outside {low}..{high}")
        self.label = target.display
        self.lock = threading.RLock()
        self.rpc: RpcClient | None = None
        self.ar_uuid: uuid.UUID | None = None
        self.session_key = 1
        self._rw_seq = 0
        self._last_activity = 0.0
        self._calls: RecordCalls | None = None  # the parameter record's datagrams, for the current AR
        self._keepalive: threading.Thread | None = None
        self._stop = threading.Event()

    # ------------------------------------------------------------- connection
    def _host(self) -> str:
        host = self.target.host
        try:
            ipaddress.ip_address(host)
            return host
        except ValueError:
            pass
        iface = self.target.query.get("iface")
        if iface:
            from akdctl.transport.dcp import resolve_station

            return resolve_station(host, iface, timeout=self.options.timeout)
        return host

    def _client(self) -> RpcClient:
        if self.rpc is None:
            obj = pnio.object_uuid(self.vendor_id, self.device_id, self.instance)
            self.rpc = RpcClient(self._host(), self.target.port or pnio.PNIO_PORT, self.options, obj, self.label)
        return self.rpc

    def open(self) -> None:
        try:
            self.connect()
            self.record_link = PnioRecordLink(self)
        except BaseException:
            self.close()
            raise

    def connect(self) -> None:
        """Establish the Device Access AR."""
        rpc = self._client()
        ar_uuid = uuid.uuid4()
        name = b"akdctl-" + socket.gethostname().encode("ascii", "replace")[:32].lower().replace(b"_", b"-")
        req = pnio.ARBlockReq(pnio.AR_TYPE_IOSAR, ar_uuid, self.session_key, _local_mac(),
                              pnio.object_uuid(0, 0, 0), pnio.DEVICE_ACCESS_PROPERTIES, self.timeout_factor,
                              name.replace(b".", b"-"))
        with self.lock:
            status, blocks = rpc.call(pnio.OP_CONNECT, req.encode())
            if not status.ok:
                if status.code == 0xDB and status.decode == 0x81 and status.code1 == 0x01 and status.code2 in (4, 9):
                    raise RecordError(
                        f"{self.label}: device refuses device-access AR ({pnio_status_text(*status.encode())}); the device does not "
                        "allow a supervisor/device-access connection, which cannot be changed from akdctl",
                        code=status.value)
                if (status.code, status.decode, status.code1, status.code2) == pnio.OUT_OF_AR_RESOURCES:
                    from akdctl.catalog.texts import PN_OUT_OF_ARS_HINT

                    raise RecordError(f"{self.label}: device refuses the connection, out of AR resources "
                                      f"({status.hex()}): {PN_OUT_OF_ARS_HINT}", code=status.value)
                raise RecordError(f"{self.label}: device refuses the connection: {pnio_status_text(*status.encode())}",
                                  code=status.value)
            try:
                res = pnio.ARBlockRes.decode(blocks)
            except CodecError as exc:
                raise MalformedReply(f"{self.label}: malformed Connect response: {exc}") from None
            if res.ar_uuid != ar_uuid:
                raise MalformedReply(f"{self.label}: Connect response names AR {res.ar_uuid}, we asked for {ar_uuid}")
            self.ar_uuid = ar_uuid
            self._record_calls()  # the parameter record's datagrams for this AR: the first request is a usual one
            self._last_activity = time.monotonic()
        self._stop.clear()
        self._keepalive = threading.Thread(target=self._keepalive_loop, name="pn-keepalive", daemon=True)
        self._keepalive.start()

    def _keepalive_loop(self) -> None:
        """Read index 0xFBFF whenever the AR has been idle for a third of its activity timeout."""
        period = self.timeout_factor * 0.1 / 3
        while not self._stop.wait(min(period / 4, 1.0)):
            if time.monotonic() - self._last_activity < period:
                continue
            if not self.lock.acquire(timeout=0.1):
                continue
            try:
                if self.ar_uuid is not None and not self._stop.is_set():
                    # its own deadline: this thread must not share the command's Budget
                    self._read(pnio.RecordAddress(self.address.api, self.address.slot, self.address.subslot,
                                                  pnio.INDEX_KEEPALIVE), 0,
                               deadline=Deadline(min(self.options.timeout, 1.0), 2))
            except (CommError, RecordError, OSError):
                pass    # the next real request reports the problem in words
            finally:
                self.lock.release()

    def close(self) -> None:
        """Stop the keep-alive and release the AR (best effort, bounded wait); safe to call twice."""
        self._stop.set()
        if self._keepalive is not None and self._keepalive is not threading.current_thread():
            self._keepalive.join(timeout=2)
        self._keepalive = None
        rpc, ar = self.rpc, self.ar_uuid
        self.ar_uuid = None
        self._calls = None
        if rpc is not None and ar is not None:
            try:
                budget = self.options.budget
                rpc.call(pnio.OP_RELEASE, pnio.ReleaseBlock(ar, self.session_key).encode(),
                         Deadline(min(budget.left(), 1.0), budget.attempts))
            except (CommError, OSError):
                pass    # the device ends the AR by its activity timeout anyway
        if rpc is not None:
            rpc.close()
        self.rpc = None
        self.record_link = None

    # ------------------------------------------------------------- records
    def _next_rw_seq(self) -> int:
        self._rw_seq = (self._rw_seq + 1) & 0xFFFF
        return self._rw_seq

    def _need_ar(self) -> uuid.UUID:
        if self.ar_uuid is None or self.rpc is None:
            raise CommError(f"{self.label}: not connected (no application relation)")
        return self.ar_uuid

    def write_record(self, data: bytes, deadline: Deadline | None = None) -> RecordReply:
        """Write ``data`` to the parameter record; returns (status, b'') and raises on refusals other than busy."""
        if deadline is None:
            with self.options.budget.request() as own:
                return self.write_record(data, own)
        calls = self._calls or self._record_calls()  # (made for an AR: raises "not connected" without one)
        rpc = self._need_rpc()
        self._rw_seq = rw_seq = (self._rw_seq + 1) & 0xFFFF
        return self._write_outcome(rpc.exchange(calls.write(rpc.next_sequence(), rw_seq, data), pnio.OP_WRITE,
                                                deadline))

    def _write_outcome(self, reply: RecordReply) -> RecordReply:
        """What a Write call's answer (PNIOStatus, blocks) means: (status, b''), busy included; raises on a refusal."""
        status, blocks = reply
        if status is pnio.OK and blocks:  # (the usual answer: its IODWriteResHeader holds the write's own status)
            try:
                status = pnio.write_response(blocks)[2]
            except CodecError as exc:
                raise MalformedReply(f"{self.label}: malformed Write response: {exc}") from None
            if status is pnio.OK:
                return status, b""
        if status.ok and blocks:
            try:
                status = pnio.write_response(blocks)[2]
            except CodecError as exc:
                raise MalformedReply(f"{self.label}: malformed Write response: {exc}") from None
        if not status.ok and not status.busy:
            raise RecordError(f"{self.label}: write record {self.address.describe()} refused: {pnio_status_text(*status.encode())}",
                              code=status.value)
        return status, b""

    def read_record(self, deadline: Deadline | None = None) -> RecordReply:
        """Read the parameter record (up to MAX_RECORD bytes): (status, data); b'' while the device is busy."""
        if deadline is None:
            with self.options.budget.request() as own:
                return self.read_record(own)
        calls = self._calls or self._record_calls()
        rpc = self._need_rpc()
        self._rw_seq = seq = (self._rw_seq + 1) & 0xFFFF
        status, blocks = rpc.exchange(calls.read(rpc.next_sequence(), seq), pnio.OP_READ, deadline)
        if status is pnio.OK:  # the usual answer: the record's data after its header, for our index and sequence
            try:
                got_seq, got_index, data = pnio.read_response(blocks)
            except CodecError:
                got_seq = -1
            if got_seq == seq and got_index == self.address.index:
                return status, data
        return self._read_reply(self.address, seq, status, blocks)

    def quick_exchange(self, request: bytes, at: float) -> "bytes | Step":
        """Write record ``request``, then read record, for a request that ends at ``at``: the record's data when both
        calls got the usual answer at once (an OK write; an OK read of our record and sequence); else the
        :class:`Step` where the request stands, for the general path (:meth:`PnioRecordLink._exchange`) to go on
        from - with the same datagrams, sequence numbers and time, so every outcome is the general path's.

        Why: this is a PNU read, and its usual course is two datagrams out and two back (issue 29, row pn). Only
        without tracing and with an AR (the link checks both); raises what the calls raise for a failed send or
        receive.
        """
        rpc, calls = self.rpc, self._calls
        assert rpc is not None and calls is not None
        attempts = self.options.budget.attempts
        sock, stream, buffer, monotonic = rpc.sock, rpc.stream, rpc._buffer, time.monotonic
        self._rw_seq = rw_seq = (self._rw_seq + 1) & 0xFFFF
        rpc.sequence = sequence = (rpc.sequence + 1) & 0xFFFFFFFF
        datagram = calls.write(sequence, rw_seq, request)
        read_seq = -1  # the Write call first, then the Read call with its own record sequence number
        while True:  # each call's first attempt as RpcClient.exchange makes it: send, then wait for its share
            try:
                sock.send(datagram)
            except OSError as exc:
                rpc._send_failed(exc, pnio.OP_READ if read_seq >= 0 else pnio.OP_WRITE)  # raises unless unreachable
                return Step(read_seq, datagram, Begun(monotonic(), None))
            now = monotonic()
            wait = (at - now) / attempts if at > now else 0.0
            if wait <= 0:
                return Step(read_seq, datagram, Begun(now, None))
            try:
                size = stream.recv_into(now + wait, buffer)
            except OSError as exc:
                raise rpc._receive_failed(exc, pnio.OP_READ if read_seq >= 0 else pnio.OP_WRITE) from None
            if size is None:
                return Step(read_seq, datagram, Begun(now, None))
            if read_seq < 0:  # (each answer is read in the receive buffer: copied only for the general path)
                if not calls.written(buffer, size, sequence):
                    return Step(-1, datagram, Begun(now, buffer[:size]))
                self._rw_seq = read_seq = (rw_seq + 1) & 0xFFFF
                rpc.sequence = sequence = (sequence + 1) & 0xFFFFFFFF
                datagram = calls.read(sequence, read_seq)
                continue
            record = calls.read_data(buffer, size, sequence, read_seq)
            if record is None:
                return Step(read_seq, datagram, Begun(now, buffer[:size]))
            self._last_activity = now
            return record

    def _record_calls(self) -> RecordCalls:
        """The parameter record's Write and Read datagrams for this AR, encoded once (``protocol/pnio_call.py``)."""
        ar = self._need_ar()
        rpc = self._need_rpc()
        self._calls = RecordCalls(rpc.template, ar.bytes, self.address, MAX_RECORD, rpc.activity)
        return self._calls

    def _need_rpc(self) -> RpcClient:
        if self.rpc is None:
            raise CommError(f"{self.label}: not connected")
        return self.rpc

    def _read(self, address: pnio.RecordAddress, length: int, implicit: bool = False,
              deadline: Deadline | None = None) -> RecordReply:
        ar = pnio.NIL_UUID if implicit else self._need_ar()
        seq = self._next_rw_seq()
        status, blocks = self._client().call(pnio.OP_READ_IMPLICIT if implicit else pnio.OP_READ,
                                             pnio.read_request(seq, ar.bytes, address, length), deadline)
        if not implicit:
            self._last_activity = time.monotonic()
        return self._read_reply(address, seq, status, blocks)

    def _read_reply(self, address: pnio.RecordAddress, seq: int, status: pnio.PnioStatus, blocks: bytes) -> RecordReply:
        if not status.ok:
            if status.busy:
                return status, b""
            raise RecordError(f"{self.label}: read record {address.describe()} refused: {pnio_status_text(*status.encode())}",
                              code=status.value)
        try:
            got_seq, got_index, data = pnio.read_response(blocks)
        except CodecError as exc:
            raise MalformedReply(f"{self.label}: malformed Read response: {exc}") from None
        if got_index != address.index or got_seq != seq:
            raise MalformedReply(f"{self.label}: Read response for index 0x{got_index:X} seq "
                                 f"{got_seq}, asked index 0x{address.index:X} seq {seq}")
        return status, data

    def read_im0(self) -> dict[str, object]:
        """I&M0 of the device in JSON-friendly form (for ``akdctl info``)."""
        return self.read_im0_record().to_json()

    def read_im0_record(self) -> pnio.IM0:
        """I&M0 of the device (Read Implicit: works without, and beside, an AR)."""
        with self.lock:
            _, data = self._read(pnio.RecordAddress(0, 0, 1, pnio.INDEX_IM0), 0xFFFF, implicit=True)
        try:
            return pnio.IM0.decode(data)
        except CodecError as exc:
            raise MalformedReply(f"{self.label}: malformed I&M0 record: {exc}") from None



def _opname(opnum: int) -> str:
    """"Write", "Read": an operation named in a message or trace note (built only when one is needed)."""
    return pnio.OPNUM_NAMES.get(opnum, f"opnum {opnum}")


def _local_mac() -> bytes:
    """Our MAC for the ARBlockReq's CM initiator field (informational; zeros if unknown)."""
    try:
        node = uuid.getnode()
    except Exception:  # noqa: BLE001
        return bytes(6)
    return node.to_bytes(6, "big") if not (node >> 40) & 1 else bytes(6)


__all__ = ["ProfinetTransport", "PnioRecordLink", "RpcClient"]


def _unknown_outcome(exc: NoAnswer, request: bytes) -> UnknownOutcome:
    """A change request whose answer never came: the drive may have applied it (issue 23.22).

    Why not "no answer": the write record carried the change, and a late or lost reply says nothing about whether
    the drive applied it (a reply 20 ms after the deadline means it did). The PNIO layer has already repeated the
    datagram as often as the budget allowed (the device answers a repeat from its cache, never applying it twice);
    akdctl does not send the change again. The user reads the parameters back before repeating.
    """
    from akdctl.protocol import bmp

    try:
        pnus = sorted({a.pnu for a in bmp.decode_request(request).addresses})
    except bmp.BmpError:
        pnus = []
    check = f"'akdctl pnu get {' '.join(str(p) for p in pnus)}'" if pnus else "'akdctl pnu get'"
    error = UnknownOutcome(f"{exc.message}: unknown outcome, the drive may or may not have applied the change; "
                           f"akdctl does not send it twice: check with {check} before repeating",
                           code=exc.code, details=exc.details)
    error.unanswered = True  # type: ignore[attr-defined]  # how links.Budget counts it
    return error
