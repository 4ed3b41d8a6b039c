"""The client's record call templates and its reading of the usual reply equal the general codecs (issue 29, item 2).

``pnio_call.RecordCalls`` patches sequence numbers into datagrams the codecs encoded once: every datagram must be
byte-equal to ``RequestTemplate.packet(encode_request_args(write_request/read_request))``. ``plain_response`` must
return exactly what the general path (``view_packet``, the activity/sequence check, ``decode_response_args``) returns
for the replies it takes, and None for every reply the general path does not take as the call's answer.
"""

from __future__ import annotations

import uuid

from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.protocol import dcerpc, pnio
from akdctl.protocol.errors import CodecError
from akdctl.protocol.pnio_call import RecordCalls, plain_response

OBJ = pnio.object_uuid(0x0100, 0x0001, 1)
u32 = st.integers(0, 0xFFFFFFFF)
u16 = st.integers(0, 0xFFFF)
addresses = st.builds(pnio.RecordAddress, api=u32, slot=st.integers(0, 0x7FFF), subslot=u16, index=u16)


@settings(max_examples=200, deadline=None)
@given(activity=st.uuids(), ar=st.binary(min_size=16, max_size=16), address=addresses, read_length=u16,
       calls=st.lists(st.tuples(u32, u16, st.binary(max_size=240)), min_size=1, max_size=6))
def test_datagrams_equal_the_general_encoders(activity: uuid.UUID, ar: bytes, address: pnio.RecordAddress,
                                               read_length: int, calls: list[tuple[int, int, bytes]]) -> None:
    template = dcerpc.RequestTemplate(OBJ, pnio.DEVICE_INTERFACE, activity)
    reference = dcerpc.RequestTemplate(OBJ, pnio.DEVICE_INTERFACE, activity)
    fast = RecordCalls(template, ar, address, read_length)
    for sequence, rw_seq, data in calls:  # record lengths change between calls: the write template follows
        assert fast.write(sequence, rw_seq, data) == reference.packet(
            sequence, pnio.OP_WRITE, pnio.encode_request_args(pnio.write_request(rw_seq, ar, address, data)))
        assert fast.read(sequence, rw_seq) == reference.packet(
            sequence, pnio.OP_READ, pnio.encode_request_args(pnio.read_request(rw_seq, ar, address, read_length)))


def _general(data: bytes, sequence: int, activity: uuid.UUID) -> tuple[pnio.PnioStatus, bytes] | None:
    """What RpcClient._accept returns for an unfragmented response of the call (None: not the answer, or an error)."""
    try:
        view = dcerpc.view_packet(data)
    except CodecError:
        return None
    if view.sequence != sequence or view.activity != (activity.bytes_le if view.little else activity.bytes):
        return None
    if view.ptype != dcerpc.PT_RESPONSE or view.is_fragment:
        return None
    try:
        return pnio.decode_response_args(view.body, view.little)
    except CodecError:
        return None


def _reply(activity: uuid.UUID, sequence: int, little: bool, status: pnio.PnioStatus, blocks: bytes) -> bytes:
    header = dcerpc.RpcHeader(ptype=dcerpc.PT_RESPONSE, object_uuid=OBJ, interface_uuid=pnio.DEVICE_INTERFACE,
                              activity_uuid=activity, sequence=sequence, opnum=pnio.OP_READ,
                              drep=dcerpc.DREP_LITTLE if little else dcerpc.DREP_BIG)
    return dcerpc.encode_packet(header, pnio.encode_response_args(status, blocks, little=little))


statuses = st.sampled_from([pnio.OK, pnio.PnioStatus(0xDE, 0x80, 0xC2, 0), pnio.PnioStatus(0xDF, 0x80, 0xB0, 1)])


@settings(max_examples=300, deadline=None)
@given(activity=st.uuids(), sequence=u32, little=st.booleans(), status=statuses, blocks=st.binary(max_size=300),
       mutations=st.lists(st.tuples(st.integers(0, 119), st.integers(0, 255)), max_size=3), cut=st.integers(0, 8))
def test_plain_response_takes_only_what_the_general_path_takes(activity: uuid.UUID, sequence: int, little: bool,
                                                                status: pnio.PnioStatus, blocks: bytes,
                                                                mutations: list[tuple[int, int]], cut: int) -> None:
    data = bytearray(_reply(activity, sequence, little, status, blocks))
    for at, value in mutations:
        if at < len(data):
            data[at] = value
    if cut:
        del data[-cut:]
    fast = plain_response(bytes(data), sequence, activity.bytes, activity.bytes_le)
    general = _general(bytes(data), sequence, activity)
    if fast is not None:
        assert general is not None and fast[0] == general[0] and bytes(fast[1]) == general[1]
    if not mutations and not cut:
        assert fast is not None and fast[0] == status and bytes(fast[1]) == blocks


def test_plain_response_leaves_stale_foreign_and_fragmented_replies_to_the_general_path() -> None:
    activity = uuid.uuid4()
    good = _reply(activity, 7, False, pnio.OK, b"\x01\x02")
    assert plain_response(good, 7, activity.bytes, activity.bytes_le) is not None
    assert plain_response(good, 8, activity.bytes, activity.bytes_le) is None  # another call's answer
    other = uuid.uuid4()
    assert plain_response(good, 7, other.bytes, other.bytes_le) is None  # another activity's
    fragment = bytearray(good)
    fragment[2] |= dcerpc.FLAG_FRAG
    assert plain_response(bytes(fragment), 7, activity.bytes, activity.bytes_le) is None
    working = bytearray(good)
    working[1] = dcerpc.PT_WORKING
    assert plain_response(bytes(working), 7, activity.bytes, activity.bytes_le) is None


rw_addresses = st.builds(pnio.RecordAddress, api=u32, slot=u16, subslot=u16, index=u16)


@settings(max_examples=300, deadline=None)
@given(seq=u16, ar=st.uuids(), address=rw_addresses, status=statuses, data=st.binary(max_size=40),
       tail=st.binary(max_size=6), mutations=st.lists(st.tuples(st.integers(0, 70), st.integers(0, 255)), max_size=2))
def test_record_responses_read_as_the_general_block_rules(seq: int, ar: uuid.UUID, address: pnio.RecordAddress,
                                                          status: pnio.PnioStatus, data: bytes, tail: bytes,
                                                          mutations: list[tuple[int, int]]) -> None:
    write = bytearray(pnio.IODWriteRes(seq, ar, address, len(data), status).encode() + tail)
    read = bytearray(pnio.IODReadRes(seq, ar, address, data).encode() + tail)
    assert pnio.write_response(bytes(write)) == (seq, address.index, status)
    assert pnio.read_response(bytes(read)) == (seq, address.index, data)
    for at, value in mutations:
        for raw in (write, read):
            if at < len(raw):
                raw[at] = value
    for fast, general, raw in ((pnio.write_response, pnio._write_response, bytes(write)),
                               (pnio.read_response, pnio._read_response, bytes(read))):
        try:
            expected = general(raw)
        except CodecError:
            expected = None
        try:
            assert fast(raw) == expected
        except CodecError:
            assert expected is None


def _general_write(data: bytes, sequence: int, activity: uuid.UUID) -> bool:
    """Whether the general path (RpcClient._accept, then ProfinetTransport._write_outcome) takes ``data`` as the
    Write call's answer with the write done (status OK)."""
    reply = _general(data, sequence, activity)
    if reply is None or reply[0] != pnio.OK or not reply[1]:
        return False
    try:
        return pnio.write_response(reply[1])[2] == pnio.OK
    except CodecError:
        return False


def _general_read(data: bytes, sequence: int, activity: uuid.UUID, rw_seq: int, index: int) -> bytes | None:
    """The record data the general path (RpcClient._accept, then ProfinetTransport._read_reply) returns for ``data``
    as the Read call's answer, or None where it returns none (busy, refused, malformed, another record's)."""
    reply = _general(data, sequence, activity)
    if reply is None or reply[0] != pnio.OK:
        return None
    try:
        got_seq, got_index, record = pnio.read_response(reply[1])
    except CodecError:
        return None
    return record if (got_seq, got_index) == (rw_seq, index) else None


@settings(max_examples=300, deadline=None)
@given(activity=st.uuids(), sequence=u32, little=st.booleans(), status=statuses, record_status=statuses, seq=u16,
       ar=st.uuids(), address=rw_addresses, data=st.binary(max_size=40), tail=st.binary(max_size=4),
       asked=st.sampled_from(["same", "other-seq", "other-index"]),
       mutations=st.lists(st.tuples(st.integers(0, 170), st.integers(0, 255)), max_size=3), cut=st.integers(0, 4))
def test_written_and_read_data_take_only_what_the_general_path_takes(
        activity: uuid.UUID, sequence: int, little: bool, status: pnio.PnioStatus, record_status: pnio.PnioStatus,
        seq: int, ar: uuid.UUID, address: pnio.RecordAddress, data: bytes, tail: bytes, asked: str,
        mutations: list[tuple[int, int]], cut: int) -> None:
    template = dcerpc.RequestTemplate(OBJ, pnio.DEVICE_INTERFACE, activity)
    calls = RecordCalls(template, ar.bytes, address, 240, activity)
    write = bytearray(_reply(activity, sequence, little, status,
                             pnio.IODWriteRes(seq, ar, address, len(data), record_status).encode() + tail))
    read = bytearray(_reply(activity, sequence, little, status, pnio.IODReadRes(seq, ar, address, data).encode()))
    for raw in (write, read):
        for at, value in mutations:
            if at < len(raw):
                raw[at] = value
        if cut:
            del raw[-cut:]
    rw_seq = seq if asked != "other-seq" else (seq + 1) & 0xFFFF
    index = address.index if asked != "other-index" else (address.index + 1) & 0xFFFF
    if index != address.index:
        calls = RecordCalls(template, ar.bytes, pnio.RecordAddress(address.api, address.slot, address.subslot, index),
                            240, activity)
    assert calls.written(bytes(write), len(write), sequence) is _general_write(bytes(write), sequence, activity)
    assert calls.read_data(bytes(read), len(read), sequence, rw_seq) == _general_read(bytes(read), sequence, activity,
                                                                                      rw_seq, index)
    # in a receive buffer longer than the datagram, the bytes after ``size`` are never read
    junk = b"\xff" * 200
    assert calls.written(bytes(write) + junk, len(write), sequence) is calls.written(bytes(write), len(write), sequence)
    assert calls.read_data(bytearray(read) + junk, len(read), sequence, rw_seq) == calls.read_data(
        bytes(read), len(read), sequence, rw_seq)
    if not mutations and not cut:  # the usual answers are taken, and only for their own call
        assert calls.written(bytes(write), len(write), sequence) is (status == pnio.OK and record_status == pnio.OK)
        usual = status == pnio.OK and asked == "same"
        assert calls.read_data(bytes(read), len(read), sequence, rw_seq) == (data if usual else None)
        assert not calls.written(bytes(write), len(write), (sequence + 1) & 0xFFFFFFFF)
        assert calls.read_data(bytes(read), len(read), (sequence + 1) & 0xFFFFFFFF, rw_seq) is None
