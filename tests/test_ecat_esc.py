"""The simulated ESC processed datagram by datagram, without sockets: addressing and working counters, the AKD's AL
state machine and codes (AKD EtherCAT manual 5.3.3, SPEC-NOTES 22), the SII EEPROM interface, mailbox full/empty
semantics and the repeat request. Plus the raw face's frame handling under fuzz: only well-formed replies or None."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.protocol import ethercat as ec
from akdctl.protocol.sii import akd_sii_image, build_sii
from akdctl.sim.esc import Esc

D = ec.Datagram
STATION = 0x1001
DUMP = (Path(__file__).parent / "data" / "ecat_akd_sii_dump.bin").read_bytes()


def esc() -> Esc:
    e = Esc(akd_sii_image())
    run(e, D(ec.Cmd.APWR, 0, ec.REG_STATION_ADDR, struct.pack("<H", STATION)))
    return e


def run(e: Esc, *datagrams: ec.Datagram) -> list[ec.Datagram]:
    return e.process(list(datagrams))


def wr(e: Esc, ado: int, data: bytes) -> int:
    return run(e, D(ec.Cmd.FPWR, STATION, ado, data))[0].wkc


def rd(e: Esc, ado: int, n: int) -> tuple[bytes, int]:
    d = run(e, D(ec.Cmd.FPRD, STATION, ado, bytes(n)))[0]
    return d.data, d.wkc


def al(e: Esc, state: int) -> tuple[int, int]:
    wr(e, ec.REG_AL_CONTROL, struct.pack("<H", state))
    status, _, code = struct.unpack("<HHH", rd(e, ec.REG_AL_STATUS, 6)[0])
    return status, code


def mailbox_sms(e: Esc, sm0_start: int = 0x1800) -> None:
    wr(e, ec.REG_SM0, ec.SyncManager(sm0_start, 1024, 0x26, 0, 1).encode()
       + ec.SyncManager(0x1C00, 1024, 0x22, 0, 1).encode())


def test_brd_counts_and_apxx_position() -> None:
    e = Esc(akd_sii_image())
    d = run(e, D(ec.Cmd.BRD, 0, 0, b"\0\0"))[0]
    assert d.wkc == 1 and d.adp == 1 and d.data == bytes([0x04, 0x01])
    # a second slave in line would see ADP 0xFFFF + 1 = 0: this one is addressed only at ADP 0
    assert run(e, D(ec.Cmd.APRD, 0xFFFF, ec.REG_TYPE, b"\0"))[0].wkc == 0
    assert run(e, D(ec.Cmd.APWR, 0, ec.REG_STATION_ADDR, b"\x01\x10"))[0].wkc == 1
    assert e.station == 0x1001
    assert run(e, D(ec.Cmd.FPRD, 0x1002, ec.REG_AL_STATUS, b"\0\0"))[0].wkc == 0  # not us
    rw = run(e, D(ec.Cmd.FPRW, STATION, 0x0F80, b"\x55"))[0]
    assert rw.wkc == 3 and rw.data == b"\0"


def test_read_only_registers_ignore_writes() -> None:
    e = esc()
    wr(e, ec.REG_AL_STATUS, b"\x08\x00")
    wr(e, ec.REG_TYPE, b"\xff")
    assert e.al_status == ec.AlState.INIT and e.mem[0] == 0x04


def test_al_init_to_preop_needs_the_akd_mailbox_sms() -> None:
    e = esc()
    assert al(e, ec.AlState.PREOP) == (ec.AlState.INIT | ec.AL_ERROR_FLAG, 0x0017)  # no SMs configured
    mailbox_sms(e, sm0_start=0x1000)
    assert al(e, ec.AlState.PREOP | ec.AL_ERROR_FLAG) == (ec.AlState.INIT | ec.AL_ERROR_FLAG, 0x0017)
    mailbox_sms(e)
    assert al(e, ec.AlState.PREOP | ec.AL_ERROR_FLAG) == (ec.AlState.PREOP, 0)


@pytest.mark.parametrize("path, code", [
    ([ec.AlState.SAFEOP], 0x0011),  # I -> S
    ([ec.AlState.OP], 0x0011),  # I -> O
    ([ec.AlState.PREOP, ec.AlState.OP], 0x0011),  # P -> O
    ([ec.AlState.PREOP, ec.AlState.BOOT], 0x0011),  # P -> B
])
def test_al_invalid_transitions_report_0x0011(path: list[int], code: int) -> None:
    e = esc()
    mailbox_sms(e)
    for state in path[:-1]:
        assert al(e, state)[1] == 0
    status, got = al(e, path[-1])
    assert got == code and status & ec.AL_ERROR_FLAG
    from akdctl.catalog.texts import al_status_line

    assert al_status_line(status, got).endswith("Invalid requested state change")


def test_al_full_run_up_and_back() -> None:
    e = esc()
    mailbox_sms(e)
    for state in (ec.AlState.PREOP, ec.AlState.SAFEOP, ec.AlState.OP, ec.AlState.INIT):
        assert al(e, state) == (state, 0)


def test_sii_eeprom_interface_reads_the_image() -> None:
    e = esc()
    image = bytearray()
    for word in range(0, 1024, 4):
        wr(e, ec.REG_EEP_CONTROL, struct.pack("<HI", ec.EEP_CMD_READ, word))
        data, wkc = rd(e, ec.REG_EEP_CONTROL, 14)
        ctl = struct.unpack_from("<H", data)[0]
        assert wkc == 1 and not ctl & ec.EEP_BUSY and ctl & ec.EEP_READ_8_BYTES
        image += data[6:14]
    assert bytes(image) == build_sii(akd_sii_image()) == DUMP


def test_mailbox_full_empty_and_repeat() -> None:
    e = esc()
    mailbox_sms(e)
    al(e, ec.AlState.PREOP)
    request = bytes.fromhex("0a00 0000 0003 0020 4018 1001 0000 0000").ljust(1024, b"\0")
    assert wr(e, 0x1800, request) == 1
    assert rd(e, 0x0805, 1)[0][0] & ec.SM_STATUS_MAILBOX_FULL
    assert wr(e, 0x1800, request) == 0  # full: not taken, WKC stays 0
    assert rd(e, 0x1C00, 1024)[1] == 0  # nothing to read yet: denied
    got = e.take_request(0.1)
    assert got is not None and got[:16] == request[:16]
    reply = bytes.fromhex("0a00 0000 0003 0030 4318 1001 6a00 0000")
    e.post_replies([reply])
    data, wkc = rd(e, 0x1C00, 1024)
    assert wkc == 1 and data[:16] == reply and not rd(e, 0x080D, 1)[0][0] & ec.SM_STATUS_MAILBOX_FULL
    # the master lost that frame: toggle the repeat request, wait for the ack, read again
    activate = rd(e, 0x080E, 1)[0][0]
    wr(e, 0x080E, bytes([activate ^ ec.SM_ACTIVATE_REPEAT]))
    assert rd(e, 0x080F, 1)[0][0] & ec.SM_PDI_REPEAT_ACK
    assert rd(e, 0x1C00, 1024)[0][:16] == reply
    assert e.stats.repeats == 1


def test_reply_frame_drop_marks_lost_frame() -> None:
    e = esc()
    mailbox_sms(e)
    al(e, ec.AlState.PREOP)
    e.post_replies([bytes.fromhex("0a00 0000 0003 0030 4318 1001 6a00 0000")], drop=True)
    rd(e, 0x1C00, 1024)
    assert e.lost_frame and e.stats.dropped == 1


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_fuzz_raw_face_frames(blob: bytes) -> None:
    from akdctl.sim.face_ethercat_raw import EthercatRawFace
    from akdctl.sim.ecat_inject import Injector

    face = EthercatRawFace("unused0", drive=None, injector=Injector())  # type: ignore[arg-type]
    for frame in (blob, b"\xff" * 6 + b"\x01" * 6 + b"\x88\xa4" + blob):
        reply = face.handle_frame(frame)
        if reply is not None:
            ec.decode_frame(reply)
