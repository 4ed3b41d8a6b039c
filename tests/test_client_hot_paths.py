"""Issue 15 deliver-2: the client's hot paths do each thing once and nothing when nobody looks.

Structure, not timing (no test asserts a timing): the gateway datagram is the channel's mailbox behind a
2-byte header (no decode/encode round trip), tracing builds nothing when off, each PNU address is checked
once per request, batch planning fills in order in one pass, and a DCE/RPC reply is judged without UUIDs.
"""

from __future__ import annotations

import socket
import uuid

import pytest

from akdctl.channels import batching
from akdctl.channels.bmp import BmpParameterChannel
from akdctl.links import RecordLink
from akdctl.protocol import bmp, dcerpc, mailbox as mbx, pnio
from akdctl.transport.ethercat_udp import GatewayMailboxLink
from akdctl.transport.trace import Tracer


def test_gateway_datagram_is_the_mailbox_behind_two_bytes() -> None:
    server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    server.bind(("127.0.0.1", 0))
    server.settimeout(5)
    link = GatewayMailboxLink("127.0.0.1", server.getsockname()[1], 1001, Tracer(record=False))
    try:
        mailbox = mbx.pack(mbx.MailboxType.COE, bytes.fromhex("00 20 40 18 10 01 00 00 00 00"), 1001, 3)
        link.send(mailbox)
        datagram, peer = server.recvfrom(100)
        assert datagram == bytes.fromhex("10 50") + mailbox
        server.sendto(datagram, peer)
        assert link.receive(5) == mailbox
    finally:
        link.close()
        server.close()


def test_mailbox_pack_and_split_agree_with_the_full_codec() -> None:
    data = bytes(range(10))
    packed = mbx.pack(mbx.MailboxType.COE, data, 0x1234, 5)
    assert packed == mbx.encode_mailbox(mbx.Mailbox(mbx.MailboxType.COE, data, 0x1234, counter=5))
    assert mbx.split(packed + b"tail") == (3, 5, 0x1234, data)
    assert mbx.unwrap_gateway(mbx.wrap_gateway(packed)) == packed


def test_an_inactive_tracer_builds_no_record(monkeypatch: pytest.MonkeyPatch) -> None:
    import akdctl.transport.trace as trace

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("a TraceRecord was built with tracing off")

    monkeypatch.setattr(trace, "TraceRecord", refuse)
    quiet = Tracer(record=False)
    assert not quiet.active
    quiet.frame("tx", "mailbox", b"\x00")  # nothing built
    quiet.record = True
    assert quiet.active


def test_open_tracer_keeps_records_only_when_asked() -> None:
    from akdctl.connection import open_tracer

    tracer = open_tracer()
    assert not tracer.active and not tracer.record
    tracer.record = True  # the support bundle asks
    tracer.frame("tx", "mailbox", b"\x01")
    assert len(tracer.records) == 1


class CannedLink(RecordLink):
    """Answers every read with one word per parameter (the reference and axis echoed)."""

    def exchange(self, request: bytes) -> bytes:
        n = request[3]
        return bytes([request[0], 0x01, request[2], n]) + b"\x42\x01\x00\x07" * n


def test_each_address_is_checked_once_per_read(monkeypatch: pytest.MonkeyPatch) -> None:
    import akdctl.channels.bmp as channel_module

    calls = []
    original = bmp.check_address

    def counting(address: object) -> bmp.ParameterAddress:
        calls.append(address)
        return original(address)

    monkeypatch.setattr(channel_module, "check_address", counting)
    monkeypatch.setattr(bmp, "check_address", counting)
    addresses = [bmp.ParameterAddress(900 + i) for i in range(39)]
    results = BmpParameterChannel(CannedLink()).read(addresses)
    assert [r.value for r in results] == [7] * 39  # type: ignore[union-attr]
    assert len(calls) == 39


def test_plan_reads_fills_in_order_in_one_pass() -> None:
    sizes = [4] * 390  # ten requests of 39 word reads
    batches = batching.plan_reads(sizes)
    assert [len(b) for b in batches] == [39] * 10
    assert [i for b in batches for i in b] == list(range(390))
    costs = [batching.read_cost(bmp.ParameterAddress(930)) for _ in range(5)]
    assert batching.pack(costs) == [[0, 1, 2, 3, 4]]


def test_dcerpc_view_matches_the_full_decode_and_the_template_the_encoder() -> None:
    obj, act = uuid.uuid4(), uuid.uuid4()
    template = dcerpc.RequestTemplate(obj, pnio.DEVICE_INTERFACE, act)
    header = dcerpc.RpcHeader(ptype=dcerpc.PT_REQUEST, object_uuid=obj, interface_uuid=pnio.DEVICE_INTERFACE,
                              activity_uuid=act, sequence=7, opnum=3, flags1=dcerpc.FLAG_IDEMPOTENT)
    assert template.packet(7, 3, b"body") == dcerpc.encode_packet(header, b"body")
    for little in (False, True):
        reply = dcerpc.encode_packet(dcerpc.RpcHeader(
            ptype=dcerpc.PT_RESPONSE, object_uuid=obj, interface_uuid=pnio.DEVICE_INTERFACE, activity_uuid=act,
            sequence=7, opnum=3, drep=dcerpc.DREP_LITTLE if little else dcerpc.DREP_BIG), b"answer")
        view = dcerpc.view_packet(reply)
        assert template.is_ours(view) and view.sequence == 7 and view.body == b"answer" and view.little is little
        assert dcerpc.decode_packet(reply).header.activity_uuid == act
    other = dcerpc.RequestTemplate(obj, pnio.DEVICE_INTERFACE, uuid.uuid4())
    assert not other.is_ours(dcerpc.view_packet(reply))


def test_gateway_receive_with_no_time_left_still_takes_what_is_there() -> None:
    """The channel drains leftovers with receive(0) after an unanswered request: that must read them."""
    server = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    server.bind(("127.0.0.1", 0))
    link = GatewayMailboxLink("127.0.0.1", server.getsockname()[1], 1001, Tracer(record=False))
    try:
        mailbox = mbx.pack(mbx.MailboxType.COE, bytes(10), 1001, 1)
        server.sendto(mbx.wrap_gateway(mailbox), link.sock.getsockname())  # type: ignore[union-attr]
        from tests.harness import wait_until

        got: list[bytes | None] = []
        wait_until(lambda: got.append(link.receive(0)) or got[-1] is not None, "the queued reply")
        assert got[-1] == mailbox
        assert link.receive(0) is None
    finally:
        link.close()
        server.close()
