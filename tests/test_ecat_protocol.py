"""EtherCAT frame/datagram codec and SII codec.

Seed vectors first: a real AKD's SII EEPROM
dump (tests/data/ecat_akd_sii_dump.bin, 2048 bytes). Then hypothesis round trips and fuzz: only CodecError escapes.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.protocol import ethercat as ec
from akdctl.protocol import sii
from akdctl.protocol.errors import CodecError

DUMP = (Path(__file__).parent / "data" / "ecat_akd_sii_dump.bin").read_bytes()

def test_datagram_frame_layout() -> None:
    # BRD 0x0000, 2 bytes: what a master sends to count slaves
    frame = ec.encode_frame([ec.Datagram(ec.Cmd.BRD, 0, 0x0000, b"\0\0", index=0x42)], src=b"\x02" * 6)
    assert len(frame) == 60  # padded to the Ethernet minimum
    assert frame[12:14] == b"\x88\xa4"
    assert frame[14:16] == bytes.fromhex("0e 10")  # 14 bytes of datagrams, type 1
    assert frame[16:28] == bytes.fromhex("07 42 00 00 00 00 02 00 00 00 00 00")
    dst, src, dgrams = ec.decode_frame(frame)
    assert dst == ec.BROADCAST_MAC and src == b"\x02" * 6
    assert dgrams == [ec.Datagram(ec.Cmd.BRD, 0, 0, b"\0\0", 0x42)]


def test_more_flag_chains_datagrams() -> None:
    ds = [ec.Datagram(ec.Cmd.FPRD, 0x1001, ec.REG_AL_STATUS, b"\0\0", 1),
          ec.Datagram(ec.Cmd.FPWR, 0x1001, 0x1800, b"\x01" * 16, 2, wkc=1)]
    payload = ec.encode_datagrams(ds)
    assert payload[2 + 6 + 1] & 0x80  # first datagram's length word has bit 15 set
    assert ec.decode_datagrams(payload) == ds


def test_logical_address_split() -> None:
    d = ec.logical_datagram(ec.Cmd.LRW, 0x00012345, b"\0" * 4)
    assert (d.adp, d.ado, d.logical) == (0x2345, 0x0001, 0x00012345)


def test_al_texts_for_akd_codes() -> None:
    # AKD EtherCAT manual 5.3.3; SPEC-NOTES 22
    from akdctl.catalog.texts import al_status_line, al_status_text  # the codec returns codes (issue 22 item 4)

    assert al_status_text(0x0011) == "Invalid requested state change"
    assert al_status_text(0x0017) == "Invalid sync manager configuration"
    assert al_status_line(0x12, 0x0011) == "PREOP+ERR, 0x0011 Invalid requested state change"
    assert not hasattr(ec, "AL_STATUS_TEXTS") and not hasattr(ec, "describe_al")
    assert ec.parse_al_state("pre-op") is ec.AlState.PREOP
    with pytest.raises(CodecError):
        ec.parse_al_state("running")


def test_sync_manager_block() -> None:
    # SOEM programs SM0 with control 0x26, activate 0x01 for the AKD's 0x1800 mailbox
    sm = ec.SyncManager(0x1800, 1024, 0x26, 0, 1, 0)
    assert sm.encode() == bytes.fromhex("00 18 00 04 26 00 01 00")
    assert ec.SyncManager.decode(sm.encode()) == sm and sm.is_mailbox and sm.writes_to_slave and sm.enabled


# --- SII -------------------------------------------------------------------------------------------------

def test_sii_dump_identity_and_mailboxes() -> None:
    im = sii.parse_sii(DUMP)
    assert (im.vendor_id, im.product_code, im.revision, im.serial) == (0x6A, 0x00414B44, 2, 2575499411)
    assert (im.std_rx_offset, im.std_rx_size, im.std_tx_offset, im.std_tx_size) == (0x1800, 1024, 0x1C00, 1024)
    assert (im.boot_rx_offset, im.boot_tx_offset) == (0x1800, 0x1C00)
    assert im.mailbox_protocols == 0x0E and im.protocol_names == ["EoE", "CoE", "FoE"]
    assert im.checksum == sii.crc8(DUMP[:14]) == 0x10
    assert im.is_akd and im.order == "AKD-P00606-NBCC-E000" and im.firmware == "01-20-00-003"
    assert im.name == "AKD EtherCAT Drive (CoE)"


def test_sii_dump_categories() -> None:
    im = sii.parse_sii(DUMP)
    assert [t for t, _ in im.categories] == [0x0800, 0x0801, 10, 30, 40, 41, 43, 50, 51, 60]
    assert len(im.strings) == 34 and im.strings[4] == "AKD EtherCAT Drive (CoE)"
    gen = im.general
    assert gen is not None and (gen.coe_details, gen.foe_details, gen.eoe_details) == (0x0D, 0x01, 0x03)
    assert im.string(gen.group_idx) == "Drive" and im.string(gen.image_idx) == "DRIVE"
    assert [(s.start, s.length, s.control, s.sm_type) for s in im.sync_managers] == [
        (0x1800, 1024, 0x26, 1), (0x1C00, 1024, 0x22, 2), (0x1100, 0, 0x24, 3), (0x1140, 0, 0x20, 4)]
    assert im.fmmus == [1, 2, 3, 0xFF]
    tx = {p.index: p for p in im.tx_pdos}
    assert tx[0x1B01].sm == 3 and [(e.index, e.bit_length) for e in tx[0x1B01].entries] == [(0x6063, 32), (0x6041, 16)]
    assert len(tx[0x1B20].entries) == 10 and im.string(tx[0x1B20].entries[9].name_idx) == "AIN.VALUE"
    rx = {p.index: p for p in im.rx_pdos}
    assert rx[0x1701].sm == 2 and [(e.index, e.subindex) for e in rx[0x1701].entries] == [(0x60C1, 1), (0x6040, 0)]
    assert sorted(rx) == [0x1600, 0x1601, 0x1602, 0x1603, 0x1701, 0x1702] + list(range(0x1720, 0x1726))


def test_sii_rebuilds_dump_byte_exact() -> None:
    assert sii.build_sii(sii.parse_sii(DUMP)) == DUMP


def test_akd_image_from_facts_equals_real_dump() -> None:
    """The simulator's SII (built from the ESI facts) is the real drive's EEPROM, byte for byte."""
    assert sii.build_sii(sii.akd_sii_image()) == DUMP
    other = sii.parse_sii(sii.build_sii(sii.akd_sii_image(serial=42, mailbox_size=512, station_alias=7)))
    assert other.serial == 42 and other.std_rx_size == 512 and other.station_alias == 7
    assert other.checksum == sii.crc8(sii.build_sii(sii.akd_sii_image(station_alias=7))[:14])


def test_sii_json_is_plain() -> None:
    import json

    data = sii.parse_sii(DUMP).to_json()
    assert json.loads(json.dumps(data))["mailbox"]["protocols"] == ["EoE", "CoE", "FoE"]


@pytest.mark.parametrize("cut", [0, 10, 127])
def test_sii_short_image_rejected(cut: int) -> None:
    with pytest.raises(CodecError):
        sii.parse_sii(DUMP[:cut])


# --- properties ------------------------------------------------------------------------------------------

datagrams = st.builds(
    ec.Datagram,
    cmd=st.sampled_from(list(ec.Cmd)),
    adp=st.integers(0, 0xFFFF),
    ado=st.integers(0, 0xFFFF),
    data=st.binary(max_size=64),
    index=st.integers(0, 255),
    wkc=st.integers(0, 0xFFFF),
    irq=st.integers(0, 0xFFFF),
    circulating=st.booleans(),
)


@given(st.lists(datagrams, min_size=1, max_size=8))
def test_datagrams_round_trip(ds: list[ec.Datagram]) -> None:
    assert ec.decode_frame(ec.encode_frame(ds, src=b"\x02\0\0\0\0\1"))[2] == ds


@settings(max_examples=300)
@given(st.binary(max_size=200))
def test_fuzz_frame_decoders(blob: bytes) -> None:
    for fn in (ec.decode_frame, ec.decode_datagrams, ec.decode_ethernet, sii.parse_sii,
               sii.decode_strings, sii.decode_pdos, ec.SyncManager.decode):
        try:
            fn(blob)
        except CodecError:
            pass


@settings(max_examples=200)
@given(st.integers(0, 2047), st.binary(min_size=1, max_size=8))
def test_fuzz_sii_mutations(pos: int, patch: bytes) -> None:
    data = bytearray(DUMP)
    data[pos : pos + len(patch)] = patch
    try:
        image = sii.parse_sii(bytes(data[:2048]))
        image.to_json()
    except CodecError:
        pass


@given(st.lists(st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), max_size=40), max_size=20))
def test_strings_round_trip(strings: list[str]) -> None:
    assert sii.decode_strings(sii.encode_strings(strings)) == strings


def test_missing_cap_net_raw_message(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without CAP_NET_RAW the raw master says in one line what to do (a UsageError, exit 2)."""
    import socket

    from akdctl.errors import UsageError
    from akdctl.transport import ethercat_raw

    def refuse(*_args: object, **_kw: object) -> socket.socket:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(ethercat_raw.socket, "socket", refuse)
    with pytest.raises(UsageError) as info:
        ethercat_raw.open_raw_socket("eth0")
    text = str(info.value)
    assert "needs CAP_NET_RAW" in text and "setcap cap_net_raw+ep" in text and "\n" not in text
    assert info.value.exit_code == 2
