"""transport/tcp_stream.DatagramSocket.exchange (issue 29, row client-cpu): ecat-udp://'s request in one call, through
the descriptor while the kernel bounds the socket and through the socket's own calls under Python's timeout. Both
ways send the same datagram, return the first datagram back (one each, never joined), None by the deadline, a
refusal as ConnectionRefusedError, a failed send as SendFailed, and fail on a closed socket instead of writing to a
descriptor number that may be reused."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import pytest

from akdctl.transport.tcp_stream import MIN_WAIT, DatagramSocket, SendFailed
from tests.harness import closed_udp_port


@pytest.fixture
def pair() -> Iterator[tuple[DatagramSocket, socket.socket]]:
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    peer.bind(("127.0.0.1", 0))
    peer.settimeout(2)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.connect(peer.getsockname())
    stream = DatagramSocket(sock, 2.0)
    yield stream, peer
    stream.close()
    peer.close()


# the kernel-bounded way (a wait of seconds) and Python's polled timeout (a wait too short for the kernel's)
WAITS = [0.5, MIN_WAIT / 2]


@pytest.mark.parametrize("wait", WAITS)
def test_one_datagram_out_and_the_first_one_back(pair: tuple[DatagramSocket, socket.socket], wait: float) -> None:
    stream, peer = pair
    local = stream.sock.getsockname()
    peer.sendto(b"first", local)
    peer.sendto(b"second", local)   # queued before the request: the first comes back alone, the second stays
    time.sleep(0.05)
    assert stream.exchange(b"request", time.monotonic() + wait) == b"first"
    assert peer.recv(100) == b"request"
    assert stream.exchange(b"again", time.monotonic() + wait) == b"second"
    assert peer.recv(100) == b"again"


@pytest.mark.parametrize("wait", WAITS)
def test_silence_is_none_by_the_deadline(pair: tuple[DatagramSocket, socket.socket], wait: float) -> None:
    stream, peer = pair
    start = time.monotonic()
    assert stream.exchange(b"request", start + wait) is None
    assert time.monotonic() - start < wait + 1.0   # bounded (no hang); the precise end is tcp_stream's own test
    assert peer.recv(100) == b"request"


def test_a_closed_port_is_a_refusal_not_a_send_failure() -> None:
    with closed_udp_port() as port:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.connect(("127.0.0.1", port))
        stream = DatagramSocket(sock, 1.0)
        try:
            with pytest.raises(ConnectionRefusedError):
                for _ in range(3):   # the ICMP answer to the first datagram fails the receive or the next send
                    stream.exchange(b"request", time.monotonic() + 0.5)
        finally:
            stream.close()


def test_a_send_that_fails_is_send_failed(pair: tuple[DatagramSocket, socket.socket]) -> None:
    stream, _peer = pair
    with pytest.raises(SendFailed) as caught:
        stream.exchange(b"x" * 70000, time.monotonic() + 0.5)   # larger than any UDP datagram: EMSGSIZE
    assert caught.value.strerror


def test_a_closed_socket_fails_and_writes_nothing(pair: tuple[DatagramSocket, socket.socket]) -> None:
    stream, peer = pair
    stream.close()
    with pytest.raises(OSError):
        stream.exchange(b"request", time.monotonic() + 0.5)
    peer.settimeout(0.1)
    with pytest.raises(TimeoutError):
        peer.recv(100)


def test_a_lone_requests_wait_is_remembered_and_forgotten_on_a_new_bound(pair: tuple[DatagramSocket, socket.socket],
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """BoundedSocket._arm (the rule TcpStream.request keeps too): once the timeout set suits a wait, a request with
    that wait reads no clock and sets no timeout; a receive that needs another bound makes it check again."""
    from akdctl.transport import tcp_stream

    stream, peer = pair
    local = stream.sock.getsockname()
    reads = []
    real = tcp_stream._monotonic
    monkeypatch.setattr(tcp_stream, "_monotonic", lambda: reads.append(1) or real())

    def request(wait: float) -> bytes | None:
        peer.sendto(b"answer", local)
        time.sleep(0.01)
        return stream.exchange(b"request", real() + wait, 4096, wait)

    assert request(1.0) == b"answer" and reads   # the first: the clock read, the timeout set, the wait remembered
    reads.clear()
    assert request(1.0) == b"answer" and not reads   # remembered: no clock read
    assert stream.recv(real() + 0.2, 100) is None   # another wait: a new bound
    reads.clear()
    assert request(1.0) == b"answer" and reads   # checked again
    for _ in range(3):
        peer.recv(100)
