"""pn://'s quick path (``ProfinetTransport.quick_exchange``: a request whose two calls are answered at once) gives
exactly what the general path gives, for the usual answers and for every unusual one (issue 29, row pn).

How: each scenario runs twice against a fresh simulated PROFINET face with the same fault injection - once with the
session's tracer on (the general path: every datagram traced, the quick path never taken) and once with it off (the
quick path first, handing over to the general path where it stops) - and the two runs must agree on every answer,
every error's words, what reached the drive, and how the command's time budget stands afterwards. Each test also
checks which path ran, so a quick path that silently stopped being taken fails here.
"""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterable, Iterator

import pytest

from akdctl.errors import AkdError
from akdctl.sim.face_profinet import Injection, ProfinetFace
from akdctl.transport.base import LinkOptions
from akdctl.transport.profinet import PnioRecordLink, ProfinetTransport
from akdctl.transport.target import split_target
from akdctl.transport.trace import Tracer
from tests.test_pn_transport import READ_930, CountingDrive

CHANGE_930 = bytes.fromhex("06 02 00 01 10 01 03 A2 00 00 42 01 00 02")


class Run:
    """One run of a scenario: its answers (bytes or an error's class and words), the drive's requests, the budget."""

    def __init__(self) -> None:
        self.outcomes: list[object] = []
        self.requests: list[bytes] = []
        self.silent: list[float] = []
        self.quick = 0


@pytest.fixture
def count_quick(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls = [0]
    real = ProfinetTransport.quick_exchange

    def quick(self: ProfinetTransport, request: bytes, at: float) -> object:
        calls[0] += 1
        return real(self, request, at)

    monkeypatch.setattr(ProfinetTransport, "quick_exchange", quick)
    return calls


Scenario = Callable[[ProfinetTransport, ProfinetFace], Iterable[bytes]]


def _run(tracing: bool, face_kwargs: dict[str, object], requests: Scenario, calls: list[int], timeout: float = 2.0,
         retries: int = 10, query: str = "") -> Run:
    drive = CountingDrive()
    face = ProfinetFace(drive, "127.0.0.1", 0, **face_kwargs)
    face.start()
    run = Run()
    calls[0] = 0
    try:
        tracer = Tracer() if tracing else Tracer(record=False)
        assert tracer.active is tracing
        target = split_target(f"pn://127.0.0.1:{face.port}{'?' + query if query else ''}")
        t = ProfinetTransport(target, LinkOptions(timeout=timeout, retries=retries, tracer=tracer))
        t.connect()
        t.record_link = link = PnioRecordLink(t)
        try:
            for request in requests(t, face):
                try:
                    run.outcomes.append(link.exchange(request))
                except AkdError as exc:
                    # each run's face has its own port: the words are compared without it
                    words = exc.message.replace(f":{face.port}", ":PORT").replace(f"port {face.port}", "port PORT")
                    run.outcomes.append((type(exc).__name__, words, exc.code))
                run.silent.append(t.options.budget.silent)
        finally:
            t.close()
    finally:
        face.stop()
    run.requests = list(drive.requests)
    run.quick = calls[0]
    return run


def _same(face_kwargs: dict[str, object], requests: Scenario, calls: list[int], **kwargs: object) -> Run:
    general = _run(True, face_kwargs, requests, calls, **kwargs)  # type: ignore[arg-type]
    assert general.quick == 0
    quick = _run(False, face_kwargs, requests, calls, **kwargs)  # type: ignore[arg-type]
    assert quick.outcomes == general.outcomes
    assert quick.requests == general.requests
    assert quick.silent == general.silent
    return quick


def _numbered(count: int) -> Scenario:
    return lambda t, face: [bytes([n + 1]) + READ_930[1:] for n in range(count)]


def test_usual_reads_and_changes_take_the_quick_path(count_quick: list[int]) -> None:
    run = _same({}, lambda t, face: [READ_930, CHANGE_930, READ_930], count_quick)
    assert run.quick == 3
    assert run.outcomes == [bytes.fromhex("05 01 00 01 42 01 00 01"), bytes.fromhex("06 02 00 01 00 00"),
                            bytes.fromhex("05 01 00 01 42 01 00 03")]


@pytest.mark.parametrize("spec", ["drop=3", "dup=2", "delay=4:0.4", "rxdrop=3", "drop=5,dup=3,delay=7:0.3,rxdrop=4"])
def test_lost_duplicated_and_late_datagrams(count_quick: list[int], spec: str) -> None:
    run = _same({"injection": Injection.parse(spec), "delay": 0.02}, _numbered(12), count_quick)
    assert run.quick == 12
    assert [r[0] for r in run.requests] == list(range(1, 13))  # each applied once


def test_busy_device(count_quick: list[int]) -> None:
    run = _same({"delay": 0.05}, _numbered(3), count_quick)
    assert run.quick == 3


def test_fragmented_responses(count_quick: list[int]) -> None:
    run = _same({"fragment": 24}, lambda t, face: [READ_930, READ_930], count_quick)
    assert run.quick == 2


def test_refused_record_access(count_quick: list[int]) -> None:
    run = _same({}, lambda t, face: [READ_930, CHANGE_930], count_quick, query="slot=2")
    assert run.quick == 2
    assert all(isinstance(o, tuple) and o[0] == "RecordError" and "invalid slot" in o[1] for o in run.outcomes)


@pytest.fixture
def silent_port() -> Iterator[int]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    try:
        yield sock.getsockname()[1]
    finally:
        sock.close()


def test_a_drive_that_falls_silent(count_quick: list[int], silent_port: int) -> None:
    """After one answered read the calls go to a port that never answers: no answer in words, an unknown outcome
    for the change, the budget's unanswered time counted, and a probe's share for the request after it."""

    def requests(t: ProfinetTransport, face: ProfinetFace) -> Iterator[bytes]:
        yield READ_930
        assert t.rpc is not None
        t.rpc.sock.connect(("127.0.0.1", silent_port))
        yield from (READ_930, CHANGE_930, READ_930)
        t.ar_uuid = None  # nothing to release: the silent port would only make close wait

    run = _same({}, requests, count_quick, timeout=0.3, retries=1)
    assert run.quick == 2  # the first unanswered one began quick; once the budget counts unanswered time, general
    assert [o[0] for o in run.outcomes[1:]] == ["NoAnswer", "UnknownOutcome", "NoAnswer"]  # type: ignore[index]


def test_nothing_listens_any_more(count_quick: list[int]) -> None:
    def requests(t: ProfinetTransport, face: ProfinetFace) -> Iterator[bytes]:
        yield READ_930
        face.stop()
        yield READ_930
        t.ar_uuid = None

    run = _same({}, requests, count_quick, timeout=0.5)
    assert run.quick == 2
    assert run.outcomes[1][0] == "CommError" and "nothing listens" in run.outcomes[1][1]  # type: ignore[index]
