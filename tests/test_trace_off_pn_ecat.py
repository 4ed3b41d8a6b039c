"""pn:// and ecat-udp:// cost nothing for tracing when it is off, and their hot paths keep to one deadline per request
and socket timeouts set only when they change (issue 29, item 1).

Counts, not timings: a read over PROFINET and an SDO upload over the ETG.8200 gateway, against ``akdctl sim serve``,
with the session's tracer off - no trace hook is called and no trace record is built; one ``Deadline`` per request;
the socket's timeout set once for the whole run, not per datagram. The same runs with tracing on call the hooks, so
the counts can fail.
"""

from __future__ import annotations

import socket
from collections import Counter
from collections.abc import Iterator

import pytest

from akdctl.connection import Connection, open_tracer
from akdctl.links import Deadline
from akdctl.protocol.bmp import ParameterAddress
from akdctl.transport import trace
from akdctl.transport.base import LinkOptions
from akdctl.transport.profinet import RpcClient
from akdctl.transport.registry import parse_target
from tests.harness import SimServer

pytestmark = pytest.mark.slow

READS = 25


class CountingSocket:
    """A socket that counts ``settimeout`` calls and passes everything else through."""

    def __init__(self, sock: socket.socket, counts: Counter[str]) -> None:
        self._sock = sock
        self._counts = counts

    def settimeout(self, value: float | None) -> None:
        self._counts["settimeout"] += 1
        self._sock.settimeout(value)

    def setsockopt(self, *args: object) -> None:  # the kernel's receive timeout (tcp_stream.BoundedSocket)
        self._counts["settimeout"] += 1
        self._sock.setsockopt(*args)  # type: ignore[arg-type]

    def __getattr__(self, name: str) -> object:
        return getattr(self._sock, name)


@pytest.fixture(scope="module")
def server() -> Iterator[SimServer]:
    with SimServer("--profinet", "127.0.0.1:0", "--ethercat-udp", "127.0.0.1:0", faces=2, duration=120) as srv:
        yield srv


@pytest.fixture
def counts(monkeypatch: pytest.MonkeyPatch) -> Counter[str]:
    counted: Counter[str] = Counter()
    real_frame, real_record, real_deadline = trace.Tracer.frame, trace.TraceRecord.__init__, Deadline.__init__

    def frame(self: trace.Tracer, direction: str, layer: str, *args: object, **kwargs: object) -> None:
        counted[f"frame {layer}"] += 1
        real_frame(self, direction, layer, *args, **kwargs)  # type: ignore[arg-type]

    def record(self: trace.TraceRecord, *args: object, **kwargs: object) -> None:
        counted["trace record"] += 1
        real_record(self, *args, **kwargs)  # type: ignore[arg-type]

    def deadline(self: Deadline, *args: object, **kwargs: object) -> None:
        counted["deadline"] += 1
        real_deadline(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(trace.Tracer, "frame", frame)
    monkeypatch.setattr(trace.TraceRecord, "__init__", record)
    monkeypatch.setattr(Deadline, "__init__", deadline)
    monkeypatch.setattr(RpcClient, "_trace", lambda self, *args: counted.update(["rpc trace"]))
    return counted


def _connection(url: str, tracing: bool) -> Connection:
    return Connection(parse_target(url), LinkOptions(timeout=2.0, tracer=open_tracer(record=tracing)))


def _pn_reads(server: SimServer, counts: Counter[str], tracing: bool) -> None:
    host, port = server.address_of("profinet")
    conn = _connection(f"pn://{host}:{port}", tracing)
    try:
        channel = conn.parameters()
        rpc = conn.transport().rpc  # type: ignore[attr-defined]
        rpc.sock = rpc.stream.sock = CountingSocket(rpc.sock, counts)  # (the stream waits on the same socket)
        addresses = [ParameterAddress(930), ParameterAddress(964, 0, 2)]
        channel.read(addresses)  # the first read plans, and sets the socket's timeout
        counts.clear()
        for _ in range(READS):
            assert len(channel.read(addresses)) == 2
        before = Counter(counts)
    finally:
        conn.close()
    counts.clear()
    counts.update(before)


def _ecat_uploads(server: SimServer, counts: Counter[str], tracing: bool) -> None:
    host, port = server.address_of("ethercat-udp")
    conn = _connection(f"ecat-udp://{host}:{port}/1001", tracing)
    try:
        objects = conn.objects()
        link = conn.transport().mailbox_link
        link.sock = link.stream.sock = CountingSocket(link.sock, counts)  # type: ignore[union-attr]
        objects.upload(0x1018, 1)
        counts.clear()
        for _ in range(READS):
            assert len(objects.upload(0x1018, 1)) == 4
        before = Counter(counts)
    finally:
        conn.close()
    counts.clear()
    counts.update(before)


def test_pn_reads_trace_nothing_when_tracing_is_off(server: SimServer, counts: Counter[str]) -> None:
    _pn_reads(server, counts, tracing=False)
    assert not {key for key in counts if "trace" in key or key.startswith("frame")}, counts
    # At most one per request: both RPCs and every repeat share it; a request whose two calls are answered at once
    # (ProfinetTransport.quick_exchange) needs none, only its end time.
    assert counts["deadline"] <= READS
    assert counts["settimeout"] == 0  # the timeout set by the first read stays


def test_pn_reads_call_the_trace_hooks_when_tracing_is_on(server: SimServer, counts: Counter[str]) -> None:
    _pn_reads(server, counts, tracing=True)
    assert counts["frame bmp"] == 2 * READS and counts["rpc trace"] == 4 * READS


def test_ecat_uploads_trace_nothing_when_tracing_is_off(server: SimServer, counts: Counter[str]) -> None:
    _ecat_uploads(server, counts, tracing=False)
    assert not {key for key in counts if "trace" in key or key.startswith("frame")}, counts
    # At most one per request: an upload answered in its one pass (CoeObjectChannel.upload) needs none, only its
    # end time (Budget.lone); one that goes on in the general path makes one for all its attempts.
    assert counts["deadline"] <= READS
    assert counts["settimeout"] == 0  # the receive timeout set by the first upload stays (tcp_stream.BoundedSocket)


def test_ecat_uploads_call_the_trace_hook_when_tracing_is_on(server: SimServer, counts: Counter[str]) -> None:
    _ecat_uploads(server, counts, tracing=True)
    assert counts["frame ecat-gw"] == 2 * READS and counts["trace record"] == 2 * READS
