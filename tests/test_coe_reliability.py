"""The CoE SDO client under loss, duplication, delay and hostile servers (issue 17 items 6 and 8).

In-memory links in front of the simulator's SdoServer: each test states what the wire does (drop a request,
drop a reply, duplicate, delay, rewrite the counter) and what the client must conclude. A write is never sent
twice, a duplicate of an earlier answer is never taken for the current request, and an upload is capped.
"""

from __future__ import annotations

import random
from collections import deque

import pytest

from akdctl.channels.coe_sdo import CoeObjectChannel
from akdctl.errors import MalformedReply, NoAnswer, UnknownOutcome
from akdctl.links import Budget, MailboxLink
from akdctl.protocol import coe, mailbox as mbx
from akdctl.protocol.coe import CoeService
from akdctl.sim.sdo_server import SdoServer
from tests import fakes


class CountingObjects(fakes.CountingObjects):
    """Objects whose every applied write is counted (what "applied twice" would show)."""

    VALUES = {(0x6040, 0): b"\x00\x00", (0x607A, 0): bytes(4),
              (0x2100, 0): b"start", (0x1000, 0): b"\x92\x01\x02\x00"}


class Wire(MailboxLink):
    """A scripted link: ``plan`` decides per request what happens to it and to its replies.

    Each entry of ``script`` (consumed per request, default "ok") is one of: ``ok``; ``lose-request``;
    ``lose-reply``; ``dup`` (reply twice); ``late`` (the reply arrives after the next request's).
    Replies held back by ``late`` are delivered just after the next request's replies.
    """

    def __init__(self, server: SdoServer, mailbox_size: int = 512) -> None:
        self.server = server
        self.mailbox_size = mailbox_size
        self.inbox: deque[bytes] = deque()
        self.sent: list[bytes] = []
        self.script: deque[str] = deque()
        self.held: list[bytes] = []
        self.rewrite_counter: int | None = None
        self.slave_counter: int | None = None  # set: replies numbered by the slave itself, 1..7

    def send(self, mailbox: bytes) -> None:
        self.sent.append(bytes(mailbox))
        what = self.script.popleft() if self.script else "ok"
        held, self.held = self.held, []
        if what == "lose-request":
            self.inbox.extend(held)
            return
        replies = self.server.handle(mailbox)
        if self.rewrite_counter is not None:
            replies = [r[:5] + bytes([r[5] & 0x0F | self.rewrite_counter << 4]) + r[6:] for r in replies]
        if self.slave_counter is not None:
            numbered = []
            for r in replies:
                self.slave_counter = mbx.next_counter(self.slave_counter)
                numbered.append(r[:5] + bytes([r[5] & 0x0F | self.slave_counter << 4]) + r[6:])
            replies = numbered
        if what == "lose-reply":
            replies = []
        elif what == "dup":
            replies = [r for r in replies for _ in (0, 1)]
        elif what == "late":
            self.held, replies = replies, []
        self.inbox.extend(replies)
        self.inbox.extend(held)

    def receive(self, timeout: float) -> bytes | None:
        return self.inbox.popleft() if self.inbox else None


def make(retries: int = 2, timeout: float = 0.2, mailbox_size: int = 512) -> tuple[CoeObjectChannel, Wire, CountingObjects]:
    objects = CountingObjects()
    wire = Wire(SdoServer(objects, mailbox_size=mailbox_size), mailbox_size)
    return CoeObjectChannel(wire, budget=Budget(timeout, retries)), wire, objects


def sdo_requests(wire: Wire) -> list[coe.SdoMessage]:
    out = []
    for frame in wire.sent:
        _service, _n, payload = coe.decode_coe(mbx.decode_mailbox(frame).data)
        out.append(coe.decode_sdo(payload, from_server=False))
    return out


def downloads(wire: Wire) -> list[coe.SdoMessage]:
    return [m for m in sdo_requests(wire) if isinstance(m, coe.SdoDownloadInitiate)]


def test_duplicate_of_the_previous_writes_answer_is_not_taken_for_the_next_write() -> None:
    """Issue 17.6: the duplicated 0x6040=0x6F answer must not confirm the 0x6040=0x7F write."""
    channel, wire, objects = make()
    wire.script.extend(["dup", "lose-request"])  # 0x6F answered twice; the 0x7F request is lost on the way
    channel.download(0x6040, 0, b"\x6f\x00")
    with pytest.raises(UnknownOutcome) as info:
        channel.download(0x6040, 0, b"\x7f\x00")
    assert objects.writes[(0x6040, 0, b"\x7f\x00")] == 0
    assert "reads back 6f 00" in info.value.message and "does not send a write twice" in info.value.message
    assert info.value.exit_code == 3
    assert len(downloads(wire)) == 2  # the lost write was not sent again


def test_a_late_answer_is_not_taken_for_the_next_write_on_an_echoing_link() -> None:
    channel, wire, objects = make()
    channel.upload(0x1000, 0)
    channel.upload(0x1000, 0)  # two echoed counters: the link is known to echo
    assert channel.filter.echoes
    wire.script.extend(["late", "ok", "lose-request"])  # 0x6F's answer comes late; the 0x7F request is lost
    channel.download(0x6040, 0, b"\x6f\x00")  # confirmed by reading back
    with pytest.raises(UnknownOutcome):
        channel.download(0x6040, 0, b"\x7f\x00")  # the late 0x6F answer carries the wrong counter
    assert objects.writes[(0x6040, 0, b"\x6f\x00")] == 1 and objects.writes[(0x6040, 0, b"\x7f\x00")] == 0


def test_a_late_answer_on_a_counter_rewriting_link_is_checked_by_reading_back() -> None:
    channel, wire, objects = make()
    wire.slave_counter = 0  # a master that rewrites counters: replies carry the slave's own counter
    wire.script.extend(["late", "ok", "lose-request"])
    channel.download(0x6040, 0, b"\x6f\x00")
    with pytest.raises(UnknownOutcome) as info:
        channel.download(0x6040, 0, b"\x7f\x00")  # the late 0x6F answer cannot be told apart: read back
    assert "late answer to an earlier write" in info.value.message and "reads back 6f 00" in info.value.message
    assert not channel.filter.echoes
    assert objects.writes[(0x6040, 0, b"\x7f\x00")] == 0
    channel.download(0x6040, 0, b"\x0f\x00")  # later writes to that object are confirmed, and succeed
    assert objects.values[(0x6040, 0)] == b"\x0f\x00"


def test_lost_answer_to_a_write_is_confirmed_by_reading_back_never_by_writing_again() -> None:
    channel, wire, objects = make()
    wire.script.append("lose-reply")
    channel.download(0x607A, 0, (1000).to_bytes(4, "little"))
    assert objects.writes[(0x607A, 0, (1000).to_bytes(4, "little"))] == 1
    kinds = [type(m).__name__ for m in sdo_requests(wire)]
    assert kinds == ["SdoDownloadInitiate", "SdoUploadInitiate"]


def test_write_without_retries_has_no_time_to_read_back() -> None:
    channel, wire, objects = make(retries=0, timeout=0.05)
    wire.script.append("lose-reply")
    with pytest.raises(UnknownOutcome) as info:
        channel.download(0x607A, 0, b"\x05\x00\x00\x00")
    assert "no time was left to read it back" in info.value.message
    assert len(wire.sent) == 1


def test_lost_segmented_write_is_aborted_and_read_back() -> None:
    channel, wire, objects = make(mailbox_size=32)
    text = bytes(range(65, 65 + 50))
    wire.script.extend(["ok", "lose-reply"])  # the first segment's answer is lost
    with pytest.raises(UnknownOutcome):
        channel.download(0x2100, 0, text)
    requests = sdo_requests(wire)
    assert isinstance(requests[2], coe.SdoAbort) and requests[2].code == coe.ABORT_TIMEOUT
    assert not any(objects.writes[k] for k in objects.writes)  # the server dropped the half transfer
    assert sum(isinstance(m, coe.SdoDownloadInitiate) for m in requests) == 1


def test_rewritten_counters_still_work_and_duplicates_are_dropped() -> None:
    """A master that rewrites the counter: a reply byte for byte equal to an accepted one is a duplicate."""
    channel, wire, objects = make()
    wire.slave_counter = 2
    for value in [b"\x06\x00", b"\x07\x00", b"\x0f\x00"]:
        wire.script.append("dup")
        channel.download(0x6040, 0, value)
    assert [objects.writes[(0x6040, 0, v)] for v in (b"\x06\x00", b"\x07\x00", b"\x0f\x00")] == [1, 1, 1]
    assert not channel.filter.echoes


def test_echo_assumption_is_dropped_when_the_counter_stops_matching() -> None:
    channel, wire, _objects = make(timeout=0.3)
    channel.upload(0x1000, 0)
    channel.upload(0x1000, 0)
    assert channel.filter.echoes
    wire.rewrite_counter = 5  # a master that rewrites after all (coincidence so far)
    assert channel.upload(0x1000, 0) == b"\x92\x01\x02\x00"  # first attempt drops it, the repeat takes it
    assert not channel.filter.echoes


@pytest.mark.parametrize("seed", range(12))
def test_random_loss_and_duplication_never_applies_a_write_twice(seed: int) -> None:
    """20 % of requests or replies lost, 20 % of replies duplicated or late: a write that reports success
    was applied exactly once, one that fails was applied at most once."""
    rng = random.Random(seed)
    channel, wire, objects = make(retries=2, timeout=0.05)
    outcomes = []
    for n in range(40):
        wire.script.extend(rng.choices(["ok", "lose-request", "lose-reply", "dup", "late"],
                                       weights=[60, 10, 10, 10, 10], k=4))
        value = (n + 1).to_bytes(4, "little")
        try:
            channel.download(0x607A, 0, value)
            outcomes.append((value, True))
        except (UnknownOutcome, NoAnswer):
            outcomes.append((value, False))
        wire.script.clear()
    for value, ok in outcomes:
        applied = objects.writes[(0x607A, 0, value)]
        assert applied <= 1
        if ok:
            assert applied == 1
    assert any(ok for _v, ok in outcomes)


class EndlessServer(MailboxLink):
    """A hostile server: announces ``size`` bytes and sends non-last segments for ever."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.inbox: deque[bytes] = deque()
        self.mailbox_size = 512
        self.sent: list[bytes] = []

    def send(self, mailbox: bytes) -> None:
        self.sent.append(bytes(mailbox))
        frame = mbx.decode_mailbox(mailbox)
        _s, _n, payload = coe.decode_coe(frame.data)
        msg = coe.decode_sdo(payload, from_server=False)
        if isinstance(msg, coe.SdoUploadInitiate):
            reply: coe.SdoMessage = coe.SdoUploadResponse(msg.index, msg.subindex, b"x" * 100, self.size, False)
        elif isinstance(msg, coe.SdoUploadSegment):
            reply = coe.SdoUploadSegmentResponse(msg.toggle, b"y" * 400, False)
        else:
            return
        data = coe.encode_coe(CoeService.SDO_RESPONSE, coe.encode_sdo(reply))
        self.inbox.append(mbx.encode_mailbox(mbx.Mailbox(mbx.MailboxType.COE, data, counter=frame.counter)))

    def receive(self, timeout: float) -> bytes | None:
        return self.inbox.popleft() if self.inbox else None


def test_upload_announcing_4_gib_is_refused_at_once() -> None:
    link = EndlessServer(0xFFFFFFFF)
    channel = CoeObjectChannel(link, budget=Budget(1.0, 2))
    with pytest.raises(MalformedReply) as info:
        channel.upload(0x2100, 0)
    assert "4294967295 bytes" in info.value.message and "aborted" in info.value.message
    assert len(link.sent) == 2  # the initiate and the abort


def test_endless_segments_stop_at_the_announced_size() -> None:
    link = EndlessServer(5000)
    channel = CoeObjectChannel(link, budget=Budget(1.0, 2))
    with pytest.raises(MalformedReply) as info:
        channel.upload(0x2100, 0)
    assert "announced 5000" in info.value.message
    assert len(link.sent) <= 2 + 5000 // 400 + 1


def test_cap_is_configurable() -> None:
    link = EndlessServer(3000)
    channel = CoeObjectChannel(link, budget=Budget(1.0, 2), max_upload=2048)
    with pytest.raises(MalformedReply, match="more than the 2048 bytes"):
        channel.upload(0x2100, 0)


def test_silent_drive_uses_one_timeout_for_all_attempts_and_then_the_command_waits_no_more() -> None:
    """Issue 17.9: the attempts share --timeout; once a request went unanswered for all of it, later
    requests of the same command are still sent (a stop must go out) but wait only a tenth of it."""
    objects = CountingObjects()
    wire = Wire(SdoServer(objects), 512)
    wire.script.extend(["lose-request"] * 10)
    budget = Budget(0.06, 2)
    channel = CoeObjectChannel(wire, budget=budget)
    with pytest.raises(NoAnswer) as info:
        channel.upload(0x1000, 0)
    assert "3 attempts of 0.02 s" in info.value.message
    assert budget.exhausted
    with pytest.raises(UnknownOutcome) as later:
        channel.download(0x6040, 0, b"\x00\x00")
    assert "the command had already waited its whole timeout" in later.value.message
    assert len(downloads(wire)) == 1  # the write still went out, once
    wire.script.clear()
    assert channel.upload(0x1000, 0) == b"\x92\x01\x02\x00"  # an answer clears the count
    assert not budget.exhausted
