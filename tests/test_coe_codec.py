"""Mailbox, CoE/SDO, SDO information and EMCY codecs: seed vectors first, then round trips and fuzz."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.protocol import coe, coe_info
from akdctl.protocol.coe import (
    CoeError,
    CoeService,
    SdoAbort,
    SdoDownloadInitiate,
    SdoDownloadResponse,
    SdoDownloadSegment,
    SdoDownloadSegmentResponse,
    SdoUploadInitiate,
    SdoUploadResponse,
    SdoUploadSegment,
    SdoUploadSegmentResponse,
    decode_coe,
    decode_sdo,
    encode_coe,
    encode_sdo,
)
from akdctl.catalog.texts import mailbox_error_text
from akdctl.catalog.texts import sdo_abort_text as abort_text
from akdctl.protocol.emcy import Emergency, EmcyError, decode_emcy, encode_emcy
from akdctl.protocol.errors import CodecError
from akdctl.protocol.mailbox import (
    Mailbox,
    MailboxError,
    MailboxErrorReply,
    MailboxType,
    decode_error_reply,
    decode_gateway,
    decode_mailbox,
    encode_error_reply,
    encode_gateway,
    encode_mailbox,
    next_counter,
)

# --- seed vectors: AKD EtherCAT manual 5.13.3 (seed 001) ----------------------------------------

MANUAL_REQUEST = bytes.fromhex("0a00 0000 00 03 0020 2b 121c 01 04170000".replace(" ", ""))
MANUAL_REPLY = bytes.fromhex("0e00 0000 00 03 0020 60 121c 01 00000000".replace(" ", ""))


def test_manual_request_decodes_as_printed() -> None:
    mbx = decode_mailbox(MANUAL_REQUEST)
    assert mbx == Mailbox(MailboxType.COE, MANUAL_REQUEST[6:], address=0, channel=0, priority=0, counter=0)
    service, number, payload = decode_coe(mbx.data)
    assert (service, number) == (CoeService.SDO_REQUEST, 0)
    msg = decode_sdo(payload, from_server=False)
    # 0x2B: expedited 2-byte write of 0x1704 to 0x1C12:01
    assert msg == SdoDownloadInitiate(0x1C12, 1, b"\x04\x17", 2, True)


def test_our_encoder_reproduces_the_manual_request() -> None:
    msg = SdoDownloadInitiate(0x1C12, 1, (0x1704).to_bytes(2, "little"), 2, True)
    frame = encode_mailbox(Mailbox(MailboxType.COE, encode_coe(CoeService.SDO_REQUEST, encode_sdo(msg))))
    assert frame == MANUAL_REQUEST


def test_manual_reply_decodes_as_printed_spec_note_15() -> None:
    """SPEC-NOTES 15: the printed reply (length 0x0E, byte 7 = 0x20) decodes as printed."""
    mbx = decode_mailbox(MANUAL_REPLY)
    assert mbx.type == MailboxType.COE
    assert len(mbx.data) == 10  # the length counted from byte 2 is clipped to what is there
    service, _number, payload = decode_coe(mbx.data)
    assert service == CoeService.SDO_REQUEST  # as printed (a slip for 3)
    assert decode_sdo(payload, from_server=True) == SdoDownloadResponse(0x1C12, 1)


def test_manual_reply_in_a_whole_sm_buffer_decodes() -> None:
    """A real SM1 read returns the whole buffer: the 4 extra bytes are padding, still a download response."""
    mbx = decode_mailbox(MANUAL_REPLY + bytes(512 - 16))
    _service, _number, payload = decode_coe(mbx.data)
    assert decode_sdo(payload, from_server=True) == SdoDownloadResponse(0x1C12, 1)


def test_our_encoder_emits_the_standard_reply_spec_note_15() -> None:
    """SPEC-NOTES 15: we emit service 3 (byte 7 = 0x30) and length 10."""
    frame = encode_mailbox(
        Mailbox(MailboxType.COE, encode_coe(CoeService.SDO_RESPONSE, encode_sdo(SdoDownloadResponse(0x1C12, 1))))
    )
    assert frame == bytes.fromhex("0a00000000030030" + "60121c0100000000")
    assert frame[7] == 0x30 and frame[0] == 10


# --- seed vectors: ETG.8200 gateway worked example (reference/ethercat-mailbox.md) -------------

GW_REQUEST = bytes.fromhex("10500a00040000030020401810010000 0000".replace(" ", ""))
GW_REPLY = bytes.fromhex("10500a00040000230030431810010200 0000".replace(" ", ""))


def test_gateway_example_request_both_ways() -> None:
    mbx = decode_gateway(GW_REQUEST)
    assert (mbx.type, mbx.address, mbx.counter) == (MailboxType.COE, 4, 0)
    service, _number, payload = decode_coe(mbx.data)
    assert service == CoeService.SDO_REQUEST
    assert decode_sdo(payload, from_server=False) == SdoUploadInitiate(0x1018, 1)
    built = Mailbox(MailboxType.COE, encode_coe(CoeService.SDO_REQUEST, encode_sdo(SdoUploadInitiate(0x1018, 1))), 4)
    assert encode_gateway(built) == GW_REQUEST


def test_gateway_example_reply_both_ways() -> None:
    mbx = decode_gateway(GW_REPLY)
    assert (mbx.type, mbx.address, mbx.counter) == (MailboxType.COE, 4, 2)
    service, _number, payload = decode_coe(mbx.data)
    assert service == CoeService.SDO_RESPONSE
    msg = decode_sdo(payload, from_server=True)
    assert msg == SdoUploadResponse(0x1018, 1, b"\x02\x00\x00\x00", 4, True)
    built = Mailbox(MailboxType.COE, encode_coe(CoeService.SDO_RESPONSE, encode_sdo(msg)), 4, counter=2)
    assert encode_gateway(built) == GW_REPLY


@pytest.mark.parametrize(
    "bad",
    [
        b"",
        GW_REQUEST[:7],
        bytes([0x10, 0x10]) + GW_REQUEST[2:],  # EtherCAT frame type 1, not 5
        bytes([0x20, 0x50]) + GW_REQUEST[2:],  # length beyond the datagram
        bytes([0x0F, 0x50]) + GW_REQUEST[2:],  # length disagrees with the mailbox length
    ],
)
def test_gateway_rejects(bad: bytes) -> None:
    with pytest.raises(MailboxError):
        decode_gateway(bad)


# --- fixed SDO command bytes (CiA 301 / reference notes) ----------------------------------------


@pytest.mark.parametrize(
    "msg, first",
    [
        (SdoDownloadInitiate(0x6060, 0, b"\x01", 1, True), 0x2F),
        (SdoDownloadInitiate(0x6040, 0, b"\x06\x00", 2, True), 0x2B),
        (SdoDownloadInitiate(0x6040, 0, b"\x06\x00\x00", 3, True), 0x27),
        (SdoDownloadInitiate(0x607A, 0, b"\x01\x02\x03\x04", 4, True), 0x23),
        (SdoDownloadInitiate(0x1008, 0, b"hello", 5, False), 0x21),
        (SdoDownloadInitiate(0x1C12, 0, b"\x00" * 6, 6, False, complete_access=True), 0x31),
        (SdoUploadInitiate(0x1018, 1), 0x40),
        (SdoUploadInitiate(0x1C12, 0, complete_access=True), 0x50),
        (SdoUploadResponse(0x1018, 1, b"\x01", 1, True), 0x4F),
        (SdoUploadResponse(0x1018, 1, b"\x01\x02\x03\x04", 4, True), 0x43),
        (SdoUploadResponse(0x1008, 0, b"AKD-P00306", 10, False), 0x41),
        (SdoDownloadResponse(0x1C12, 1), 0x60),
        (SdoAbort(0x1C12, 1, 0x06090030), 0x80),
        (SdoUploadSegment(0), 0x60),
        (SdoUploadSegment(1), 0x70),
        (SdoDownloadSegmentResponse(0), 0x20),
        (SdoDownloadSegmentResponse(1), 0x30),
        (SdoDownloadSegment(0, b"abc", True), 0x01 | 4 << 1),
        (SdoDownloadSegment(1, b"abcdefg", False), 0x10),
        (SdoUploadSegmentResponse(1, b"abcdefghij", True), 0x11),
    ],
)
def test_command_bytes(msg: coe.SdoMessage, first: int) -> None:
    payload = encode_sdo(msg)
    assert payload[0] == first
    assert len(payload) >= 8


def test_abort_layout_and_text() -> None:
    payload = encode_sdo(SdoAbort(0x1C12, 1, 0x06090030))
    assert payload == bytes.fromhex("80121c0130000906")
    assert abort_text(0x06090030) == "Value range of parameter exceeded (write access only)"
    assert "0x12345678" in abort_text(0x12345678)


def test_normal_initiate_carries_size_then_data() -> None:
    payload = encode_sdo(SdoUploadResponse(0x1008, 0, b"AKD", 300, False))
    assert payload == bytes.fromhex("41081000") + (300).to_bytes(4, "little") + b"AKD"
    assert decode_sdo(payload, from_server=True) == SdoUploadResponse(0x1008, 0, b"AKD", 300, False)


def test_short_segment_is_padded_with_unused_count() -> None:
    payload = encode_sdo(SdoUploadSegmentResponse(0, b"xy", True))
    assert payload == bytes([0x01 | 5 << 1]) + b"xy" + bytes(5)
    assert decode_sdo(payload, from_server=True) == SdoUploadSegmentResponse(0, b"xy", True)


def test_direction_disambiguates_0x60() -> None:
    payload = bytes.fromhex("6000000000000000")
    assert decode_sdo(payload, from_server=True) == SdoDownloadResponse(0, 0)
    assert decode_sdo(payload, from_server=False) == SdoUploadSegment(0)


@pytest.mark.parametrize(
    "bad",
    [
        SdoDownloadInitiate(0x10000, 0, b"\x01", 1, True),
        SdoDownloadInitiate(0x1000, 256, b"\x01", 1, True),
        SdoDownloadInitiate(0x1000, 0, b"\x01\x02", 1, True),
        SdoDownloadInitiate(0x1000, 0, b"\x01\x02\x03\x04\x05", 5, True),
        SdoDownloadInitiate(0x1000, 0, b"\x01\x02", None, True),
        SdoDownloadInitiate(0x1000, 0, b"\x01\x02\x03", 2, False),
        SdoUploadSegment(2),
        SdoAbort(0, 0, 1 << 32),
    ],
)
def test_encode_rejects(bad: coe.SdoMessage) -> None:
    with pytest.raises(CoeError):
        encode_sdo(bad)


def test_block_transfer_commands_are_unknown() -> None:
    for command in (0xA0, 0xC0, 0xE0):
        with pytest.raises(CoeError):
            decode_sdo(bytes([command]) + bytes(7), from_server=False)
    for command in (0xA0, 0xC0, 0xE0):
        with pytest.raises(CoeError):
            decode_sdo(bytes([command]) + bytes(7), from_server=True)


# --- mailbox header -------------------------------------------------------------------------------


def test_mailbox_header_bits() -> None:
    frame = encode_mailbox(Mailbox(MailboxType.COE, b"\x00\x20", address=0x1001, channel=5, priority=2, counter=7))
    assert frame == bytes([2, 0, 0x01, 0x10, 5 | 2 << 6, 3 | 7 << 4, 0x00, 0x20])


def test_mailbox_tail_ignored_and_short_refused() -> None:
    frame = encode_mailbox(Mailbox(MailboxType.COE, b"\x00\x20" + bytes(8)))
    assert decode_mailbox(frame + b"\xff" * 100) == decode_mailbox(frame)
    with pytest.raises(MailboxError):
        decode_mailbox(frame[:5])
    with pytest.raises(MailboxError):
        decode_mailbox(bytes([30, 0, 0, 0, 0, 3]) + bytes(10))


@pytest.mark.parametrize("field, value", [("type", 16), ("counter", 8), ("channel", 64), ("priority", 4), ("address", -1)])
def test_mailbox_encode_rejects(field: str, value: int) -> None:
    kwargs = {"type": 3, "data": b"", "address": 0, "channel": 0, "priority": 0, "counter": 0, field: value}
    with pytest.raises(MailboxError):
        encode_mailbox(Mailbox(**kwargs))


def test_counter_wraps_1_to_7() -> None:
    seen = [next_counter(0)]
    for _ in range(8):
        seen.append(next_counter(seen[-1]))
    assert seen == [1, 2, 3, 4, 5, 6, 7, 1, 2]


def test_mailbox_error_reply() -> None:
    data = encode_error_reply(MailboxErrorReply(2))
    assert data == bytes.fromhex("01000200")
    reply = decode_error_reply(data)
    assert reply.code == 2 and "not supported" in mailbox_error_text(reply.code).lower()
    for code in range(1, 9):
        assert mailbox_error_text(MailboxErrorReply(code).code)
    assert "0x0063" in mailbox_error_text(MailboxErrorReply(0x63).code)
    with pytest.raises(MailboxError):
        decode_error_reply(b"\x01\x00")
    with pytest.raises(MailboxError):
        decode_error_reply(bytes.fromhex("02000100"))


# --- EMCY -----------------------------------------------------------------------------------------


def test_emcy_layout() -> None:
    emcy = Emergency(0x7305, 0x81, b"\x01\x02\x03\x04\x05")
    assert encode_emcy(emcy) == bytes.fromhex("0573810102030405")
    assert decode_emcy(bytes.fromhex("0573810102030405")) == emcy
    assert encode_emcy(Emergency(0x1000, 0x01)) == bytes.fromhex("0010010000000000")
    assert decode_emcy(bytes(8)).is_reset


@pytest.mark.parametrize("bad", [Emergency(0x10000, 0), Emergency(0, 256), Emergency(0, 0, bytes(6))])
def test_emcy_encode_rejects(bad: Emergency) -> None:
    with pytest.raises(EmcyError):
        encode_emcy(bad)


def test_emcy_decode_needs_8_bytes() -> None:
    for n in (0, 7, 9):
        with pytest.raises(EmcyError):
            decode_emcy(bytes(n))


# --- SDO information ------------------------------------------------------------------------------


def test_sdo_info_od_list_request_matches_soem_layout() -> None:
    frame = coe_info.encode_sdo_info(coe_info.pack_info(coe_info.OdListRequest()))
    # opcode 1, reserved, 0 fragments left, list type 1 (all objects), as SOEM ecx_readODlist sends it
    assert frame == bytes.fromhex("010000000100")


def test_sdo_info_fragments_reassemble() -> None:
    indices = tuple(range(0x1000, 0x1000 + 300))
    whole = coe_info.pack_info(coe_info.OdListResponse(1, indices))
    parts = coe_info.fragment_info(whole, 100)
    assert len(parts) > 1
    assert all(p.incomplete for p in parts[:-1]) and not parts[-1].incomplete
    assert [p.fragments_left for p in parts] == list(range(len(parts) - 1, -1, -1))
    assembler = coe_info.InfoReassembler()
    results = [assembler.add(coe_info.decode_sdo_info(coe_info.encode_sdo_info(p))) for p in parts]
    assert results[:-1] == [None] * (len(parts) - 1)
    assert coe_info.unpack_info(results[-1]) == coe_info.OdListResponse(1, indices)


def test_sdo_info_reassembler_rejects_out_of_order() -> None:
    parts = coe_info.fragment_info(coe_info.pack_info(coe_info.OdListResponse(1, tuple(range(200)))), 50)
    assembler = coe_info.InfoReassembler()
    assembler.add(parts[0])
    with pytest.raises(CoeError):
        assembler.add(parts[2])


def test_entry_description_layout_matches_soem_offsets() -> None:
    msg = coe_info.EntryDescription(0x6041, 0, 0, 0x0006, 16, 0x0087, "Statusword")
    frame = coe_info.encode_sdo_info(coe_info.pack_info(msg))
    coe_data = encode_coe(CoeService.SDO_INFO, frame)
    # SOEM: name length = mailbox length - 16; data type at wdata[2], bit length wdata[3], access wdata[4]
    assert len(coe_data) - 16 == len("Statusword")
    body = frame[4:]
    assert body[4:6] == b"\x06\x00" and body[6:8] == b"\x10\x00" and body[8:10] == b"\x87\x00"


def test_entry_description_with_values() -> None:
    msg = coe_info.EntryDescription(0x6060, 0, coe_info.VALUE_INFO_MIN | coe_info.VALUE_INFO_MAX, 0x0002, 8, 0x3F, "Mode", b"\xff\x0a")
    assert coe_info.unpack_info(coe_info.pack_info(msg)) == msg
    with pytest.raises(CoeError):
        coe_info.pack_info(coe_info.EntryDescription(0x6060, 0, coe_info.VALUE_INFO_MIN, 0x0002, 8, 0x3F, "Mode", b""))


def test_object_description_nul_padded_name() -> None:
    frame = coe_info.SdoInfo(coe_info.SdoInfoOpcode.OBJECT_RESPONSE, bytes.fromhex("1810 0900 04 09") + b"Identity\x00\x00")
    assert coe_info.unpack_info(frame) == coe_info.ObjectDescription(0x1018, 0x0009, 4, 9, "Identity")


# --- hypothesis: round trips ------------------------------------------------------------------------

u16 = st.integers(0, 0xFFFF)
u8 = st.integers(0, 0xFF)
bit = st.integers(0, 1)
blob = st.binary(max_size=64)


@st.composite
def initiates(draw: st.DrawFn, cls: type) -> object:
    index, sub = draw(u16), draw(u8)
    kind = draw(st.sampled_from(["exp", "exp-nosize", "normal", "normal-nosize"]))
    if kind == "exp":
        data = draw(st.binary(min_size=1, max_size=4))
        args = (index, sub, data, len(data), True)
    elif kind == "exp-nosize":
        args = (index, sub, draw(st.binary(min_size=4, max_size=4)), None, True)
    elif kind == "normal":
        data = draw(blob)
        args = (index, sub, data, len(data) + draw(st.integers(0, 100000)), False)
    else:
        args = (index, sub, draw(blob), None, False)
    if cls is SdoDownloadInitiate:
        return SdoDownloadInitiate(*args, complete_access=draw(st.booleans()))
    return SdoUploadResponse(*args)


client_messages = st.one_of(
    initiates(SdoDownloadInitiate),
    st.builds(SdoDownloadSegment, bit, blob, st.booleans()),
    st.builds(SdoUploadInitiate, u16, u8, st.booleans()),
    st.builds(SdoUploadSegment, bit),
    st.builds(SdoAbort, u16, u8, st.integers(0, 0xFFFFFFFF)),
)
server_messages = st.one_of(
    initiates(SdoUploadResponse),
    st.builds(SdoDownloadResponse, u16, u8),
    st.builds(SdoDownloadSegmentResponse, bit),
    st.builds(SdoUploadSegmentResponse, bit, blob, st.booleans()),
    st.builds(SdoAbort, u16, u8, st.integers(0, 0xFFFFFFFF)),
)


@given(client_messages)
def test_client_sdo_round_trip(msg: coe.SdoMessage) -> None:
    assert decode_sdo(encode_sdo(msg), from_server=False) == msg


@given(server_messages)
def test_server_sdo_round_trip(msg: coe.SdoMessage) -> None:
    assert decode_sdo(encode_sdo(msg), from_server=True) == msg


@given(
    st.builds(
        Mailbox,
        st.integers(0, 15),
        st.binary(max_size=200),
        u16,
        st.integers(0, 63),
        st.integers(0, 3),
        st.integers(0, 7),
    )
)
def test_mailbox_and_gateway_round_trip(mbx: Mailbox) -> None:
    assert decode_mailbox(encode_mailbox(mbx)) == mbx
    assert decode_gateway(encode_gateway(mbx)) == mbx


@given(st.sampled_from(sorted(coe.SERVICES)), st.integers(0, 0x1FF), blob)
def test_coe_header_round_trip(service: CoeService, number: int, payload: bytes) -> None:
    assert decode_coe(encode_coe(service, payload, number)) == (service, number, payload)


@given(st.builds(Emergency, u16, u8, st.binary(min_size=5, max_size=5)))
def test_emcy_round_trip(emcy: Emergency) -> None:
    assert decode_emcy(encode_emcy(emcy)) == emcy


names = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=40)


@st.composite
def entry_descriptions(draw: st.DrawFn) -> coe_info.EntryDescription:
    value_info = draw(st.sampled_from([0, 0x08, 0x10, 0x20 | 0x40, 0x78]))
    bit_length = draw(st.integers(1, 64))
    size = coe_info._values_size(value_info, bit_length)
    return coe_info.EntryDescription(
        draw(u16), draw(u8), value_info, draw(u16), bit_length, draw(u16), draw(names),
        draw(st.binary(min_size=size, max_size=size)),
    )


info_messages = st.one_of(
    st.builds(coe_info.OdListRequest, u16),
    st.builds(coe_info.OdListResponse, u16, st.lists(u16, max_size=300).map(tuple)),
    st.builds(coe_info.ObjectDescriptionRequest, u16),
    st.builds(coe_info.ObjectDescription, u16, u16, u8, u8, names),
    st.builds(coe_info.EntryDescriptionRequest, u16, u8, u8),
    entry_descriptions(),
    st.builds(coe_info.SdoInfoError, st.integers(0, 0xFFFFFFFF)),
)


@given(info_messages, st.integers(2, 600))
def test_sdo_info_round_trip_through_fragments(msg: coe_info.SdoInfoMessage, room: int) -> None:
    assembler = coe_info.InfoReassembler()
    done = None
    for part in coe_info.fragment_info(coe_info.pack_info(msg), room):
        assert done is None
        done = assembler.add(coe_info.decode_sdo_info(coe_info.encode_sdo_info(part)))
    assert done is not None
    assert coe_info.unpack_info(done) == msg


# --- fuzz: arbitrary bytes raise only CodecError ------------------------------------------------------


@settings(max_examples=300)
@given(st.binary(max_size=80))
def test_fuzz_decoders_raise_only_codec_error(data: bytes) -> None:
    decoders = [
        decode_mailbox,
        decode_gateway,
        decode_error_reply,
        decode_coe,
        decode_emcy,
        lambda d: decode_sdo(d, from_server=True),
        lambda d: decode_sdo(d, from_server=False),
        lambda d: coe_info.unpack_info(coe_info.decode_sdo_info(d)),
        lambda d: coe_info.InfoReassembler().add(coe_info.decode_sdo_info(d)),
    ]
    for decoder in decoders:
        try:
            decoder(data)
        except CodecError:
            pass


@given(st.integers(0, 7), st.binary(max_size=80))
def test_fuzz_unpack_info_every_opcode(opcode: int, data: bytes) -> None:
    try:
        coe_info.unpack_info(coe_info.SdoInfo(opcode, data))
    except CodecError:
        pass
