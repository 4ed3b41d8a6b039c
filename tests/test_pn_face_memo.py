"""The PROFINET face's memo of plain record call shapes (``ProfinetFace._calls``, ``_learn``; issue 29) against the
general path it stands for: calls whose shapes share the memo's key (the record header's tail) and take turns in
it, and calls that differ from a kept shape only in the parts the memo compares (head, middle) or in their length,
get the frames the general path sends (``_short_way`` off, the codec's short way off)."""

from __future__ import annotations

import random
import uuid
from pathlib import Path

import pytest

from akdctl.protocol import dcerpc, pnio
from akdctl.sim import face_profinet
from akdctl.sim.drive import SimDrive
from tests.pn_calls import READ_930, CaptureSocket
from tests.pn_calls import call as _call
from tests.pn_calls import connect as _connect


def _frames(requests: list[bytes], directory: Path, monkeypatch: pytest.MonkeyPatch, short_way: bool) -> list[bytes]:
    with monkeypatch.context() as patch:
        if not short_way:
            patch.setattr(face_profinet.pnio_record, "plain_record_call", lambda data: None)
        face = face_profinet.ProfinetFace(SimDrive("default", directory), "127.0.0.1", 0)
        face._short_way = short_way
        face.boot_time = 4321
        sent: list[bytes] = []
        face._sock = CaptureSocket(sent)  # type: ignore[assignment]
        for request in requests:
            sent.append(b"--")
            face._datagram(request, ("127.0.0.1", 1))
        if short_way:
            assert face._calls  # the memo was used
    return sent


def test_shapes_sharing_the_memo_key_answer_as_the_general_path(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """A Write of as many record bytes as the Read after it takes has the same tail: the two shapes take turns."""
    ar, activity = uuid.uuid4(), uuid.uuid4()
    address = pnio.RecordAddress()
    bmp = READ_930 + bytes(230)  # 240 bytes: the parameter manager refuses the request, the record layer answers
    rng = random.Random(47)
    requests = [_connect(ar, activity)]
    for sequence in range(2, 200):  # Writes of either length and Reads in any order: the shapes take turns
        kind = rng.choice(["write", "write long", "read"])
        if kind == "read":
            requests.append(_call(pnio.OP_READ, pnio.IODReadReq(sequence, ar, address, len(bmp)).encode(), sequence,
                                  activity))
        else:
            data = READ_930 if kind == "write" else bmp
            requests.append(_call(pnio.OP_WRITE, pnio.IODWriteReq(sequence, ar, address, data).encode(), sequence,
                                  activity))
    short, general = (_frames(requests, tmp_path / str(way), monkeypatch, way) for way in (True, False))
    assert short == general
    assert sum(1 for frame in short if frame[:2] == b"\x04\x02") > 150


def test_a_call_differing_from_a_kept_shape_in_a_compared_part_is_answered_as_itself(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Calls that share the tail of a kept shape but differ in the head (object UUID, byte order), the middle
    (interface hint, opnum) or that are cut short or padded get what the general path gives them."""
    rng = random.Random(29)
    ar, activity = uuid.uuid4(), uuid.uuid4()
    address = pnio.RecordAddress()
    requests = [_connect(ar, activity)]
    for sequence in range(2, 300):
        little, node, hint = rng.random() < 0.3, rng.choice([1, 1, 2]), rng.choice([0xFFFF, 0xFFFF, 3])
        if rng.random() < 0.5:
            request = _call(pnio.OP_WRITE, pnio.IODWriteReq(sequence, ar, address, READ_930).encode(), sequence,
                            activity, little=little, object_node=node, hint=hint)
        else:
            request = _call(pnio.OP_READ, pnio.IODReadReq(sequence, ar, address, 240).encode(), sequence, activity,
                            little=little, object_node=node, hint=hint)
        kind = rng.random()
        if kind < 0.1:
            request = request[:rng.randrange(len(request))]
        elif kind < 0.15:
            request += bytes(rng.randint(1, 3))
        elif kind < 0.25:  # a byte of the head or middle the memo compares
            where = rng.choice([9, 20, 70, 71, 80, 95])
            request = request[:where] + bytes([request[where] ^ 0x01]) + request[where + 1:]
        requests.append(request)
        if rng.random() < 0.1:
            requests.append(request)  # a retransmission
    short, general = (_frames(requests, tmp_path / str(way), monkeypatch, way) for way in (True, False))
    assert short == general
    assert sum(1 for frame in short if frame[:2] == b"\x04\x02") > 150


def test_a_new_boot_time_reaches_the_replies_of_shapes_already_kept(tmp_path: Path) -> None:
    """The memo's reply templates carry the face's boot time: setting another one forgets them, so the next replies
    of the same shapes carry the new one, as the general path's do."""
    ar, activity = uuid.uuid4(), uuid.uuid4()
    address = pnio.RecordAddress()
    face = face_profinet.ProfinetFace(SimDrive("default", tmp_path), "127.0.0.1", 0)
    face.boot_time = 1111
    sent: list[bytes] = []
    face._sock = CaptureSocket(sent)  # type: ignore[assignment]
    face._datagram(_connect(ar, activity), ("127.0.0.1", 1))
    for sequence in range(2, 12, 2):
        if sequence == 6:
            face.boot_time = 2222
        face._datagram(_call(pnio.OP_WRITE, pnio.IODWriteReq(sequence, ar, address, READ_930).encode(), sequence,
                             activity), ("127.0.0.1", 1))
        face._datagram(_call(pnio.OP_READ, pnio.IODReadReq(sequence + 1, ar, address, 240).encode(), sequence + 1,
                             activity), ("127.0.0.1", 1))
    boots = [dcerpc.decode_packet(frame).header.server_boot for frame in sent[1:]]
    assert boots == [1111] * 4 + [2222] * 6
    assert face._calls  # the short way answered them
