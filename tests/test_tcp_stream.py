"""transport/tcp_stream.py (issue 29): a bounded receive that costs one system call -- nothing within the wait is
None, a closed peer is b"", and the socket's receive timeout follows the wait asked for, re-set only when the wait
moves by more than the slack."""

from __future__ import annotations

import socket
import struct
import sys
import time

import pytest

from akdctl.transport import tcp_stream
from akdctl.transport.tcp_stream import TcpStream


@pytest.fixture
def pair() -> tuple[TcpStream, socket.socket]:
    listener = socket.create_server(("127.0.0.1", 0))
    stream = TcpStream.connect("127.0.0.1", listener.getsockname()[1], 2.0)
    peer, _ = listener.accept()
    listener.close()
    yield stream, peer
    stream.close()
    peer.close()


def _set_wait(stream: TcpStream) -> float:
    """The receive timeout the socket holds now (seconds)."""
    if sys.platform.startswith("linux"):
        sec, usec = struct.unpack("@ll", stream.sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, 16))
        return sec + usec / 1e6
    timeout = stream.sock.gettimeout()
    assert timeout is not None
    return timeout


def _in(seconds: float) -> float:
    return time.monotonic() + seconds


def test_nothing_within_the_wait_is_none_and_a_close_is_empty(pair: tuple[TcpStream, socket.socket]) -> None:
    stream, peer = pair
    assert stream.recv(_in(0.05)) is None
    peer.sendall(b"0\r\n-->")
    assert stream.request(b"DRV.OPMODE\r\n", _in(1.0)) == b"0\r\n-->"
    assert peer.recv(100) == b"DRV.OPMODE\r\n"
    peer.close()
    assert stream.recv(_in(1.0)) == b""


def test_a_silent_peer_is_given_up_on_at_the_deadline_not_before_nor_much_after(
        pair: tuple[TcpStream, socket.socket]) -> None:
    stream, _ = pair
    for wait in (0.3, 0.3, 0.05):   # the second wait keeps the timeout the first set (within the slack)
        at = _in(wait)
        assert stream.recv(at) is None
        # never before the deadline (a kernel timeout set early is finished with Python's exact one); how
        # late is the scheduler's business and not asserted
        assert time.monotonic() >= at


def test_the_receive_timeout_is_reset_only_when_the_wait_moves(pair: tuple[TcpStream, socket.socket]) -> None:
    stream, peer = pair
    # the kernel keeps the timeout in clock ticks (4 ms at HZ=250): compared within a tick
    peer.sendall(b"a")
    assert stream.recv(_in(0.5)) == b"a"   # sets the wait, ending early enough for the kernel's late timers
    first = _set_wait(stream)
    assert first == pytest.approx(tcp_stream.early(0.5) - tcp_stream.SLACK / 2, abs=0.005)
    assert first < 0.5
    peer.sendall(b"b")
    assert stream.recv(_in(0.45)) == b"b"   # beyond the slack: the new wait
    assert _set_wait(stream) == pytest.approx(tcp_stream.early(0.45) - tcp_stream.SLACK / 2, abs=0.005)
    second = _set_wait(stream)
    peer.sendall(b"c")
    assert stream.recv(_in(0.45 - 0.001)) == b"c"   # within the slack: the socket is left alone
    assert _set_wait(stream) == second
    assert stream.recv(_in(0.0001)) is None   # never "forever" (a zero timeout): a last look at what is there
