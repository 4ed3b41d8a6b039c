"""akdctl's own Modbus TCP client (issue 29): the codec against the specification's example, malformed replies as
CodecError only, and the link over a real loopback socket -- a late reply to an earlier request is skipped by its
transaction identifier, a reply split into segments is put together, an exception reply is a ModbusRefused."""

from __future__ import annotations

import random
import socket
import threading
from collections.abc import Callable

import pytest

from akdctl.errors import MalformedReply, ModbusRefused, NoAnswer
from akdctl.protocol import modbus as codec
from akdctl.protocol.errors import CodecError
from akdctl.transport.base import LinkOptions
from akdctl.transport.modbus import ModbusLink
from akdctl.transport.tcp_stream import TcpStream


def test_read_holding_registers_as_the_specification_shows() -> None:
    # Modbus Application Protocol v1.1b3, 6.3: registers 108..110, reply 0x022B, 0x0000, 0x0064
    adu = codec.pack_read_holding(0x1234, 1, 107, 3)
    assert adu == bytes.fromhex("1234 0000 0006 01" "03 006B 0003")
    reply = bytes.fromhex("1234 0000 0009 01" "03 06 022B 0000 0064")
    assert codec.unpack_read_reply(reply, 1, 3) == (None, [0x022B, 0, 0x64])
    assert codec.unpack_reply(reply, 1, 3) == (None, bytes.fromhex("06 022B 0000 0064"))
    assert codec.unpack_read_reply(bytes.fromhex("1234 0000 0003 01 83 02"), 1, 3) == (2, [])


def test_write_multiple_registers_as_the_specification_shows() -> None:
    # 6.12: registers 2..3 := 0x000A, 0x0102
    adu = codec.pack_write_multiple(1, 1, 1, [0x000A, 0x0102])
    assert adu == bytes.fromhex("0001 0000 000B 01" "10 0001 0002 04 000A 0102")
    exception, data = codec.unpack_reply(bytes.fromhex("0001 0000 0006 01 10 0001 0002"), 1, 16)
    assert exception is None
    codec.check_write_multiple(data, 1, 2)
    with pytest.raises(CodecError):
        codec.check_write_multiple(data, 1, 3)


@pytest.mark.parametrize("address,count", [(0, 0), (0, 126), (-1, 1), (65535, 2), (70000, 1)])
def test_requests_outside_the_protocol_are_refused(address: int, count: int) -> None:
    with pytest.raises(CodecError):
        codec.pack_read_holding(1, 1, address, count)


def test_malformed_replies_raise_codec_errors_only() -> None:
    rng = random.Random(29)
    good = bytes.fromhex("0001 0000 0007 01 03 04 0000 0834")
    for _ in range(3000):
        data = bytearray(good[:rng.randrange(0, len(good) + 3)])
        for _ in range(rng.randrange(0, 3)):
            if data:
                data[rng.randrange(len(data))] = rng.randrange(256)
        try:
            codec.unpack_read_reply(bytes(data), 1, 2)
            codec.adu_size(bytes(data))
        except CodecError:
            pass


class Server:
    """One loopback connection answering each request with ``answer(request) -> list of segments``."""

    def __init__(self, answer: Callable[[bytes], list[bytes]]) -> None:
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.answer = answer
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        conn, _ = self.listener.accept()
        conn.settimeout(5)
        with conn:
            try:
                while True:
                    request = conn.recv(260)
                    if not request:
                        return
                    for segment in self.answer(request):
                        conn.sendall(segment)
            except OSError:
                return

    def link(self, timeout: float = 1.0) -> ModbusLink:
        stream = TcpStream.connect("127.0.0.1", self.port, timeout)
        return ModbusLink(stream, 1, LinkOptions(timeout=timeout), f"mb://127.0.0.1:{self.port}")

    def close(self) -> None:
        self.listener.close()


def _reply(request: bytes, words: list[int], transaction: int | None = None) -> bytes:
    tid = request[:2] if transaction is None else transaction.to_bytes(2, "big")
    body = bytes([3, 2 * len(words)]) + b"".join(w.to_bytes(2, "big") for w in words)
    return tid + b"\0\0" + (len(body) + 1).to_bytes(2, "big") + b"\x01" + body


def test_a_late_reply_to_an_earlier_request_is_skipped() -> None:
    server = Server(lambda req: [_reply(req, [9, 9], transaction=int.from_bytes(req[:2], "big") - 1) + _reply(req, [1, 2])])
    link = server.link()
    try:
        assert link.read_registers(20, 2) == [1, 2]
        assert link.read_registers(20, 2) == [1, 2]
    finally:
        link.close()
        server.close()


def test_a_reply_in_segments_is_put_together() -> None:
    def split(req: bytes) -> list[bytes]:
        whole = _reply(req, [0x1234, 0x5678])
        return [whole[:3], whole[3:9], whole[9:]]

    server = Server(split)
    link = server.link()
    try:
        for _ in range(5):
            assert link.read_registers(0, 2) == [0x1234, 0x5678]
    finally:
        link.close()
        server.close()


def test_an_exception_reply_and_a_wrong_reply() -> None:
    replies = iter([lambda req: req[:2] + bytes.fromhex("0000 0003 01 83 02"),
                    lambda req: req[:2] + bytes.fromhex("0000 0003 01 04 00")])
    server = Server(lambda req: [next(replies)(req)])
    link = server.link()
    try:
        with pytest.raises(ModbusRefused, match="illegal data address"):
            link.read_registers(4, 2)
        with pytest.raises(MalformedReply):
            link.read_registers(4, 2)
    finally:
        link.close()
        server.close()


def test_silence_ends_within_the_timeout() -> None:
    server = Server(lambda req: [])
    link = server.link(timeout=0.3)
    try:
        with pytest.raises(NoAnswer, match="no answer to reading registers 20..21"):
            link.read_registers(20, 2)
    finally:
        link.close()
        server.close()
