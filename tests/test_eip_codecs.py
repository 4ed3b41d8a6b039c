"""EtherNet/IP encapsulation, CIP and AKD assembly codecs: seed vectors, round trips, fuzz, scapy interop.

Seed 002 (AKD EtherNet/IP manual p. 16, SPEC-NOTES 24) gives the handshake example bytes.
"""

from __future__ import annotations

import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.catalog.texts import CIP_STATUS_TEXTS, cip_status_text
from akdctl.protocol import akd_assembly as asm
from akdctl.protocol import cip, enip
from akdctl.protocol.errors import CodecError

SEED_C1 = bytes.fromhex("80 00 21 20 E8 03 00 00")
SEED_R2 = bytes.fromhex("84 00 00 20 00 00 00 00")
SEED_C3 = bytes.fromhex("81 00 21 20 E8 03 00 00")


# ------------------------------------------------------------- seed vectors (SPEC-NOTES 24)

def test_seed_command_step1() -> None:
    cmd = asm.Command(control=asm.CTL_ENABLE, command_axis=1, command_type=asm.CMD_TARGET_POSITION,
                      response_axis=1, response_type=asm.RSP_NONE, data=1000)
    raw = cmd.encode()
    assert len(raw) == 64 and raw[:8] == SEED_C1 and raw[8:] == bytes(56)
    back = asm.Command.decode(SEED_C1 + bytes(56))
    assert back == cmd and back.flag(asm.CTL_ENABLE) and not back.flag(asm.CTL_LOAD_START)


def test_seed_response_step2() -> None:
    rsp = asm.Response.decode(SEED_R2 + bytes(56))
    assert rsp.status1 & asm.ST1_ENABLED and rsp.status1 & asm.ST1_IN_POSITION
    assert not rsp.load_complete and rsp.response_axis == 1 and rsp.response_type == 0 and rsp.data_value == 0
    assert rsp.encode()[:8] == SEED_R2


def test_seed_command_step3_load_start() -> None:
    cmd = asm.Command.decode(SEED_C3 + bytes(56))
    assert cmd.flag(asm.CTL_LOAD_START) and cmd.flag(asm.CTL_ENABLE)
    assert (cmd.command_axis, cmd.command_type, cmd.response_axis, cmd.data) == (1, 1, 1, 1000)


def test_error_response_type_0x14_echoes_command_bytes() -> None:
    cmd = asm.Command.decode(SEED_C3 + bytes(56))
    rsp = asm.error_response(asm.Response(status1=0x80), cmd, cip.INVALID_PARAMETER)
    raw = rsp.encode()
    assert raw[3] == 0x20 | 0x14 and raw[4:8] == bytes([0x20, 0xFF, 0x21, 0x20])
    err = asm.Response.decode(raw).error
    assert err is not None and (err.code, err.additional, err.echo_command, err.echo_response) == (0x20, 0xFF, 0x21, 0x20)
    assert asm.Response.decode(SEED_R2 + bytes(56)).error is None


def test_assembly_field_offsets() -> None:
    cmd = asm.Command(block=7, position=-2, velocity=3, acceleration=4, deceleration=5,
                      parameter_data=bytes(range(8)), attribute_to_get=9, map_type=2, dynamic_map=b"\xAA" * 28)
    raw = cmd.encode()
    assert raw[1] == 7 and struct.unpack_from("<iiii", raw, 8) == (-2, 3, 4, 5)
    assert raw[24:32] == bytes(range(8)) and raw[32] == 9 and raw[33] == 2 and raw[36:] == b"\xAA" * 28
    rsp = asm.Response(executing_block=3, actual_position=-7, actual_velocity=11, motion_status=0x800)
    raw = rsp.encode()
    assert raw[1] == 3 and struct.unpack_from("<iiI", raw, 8) == (-7, 11, 0x800)


def test_cip_status_texts_cover_seed_table() -> None:
    # seed 002: B C D E F 10 11 13 14 15 16 17 20
    for code, name in ((0x0B, "ALREADY_IN_STATE"), (0x0E, "ATTRIBUTE_NOT_SETTABLE"), (0x14, "ATTRIBUTE_NOT_SUPP"),
                       (0x16, "OBJECT_DOES_NOT_EXIST"), (0x17, "FRAGMENTATION_SEQ_ERR"), (0x20, "INVALID_PARAMETER")):
        assert name in CIP_STATUS_TEXTS[code]
    assert "0x77" in cip_status_text(0x77)
    assert "ownership conflict" in cip_status_text(0x01, (0x0106,))


# ------------------------------------------------------------- encapsulation vectors

def test_register_session_vector() -> None:
    raw = enip.Packet(enip.REGISTER_SESSION, enip.register_session_data(), context=b"akdctl\0\0").encode()
    assert raw == bytes.fromhex("6500 0400 00000000 00000000") + b"akdctl\0\0" + bytes(4) + bytes.fromhex("0100 0000")


def test_send_rr_data_ucmm_vector() -> None:
    msg = cip.request(cip.GET_ATTRIBUTE_SINGLE, cip.PARAMETER, 796, 1).encode()
    assert msg == bytes.fromhex("0E 04 20 0F 25 00 1C 03 30 01")   # pycomm3 encodes 796 as 25 00 1C 03
    data = enip.unconnected(msg, timeout=10).encode()
    assert data == bytes.fromhex("00000000 0A00 0200 0000 0000 B200 0A00") + msg
    rr = enip.RRData.decode(data)
    assert enip.unconnected_message(rr) == msg


def test_paths() -> None:
    assert cip.Path(0x0F, 205, 1).encode() == bytes.fromhex("20 0F 24 CD 30 01")
    assert cip.Path(0x04, 1, None, (101, 102)).encode() == bytes.fromhex("20 04 24 01 2C 65 2C 66")
    keyed = bytes.fromhex("34 04 00 00 00 00 00 00 00 00 20 04 24 64 2C 65 2C 66")   # as the ethernetip package sends
    assert cip.decode_path(keyed) == cip.Path(4, 100, None, (101, 102), cip.ElectronicKey())
    assert cip.decode_path(bytes.fromhex("21 00 0F 01 25 00 1C 03 31 00 00 01")) == cip.Path(0x10F, 796, 256)
    with pytest.raises(CodecError):
        cip.decode_path(bytes.fromhex("24 01"))        # no class
    with pytest.raises(CodecError):
        cip.decode_path(bytes.fromhex("20 01 25 00 01"))   # truncated


def test_response_with_extended_status() -> None:
    raw = cip.Response(cip.FORWARD_OPEN, 0x01, (0x0106,), b"\x01\x02").encode()
    assert raw == bytes.fromhex("D4 00 01 01 06 01 01 02")
    assert cip.Response.decode(raw) == cip.Response(cip.FORWARD_OPEN, 1, (0x0106,), b"\x01\x02")


def test_forward_open_sizes() -> None:
    fo = cip.ForwardOpen(0, 0x1234, 7, 0x1AB, 99, 10000, cip.NetParams(70), 10000, cip.NetParams(66),
                         cip.Path(0x04, 1, None, (100, 101, 102)).encode())
    raw = fo.encode()
    assert len(raw) == 36 + 10 and raw[-11] == 5
    assert cip.ForwardOpen.decode(raw) == fo
    large = fo.__class__(**{**fo.__dict__, "large": True})
    assert cip.ForwardOpen.decode(large.encode(), large=True) == large
    assert cip.NetParams.decode(cip.NetParams(70).encode(False), False) == cip.NetParams(70)
    assert cip.NetParams(70, cip.TYPE_P2P, cip.PRIORITY_SCHEDULED).encode(False) == 0x4846


# ------------------------------------------------------------- round trips

u8, u16, u32 = st.integers(0, 0xFF), st.integers(0, 0xFFFF), st.integers(0, 0xFFFFFFFF)
i32 = st.integers(-(1 << 31), (1 << 31) - 1)
words = st.binary(max_size=40).map(lambda b: b[: len(b) // 2 * 2])


@given(st.builds(enip.Packet, u16, st.binary(max_size=200), u32, u32, st.binary(min_size=8, max_size=8), u32))
def test_packet_round_trip(packet: enip.Packet) -> None:
    assert enip.decode_packet(packet.encode()) == packet


@given(st.lists(st.builds(enip.Item, u16, st.binary(max_size=50)), max_size=5), u16, u32)
def test_rr_data_round_trip(items: list[enip.Item], timeout: int, interface: int) -> None:
    rr = enip.RRData(tuple(items), timeout, interface)
    assert enip.RRData.decode(rr.encode()) == rr


@given(st.builds(cip.Path, u16, st.none() | u32, st.none() | u16, st.lists(u16, max_size=3).map(tuple),
                 st.none() | st.builds(cip.ElectronicKey, u16, u16, u16, u8, u8)))
def test_path_round_trip(path: cip.Path) -> None:
    assert cip.decode_path(path.encode()) == path


@given(st.integers(0, 0x7F), words, st.binary(max_size=40))
def test_request_round_trip(service: int, path: bytes, data: bytes) -> None:
    req = cip.Request(service, path, data)
    assert cip.Request.decode(req.encode()) == req


@given(st.integers(0, 0x7F), u8, st.lists(u16, max_size=4).map(tuple), st.binary(max_size=40))
def test_response_round_trip(service: int, status: int, ext: tuple[int, ...], data: bytes) -> None:
    resp = cip.Response(service, status, ext, data)
    assert cip.Response.decode(resp.encode()) == resp


net_small = st.builds(cip.NetParams, st.integers(0, 0x1FF), st.integers(0, 3), st.integers(0, 3), st.booleans(),
                      st.booleans())
net_large = st.builds(cip.NetParams, u16, st.integers(0, 3), st.integers(0, 3), st.booleans(), st.booleans())


@given(st.booleans(), st.data())
def test_forward_open_round_trip(large: bool, data: st.DataObject) -> None:
    net = net_large if large else net_small
    fo = cip.ForwardOpen(data.draw(u32), data.draw(u32), data.draw(u16), data.draw(u16), data.draw(u32),
                         data.draw(u32), data.draw(net), data.draw(u32), data.draw(net), data.draw(words),
                         data.draw(u8), data.draw(u8), data.draw(u8), data.draw(u8), large)
    assert cip.ForwardOpen.decode(fo.encode(), large=large) == fo


@given(st.builds(cip.ForwardOpenReply, u32, u32, u16, u16, u32, u32, u32, words),
       st.builds(cip.ForwardClose, u16, u16, u32, words, u8, u8),
       st.builds(cip.ForwardCloseReply, u16, u16, u32, words))
def test_connection_manager_round_trips(rep: cip.ForwardOpenReply, close: cip.ForwardClose,
                                        crep: cip.ForwardCloseReply) -> None:
    assert cip.ForwardOpenReply.decode(rep.encode()) == rep
    assert cip.ForwardClose.decode(close.encode()) == close
    assert cip.ForwardCloseReply.decode(crep.encode()) == crep


@given(st.builds(asm.Command, u8, u8, st.integers(0, 7), st.integers(0, 31), st.integers(0, 7), st.integers(0, 31),
                 i32, i32, i32, i32, i32, st.binary(min_size=8, max_size=8), u8, u8, st.binary(min_size=2, max_size=2),
                 st.binary(min_size=28, max_size=28)))
def test_command_round_trip(cmd: asm.Command) -> None:
    assert asm.Command.decode(cmd.encode()) == cmd


@given(st.binary(min_size=64, max_size=64))
def test_response_bytes_round_trip(raw: bytes) -> None:
    assert asm.Response.decode(raw).encode() == raw
    assert asm.Command.decode(raw).encode() == raw


@given(st.builds(enip.Identity, u16, u16, u16, st.tuples(u8, u8), u16, u32,
                 st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=40), u8,
                 st.builds(enip.SockAddr, st.ip_addresses(v=4).map(str), u16)))
def test_identity_round_trip(identity: enip.Identity) -> None:
    assert enip.decode_list_identity(enip.list_identity_reply(identity)) == [identity]
    attrs = cip.IdentityAttributes(identity.vendor, identity.device_type, identity.product_code, identity.revision,
                                   identity.status, identity.serial, identity.product_name)
    assert cip.IdentityAttributes.decode(attrs.encode()) == attrs


@given(u32, u32, u16, st.binary(max_size=70))
def test_io_packet_round_trip(conn: int, seq: int, count: int, data: bytes) -> None:
    pkt = enip.IoPacket(conn, seq, count, data)
    assert enip.IoPacket.decode(pkt.encode()) == pkt


# ------------------------------------------------------------- fuzz: only CodecError

DECODERS = [enip.decode_packet, enip.decode_cpf, enip.RRData.decode, enip.Identity.decode, enip.IoPacket.decode,
            enip.SockAddr.decode, enip.decode_register_session, enip.decode_list_identity,
            cip.decode_path, cip.Request.decode, cip.Response.decode, cip.ForwardOpen.decode,
            lambda d: cip.ForwardOpen.decode(d, large=True), cip.ForwardOpenReply.decode, cip.ForwardClose.decode,
            cip.ForwardCloseReply.decode, cip.ConnectionFailure.decode, cip.IdentityAttributes.decode,
            cip.decode_short_string, asm.Command.decode, asm.Response.decode, enip.split_run_idle,
            lambda d: enip.unconnected_message(enip.RRData.decode(d))]


@settings(max_examples=300)
@given(st.binary(max_size=100))
def test_fuzz_decoders_raise_only_codec_error(data: bytes) -> None:
    for decode in DECODERS:
        try:
            decode(data)
        except CodecError:
            pass


@given(st.binary(min_size=24, max_size=60), st.integers(0, 0xFFFF))
def test_inconsistent_header_length_is_refused(data: bytes, length: int) -> None:
    raw = data[:2] + struct.pack("<H", length) + data[4:]
    if length == len(raw) - 24:
        return
    with pytest.raises(CodecError):
        enip.decode_packet(raw)


def test_encoders_refuse_out_of_range() -> None:
    with pytest.raises(CodecError):
        asm.Command(command_type=0x20).encode()
    with pytest.raises(CodecError):
        asm.Command(data=1 << 31).encode()
    with pytest.raises(CodecError):
        cip.Path(1, -1).encode()
    with pytest.raises(CodecError):
        cip.NetParams(0x200).encode(False)
    with pytest.raises(CodecError):
        enip.Packet(enip.NOP, context=b"x").encode()


# ------------------------------------------------------------- scapy (independent encapsulation layer)

def test_scapy_parses_our_register_session_and_list_identity() -> None:
    scapy = pytest.importorskip("scapy.contrib.enipTCP")
    raw = enip.Packet(enip.REGISTER_SESSION, enip.register_session_data(), session=0x11223344).encode()
    pkt = scapy.ENIPTCP(raw)
    assert pkt.commandId == 0x65 and pkt.session == 0x11223344 and pkt.length == 4
    msg = cip.request(cip.GET_ATTRIBUTE_SINGLE, cip.IDENTITY, 1, 7).encode()
    raw = enip.Packet(enip.SEND_RR_DATA, enip.unconnected(msg).encode(), session=5).encode()
    rr = scapy.ENIPTCP(raw)
    assert rr.commandId == 0x6F and rr.length == len(raw) - 24
    items = rr.payload.items
    assert [(i.typeId, i.length) for i in items] == [(0x0000, 0), (0x00B2, len(msg))]
    assert bytes(rr) == raw      # scapy re-serialises the frame it parsed to our bytes


# ------------------------------------------------------------- --pcap: TCP segments for explicit messaging

@given(st.binary(max_size=300), st.integers(1, 65535), st.integers(0, 0xFFFFFFFF))
def test_tcp_frame_checksums_always_valid(payload: bytes, port: int, seq: int) -> None:
    from akdctl.transport.pcap import internet_checksum, tcp_frame

    frame = tcp_frame(("127.0.0.1", port), ("127.0.0.2", 44818), payload, seq, 1)
    ip, tcp = frame[14:34], frame[34:]
    assert frame[12:14] == b"\x08\x00" and ip[9] == 6 and internet_checksum(ip) == 0
    pseudo = ip[12:20] + struct.pack("!BBH", 0, 6, len(tcp))
    assert internet_checksum(pseudo + tcp) == 0
    assert struct.unpack("!HHI", tcp[:8]) == (port, 44818, seq) and tcp[20:] == payload


def test_pcap_counts_tcp_sequence_numbers_per_direction(tmp_path) -> None:
    from akdctl.transport.pcap import PcapWriter
    from akdctl.transport.trace import Tracer

    tracer, writer = Tracer(), PcapWriter(tmp_path / "t.pcap")
    tracer.add_sink(writer.write)
    a, b = ("127.0.0.1", 40000), ("127.0.0.1", 44818)
    for direction, src, dst, data in (("tx", a, b, b"x" * 28), ("rx", b, a, b"y" * 28), ("tx", a, b, b"z" * 48)):
        tracer.frame(direction, "enip", data, meta={"proto": "tcp", "src": src, "dst": dst})
    writer.close()
    raw = (tmp_path / "t.pcap").read_bytes()[24:]
    seqs = []
    while raw:
        incl = struct.unpack_from("<I", raw, 8)[0]
        frame = raw[16:16 + incl]
        seqs.append(struct.unpack_from("!II", frame, 34 + 4))
        raw = raw[16 + incl:]
    assert seqs == [(1, 1), (1, 29), (29, 29)]      # (seq, ack) as the two directions advance
