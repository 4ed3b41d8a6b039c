"""SdoServer: what the simulated AKD answers to CoE mailboxes, byte for byte."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.protocol import coe, coe_info
from akdctl.protocol.coe import CoeService
from akdctl.protocol.emcy import Emergency, decode_emcy
from akdctl.protocol.mailbox import (
    Mailbox,
    MailboxType,
    decode_error_reply,
    decode_mailbox,
    encode_mailbox,
)
from akdctl.sim.sdo_server import EntryInfo, ObjectInfo, SdoAccessError, SdoServer

STRING = bytes(range(256)) * 4 + b"tail"  # 1028 bytes


class FakeObjects:
    """Dict-backed ObjectAccess with SDO-information support."""

    def __init__(self) -> None:
        self.values: dict[tuple[int, int], bytes] = {
            (0x6041, 0): b"\x37\x02",
            (0x1018, 1): b"\x6a\x00\x00\x00",
            (0x1008, 0): b"AKD-P00306-NBEC",
            (0x2100, 0): STRING,
            (0x6060, 0): b"\x01",
        }
        self.read_only = {(0x6041, 0), (0x1018, 1), (0x1008, 0)}
        self.writes: list[tuple[int, int, bytes]] = []

    def object_read(self, index: int, subindex: int) -> bytes:
        if (index, subindex) not in self.values:
            raise SdoAccessError(0x06020000 if all(i != index for i, _ in self.values) else 0x06090011)
        return self.values[(index, subindex)]

    def object_write(self, index: int, subindex: int, data: bytes) -> None:
        self.object_read(index, subindex)
        if (index, subindex) in self.read_only:
            raise SdoAccessError(0x06010002)
        self.values[(index, subindex)] = data
        self.writes.append((index, subindex, data))

    def object_indices(self) -> list[int]:
        return sorted({i for i, _ in self.values})

    def object_info(self, index: int) -> ObjectInfo:
        if index not in self.object_indices():
            raise SdoAccessError(0x06020000)
        entries = {s: EntryInfo(f"entry {s}", 0x0007, 32, 0x07 | (0x80 if index == 0x6041 else 0))
                   for i, s in self.values if i == index}
        return ObjectInfo(index, f"object {index:04X}", 7, 0x0007, max(entries), entries)


class PlainObjects:
    """An ObjectAccess without SDO information."""

    def object_read(self, index: int, subindex: int) -> bytes:
        return b"\x01\x02"

    def object_write(self, index: int, subindex: int, data: bytes) -> None:
        raise RuntimeError("model bug")


def request(msg: coe.SdoMessage, counter: int = 3, address: int = 0) -> bytes:
    data = coe.encode_coe(CoeService.SDO_REQUEST, coe.encode_sdo(msg))
    return encode_mailbox(Mailbox(MailboxType.COE, data, address=address, counter=counter))


def sdo_reply(frame: bytes) -> coe.SdoMessage:
    mbx = decode_mailbox(frame)
    assert mbx.type == MailboxType.COE
    service, _number, payload = coe.decode_coe(mbx.data)
    msg = coe.decode_sdo(payload, from_server=True)
    # ETG.1000.6: an abort travels as CoE service 2 (SDO request), every other reply as 3 (what SOEM expects)
    assert service == (CoeService.SDO_REQUEST if isinstance(msg, coe.SdoAbort) else CoeService.SDO_RESPONSE)
    return msg


def only(replies: list[bytes]) -> coe.SdoMessage:
    assert len(replies) == 1
    return sdo_reply(replies[0])


@pytest.fixture
def objects() -> FakeObjects:
    return FakeObjects()


@pytest.fixture
def server(objects: FakeObjects) -> SdoServer:
    return SdoServer(objects, mailbox_size=64)


# --- uploads -----------------------------------------------------------------------------------


def test_expedited_upload_bytes_echo_counter_and_address(server: SdoServer) -> None:
    replies = server.handle(request(coe.SdoUploadInitiate(0x1018, 1), counter=5, address=4))
    # the ETG.8200 worked example's reply, with our counter echoed
    assert replies == [bytes.fromhex("0a00040000530030431810016a000000")]


def test_normal_upload_in_one_mailbox(server: SdoServer) -> None:
    assert only(server.handle(request(coe.SdoUploadInitiate(0x1008, 0)))) == coe.SdoUploadResponse(
        0x1008, 0, b"AKD-P00306-NBEC", 15, False
    )


def test_segmented_upload_with_toggles(server: SdoServer) -> None:
    first = only(server.handle(request(coe.SdoUploadInitiate(0x2100, 0))))
    assert isinstance(first, coe.SdoUploadResponse) and first.size == len(STRING)
    assert len(first.data) == 64 - 16
    data, toggle = bytearray(first.data), 0
    while True:
        replies = server.handle(request(coe.SdoUploadSegment(toggle)))
        assert all(len(r) <= 64 for r in replies)
        seg = only(replies)
        assert isinstance(seg, coe.SdoUploadSegmentResponse) and seg.toggle == toggle
        data += seg.data
        toggle ^= 1
        if seg.last:
            break
    assert bytes(data) == STRING


def test_upload_segment_toggle_error_aborts(server: SdoServer) -> None:
    server.handle(request(coe.SdoUploadInitiate(0x2100, 0)))
    assert only(server.handle(request(coe.SdoUploadSegment(1)))) == coe.SdoAbort(0x2100, 0, 0x05030000)
    # the transfer is gone: a further segment request is an unknown command
    assert only(server.handle(request(coe.SdoUploadSegment(0)))).code == 0x05040001


def test_upload_aborts_from_access(server: SdoServer) -> None:
    assert only(server.handle(request(coe.SdoUploadInitiate(0x1234, 0)))) == coe.SdoAbort(0x1234, 0, 0x06020000)
    assert only(server.handle(request(coe.SdoUploadInitiate(0x6041, 7)))) == coe.SdoAbort(0x6041, 7, 0x06090011)


def test_complete_access_refused(server: SdoServer) -> None:
    reply = only(server.handle(request(coe.SdoUploadInitiate(0x1C12, 0, complete_access=True))))
    assert reply == coe.SdoAbort(0x1C12, 0, 0x06010000)


# --- downloads ---------------------------------------------------------------------------------


def test_expedited_download(server: SdoServer, objects: FakeObjects) -> None:
    reply = only(server.handle(request(coe.SdoDownloadInitiate(0x6060, 0, b"\x03", 1, True))))
    assert reply == coe.SdoDownloadResponse(0x6060, 0)
    assert objects.values[(0x6060, 0)] == b"\x03"


def test_download_read_only_aborts(server: SdoServer, objects: FakeObjects) -> None:
    reply = only(server.handle(request(coe.SdoDownloadInitiate(0x6041, 0, b"\x00\x00", 2, True))))
    assert reply == coe.SdoAbort(0x6041, 0, 0x06010002)
    assert objects.writes == []


def test_normal_download(server: SdoServer, objects: FakeObjects) -> None:
    reply = only(server.handle(request(coe.SdoDownloadInitiate(0x2100, 0, b"x" * 40, 40, False))))
    assert reply == coe.SdoDownloadResponse(0x2100, 0)
    assert objects.values[(0x2100, 0)] == b"x" * 40


def test_segmented_download(server: SdoServer, objects: FakeObjects) -> None:
    payload = bytes(range(200))
    assert only(server.handle(request(coe.SdoDownloadInitiate(0x2100, 0, payload[:48], 200, False)))) == (
        coe.SdoDownloadResponse(0x2100, 0)
    )
    rest, toggle = payload[48:], 0
    while rest:
        chunk, rest = rest[:55], rest[55:]
        assert objects.writes == []  # nothing is written before the last segment
        reply = only(server.handle(request(coe.SdoDownloadSegment(toggle, chunk, not rest))))
        assert reply == coe.SdoDownloadSegmentResponse(toggle)
        toggle ^= 1
    assert objects.values[(0x2100, 0)] == payload


def test_download_segment_toggle_error(server: SdoServer, objects: FakeObjects) -> None:
    server.handle(request(coe.SdoDownloadInitiate(0x2100, 0, b"a" * 10, 30, False)))
    assert only(server.handle(request(coe.SdoDownloadSegment(1, b"b" * 20, True)))) == coe.SdoAbort(
        0x2100, 0, 0x05030000
    )
    assert objects.writes == []


def test_download_segment_length_checks(server: SdoServer, objects: FakeObjects) -> None:
    server.handle(request(coe.SdoDownloadInitiate(0x2100, 0, b"a" * 10, 20, False)))
    assert only(server.handle(request(coe.SdoDownloadSegment(0, b"b" * 20, True)))).code == 0x06070012
    server.handle(request(coe.SdoDownloadInitiate(0x2100, 0, b"a" * 10, 20, False)))
    assert only(server.handle(request(coe.SdoDownloadSegment(0, b"b" * 5, True)))).code == 0x06070013
    assert objects.writes == []


def test_download_segment_without_initiate(server: SdoServer) -> None:
    assert only(server.handle(request(coe.SdoDownloadSegment(0, b"x", True)))).code == 0x05040001


def test_client_abort_clears_transfer_without_reply(server: SdoServer) -> None:
    server.handle(request(coe.SdoUploadInitiate(0x2100, 0)))
    assert server.handle(request(coe.SdoAbort(0x2100, 0, 0x05040000))) == []
    assert only(server.handle(request(coe.SdoUploadSegment(0)))).code == 0x05040001


def test_block_transfer_command_aborts_unknown(server: SdoServer) -> None:
    data = coe.encode_coe(CoeService.SDO_REQUEST, bytes([0xC0]) + struct.pack("<HB", 0x2100, 0) + bytes(4))
    reply = only(server.handle(encode_mailbox(Mailbox(MailboxType.COE, data))))
    assert reply == coe.SdoAbort(0x2100, 0, 0x05040001)


def test_model_bug_becomes_general_error() -> None:
    server = SdoServer(PlainObjects())
    reply = only(server.handle(request(coe.SdoDownloadInitiate(0x1000, 0, b"\x01", 1, True))))
    assert reply == coe.SdoAbort(0x1000, 0, 0x08000000)


# --- mailbox errors ----------------------------------------------------------------------------


def error_code(replies: list[bytes]) -> int:
    assert len(replies) == 1
    mbx = decode_mailbox(replies[0])
    assert mbx.type == MailboxType.ERROR
    return decode_error_reply(mbx.data).code


def test_mailbox_error_replies(server: SdoServer) -> None:
    assert error_code(server.handle(b"\x0a\x00")) == 6
    assert error_code(server.handle(bytes([40, 0, 0, 0, 0, 3]) + bytes(10))) == 8
    assert error_code(server.handle(encode_mailbox(Mailbox(MailboxType.FOE, bytes(10), counter=2)))) == 2
    assert error_code(server.handle(encode_mailbox(Mailbox(MailboxType.COE, b"\x00\x20" + bytes(8), channel=1)))) == 3
    assert error_code(server.handle(encode_mailbox(Mailbox(MailboxType.COE, b"\x00\x50" + bytes(8))))) == 4
    assert error_code(server.handle(encode_mailbox(Mailbox(MailboxType.COE, b"\x00\xf0" + bytes(8))))) == 4
    assert error_code(server.handle(encode_mailbox(Mailbox(MailboxType.COE, b"\x00\x20\x40")))) == 6
    assert error_code(server.handle(encode_mailbox(Mailbox(MailboxType.COE, b"\x00\x20" + bytes(100))))) == 8


def test_mailbox_error_reply_echoes_counter(server: SdoServer) -> None:
    [reply] = server.handle(encode_mailbox(Mailbox(MailboxType.EOE, bytes(4), address=7, counter=6)))
    mbx = decode_mailbox(reply)
    assert (mbx.address, mbx.counter) == (7, 6)


# --- emergencies -------------------------------------------------------------------------------


def test_queued_emergency_precedes_next_response(server: SdoServer) -> None:
    emcy = Emergency(0x4310, 0x09, b"\x01\x00\x00\x00\x00")
    server.queue_emergency(emcy)
    replies = server.handle(request(coe.SdoUploadInitiate(0x6041, 0)))
    assert len(replies) == 2
    mbx = decode_mailbox(replies[0])
    service, _n, payload = coe.decode_coe(mbx.data)
    assert service == CoeService.EMERGENCY and decode_emcy(payload) == emcy
    assert 1 <= mbx.counter <= 7
    assert isinstance(sdo_reply(replies[1]), coe.SdoUploadResponse)
    assert len(server.handle(request(coe.SdoUploadInitiate(0x6041, 0)))) == 1


# --- SDO information ---------------------------------------------------------------------------


def info_exchange(server: SdoServer, msg: coe_info.SdoInfoMessage) -> coe_info.SdoInfoMessage:
    data = coe.encode_coe(CoeService.SDO_INFO, coe_info.encode_sdo_info(coe_info.pack_info(msg)))
    replies = server.handle(encode_mailbox(Mailbox(MailboxType.COE, data, counter=1)))
    assembler, done = coe_info.InfoReassembler(), None
    for frame in replies:
        assert len(frame) <= server.mailbox_size
        service, _n, payload = coe.decode_coe(decode_mailbox(frame).data)
        assert service == CoeService.SDO_INFO
        assert done is None
        done = assembler.add(coe_info.decode_sdo_info(payload))
    assert done is not None
    return coe_info.unpack_info(done)


def test_info_object_list(server: SdoServer) -> None:
    assert info_exchange(server, coe_info.OdListRequest()) == coe_info.OdListResponse(1, (0x1008, 0x1018, 0x2100, 0x6041, 0x6060))
    assert info_exchange(server, coe_info.OdListRequest(0)) == coe_info.OdListResponse(0, (5, 0, 1, 0, 0))
    assert info_exchange(server, coe_info.OdListRequest(3)) == coe_info.OdListResponse(3, (0x6041,))


def test_info_object_list_fragmented() -> None:
    objects = FakeObjects()
    for i in range(0x3000, 0x3000 + 100):
        objects.values[(i, 0)] = b"\x00"
    server = SdoServer(objects, mailbox_size=32)
    reply = info_exchange(server, coe_info.OdListRequest())
    assert isinstance(reply, coe_info.OdListResponse) and len(reply.indices) == 105


def test_info_descriptions(server: SdoServer) -> None:
    assert info_exchange(server, coe_info.ObjectDescriptionRequest(0x1018)) == coe_info.ObjectDescription(
        0x1018, 0x0007, 1, 7, "object 1018"
    )
    assert info_exchange(server, coe_info.EntryDescriptionRequest(0x6041, 0, 7)) == coe_info.EntryDescription(
        0x6041, 0, 0, 0x0007, 32, 0x87, "entry 0"
    )
    assert info_exchange(server, coe_info.EntryDescriptionRequest(0x6041, 9)) == coe_info.SdoInfoError(0x06090011)
    assert info_exchange(server, coe_info.ObjectDescriptionRequest(0x1234)) == coe_info.SdoInfoError(0x06020000)
    assert info_exchange(server, coe_info.SdoInfoError(1)) == coe_info.SdoInfoError(0x05040001)


def test_info_without_model_support() -> None:
    assert info_exchange(SdoServer(PlainObjects()), coe_info.OdListRequest()) == coe_info.SdoInfoError(0x08000023)


# --- hostile input -------------------------------------------------------------------------------


@settings(max_examples=300)
@given(st.binary(max_size=80))
def test_fuzz_raw_bytes_never_raise(data: bytes) -> None:
    server = SdoServer(FakeObjects(), mailbox_size=64)
    for reply in server.handle(data):
        assert len(reply) <= 64
        decode_mailbox(reply)


@settings(max_examples=300)
@given(st.lists(st.binary(min_size=2, max_size=40), max_size=6))
def test_fuzz_coe_sequences_never_raise(payloads: list[bytes]) -> None:
    server = SdoServer(FakeObjects(), mailbox_size=64)
    for payload in payloads:
        for service in (0x20, 0x80):
            frame = encode_mailbox(Mailbox(MailboxType.COE, bytes([0x00, service]) + payload))
            for reply in server.handle(frame):
                assert len(reply) <= 64
                mbx = decode_mailbox(reply)
                assert mbx.type in (MailboxType.COE, MailboxType.ERROR)
