"""The PROFINET face keeps one call per activity (``ProfinetFace._activity``): a retransmission of the activity's last
call gets its reply again and is not applied twice; a request or ping older than that call is discarded, as a
DCE/RPC CL server discards it (MS-RPCE 3.2.3.5.4/3.2.3.5.5); the sequence space wraps. Every case is answered the
same by the face's one pass, its second short way and the general path (both short ways off)."""

from __future__ import annotations

import random
import uuid
from pathlib import Path
from typing import Any

import pytest

from akdctl.protocol import dcerpc, pnio
from akdctl.sim import face_profinet
from akdctl.sim.drive import SimDrive
from tests.pn_calls import READ_930, CaptureSocket, connect
from tests.pn_calls import call as _call

PEER = ("127.0.0.1", 1)


def _write(ar: uuid.UUID, sequence: int, activity: uuid.UUID, bmp: bytes = READ_930, **kw: Any) -> bytes:
    return _call(pnio.OP_WRITE, pnio.IODWriteReq(sequence & 0xFFFF, ar, pnio.RecordAddress(), bmp).encode(),
                 sequence, activity, **kw)


def _read(ar: uuid.UUID, sequence: int, activity: uuid.UUID, **kw: Any) -> bytes:
    return _call(pnio.OP_READ, pnio.IODReadReq(sequence & 0xFFFF, ar, pnio.RecordAddress(), 240).encode(), sequence,
                 activity, **kw)


def _ping(sequence: int, activity: uuid.UUID) -> bytes:
    return _call(pnio.OP_READ, b"", sequence, activity, ptype=dcerpc.PT_PING)


WAYS = ("one pass", "second short way", "general")


def _face(directory: Path, monkeypatch: pytest.MonkeyPatch, way: str, **options: Any) -> tuple[Any, list[bytes]]:
    """A face answering by ``way``: its one pass, only its second short way (``plain_record_call``), or only the
    general decoders."""
    if way == "general":
        monkeypatch.setattr(face_profinet.pnio_record, "plain_record_call", lambda data: None)
    face = face_profinet.ProfinetFace(SimDrive("default", directory), "127.0.0.1", 0, **options)
    face._short_way = way == "one pass"
    face.boot_time = 77
    sent: list[bytes] = []
    face._sock = CaptureSocket(sent)  # type: ignore[assignment]
    return face, sent


def _answers(face: Any, sent: list[bytes], datagram: bytes) -> list[bytes]:
    del sent[:]
    face._datagram(datagram, PEER)
    return list(sent)


@pytest.mark.parametrize("way", WAYS)
def test_the_last_call_is_replayed_and_older_calls_are_discarded(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                 way: str) -> None:
    ar, activity = uuid.uuid4(), uuid.uuid4()
    face, sent = _face(tmp_path, monkeypatch, way)
    assert _answers(face, sent, connect(ar, activity, 0))
    (written,) = _answers(face, sent, _write(ar, 1, activity))
    assert _answers(face, sent, _write(ar, 1, activity)) == [written]  # retransmitted: the same reply
    assert face.stats.bmp_requests == 1 and face.stats.replayed == 1  # ... and not applied twice
    (read,) = _answers(face, sent, _read(ar, 2, activity))
    assert pnio.decode_response_args(dcerpc.decode_packet(read).body, False)[0].ok
    assert _answers(face, sent, _read(ar, 2, activity)) == [read]
    # older than the activity's last call: discarded, whether it was answered once (1) or never seen (0)
    assert _answers(face, sent, _write(ar, 1, activity)) == []
    assert _answers(face, sent, _write(ar, 0, activity)) == []
    assert _answers(face, sent, _ping(1, activity)) == []
    assert face.stats.bmp_requests == 1 and face.stats.replayed == 2
    # a ping of the last call gets its reply, of a newer one "no call"
    assert _answers(face, sent, _ping(2, activity)) == [read]
    (nocall,) = _answers(face, sent, _ping(3, activity))
    assert dcerpc.decode_packet(nocall).header.ptype == dcerpc.PT_NOCALL
    # another activity is not held back by this one's sequence numbers
    other = uuid.uuid4()
    (answer,) = _answers(face, sent, _write(ar, 1, other))
    assert pnio.decode_response_args(dcerpc.decode_packet(answer).body, False)[0].ok
    assert face.stats.bmp_requests == 2


@pytest.mark.parametrize("way", WAYS)
def test_the_sequence_number_wraps(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, way: str) -> None:
    """After 0xFFFFFFFF comes 0 (a new call); 0xFFFFFFFE is then older, and the half of the space below the last
    call is older while the half above is newer."""
    ar, activity = uuid.uuid4(), uuid.uuid4()
    face, sent = _face(tmp_path, monkeypatch, way)
    assert _answers(face, sent, connect(ar, activity, 0xFFFFFFF0))
    assert len(_answers(face, sent, _write(ar, 0xFFFFFFFF, activity))) == 1
    assert len(_answers(face, sent, _read(ar, 0, activity))) == 1
    assert _answers(face, sent, _write(ar, 0xFFFFFFFE, activity)) == []
    assert _answers(face, sent, _write(ar, 0x80000001, activity)) == []  # the older half of the space
    assert len(_answers(face, sent, _write(ar, 0x7FFFFFFF, activity))) == 1  # the newer half
    assert face.stats.bmp_requests == 2


@pytest.mark.parametrize("way", WAYS)
def test_a_first_call_of_any_sequence_number_is_new(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    way: str) -> None:
    ar = uuid.uuid4()
    face, sent = _face(tmp_path, monkeypatch, way)
    assert _answers(face, sent, connect(ar, uuid.uuid4(), 0))
    for first in (0, 1, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF):
        activity = uuid.uuid4()
        assert len(_answers(face, sent, _write(ar, first, activity))) == 1
        assert len(_answers(face, sent, _read(ar, (first + 1) & 0xFFFFFFFF, activity))) == 1


def test_the_activities_kept_are_bounded_and_start_over(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """More activities than ACTIVITIES_KEPT: the memo starts over (sim/memo.remember) and forgets the shapes that
    held the old activities' calls, so a kept shape never answers from a forgotten activity's list."""
    monkeypatch.setattr(face_profinet, "ACTIVITIES_KEPT", 4)
    ar = uuid.uuid4()
    face, sent = _face(tmp_path, monkeypatch, "one pass")
    assert _answers(face, sent, connect(ar, uuid.uuid4(), 0))
    activities = [uuid.uuid4() for _ in range(10)]
    for round_ in range(3):
        for n, activity in enumerate(activities):
            sequence = 10 * round_ + 2
            (answer,) = _answers(face, sent, _write(ar, sequence, activity))
            assert _answers(face, sent, _write(ar, sequence, activity)) == [answer]
            assert len(_answers(face, sent, _read(ar, sequence + 1, activity))) == 1
            assert len(face._last) <= 4
    assert face.stats.bmp_requests == 30 and face.stats.replayed == 30


@pytest.mark.parametrize("delay, inject", [(0.0, ""), (30.0, ""), (0.0, "drop=3,dup=4,rxdrop=7")])
def test_out_of_order_calls_get_the_same_frames_every_way(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                          delay: float, inject: str) -> None:
    """Seeded polls of a few clients with retransmissions of the last call, of older calls (answered or never seen),
    pings, a stale AR, a busy parameter manager and fault injection: the three ways send the same frames."""
    rng = random.Random(2929)
    ars = [uuid.uuid4() for _ in range(3)]
    activities = [uuid.uuid4() for _ in range(3)]
    requests = [connect(ar, activity, 0) for ar, activity in zip(ars[:2], activities)]  # the third AR: stale
    sequences = [rng.randrange(1 << 32) for _ in activities]
    for _ in range(400):
        client = rng.randrange(3)
        activity, ar = activities[client], ars[client]
        little = rng.random() < 0.3
        kind = rng.random()
        if kind < 0.6:
            sequences[client] = (sequences[client] + 1) & 0xFFFFFFFF
            sequence = sequences[client]
        else:  # the last call again, an older one, or a newer one skipping some
            sequence = (sequences[client] + rng.choice([0, 0, -1, -2, -100, 5])) & 0xFFFFFFFF
        if rng.random() < 0.1:
            requests.append(_ping(sequence, activity))
        elif rng.random() < 0.5:
            requests.append(_write(ar, sequence, activity, little=little))
        else:
            requests.append(_read(ar, sequence, activity, little=little))
    frames = []
    for way in WAYS:
        with monkeypatch.context() as patch:
            face, sent = _face(tmp_path / way.replace(" ", "-"), patch, way, delay=delay,
                               injection=face_profinet.Injection.parse(inject or None))
            for request in requests:
                sent.append(b"--")
                face._datagram(request, PEER)
            frames.append(sent)
            assert face.stats.replayed > 10
    assert frames[0] == frames[1] == frames[2]
    assert sum(1 for f in frames[0] if f[:2] == b"\x04\x02") > 100
    if not inject:  # every request answered but the older ones (and pings of them): some were discarded
        unanswered = b"".join(b"." if f == b"--" else b"x" for f in frames[0]).split(b".")[1:].count(b"")
        assert unanswered > 10


@pytest.mark.parametrize("delay", [0.0, 30.0])
def test_a_kept_receive_buffer_answers_as_the_datagrams_bytes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                              delay: float) -> None:
    """The face's loop receives into one kept buffer (recvfrom_into): a datagram cut short, after a longer one of
    the same shape, leaves that one's bytes behind it in the buffer. Its size alone must tell it short: every
    datagram is answered as the general path answers its own bytes."""
    rng = random.Random(8200)
    ar, activity = uuid.uuid4(), uuid.uuid4()
    requests = [connect(ar, activity, 0)]
    for sequence in range(1, 300):
        request = _write(ar, sequence, activity) if sequence % 2 else _read(ar, sequence, activity)
        kind = rng.random()
        if kind < 0.25:  # cut short: inside the record header, its padding, the record data, or by one byte
            request = request[:rng.choice([100, 139, 150, 163, 164, len(request) - 1])]
        elif kind < 0.3:
            request += bytes(rng.randint(1, 8))
        requests.append(request)
        if rng.random() < 0.1:
            requests.append(request)
    frames = []
    for way in ("one pass", "general"):
        with monkeypatch.context() as patch:
            face, sent = _face(tmp_path / way.replace(" ", "-"), patch, way, delay=delay)
            buffer = bytearray(rng.randbytes(1024))
            for request in requests:
                sent.append(b"--")
                if way == "general":
                    face._datagram(request, PEER)
                else:  # as recvfrom_into leaves it: the datagram at the start, the buffer's old bytes after it
                    buffer[:len(request)] = request
                    face._datagrams(buffer, len(request), PEER, None, False, face_profinet._NEVER)
            frames.append(sent)
    assert frames[0] == frames[1]
    assert sum(1 for f in frames[0] if f[:2] == b"\x04\x02") > 150


def test_the_write_data_reader_reads_the_record_plain_record_call_reads() -> None:
    """pnio_record.write_data_reader (the one pass's Write record data, from a buffer that may hold older bytes
    after the datagram) gives the data plain_record_call finds, in either byte order."""
    from akdctl.protocol import pnio_record

    rng = random.Random(164)
    ar = uuid.uuid4()
    for _ in range(50):
        record = rng.randbytes(rng.randint(1, 240))
        datagram = _write(ar, rng.randrange(1 << 32), uuid.uuid4(), record, little=rng.random() < 0.5)
        plain = pnio_record.plain_record_call(datagram)
        assert plain is not None and plain[3].data == record
        buffer = bytearray(datagram + rng.randbytes(64))
        assert pnio_record.write_data_reader(len(record))(buffer) == (record,)
        assert pnio_record.write_data_reader(len(record))(datagram) == (record,)
