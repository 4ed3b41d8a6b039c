"""Frame tracing: one place where every request and reply byte is seen.

Transports call :meth:`Tracer.frame` for each frame they send or receive (the
simulated drive included), so ``--trace`` hex dumps, ``--pcap`` captures and the
support bundle's session trace all come from the same records. Sinks (such as
a pcap writer) subscribe with :meth:`Tracer.add_sink`.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from typing import Callable, Literal, TextIO

Direction = Literal["tx", "rx"]


@dataclass(frozen=True)
class TraceRecord:
    """One frame as it crossed the link.

    ``layer`` names the wire format of ``data`` (``"bmp"`` PROFIdrive parameter
    request/response, ``"mailbox"`` EtherCAT mailbox, ``"pnio-rpc"`` DCE/RPC
    datagram, ``"ecat"`` EtherCAT frame, ``"can"`` CAN frame). ``meta`` carries
    addresses for capture sinks, e.g. ``{"proto": "udp", "src": (ip, port),
    "dst": (ip, port)}`` or ``{"proto": "ethernet", "ethertype": 0x88A4}``.
    """

    time: float
    direction: Direction
    layer: str
    data: bytes
    note: str = ""
    meta: dict[str, object] = field(default_factory=dict)

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

    Keeping records costs little (sessions are short) and lets the support
    bundle include the session's trace even without ``--trace``.
    """

    def __init__(self, enabled: bool = False, stream: TextIO | None = None, keep: int = 10000) -> None:
        self.enabled = enabled
        self.stream = stream
        self.keep = keep
        self.records: list[TraceRecord] = []
        self._sinks: list[Callable[[TraceRecord], None]] = []

    def add_sink(self, sink: Callable[[TraceRecord], None]) -> None:
        self._sinks.append(sink)

    def frame(
        self,
        direction: Direction,
        layer: str,
        data: bytes,
        *,
        note: str = "",
        meta: dict[str, object] | None = None,
    ) -> None:
        record = TraceRecord(time.time(), direction, layer, bytes(data), note, dict(meta or {}))
        if len(self.records) < self.keep:
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
