"""CoeObjectChannel against SdoServer through an in-memory MailboxLink."""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable

import pytest

from akdctl.channels.coe_sdo import CoeObjectChannel
from akdctl.errors import CommError, MalformedReply, NoAnswer, SdoAborted
from akdctl.protocol import coe, coe_info
from akdctl.protocol.coe import CoeService
from akdctl.protocol.emcy import Emergency
from akdctl.protocol.mailbox import (
    Mailbox,
    MailboxErrorReply,
    MailboxType,
    decode_mailbox,
    encode_error_reply,
    encode_mailbox,
)
from akdctl.sim.sdo_server import EntryInfo, ObjectInfo, SdoAccessError, SdoServer
from akdctl.links import MailboxLink

LONG_TEXT = bytes((i * 7 + 3) % 95 + 32 for i in range(3000))  # a 3000-byte visible string


class DictObjects:
    """A dict-backed ObjectAccess (with SDO information) standing in for the drive model."""

    def __init__(self) -> None:
        self.values: dict[tuple[int, int], bytes] = {
            (0x6041, 0): b"\x37\x02",
            (0x6060, 0): b"\x01",
            (0x607A, 0): b"\x00\x00\x00\x00",
            (0x1008, 0): b"AKD-P00306-NBEC-0000",
            (0x2100, 0): LONG_TEXT,
        }
        self.read_only = {(0x6041, 0), (0x1008, 0)}

    def object_read(self, index: int, subindex: int) -> bytes:
        try:
            return self.values[(index, subindex)]
        except KeyError:
            raise SdoAccessError(0x06020000) from None

    def object_write(self, index: int, subindex: int, data: bytes) -> None:
        self.object_read(index, subindex)
        if (index, subindex) in self.read_only:
            raise SdoAccessError(0x06010002)
        self.values[(index, subindex)] = data

    def object_indices(self) -> list[int]:
        return sorted({i for i, _ in self.values})

    def object_info(self, index: int) -> ObjectInfo:
        if index not in self.object_indices():
            raise SdoAccessError(0x06020000)
        entries = {0: EntryInfo(f"value of {index:04X}", 0x0006, 16, 0x87)}
        return ObjectInfo(index, f"object {index:04X}", 7, 0x0006, 0, entries)


class MemoryLink(MailboxLink):
    """Hands each request to an SdoServer and queues its replies; hooks can drop or rewrite them."""

    def __init__(self, server: SdoServer, mailbox_size: int = 512) -> None:
        self.server = server
        self.mailbox_size = mailbox_size
        self.inbox: deque[bytes] = deque()
        self.sent: list[bytes] = []
        self.drop_replies = 0
        self.silent = False
        self.rewrite: Callable[[bytes], bytes] | None = None

    def send(self, mailbox: bytes) -> None:
        assert len(mailbox) <= self.mailbox_size
        self.sent.append(mailbox)
        replies = self.server.handle(mailbox)
        if self.silent:
            return
        if self.drop_replies:
            self.drop_replies -= 1
            return
        for reply in replies:
            self.inbox.append(self.rewrite(reply) if self.rewrite else reply)

    def receive(self, timeout: float) -> bytes | None:
        return self.inbox.popleft() if self.inbox else None


@pytest.fixture
def objects() -> DictObjects:
    return DictObjects()


def make(objects: DictObjects, mailbox_size: int = 512, **kwargs: object) -> tuple[CoeObjectChannel, MemoryLink]:
    link = MemoryLink(SdoServer(objects, mailbox_size=mailbox_size), mailbox_size)
    options: dict = {"timeout": 0.05, "retries": 2, **kwargs}
    return CoeObjectChannel(link, **options), link


def sent_sdo(link: MemoryLink) -> list[coe.SdoMessage]:
    out = []
    for frame in link.sent:
        _service, _n, payload = coe.decode_coe(decode_mailbox(frame).data)
        out.append(coe.decode_sdo(payload, from_server=False))
    return out


def test_expedited_upload_and_download(objects: DictObjects) -> None:
    channel, link = make(objects)
    assert channel.upload(0x6041, 0) == b"\x37\x02"
    channel.download(0x607A, 0, (100000).to_bytes(4, "little"))
    assert objects.values[(0x607A, 0)] == (100000).to_bytes(4, "little")
    assert channel.requests == 2
    assert [type(m) for m in sent_sdo(link)] == [coe.SdoUploadInitiate, coe.SdoDownloadInitiate]
    assert sent_sdo(link)[1].expedited


def test_normal_transfer_in_one_round_trip(objects: DictObjects) -> None:
    channel, link = make(objects)
    assert channel.upload(0x1008, 0) == b"AKD-P00306-NBEC-0000"
    channel.download(0x2100, 0, b"x" * 400)
    assert objects.values[(0x2100, 0)] == b"x" * 400
    assert channel.requests == 2
    assert sent_sdo(link)[1] == coe.SdoDownloadInitiate(0x2100, 0, b"x" * 400, 400, False)


def test_segmented_3000_byte_string_with_small_mailbox(objects: DictObjects) -> None:
    channel, link = make(objects, mailbox_size=64)
    assert channel.upload(0x2100, 0) == LONG_TEXT
    # 48 bytes in the initiate reply, then 55 per segment
    assert channel.requests == 1 + -(-(3000 - 48) // 55)
    reversed_text = LONG_TEXT[::-1]
    channel.download(0x2100, 0, reversed_text)
    assert objects.values[(0x2100, 0)] == reversed_text
    assert channel.upload(0x2100, 0) == reversed_text
    assert all(len(frame) <= 64 for frame in link.sent)


def test_empty_download(objects: DictObjects) -> None:
    channel, _link = make(objects)
    channel.download(0x2100, 0, b"")
    assert objects.values[(0x2100, 0)] == b""
    assert channel.upload(0x2100, 0) == b""


def test_abort_becomes_sdo_aborted(objects: DictObjects) -> None:
    channel, _link = make(objects)
    with pytest.raises(SdoAborted) as info:
        channel.download(0x6041, 0, b"\x06\x00")
    assert info.value.code == 0x06010002
    assert "0x6041:00" in info.value.message and "0x06010002" in info.value.message
    assert "read-only" in info.value.message
    with pytest.raises(SdoAborted) as info:
        channel.upload(0x1234, 5)
    assert info.value.code == 0x06020000 and "0x1234:05" in info.value.message


def test_dropped_reply_is_retried(objects: DictObjects) -> None:
    channel, link = make(objects)
    link.drop_replies = 1
    assert channel.upload(0x6041, 0) == b"\x37\x02"
    assert channel.requests == 2


def test_dropped_segment_reply_restarts_the_transfer(objects: DictObjects) -> None:
    """A segment cannot be repeated alone (the server already flipped its toggle): start over."""
    channel, link = make(objects, mailbox_size=64)
    sends = {"n": 0}
    original_send = link.send

    def send(mailbox: bytes) -> None:
        sends["n"] += 1
        if sends["n"] == 3:  # lose the reply to the second segment request
            link.drop_replies = 1
        original_send(mailbox)

    link.send = send  # type: ignore[method-assign]
    assert channel.upload(0x2100, 0) == LONG_TEXT
    segments = -(-(3000 - 48) // 55)
    assert channel.requests == 3 + 1 + segments
    assert isinstance(sent_sdo(link)[3], coe.SdoUploadInitiate)


def test_silent_link_gives_no_answer(objects: DictObjects) -> None:
    channel, link = make(objects, retries=1, timeout=0.01)
    link.silent = True
    with pytest.raises(NoAnswer) as info:
        channel.upload(0x6041, 0)
    assert channel.requests == 2
    assert "0x6041:00" in info.value.message and "2 attempts" in info.value.message
    assert info.value.exit_code == 3


def test_emergencies_interleaved_are_queued(objects: DictObjects) -> None:
    channel, link = make(objects)
    emcy = Emergency(0x4310, 0x09, b"\x0d\x00\x00\x00\x00")
    link.server.queue_emergency(emcy)
    assert channel.upload(0x6060, 0) == b"\x01"
    link.server.queue_emergency(Emergency(0x0000, 0x00))
    channel.download(0x6060, 0, b"\x03")
    assert channel.take_emergencies() == [emcy, Emergency(0, 0)]
    assert channel.take_emergencies() == []


def test_service_2_reply_accepted_with_warning_spec_note_15(
    objects: DictObjects, caplog: pytest.LogCaptureFixture
) -> None:
    channel, link = make(objects)

    def as_printed(frame: bytes) -> bytes:  # the manual's reply: byte 7 reads 0x20
        return frame[:7] + bytes([frame[7] & 0x0F | 0x20]) + frame[8:]

    link.rewrite = as_printed
    with caplog.at_level(logging.WARNING, logger="akdctl"):
        channel.download(0x6060, 0, b"\x01")
        assert channel.upload(0x6060, 0) == b"\x01"
    assert any("service 2" in r.getMessage() for r in caplog.records)


def test_gateway_counter_rewrite_is_tolerated(objects: DictObjects) -> None:
    channel, link = make(objects)
    link.rewrite = lambda frame: frame[:5] + bytes([frame[5] & 0x0F | 6 << 4]) + frame[6:]
    assert channel.upload(0x6041, 0) == b"\x37\x02"


def test_strict_counter_drops_foreign_counters(objects: DictObjects) -> None:
    channel, link = make(objects, strict_counter=True, retries=0, timeout=0.01)
    assert channel.upload(0x6041, 0) == b"\x37\x02"  # the server echoes the counter
    link.rewrite = lambda frame: frame[:5] + bytes([frame[5] & 0x0F | 6 << 4]) + frame[6:]
    with pytest.raises(NoAnswer):
        channel.upload(0x6041, 0)


def test_counter_wraps_1_to_7(objects: DictObjects) -> None:
    channel, link = make(objects)
    for _ in range(9):
        channel.upload(0x6041, 0)
    assert [decode_mailbox(f).counter for f in link.sent] == [1, 2, 3, 4, 5, 6, 7, 1, 2]


def test_station_address_in_requests(objects: DictObjects) -> None:
    channel, link = make(objects, station=0x1001)
    channel.upload(0x6041, 0)
    assert decode_mailbox(link.sent[0]).address == 0x1001


def test_mailbox_error_reply_is_a_comm_error(objects: DictObjects) -> None:
    channel, link = make(objects)

    def refuse(frame: bytes) -> bytes:
        request = decode_mailbox(frame)
        return encode_mailbox(Mailbox(MailboxType.ERROR, encode_error_reply(MailboxErrorReply(4)), counter=request.counter))

    link.rewrite = refuse
    with pytest.raises(CommError) as info:
        channel.upload(0x6041, 0)
    assert info.value.code == 4 and "not supported" in info.value.message.lower()


def test_garbage_and_foreign_mailboxes_are_skipped(objects: DictObjects) -> None:
    channel, link = make(objects)
    link.inbox.extend([b"\x01", encode_mailbox(Mailbox(MailboxType.FOE, b"xx")), b"\xff" * 20])
    original_send = link.send

    def send(mailbox: bytes) -> None:
        link.inbox.extend([b"\x00\x00\x00", encode_mailbox(Mailbox(MailboxType.COE, b"\x00\x90"))])
        original_send(mailbox)

    link.send = send  # type: ignore[method-assign]
    assert channel.upload(0x6041, 0) == b"\x37\x02"


def test_stale_reply_for_another_object_is_not_taken(objects: DictObjects) -> None:
    channel, link = make(objects)
    stale = coe.encode_coe(CoeService.SDO_RESPONSE, coe.encode_sdo(coe.SdoUploadResponse(0x6060, 0, b"\x07", 1, True)))
    original_send = link.send

    def send(mailbox: bytes) -> None:
        link.inbox.append(encode_mailbox(Mailbox(MailboxType.COE, stale, counter=1)))
        original_send(mailbox)

    link.send = send  # type: ignore[method-assign]
    assert channel.upload(0x6041, 0) == b"\x37\x02"


def test_inconsistent_segmented_upload_is_malformed(objects: DictObjects) -> None:
    channel, link = make(objects, mailbox_size=64)

    def shrink(frame: bytes) -> bytes:  # announce one byte more than the server will send
        mbx = decode_mailbox(frame)
        service, _n, payload = coe.decode_coe(mbx.data)
        msg = coe.decode_sdo(payload, from_server=True)
        if isinstance(msg, coe.SdoUploadResponse) and not msg.expedited:
            msg = coe.SdoUploadResponse(msg.index, msg.subindex, msg.data, (msg.size or 0) + 1, False)
            return encode_mailbox(Mailbox(MailboxType.COE, coe.encode_coe(service, coe.encode_sdo(msg)), counter=mbx.counter))
        return frame

    link.rewrite = shrink
    with pytest.raises(MalformedReply):
        channel.upload(0x2100, 0)


def test_object_list_and_descriptions(objects: DictObjects) -> None:
    channel, _link = make(objects)
    assert channel.object_list() == [0x1008, 0x2100, 0x6041, 0x6060, 0x607A]
    assert channel.entry_description(0x6041, 0) == coe_info.EntryDescription(0x6041, 0, 0, 0x0006, 16, 0x87, "value of 6041")
    assert channel.object_description(0x6060).name == "object 6060"
    with pytest.raises(SdoAborted) as info:
        channel.entry_description(0x6041, 3)
    assert info.value.code == 0x06090011


def test_object_list_fragmented_over_small_mailbox(objects: DictObjects) -> None:
    for i in range(200):
        objects.values[(0x3000 + i, 0)] = b"\x00"
    channel, _link = make(objects, mailbox_size=32)
    indices = channel.object_list()
    assert len(indices) == 205 and indices == sorted(indices)
    assert channel.requests == 1
