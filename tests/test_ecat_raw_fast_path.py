"""Issue 29: the raw master's SDO upload path and the simulated slave's quick answers.

* the simulated ESC hands SDO uploads to the frame thread (:attr:`Esc.quick`), everything else to the application
  thread, and never lets a quick answer overtake a reply the application still owes;
* the raw master sends the first poll right behind the SM0 write, before the write is answered: two frames per
  upload from a slave that answers at once, more polls (never a wrong reply) from one that does not.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from akdctl.connection import Connection
from akdctl.protocol import coe, ethercat as ec, mailbox as mbx
from akdctl.sim.drive import SimDrive
from akdctl.sim.face_ethercat_raw import quick_request
from akdctl.transport.trace import Tracer
from tests.test_ecat_esc import al, esc, mailbox_sms, rd, wr
from tests.test_ecat_raw_inprocess import Wire, transport

UPLOAD = mbx.pack(mbx.MailboxType.COE, coe.upload_request(0x1018, 1), 0, 1)
DOWNLOAD = bytes.fromhex("0a00 0000 0023 0020 2f60 6000 0300 0000")  # expedited download 0x6060:00 = 3
REPLY = bytes.fromhex("0a00 0000 0003 0030 4318 1001 6a00 0000")


def test_quick_request_picks_sdo_uploads_only() -> None:
    assert quick_request(UPLOAD.ljust(512, b"\0"))
    segment = mbx.pack(mbx.MailboxType.COE, coe.encode_coe(coe.CoeService.SDO_REQUEST, bytes([0x60]) + bytes(7)), 0, 2)
    assert quick_request(segment)
    assert not quick_request(DOWNLOAD)
    assert not quick_request(mbx.pack(mbx.MailboxType.FOE, bytes(10), 0, 1))
    assert not quick_request(b"\x01")  # not even a mailbox header


def test_the_esc_leaves_quick_requests_to_the_frame_thread_in_order() -> None:
    e = esc()
    mailbox_sms(e)
    al(e, ec.AlState.PREOP)
    e.quick = quick_request
    assert wr(e, 0x1800, UPLOAD.ljust(1024, b"\0")) == 1
    assert e.take_request(0) is None  # not the application's
    assert e.take_quick() == UPLOAD and not rd(e, 0x0805, 1)[0][0] & ec.SM_STATUS_MAILBOX_FULL  # SM0 empty again
    e.post_quick_replies([REPLY])
    assert rd(e, 0x1C00, 1024) == (REPLY.ljust(1024, b"\0"), 1)
    # a write goes to the application; an upload behind it waits its turn there (replies keep their order)
    assert wr(e, 0x1800, DOWNLOAD.ljust(1024, b"\0")) == 1
    assert e.take_request(0) == DOWNLOAD
    assert wr(e, 0x1800, UPLOAD.ljust(1024, b"\0")) == 1
    assert e.take_quick() is None
    e.post_replies([b"download reply"])
    assert e.take_request(0) == UPLOAD
    e.post_replies([REPLY])
    assert e.take_quick() is None
    assert wr(e, 0x1800, UPLOAD.ljust(1024, b"\0")) == 1  # nothing owed any more: quick again
    assert e.take_quick() == UPLOAD


def test_a_mailbox_sm_changed_behind_the_esc_s_back_is_seen_at_once() -> None:
    e = esc()
    mailbox_sms(e)
    al(e, ec.AlState.PREOP)
    e.post_replies([REPLY])
    assert rd(e, 0x1C00, 16)[1] == 1
    e.mem[ec.REG_SM0 + ec.SM_STRIDE + 4] = 0x20  # SM1 in buffered mode now: no longer a mailbox
    assert rd(e, 0x1C00, 16)[1] == 1 and rd(e, 0x1C00 + 1023, 1)[1] == 1  # plain memory: read, nothing released
    assert e.stats.mailbox_replies == 0


@pytest.fixture
def wire(tmp_path: Path):  # noqa: ANN201
    w = Wire(SimDrive("default", tmp_path))
    try:
        yield w
    finally:
        w.close()


def test_an_upload_is_two_frames_the_poll_sent_before_the_write_is_answered(wire: Wire) -> None:
    tracer = Tracer()
    t = transport(wire, tracer)
    conn = Connection.over(t)
    objects = conn.objects()
    assert objects.upload(0x1018, 1) == b"\x6a\0\0\0"
    assert t.master is not None and t.link is not None
    frames, polls = t.master.frames, t.link.polls
    tracer.records.clear()
    for _ in range(20):
        assert objects.upload(0x1018, 1) == b"\x6a\0\0\0"
    assert t.master.frames - frames == 40 and t.link.polls - polls == 20
    directions = [r.direction for r in tracer.records if r.layer == "ecat"]
    assert directions[:4] == ["tx", "tx", "rx", "rx"]  # write and poll out, then both answers
    conn.close()


def test_a_slow_application_costs_polls_not_a_wrong_reply(wire: Wire) -> None:
    wire.face.esc.quick = None  # every request to the application thread: the first poll finds SM1 empty
    t = transport(wire)
    conn = Connection.over(t)
    objects = conn.objects()
    for value in (b"\x01", b"\x03", b"\x06"):
        objects.download(0x6060, 0, value)
        assert objects.upload(0x6060, 0) == value
        assert objects.upload(0x1018, 1) == b"\x6a\0\0\0"
    assert t.master is not None and t.master.frames >= 2 * 9
    conn.close()
