"""transport/tcp_stream.py (issue 29): a bounded receive that costs one system call -- nothing within the wait is
None, a closed peer is b"", and the socket's receive timeout follows the wait asked for, re-set only when the wait
moves by more than the slack."""

from __future__ import annotations

import socket
import struct
import sys

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


def test_nothing_within_the_wait_is_none_and_a_close_is_empty(pair: tuple[TcpStream, socket.socket]) -> None:
    stream, peer = pair
    assert stream.recv(0.05) is None
    peer.sendall(b"0\r\n-->")
    assert stream.request(b"DRV.OPMODE\r\n", 1.0) == b"0\r\n-->"
    assert peer.recv(100) == b"DRV.OPMODE\r\n"
    peer.close()
    assert stream.recv(1.0) == b""


def test_the_receive_timeout_is_reset_only_when_the_wait_moves(pair: tuple[TcpStream, socket.socket]) -> None:
    stream, peer = pair
    # the kernel keeps the timeout in clock ticks (4 ms at HZ=250): compared within a tick
    peer.sendall(b"a")
    assert stream.recv(0.5) == b"a"   # sets the wait
    assert _set_wait(stream) == pytest.approx(0.5, abs=0.005)
    peer.sendall(b"b")
    assert stream.recv(0.45) == b"b"   # beyond the slack: the new wait
    assert _set_wait(stream) == pytest.approx(0.45, abs=0.005)
    stream._wait = 0.3   # what was set, as the stream remembers it; a wait within the slack leaves the socket alone
    peer.sendall(b"c")
    assert stream.recv(0.3 - tcp_stream.SLACK * 0.3 / 2) == b"c"
    assert _set_wait(stream) == pytest.approx(0.45, abs=0.005)
    assert stream.recv(0.0001) is None   # never "forever" (a zero SO_RCVTIMEO): at least a millisecond
    assert 0 < _set_wait(stream) <= 0.01
