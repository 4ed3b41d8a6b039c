"""What ``-v`` adds on every command, in one place: the link, the requests made, the timings.

Why here and not in each command: ``-v`` used to change nothing on most commands (issue 14). Everything it needs
is already collected once per invocation — the target and where it came from (:class:`AppContext`), and every
frame on every link in the session's tracer (``transport/trace.py``, the same records ``--trace`` prints and a
support bundle keeps). So ``-v`` prints, on stderr:

* when the command first reaches for the drive: the target, where it came from, the transport and the timeout;
* when the command ends: the frames per layer (requests → replies), the time spent waiting on the link, and the
  whole command's time; with ``-vv`` also one line per exchange (layer, bytes out, bytes back, round trip).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


def link_line(target: Any, timeout: float) -> str:
    """``akdctl: target sim (default) via the built-in simulated AKD ..., timeout 2 s``."""
    from akdctl.transport.registry import BUILTIN

    spec = BUILTIN.get(target.scheme)
    via = f" via {spec.summary}" if spec is not None else ""
    return f"akdctl: target {target.display} (from {target.source}){via}, timeout {timeout:g} s"


@dataclass
class Exchange:
    """One request on one layer and what came back for it."""

    layer: str
    sent: int
    started: float
    received: int = 0
    rtt_s: float | None = None


def exchanges(records: list[Any]) -> list[Exchange]:
    """Each sent frame with the frames of its layer that come back before that layer's next request."""
    out: list[Exchange] = []
    pending: dict[str, Exchange] = {}
    for record in records:
        if record.direction == "tx":
            pending[record.layer] = Exchange(record.layer, len(record.data), record.time)
            out.append(pending[record.layer])
        elif record.layer in pending:
            exchange = pending[record.layer]
            if exchange.rtt_s is None:
                exchange.rtt_s = record.time - exchange.started
            exchange.received += len(record.data)
    return out


def summary_lines(records: list[Any], elapsed_s: float, level: int, contacted: bool) -> list[str]:
    """The end-of-command lines for ``-v`` (level 1) and ``-vv`` (level 2)."""
    lines = []
    done = exchanges(records)
    if level >= 2:
        for e in done:
            back = f"<- {e.received} B in {e.rtt_s * 1000:.1f} ms" if e.rtt_s is not None else "<- no reply"
            lines.append(f"akdctl: {e.layer:8s} -> {e.sent} B  {back}")
    if done:
        per_layer: dict[str, list[int]] = {}
        for e in done:
            counts = per_layer.setdefault(e.layer, [0, 0])
            counts[0] += 1
            counts[1] += 1 if e.received else 0
        layers = ", ".join(f"{layer} {n} -> {answered}" for layer, (n, answered) in per_layer.items())
        waited = sum(e.rtt_s for e in done if e.rtt_s is not None)
        lines.append(f"akdctl: requests (sent -> answered): {layers}; {waited * 1000:.1f} ms waiting on the link")
    elif contacted:
        lines.append("akdctl: no frame recorded on the link")
    else:
        lines.append("akdctl: no drive contacted")
    lines.append(f"akdctl: done in {elapsed_s * 1000:.0f} ms")
    return lines
