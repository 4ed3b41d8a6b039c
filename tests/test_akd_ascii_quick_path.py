"""akd://'s quick path (``AsciiLink.command`` with tracing off: one send, one receive holding the whole usual reply)
gives exactly what the general path gives, for the usual replies and for every unusual one (issue 29, row ascii).

How: each scenario runs twice against a scripted drive on a real TCP socket -- once with the session's tracer on
(the general path: every segment traced, the quick path never taken) and once with it off (the quick path first,
handing over to the general path where it stops) -- and the two runs must agree on every answer, every error's
words, the bytes that reached the drive (Telnet refusals included) and how the command's time budget stands
afterwards. Each test also checks how often the quick path ran, so one that silently stopped being taken fails.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from akdctl.errors import AkdError
from akdctl.transport import tcp_stream
from akdctl.transport.akd_ascii import QUICK_READ, AkdAsciiTransport
from akdctl.transport.base import LinkOptions
from akdctl.transport.target import split_target
from akdctl.transport.trace import Tracer

# A reply: the chunks the drive sends (each its own segment: a pause between them), or SILENT / CLOSE.
SILENT, CLOSE = "silent", "close"
Script = Callable[[bytes], "list[bytes] | str"]


class Drive:
    """One TCP connection's scripted drive: ``on_connect`` chunks first, then ``script(line)`` per command line."""

    def __init__(self, script: Script, on_connect: tuple[bytes, ...] = ()) -> None:
        self.script = script
        self.on_connect = on_connect
        self.received = bytearray()
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.done = threading.Event()
        self.connected = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            conn, _ = self.listener.accept()
        except OSError:
            return
        self.connected.set()
        with conn:
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            for chunk in self.on_connect:
                conn.sendall(chunk)
            pending = b""
            conn.settimeout(5.0)
            while not self.done.is_set():
                try:
                    data = conn.recv(4096)
                except OSError:
                    return
                if not data:
                    return
                self.received += data
                pending += data
                while b"\r\n" in pending:
                    line, pending = pending.split(b"\r\n", 1)
                    while line.startswith(b"\xff"):   # the client's Telnet refusals precede its line
                        line = line[3:]
                    reply = self.script(line)
                    if reply == CLOSE:
                        return
                    if reply == SILENT:
                        continue
                    for n, chunk in enumerate(reply):
                        if n:
                            time.sleep(0.02)   # its own segment
                        try:
                            conn.sendall(chunk)
                        except OSError:
                            return  # the client has gone (a reply to its last line, read after it closed)

    def close(self) -> None:
        """After the client closed its end: the thread reads on to the end of the stream, so ``received`` holds every
        byte the client sent however late this thread runs (a loaded host once ended it before it had read the
        last line: one run's bytes differed from the other's); ``done`` and the closed listener end it otherwise."""
        if self.connected.is_set():
            self.thread.join(timeout=6)
        self.done.set()
        self.listener.close()
        self.thread.join(timeout=6)


class Run:
    def __init__(self) -> None:
        self.outcomes: list[object] = []
        self.silent: list[float] = []
        self.received = b""
        self.quick = 0


@pytest.fixture
def count_quick(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls = [0]
    real = tcp_stream.TcpStream.request

    def request(self: tcp_stream.TcpStream, data: bytes, at: float, size: int = 4096,
                wait: float = -2.0) -> bytes | None:
        calls[0] += 1
        return real(self, data, at, size, wait)

    monkeypatch.setattr(tcp_stream.TcpStream, "request", request)
    return calls


def _run(tracing: bool, script: Script, lines: list[str], calls: list[int], on_connect: tuple[bytes, ...] = (),
         timeout: float = 1.0) -> Run:
    drive = Drive(script, on_connect)
    run = Run()
    calls[0] = 0
    try:
        tracer = Tracer() if tracing else Tracer(record=False)
        assert tracer.active is tracing
        transport = AkdAsciiTransport(split_target(f"akd://127.0.0.1:{drive.port}"),
                                      LinkOptions(timeout=timeout, retries=0, tracer=tracer))
        transport.open()
        link = transport.command_link
        assert link is not None
        try:
            for line in lines:
                try:
                    run.outcomes.append(link.command(line))
                except AkdError as exc:
                    run.outcomes.append((type(exc).__name__, exc.message.replace(str(drive.port), "PORT"), exc.code))
                run.silent.append(transport.options.budget.silent)
        finally:
            transport.close()
    finally:
        drive.close()
    run.received = bytes(drive.received)
    run.quick = calls[0]
    return run


def _same(script: Script, lines: list[str], calls: list[int], **kwargs: object) -> Run:
    general = _run(True, script, lines, calls, **kwargs)  # type: ignore[arg-type]
    assert general.quick == 0
    quick = _run(False, script, lines, calls, **kwargs)  # type: ignore[arg-type]
    assert quick.outcomes == general.outcomes
    assert quick.received == general.received
    assert quick.silent == general.silent
    return quick


def _table(replies: dict[bytes, list[bytes] | str]) -> Script:
    return lambda line: replies.get(line, [b"Error: Command was not found.\r\n-->"])


USUAL = {
    b"DRV.OPMODE": [b"2\r\n-->"],
    b"VL.KP 1.5": [b"\r\n-->"],
    b"VL.KP": [b"1.500\r\n-->"],
    b"DRV.INFO": [b"Drive information\r\n-----\r\nModel : AKD\r\n-->"],
    b"PL.FB": [b"1.234 [\xb5s]\r\n-->"],           # Latin-1
    b"DRV.NAME": [b"  padded name \t \r\n-->"],
    b"DRV.TAB": [b"a\tb\r\n-->"],
    b"DRV.CR": [b"one\rtwo\r\n-->"],
}


def test_usual_and_unusual_whole_replies(count_quick: list[int]) -> None:
    lines = ["DRV.OPMODE", "VL.KP 1.5", "VL.KP", "DRV.INFO", "PL.FB", "DRV.NAME", "DRV.TAB", "DRV.CR", "NOPE",
             "  DRV.OPMODE  ", "error"]
    run = _same(_table(USUAL), lines, count_quick)
    assert run.quick == len(lines)
    assert run.outcomes[:3] == ["2", "", "1.500"]
    assert run.outcomes[4] == "1.234 [\xb5s]"
    assert run.outcomes[8][0] == "CommandRefused"  # type: ignore[index]


def test_echo_and_a_reply_that_is_only_the_echo(count_quick: list[int]) -> None:
    def echo(line: bytes) -> list[bytes]:
        reply = {b"DRV.OPMODE": b"2\r\n", b"DRV.EN": b""}.get(line.upper(), b"Error: Command was not found.\r\n")
        return [line + b"\r\n" + reply + b"-->"]

    run = _same(echo, ["DRV.OPMODE", "DRV.EN", "drv.en", "X"], count_quick)
    assert run.outcomes[:3] == ["2", "", ""]
    assert run.quick == 4


def test_segmented_replies(count_quick: list[int]) -> None:
    cuts = {b"A": [b"1", b"2\r\n-->"], b"B": [b"12\r\n", b"-->"], b"C": [b"12\r\n-", b"->"],
            b"D": [b"Err", b"or: no\r\n-->"], b"E": [b"", b"7\r\n-->"]}
    run = _same(_table(cuts), ["A", "B", "C", "D", "E", "A"], count_quick)
    assert run.outcomes[:3] == ["12", "12", "12"] and run.outcomes[3][0] == "CommandRefused"  # type: ignore[index]
    assert run.quick == 6


def test_a_reply_longer_than_the_first_read(count_quick: list[int]) -> None:
    long = b"x" * (QUICK_READ * 3 + 7)
    run = _same(_table({b"L": [long + b"\r\n-->"], b"S": [b"5\r\n-->"]}), ["L", "S", "L"], count_quick)
    assert run.outcomes == [long.decode(), "5", long.decode()]
    assert run.quick == 3


def test_telnet_bytes_in_replies_and_on_connect(count_quick: list[int]) -> None:
    telnet = {b"A": [b"\xff\xfd\x1f1\r\n-->"],                       # an option offer before the value: refused once
              b"B": [b"2\r\n\xff", b"\xfd\x01-->"],                   # an IAC cut by the segment boundary
              b"C": [b"\xff\xfa\x1f\x00\x50", b"\xff\xf03\r\n-->"],  # a subnegotiation across two segments
              b"D": [b"4\xff\xff\r\n-->"],                           # an escaped 255 in the text
              b"E": [b"5\r\n-->\xff"]}                               # a cut IAC after the prompt: kept for later
    run = _same(_table(telnet), ["A", "B", "C", "D", "E", "A", "B"], count_quick,
                on_connect=(b"\xff\xfd\x18\xff\xfb\x01", b"Welcome\r\n-->"))
    assert run.outcomes[:4] == ["1", "2", "3", "4\xff"]
    assert b"\xff\xfc\x1f" in run.received and b"\xff\xfc\x18" in run.received
    assert run.quick == 6   # after E the parser holds a cut IAC: the next command takes the general path


def test_two_replies_in_one_segment(count_quick: list[int]) -> None:
    run = _same(_table({b"A": [b"1\r\n-->2\r\n-->"], b"B": [b"3\r\n-->"]}), ["A", "B", "B", "B"], count_quick)
    # the second prompt answers the next command (the bytes left over: the general path), and every reply after
    # it is one late: what a drive that replied twice makes of a line-oriented channel, either way
    assert run.outcomes == ["1", "2", "3", "3"]
    assert run.quick >= 2


def test_a_silent_drive(count_quick: list[int]) -> None:
    run = _same(_table({b"A": [b"1\r\n-->"], b"Q": SILENT}), ["A", "Q", "A"], count_quick, timeout=0.3)
    assert run.outcomes[0] == "1"
    assert run.outcomes[1][0] == "NoAnswer" and "no prompt" in run.outcomes[1][1]  # type: ignore[index]
    assert run.outcomes[2][0] == "CommError" and "out of step" in run.outcomes[2][1]  # type: ignore[index]
    assert run.quick == 2


def test_a_partial_reply_then_silence(count_quick: list[int]) -> None:
    run = _same(_table({b"A": [b"1\r\n"], b"B": [b"2\r\n-->"]}), ["B", "A", "B"], count_quick, timeout=0.3)
    assert run.outcomes[1][0] == "NoAnswer" and "got 3 bytes" in run.outcomes[1][1]  # type: ignore[index]
    assert run.quick == 2


def test_a_drive_that_closes_the_connection(count_quick: list[int]) -> None:
    run = _same(_table({b"A": [b"1\r\n-->"], b"X": CLOSE}), ["A", "X", "A"], count_quick)
    assert run.outcomes[1][0] == "CommError" and "closed the connection" in run.outcomes[1][1]  # type: ignore[index]
    assert run.quick >= 2


def test_an_enclosing_request_takes_the_general_path(count_quick: list[int]) -> None:
    """Inside another request's deadline (or with unanswered time counted) links.Budget.lone gives no end time:
    the general path, with the enclosing deadline."""
    drive = Drive(_table(USUAL))
    try:
        transport = AkdAsciiTransport(split_target(f"akd://127.0.0.1:{drive.port}"),
                                      LinkOptions(timeout=1.0, retries=0, tracer=Tracer(record=False)))
        transport.open()
        link = transport.command_link
        assert link is not None
        count_quick[0] = 0
        with transport.options.budget.request(attempts=1):
            assert link.command("DRV.OPMODE") == "2"
        assert count_quick[0] == 0
        assert link.command("DRV.OPMODE") == "2" and count_quick[0] == 1
        transport.close()
    finally:
        drive.close()


@pytest.fixture
def closed_stream() -> Iterator[tcp_stream.TcpStream]:
    listener = socket.create_server(("127.0.0.1", 0))
    stream = tcp_stream.TcpStream.connect("127.0.0.1", listener.getsockname()[1], 1.0)
    peer, _ = listener.accept()
    listener.close()
    peer.close()
    stream.close()
    yield stream


def test_a_closed_stream_fails_as_the_socket_would(closed_stream: tcp_stream.TcpStream) -> None:
    """The descriptor is read from the socket each request: after close, EBADF -- never a reused number."""
    with pytest.raises(OSError):
        closed_stream.request(b"DRV.OPMODE\r\n", time.monotonic() + 0.5)


@pytest.fixture
def stream_pair() -> Iterator[tuple[tcp_stream.TcpStream, socket.socket]]:
    listener = socket.create_server(("127.0.0.1", 0))
    stream = tcp_stream.TcpStream.connect("127.0.0.1", listener.getsockname()[1], 1.0)
    peer, _ = listener.accept()
    listener.close()
    yield stream, peer
    stream.close()
    peer.close()


@pytest.mark.parametrize("through", ["lone", "descriptor", "socket"])
def test_stream_request_both_ways(stream_pair: tuple[tcp_stream.TcpStream, socket.socket], through: str) -> None:
    """TcpStream.request for a lone request's wait and for any (os.write/os.read on the descriptor) and
    BoundedSocket.request (the socket's methods): the same bytes sent, the same first segment (bounded by ``size``), None at the deadline,
    b"" on a close."""
    stream, peer = stream_pair

    def lone(stream: tcp_stream.TcpStream, data: bytes, at: float, size: int = 4096) -> bytes | None:
        # the wait a lone request's Budget gave
        return tcp_stream.TcpStream.request(stream, data, at, size, round(at - time.monotonic(), 2))

    request = {"lone": lone, "descriptor": tcp_stream.TcpStream.request,
               "socket": tcp_stream.BoundedSocket.request}[through]
    assert request(stream, b"X\r\n", time.monotonic() + 0.05) is None   # nothing answered
    peer.settimeout(1.0)
    assert peer.recv(100) == b"X\r\n"
    peer.sendall(b"0123456789")
    assert request(stream, b"Y\r\n", time.monotonic() + 1.0, 4) == b"0123"   # the rest stays for the next receive
    assert stream.recv(time.monotonic() + 1.0) == b"456789"
    assert peer.recv(100) == b"Y\r\n"
    start = time.monotonic()
    assert request(stream, b"Z\r\n", start + 0.1) is None
    assert time.monotonic() - start >= 0.1
    assert peer.recv(100) == b"Z\r\n"
    peer.shutdown(socket.SHUT_WR)   # the drive's side closed for sending: the reply is b""
    assert request(stream, b"W\r\n", time.monotonic() + 1.0) == b""
    peer.close()                     # gone: its kernel resets the next request, an OSError either way
    time.sleep(0.05)
    with pytest.raises(OSError):
        request(stream, b"V\r\n", time.monotonic() + 1.0)
        request(stream, b"V\r\n", time.monotonic() + 1.0)


def _changing(values: dict[bytes, list[bytes | str]]) -> Script:
    """Each line answers the next of its replies in turn (the last one again once they run out); a reply is one
    segment, or SILENT / CLOSE."""
    def script(line: bytes) -> list[bytes] | str:
        queue = values.get(line)
        if not queue:
            return [b"Error: Command was not found.\r\n-->"]
        reply = queue.pop(0) if len(queue) > 1 else queue[0]
        return reply if isinstance(reply, str) else [reply]
    return script


def test_a_line_s_last_reply_is_kept_only_for_the_very_same_bytes(count_quick: list[int]) -> None:
    """The quick path keeps each line's last quick reply (bytes and text): the same bytes again give that text, and
    any other bytes -- a changed value, a refusal, silence, a close -- are checked as ever (tests both ways)."""
    def replies() -> dict[bytes, list[bytes | str]]:
        return {b"DRV.OPMODE": [b"2\r\n-->", b"2\r\n-->", b"3\r\n-->", b"2\r\n-->", b"Error: busy\r\n-->",
                                b"2\r\n-->", b"2 \r\n-->", b"2\r\n\r\n-->", b"\xff\xfd\x1f2\r\n-->", b"2\r\n-->"],
                # another line, the same reply bytes: an echo for this one (its own last reply, not the other's)
                b"2": [b"2\r\n-->", b"2\r\n-->"]}

    lines = ["DRV.OPMODE"] * 4 + ["2", "DRV.OPMODE", "2"] + ["DRV.OPMODE"] * 6
    general = _run(True, _changing(replies()), lines, count_quick)
    assert general.quick == 0
    quick = _run(False, _changing(replies()), lines, count_quick)
    assert quick.outcomes == general.outcomes
    assert quick.received == general.received
    assert quick.quick == len(lines)
    assert quick.outcomes[:4] == ["2", "2", "3", "2"]
    assert quick.outcomes[4] == ""   # "2" answered by "2": only the echo of its line
    assert quick.outcomes[5][0] == "CommandRefused"  # type: ignore[index]
    assert quick.outcomes[6] == ""
    assert quick.outcomes[7:] == ["2", "2", "2", "2", "2", "2"]


def test_a_kept_reply_is_never_an_answer_to_silence_or_a_close(count_quick: list[int]) -> None:
    for last, timeout in ((SILENT, 0.3), (CLOSE, 1.0)):
        runs = [_run(tracing, _changing({b"A": [b"7\r\n-->", b"7\r\n-->", last]}), ["A", "A", "A"], count_quick,
                     timeout=timeout) for tracing in (True, False)]
        assert runs[0].outcomes == runs[1].outcomes and runs[0].silent == runs[1].silent
        assert runs[1].quick == 3
        assert runs[1].outcomes[:2] == ["7", "7"]
        assert runs[1].outcomes[2][0] == ("NoAnswer" if last == SILENT else "CommError")  # type: ignore[index]


def test_tracing_switched_on_takes_the_general_path_for_a_kept_reply(count_quick: list[int]) -> None:
    """A reply kept by the quick path does not bypass tracing: with the tracer on, the same bytes are traced."""
    drive = Drive(_table(USUAL))
    try:
        tracer = Tracer(record=False)
        transport = AkdAsciiTransport(split_target(f"akd://127.0.0.1:{drive.port}"),
                                      LinkOptions(timeout=1.0, retries=0, tracer=tracer))
        transport.open()
        link = transport.command_link
        assert link is not None
        count_quick[0] = 0
        assert link.command("DRV.OPMODE") == "2" and link.command("DRV.OPMODE") == "2"
        assert count_quick[0] == 2
        tracer.record = True
        assert tracer.active
        assert link.command("DRV.OPMODE") == "2"
        assert count_quick[0] == 2
        assert [r.data for r in tracer.records if r.direction == "rx"] == [b"2\r\n-->"]
        transport.close()
    finally:
        drive.close()


def test_a_lone_request_after_close_fails_as_the_socket_would(closed_stream: tcp_stream.TcpStream) -> None:
    with pytest.raises(OSError):
        closed_stream.request(b"DRV.OPMODE\r\n", time.monotonic() + 0.5, 4096, 0.5)


def test_a_lone_request_keeps_the_receive_timeout_for_its_wait_and_checks_again_after_another(
        stream_pair: tuple[tcp_stream.TcpStream, socket.socket]) -> None:
    """TcpStream.request remembers that the socket's receive timeout suits a lone request of its wait, and forgets
    it once another receive set a different one: its request never waits on a timeout set for a longer wait."""
    stream, peer = stream_pair
    peer.settimeout(1.0)
    wanted = tcp_stream.early(0.5)
    for _ in range(3):
        peer.sendall(b"1\r\n-->")
        assert stream.request(b"A\r\n", time.monotonic() + 0.5, 4096, 0.5) == b"1\r\n-->"
        assert wanted - tcp_stream.SLACK <= stream._wait <= wanted and not stream._polled
    peer.sendall(b"x")
    assert stream.recv(time.monotonic() + 1.5) == b"x"    # a longer wait: a longer receive timeout
    assert stream._wait > wanted
    start = time.monotonic()
    assert stream.request(b"B\r\n", start + 0.2, 4096, 0.2) is None   # nobody answers: given up at its own deadline
    assert time.monotonic() >= start + 0.2
    assert stream._wait <= tcp_stream.early(0.2) or stream._polled
    peer.sendall(b"2\r\n-->")
    assert stream.request(b"C\r\n", time.monotonic() + 0.5, 4096, 0.5) == b"2\r\n-->"
    assert wanted - tcp_stream.SLACK <= stream._wait <= wanted
    assert peer.recv(100) == b"A\r\nA\r\nA\r\nB\r\nC\r\n"
