"""ecat-udp://'s gateway link waits through tcp_stream.BoundedSocket (the rule pn:// and the TCP transports wait
by): the reply behind ignored datagrams is found within the wait; past its end, ignored datagrams already queued are
read on only so many (_LATE_LOOKS), so a peer that never stops sending cannot hold a receive; the socket's timeout
is set once for a run of receives, not per datagram. Counts, not timings."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from akdctl.protocol import mailbox as mbx
from akdctl.transport import ethercat_udp
from akdctl.transport.ethercat_udp import GatewayMailboxLink
from akdctl.transport.trace import Tracer

STATION = 1001


@pytest.fixture
def pair() -> Iterator[tuple[socket.socket, GatewayMailboxLink]]:
    server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    server.bind(("127.0.0.1", 0))
    link = GatewayMailboxLink("127.0.0.1", server.getsockname()[1], STATION, Tracer(record=False), timeout=2.0)
    try:
        yield server, link
    finally:
        link.close()
        server.close()


def _datagram(station: int, counter: int) -> bytes:
    return mbx.wrap_gateway(mbx.pack(mbx.MailboxType.COE, bytes(10), station, counter))


def test_the_reply_behind_foreign_and_broken_datagrams_is_taken(pair: tuple[socket.socket, GatewayMailboxLink]) -> None:
    server, link = pair
    to = link.sock.getsockname()  # type: ignore[union-attr]
    for datagram in (_datagram(7, 1), b"\x01", _datagram(8, 2), _datagram(STATION, 3)):
        server.sendto(datagram, to)
    assert link.receive(2.0) == mbx.unwrap_gateway(_datagram(STATION, 3))
    assert link.received == 1


def test_past_its_end_a_receive_reads_only_so_many_ignored_datagrams(pair: tuple[socket.socket, GatewayMailboxLink]
                                                                     ) -> None:
    server, link = pair
    to = link.sock.getsockname()  # type: ignore[union-attr]
    extra = 10
    for n in range(ethercat_udp._LATE_LOOKS + 1 + extra):
        server.sendto(_datagram(7, n % 7 + 1), to)
    server.sendto(_datagram(STATION, 1), to)
    assert link.receive(0) is None  # no time left: the queued foreign ones read up to the cap, then silence
    # what the cap left is still queued, the reply behind it too
    assert link.receive(2.0) == mbx.unwrap_gateway(_datagram(STATION, 1))


def test_one_timeout_serves_a_run_of_receives(pair: tuple[socket.socket, GatewayMailboxLink]) -> None:
    server, link = pair
    to = link.sock.getsockname()  # type: ignore[union-attr]
    calls = []
    real = link.stream.sock

    class Counting:
        def __getattr__(self, name: str) -> object:
            if name in ("settimeout", "setsockopt"):
                calls.append(name)
            return getattr(real, name)

    link.stream.sock = Counting()  # type: ignore[assignment]
    for n in range(20):
        server.sendto(_datagram(STATION, n % 7 + 1), to)
        assert link.receive(1.5) is not None
    assert len(calls) <= 2, calls  # the first receive sets it (switching to the kernel's timeout); the rest keep it
