"""Frame tracing: one place where every request and reply byte is seen.

One :class:`Tracer` per session receives every frame, so ``--trace`` hex dumps,
``--pcap`` captures and the support bundle's session trace all come from the
same records. Sinks (such as a pcap writer) subscribe with :meth:`Tracer.add_sink`.

Who calls it, once per layer:

* the protocol layer the channels speak (``bmp`` PROFIdrive blocks, ``mailbox``
  EtherCAT mailboxes) is traced by :class:`TracedRecordLink` /
  :class:`TracedMailboxLink`, the one wrapper :class:`akdctl.connection.Connection`
  puts around every link -- channels and links never trace these;
* the wire frames only a transport sees (PNIO DCE/RPC datagrams, raw EtherCAT
  frames, ETG.8200 gateway datagrams, CAN frames) are reported by that transport
  to the same tracer, which the Connection hands it in
  :class:`~akdctl.transport.base.LinkOptions`.
"""

from __future__ import annotations

import sys
import time
from typing import Callable, Literal, TextIO

from akdctl.links import MailboxLink, RecordLink
from akdctl.protocol.record import Record

Direction = Literal["tx", "rx"]


class TraceRecord(Record):
    """One frame as it crossed the link.

    ``layer`` names the wire format of ``data`` (``"bmp"`` PROFIdrive parameter
    request/response, ``"mailbox"`` EtherCAT mailbox, ``"pnio-rpc"`` DCE/RPC
    datagram, ``"ecat"`` EtherCAT frame, ``"can"`` CAN frame). ``meta`` carries
    addresses for capture sinks, e.g. ``{"proto": "udp", "src": (ip, port),
    "dst": (ip, port)}`` or ``{"proto": "ethernet", "ethertype": 0x88A4}``.
    """

    __slots__ = ("time", "direction", "layer", "data", "note", "meta")
    __hash__ = None  # type: ignore[assignment]

    def __init__(self, time: float, direction: Direction, layer: str, data: bytes, note: str = "",
                 meta: dict[str, object] | None = None) -> None:
        self.time = time
        self.direction = direction
        self.layer = layer
        self.data = data
        self.note = note
        self.meta: dict[str, object] = {} if meta is None else meta

    def to_json(self) -> dict[str, object]:
        return {
            "time": round(self.time, 6),
            "direction": self.direction,
            "layer": self.layer,
            "hex": self.data.hex(" "),
            **({"note": self.note} if self.note else {}),
        }


class Tracer:
    """Collects frames; prints them when enabled; forwards them to sinks.

    ``record`` keeps the records (up to ``keep``) for whoever reads ``records``
    afterwards -- the support bundle switches it on for its session. Tracing
    costs nothing when nobody looks: :attr:`active` is False without ``--trace``,
    a sink or ``record``, and every caller checks it before it builds a note or
    a record for a frame.
    """

    def __init__(self, enabled: bool = False, stream: TextIO | None = None, keep: int = 10000,
                 record: bool = True) -> None:
        self.enabled = enabled
        self.stream = stream
        self.keep = keep
        self.records: list[TraceRecord] = []
        self._record = record
        self._sinks: list[Callable[[TraceRecord], None]] = []
        self._closers: list[Callable[[], None]] = []
        self.active = False
        self._update()

    def _update(self) -> None:
        self.active = bool(self.enabled or self._sinks or (self._record and self.keep > 0))

    @property
    def record(self) -> bool:
        """Whether frames are kept in ``records`` (the support bundle reads them)."""
        return self._record

    @record.setter
    def record(self, value: bool) -> None:
        self._record = value
        self._update()

    def add_sink(self, sink: Callable[[TraceRecord], None], close: Callable[[], None] | None = None) -> None:
        """Forward every record to ``sink``; ``close`` (if given) runs at :meth:`close`."""
        self._sinks.append(sink)
        if close is not None:
            self._closers.append(close)
        self._update()

    def close(self) -> None:
        """Close the sinks (a pcap file is complete after this); safe to call twice."""
        closers, self._closers = self._closers, []
        for close in closers:
            close()

    def frame(
        self,
        direction: Direction,
        layer: str,
        data: bytes,
        *,
        note: str = "",
        meta: dict[str, object] | None = None,
    ) -> None:
        if not self.active:
            return
        record = TraceRecord(time.time(), direction, layer, bytes(data), note, dict(meta or {}))
        if self._record and len(self.records) < self.keep:
            self.records.append(record)
        if self.enabled:
            stream = self.stream or sys.stderr
            arrow = "->" if direction == "tx" else "<-"
            suffix = f"  ({note})" if note else ""
            stream.write(f"trace {arrow} {layer:8s} {len(data):4d} B  {data.hex(' ')}{suffix}\n")
            stream.flush()
        for sink in self._sinks:
            sink(record)


NULL_TRACER = Tracer(enabled=False, keep=0)


class TracedRecordLink(RecordLink):
    """A :class:`RecordLink` that reports each request and response block to the tracer (layer ``bmp``)."""

    def __init__(self, link: RecordLink, tracer: Tracer) -> None:
        self.link = link
        self.tracer = tracer
        self.max_record = link.max_record
        self.axis = link.axis
        self.trace_note = link.trace_note
        self.trace_meta = link.trace_meta  # a capture sink's hint (the sim: no wire)

    def exchange(self, request: bytes) -> bytes:
        tracer = self.tracer
        if not tracer.active:
            return self.link.exchange(request)
        tracer.frame("tx", "bmp", request, note=self.trace_note, meta=self.trace_meta)
        response = self.link.exchange(request)
        if isinstance(response, (bytes, bytearray, memoryview)):
            tracer.frame("rx", "bmp", bytes(response), note=self.trace_note, meta=self.trace_meta)
        return response


class TracedMailboxLink(MailboxLink):
    """A :class:`MailboxLink` that reports each mailbox sent and received to the tracer (layer ``mailbox``)."""

    def __init__(self, link: MailboxLink, tracer: Tracer) -> None:
        self.link = link
        self.tracer = tracer
        self.mailbox_address = link.mailbox_address
        self.trace_note = link.trace_note
        self.trace_meta = link.trace_meta

    @property
    def mailbox_size(self) -> int:  # type: ignore[override]
        return self.link.mailbox_size  # the raw master learns it from the sync managers

    def send(self, mailbox: bytes) -> None:
        if self.tracer.active:
            self.tracer.frame("tx", "mailbox", mailbox, note=self.trace_note, meta=self.trace_meta)
        self.link.send(mailbox)

    def receive(self, timeout: float) -> bytes | None:
        reply = self.link.receive(timeout)
        if reply is not None and self.tracer.active:
            self.tracer.frame("rx", "mailbox", reply, note=self.trace_note, meta=self.trace_meta)
        return reply


def traced_mailbox_link(link: MailboxLink, tracer: Tracer) -> MailboxLink:
    """The link wrapped in the tracer, unless its wire trace already shows each mailbox (no second copy)."""
    return link if link.traced_on_wire else TracedMailboxLink(link, tracer)
