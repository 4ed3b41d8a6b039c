"""Issue 23.10: a TCP face caps its clients, refuses the excess in its protocol's words, survives EMFILE by
backing off and says so once.

Before, the EtherNet/IP face's accept thread died on EMFILE (the socket stayed open, every later connect timed
out, nothing was logged) and it held one thread per client without a cap.
"""

from __future__ import annotations

import errno
import os
import socket
from pathlib import Path

import pytest

from akdctl.protocol import enip
from akdctl.sim import face_ethernetip, tcp_clients
from akdctl.sim.drive import SimDrive


def _register(sock: socket.socket) -> int:
    """RegisterSession; the encapsulation status of the reply (-1: the connection was closed instead)."""
    sock.sendall(enip.Packet(enip.REGISTER_SESSION, enip.register_session_data(), 0, 0, b"ctx-0001").encode())
    head = b""
    while len(head) < enip.HEADER_SIZE:
        chunk = sock.recv(enip.HEADER_SIZE - len(head))
        if not chunk:
            return -1
        head += chunk
    header = enip.decode_header(head)
    if header.length:
        sock.recv(header.length)
    assert header.context == b"ctx-0001"
    return header.status


def test_the_face_serves_its_cap_and_refuses_one_more_in_enip_words(tmp_path: Path, monkeypatch,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(tcp_clients, "DEFAULT_LIMIT", 3)
    face = face_ethernetip.from_options(SimDrive("default", tmp_path), ethernetip="127.0.0.1:0", eip_io_port=0)
    assert face is not None
    face.start()
    socks = []
    try:
        for _ in range(5):
            sock = socket.create_connection(("127.0.0.1", face.port), timeout=5)
            socks.append(sock)
        statuses = [_register(sock) for sock in socks]
        assert statuses[:3] == [enip.STATUS_SUCCESS] * 3
        assert statuses[3:] == [enip.STATUS_NO_MEMORY] * 2  # "insufficient memory": the protocol's refusal
        socks[0].close()  # one served client leaves: a new one is served
        socks.pop(0)
        for _ in range(50):
            late = socket.create_connection(("127.0.0.1", face.port), timeout=5)
            status = _register(late)
            late.close()
            if status == enip.STATUS_SUCCESS:
                break
        assert status == enip.STATUS_SUCCESS
    finally:
        for sock in socks:
            sock.close()
        face.stop()
    lines = [line for line in capsys.readouterr().err.splitlines() if "too many clients" in line or "refused" in line]
    assert 1 <= len(lines) <= 2, lines  # the first refusal in full, the others counted


class _Listener:
    """A listening socket whose accept() runs out of descriptors ``fail`` times, then accepts."""

    def __init__(self, fail: int) -> None:
        self.fail = fail
        self.real = socket.socket()
        self.real.bind(("127.0.0.1", 0))
        self.real.listen(4)
        self.peer = socket.create_connection(self.real.getsockname(), timeout=5)

    def fileno(self) -> int:
        return self.real.fileno()

    def accept(self) -> tuple[socket.socket, tuple[str, int]]:
        if self.fail:
            self.fail -= 1
            raise OSError(errno.EMFILE, os.strerror(errno.EMFILE))
        return self.real.accept()


def test_emfile_is_survived_by_backing_off_and_said_once(monkeypatch) -> None:
    monkeypatch.setattr(tcp_clients, "BACKOFF_S", (0.001, 0.004))
    said: list[str] = []
    clients = tcp_clients.TcpClients("ethernetip", lambda sock: None, limit=4, write=said.append)
    listener = _Listener(fail=6)
    try:
        results = [clients.accept(listener, wait=1.0) for _ in range(7)]  # type: ignore[arg-type]
    finally:
        listener.peer.close()
        listener.real.close()
    assert results[:6] == [None] * 6 and results[6] is not None
    results[6][0].close()
    assert len([s for s in said if "cannot accept a client (Too many open files); backing off" in s]) == 1
    assert said[-1].endswith("accepting clients again")
    assert clients.active == 1
