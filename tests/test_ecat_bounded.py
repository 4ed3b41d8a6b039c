"""Issue 23 item 12: the raw master must not loop for ever when SM1 keeps presenting a mailbox that does not
answer its request (an SDO reply for another object left in SM1, SM1 in buffered mode). Every wait is bounded by
the command's deadline, and a mailbox SM1 in buffered mode is re-established at open."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from akdctl.connection import Connection
from akdctl.errors import NoAnswer
from akdctl.protocol import ethercat as ec
from akdctl.sim.drive import SimDrive
from tests.test_ecat_raw_inprocess import Wire, transport

FOREIGN = bytes.fromhex("0a00 0000 0003 0030 4308 1000 414b4400")  # an SDO upload reply for 0x1008:00
SM1 = ec.REG_SM0 + ec.SM_STRIDE


@pytest.fixture
def wire(tmp_path: Path) -> Iterator[Wire]:
    w = Wire(SimDrive("default", tmp_path))
    try:
        yield w
    finally:
        w.close()


def _stuck(wire: Wire) -> None:
    esc = wire.face.esc
    esc.mem[SM1 + 4] = 0x20  # buffered mode
    esc.mem[0x1C00:0x1C00 + len(FOREIGN)] = FOREIGN
    esc.mem[SM1 + 5] |= ec.SM_STATUS_MAILBOX_FULL


def test_a_foreign_reply_presented_for_ever_ends_within_the_deadline(wire: Wire) -> None:
    conn = Connection.over(transport(wire))
    assert conn.objects().upload(0x1018, 1) == b"j\x00\x00\x00"
    _stuck(wire)
    start = time.monotonic()
    with pytest.raises(NoAnswer):
        conn.objects().upload(0x1018, 1)
    assert time.monotonic() - start < 2.0  # --timeout 0.5 in the harness
    conn.close()


def test_open_re_establishes_a_mailbox_left_in_buffered_mode(wire: Wire) -> None:
    Connection.over(transport(wire)).objects()  # not closed: both share the harness's socket
    _stuck(wire)
    again = Connection.over(transport(wire))  # a new command: opens the bus and checks the mailbox
    assert again.objects().upload(0x1018, 1) == b"j\x00\x00\x00"
    again.close()


def test_a_flood_of_foreign_frames_does_not_hold_the_master() -> None:
    """A peer whose frames never stop and are never the answer (a socket that always has one ready): the wait
    still ends at its timeout, in both of the master's receive loops."""
    from akdctl.transport.ethercat_raw import EcatMaster, FrameLost
    from akdctl.transport.trace import Tracer

    foreign = ec.encode_frame([ec.Datagram(ec.Cmd.BRD, 0, 0, bytes(2), index=0xEE)], src=b"\x02" * 6)

    class Flood:
        def send(self, frame: bytes) -> int:
            return len(frame)

        def settimeout(self, value: float) -> None:
            pass

        def setsockopt(self, *option: object) -> None:
            pass

        def recv_into(self, buffer: bytearray) -> int:
            buffer[:len(foreign)] = foreign
            return len(foreign)

        def close(self) -> None:
            pass

    master = EcatMaster("flood0", Tracer(), timeout=0.2, retries=0, sock=Flood())  # type: ignore[arg-type]
    template = ec.FrameTemplate([ec.Datagram(ec.Cmd.FPRD, 0x1001, 0x0130, bytes(2))], b"\x01" * 6)
    start = time.monotonic()
    with pytest.raises(FrameLost):
        master.txrx_template(template)
    with pytest.raises(FrameLost):
        master.txrx([ec.Datagram(ec.Cmd.FPRD, 0x1001, 0x0130, bytes(2))])
    assert time.monotonic() - start < 2.0
