"""DCE/RPC v4 and PNIO codecs: seed byte vectors, round trips, fuzz, and scapy interop."""

from __future__ import annotations

import uuid

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.protocol import dcerpc, pnio
from akdctl.protocol.errors import CodecError

ACT = uuid.UUID("11223344-5566-7788-99aa-bbccddeeff00")
AR = uuid.UUID("0102030405060708090a0b0c0d0e0f10")
OBJ = pnio.object_uuid(vendor_id=0x011E, device_id=0x0002, instance=1)


# ------------------------------------------------------------- seed vectors

def test_object_uuid_layout() -> None:
    # DEA00000-6C97-11D1-8271-{instance}{device}{vendor}
    assert str(OBJ) == "dea00000-6c97-11d1-8271-00010002011e"


def test_header_big_endian_vector() -> None:
    head = dcerpc.RpcHeader(ptype=dcerpc.PT_REQUEST, object_uuid=OBJ, interface_uuid=pnio.DEVICE_INTERFACE,
                            activity_uuid=ACT, sequence=0x01020304, opnum=pnio.OP_WRITE,
                            flags1=dcerpc.FLAG_IDEMPOTENT)
    raw = dcerpc.encode_packet(head, b"\xAA\xBB")
    assert raw[:8] == bytes.fromhex("04 00 20 00 00 00 00 00")
    assert raw[8:24] == bytes.fromhex("dea000006c9711d1827100010002011e")
    assert raw[24:40] == bytes.fromhex("dea000016c9711d1827100a02442df7d")
    assert raw[40:56] == ACT.bytes
    assert raw[56:80] == bytes.fromhex("00000000 00000001 01020304 0003 ffff ffff 0002 0000 00 00")
    assert raw[80:] == b"\xAA\xBB"
    assert len(raw) == 82


def test_header_little_endian_uuid_order() -> None:
    head = dcerpc.RpcHeader(ptype=dcerpc.PT_RESPONSE, object_uuid=OBJ, interface_uuid=pnio.CONTROLLER_INTERFACE,
                            activity_uuid=ACT, sequence=7, opnum=2, drep=dcerpc.DREP_LITTLE)
    raw = dcerpc.encode_packet(head, b"")
    # first three UUID groups byte-swapped, the rest as is
    assert raw[8:24] == bytes.fromhex("0000a0de976cd1118271" "00010002011e")
    assert raw[64:68] == bytes.fromhex("07000000")
    back = dcerpc.decode_packet(raw)
    assert back.header.object_uuid == OBJ and back.header.activity_uuid == ACT and back.header.sequence == 7


def test_write_request_vector() -> None:
    bmp = bytes.fromhex("05 02 00 01 10 01 03 A2 00 00 42 01 00 02")   # seed 000 3.5.2, SPEC-NOTES 1
    block = pnio.IODWriteReq(1, AR, pnio.RecordAddress(), bmp).encode()
    assert block[:6] == bytes.fromhex("0008 003C 01 00")
    assert block[6:8] == b"\x00\x01" and block[8:24] == AR.bytes
    assert block[24:40] == bytes.fromhex("00003A00 0001 0001 0000 002F 0000000E")
    assert block[40:64] == bytes(24)
    assert block[64:] == bmp


def test_ndr_request_and_response_vectors() -> None:
    args = pnio.encode_request_args(b"\x01\x02", args_maximum=1024)
    assert args == bytes.fromhex("00000400 00000002 00000400 00000000 00000002 0102")
    res = pnio.encode_response_args(pnio.rw_error(False, 0xB5), b"")
    assert res == bytes.fromhex("DE80B500 00000000 00000000 00000000 00000000")
    status, blocks = pnio.decode_response_args(res)
    assert status.busy and blocks == b""


def test_ar_block_vector_and_length() -> None:
    req = pnio.ARBlockReq(pnio.AR_TYPE_IOSAR, AR, 1, bytes(6), ACT, pnio.DEVICE_ACCESS_PROPERTIES, 100, b"akdctl")
    raw = req.encode()
    assert raw[:6] == bytes.fromhex("0101 003C 01 00")          # 54 + name length
    assert raw[6:8] == b"\x00\x06"
    assert raw[48:52] == bytes.fromhex("00000111")
    assert raw[52:58] == bytes.fromhex("0064 8892 0006")


def test_status_words() -> None:
    """The codec returns codes; the catalogue words them (issue 22 item 4)."""
    from akdctl.catalog.texts import pnio_status_text

    assert "busy" in pnio_status_text(*pnio.PnioStatus(0xDE, 0x80, 0xB5, 0).encode())
    assert "invalid index" in pnio_status_text(*pnio.PnioStatus(0xDF, 0x80, 0xB0, 0).encode())
    assert "AR type" in pnio_status_text(*pnio.PnioStatus(*pnio.AR_TYPE_REFUSED).encode())
    assert not hasattr(pnio.PnioStatus, "describe")
    assert pnio.PnioStatus(0xDE, 0x80, 0xC2, 0).busy
    assert pnio.OK.ok and not pnio.OK.busy


def test_im0_round_trip_and_length() -> None:
    im = pnio.IM0(0x011E, "AKD-P00306-NBPN-0000", "R1234", 3, ("V", 1, 13, 2))
    raw = im.encode()
    assert raw[:6] == bytes.fromhex("0020 0038 01 00") and len(raw) == 60
    assert pnio.IM0.decode(raw) == im and im.software == "V1.13.2"


def test_fragments_reassemble_out_of_order() -> None:
    head = dcerpc.RpcHeader(ptype=dcerpc.PT_RESPONSE, object_uuid=OBJ, interface_uuid=pnio.DEVICE_INTERFACE,
                            activity_uuid=ACT, sequence=1, opnum=2)
    body = bytes(range(256)) * 3
    frames = dcerpc.fragment_body(head, body, 100)
    assert len(frames) == 8
    packets = [dcerpc.decode_packet(f) for f in frames]
    assert all(p.header.is_fragment for p in packets) and packets[-1].header.is_last_fragment
    r = dcerpc.Reassembler()
    order = [3, 0, 7, 1, 1, 2, 4, 6]
    for i in order:
        assert r.add(packets[i]) is None
    assert r.add(packets[5]) == body


# ------------------------------------------------------------- round trips

uuids = st.builds(uuid.UUID, int=st.integers(0, 2**128 - 1))
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFFFFFF)


@given(ptype=st.integers(0, 10), obj=uuids, iface=uuids, act=uuids, seq=u32, opnum=u16, flags=st.integers(0, 255),
       little=st.booleans(), frag=u16, body=st.binary(max_size=300), boot=u32)
def test_header_round_trip(ptype, obj, iface, act, seq, opnum, flags, little, frag, body, boot) -> None:
    head = dcerpc.RpcHeader(ptype=ptype, object_uuid=obj, interface_uuid=iface, activity_uuid=act, sequence=seq,
                            opnum=opnum, flags1=flags, fragment=frag, server_boot=boot,
                            drep=dcerpc.DREP_LITTLE if little else dcerpc.DREP_BIG)
    back = dcerpc.decode_packet(dcerpc.encode_packet(head, body))
    assert back.body == body
    assert back.header == dcerpc.replace(head, body_length=len(body))


addresses = st.builds(pnio.RecordAddress, api=u32, slot=u16, subslot=u16, index=u16)


@given(seq=u16, ar=uuids, addr=addresses, data=st.binary(max_size=300), little=st.booleans())
def test_write_read_round_trip(seq, ar, addr, data, little) -> None:
    w = pnio.IODWriteReq(seq, ar, addr, data)
    _, blocks = pnio.decode_request_args(pnio.encode_request_args(w.encode(), little=little), little)
    assert pnio.IODWriteReq.decode(blocks) == w
    r = pnio.IODReadRes(seq, ar, addr, data, 1, 2)
    status, blocks = pnio.decode_response_args(pnio.encode_response_args(pnio.OK, r.encode(), little=little), little)
    assert status.ok and pnio.IODReadRes.decode(blocks) == r


@given(seq=u16, ar=uuids, addr=addresses, length=u32, st4=st.tuples(*[st.integers(0, 255)] * 4), target=uuids)
def test_headers_round_trip(seq, ar, addr, length, st4, target) -> None:
    wr = pnio.IODWriteRes(seq, ar, addr, length, pnio.PnioStatus(*st4), 3, 4)
    assert pnio.IODWriteRes.decode(wr.encode()) == wr
    rq = pnio.IODReadReq(seq, ar, addr, length, target)
    assert pnio.IODReadReq.decode(rq.encode()) == rq


@given(ar_type=u16, ar=uuids, key=u16, mac=st.binary(min_size=6, max_size=6), obj=uuids, props=u32,
       factor=u16, name=st.binary(max_size=240))
def test_ar_blocks_round_trip(ar_type, ar, key, mac, obj, props, factor, name) -> None:
    req = pnio.ARBlockReq(ar_type, ar, key, mac, obj, props, factor, name)
    assert pnio.ARBlockReq.decode(req.encode()) == req
    res = pnio.ARBlockRes(ar_type, ar, key, mac)
    assert pnio.ARBlockRes.decode(res.encode()) == res
    rel = pnio.ReleaseBlock(ar, key, pnio.CONTROL_DONE, 0, True)
    assert pnio.ReleaseBlock.decode(rel.encode()) == rel


# ------------------------------------------------------------- fuzz

DECODERS = [dcerpc.decode_packet, pnio.ARBlockReq.decode, pnio.ARBlockRes.decode, pnio.IODWriteReq.decode,
            pnio.IODWriteRes.decode, pnio.IODReadReq.decode, pnio.IODReadRes.decode, pnio.ReleaseBlock.decode,
            pnio.IM0.decode, pnio.split_blocks, pnio.decode_request_args, pnio.decode_response_args]


@settings(max_examples=300)
@given(data=st.binary(max_size=200), which=st.integers(0, len(DECODERS) - 1))
def test_fuzz_only_codec_error(data, which) -> None:
    try:
        DECODERS[which](data)
    except CodecError:
        pass


@settings(max_examples=200)
@given(cut=st.integers(0, 140), flip=st.integers(0, 139), bit=st.integers(0, 7))
def test_fuzz_mutated_valid_frames(cut, flip, bit) -> None:
    raw = bytearray(pnio.IODWriteReq(1, AR, pnio.RecordAddress(), b"\x05\x01\x00\x01\x10\x01\x03\xa2\x00\x00").encode()
                    + pnio.ARBlockReq(6, AR, 1, bytes(6), ACT, 0x111, 100, b"x").encode())
    if flip < len(raw):
        raw[flip] ^= 1 << bit
    for decoder in DECODERS:
        try:
            decoder(bytes(raw[:cut]))
        except CodecError:
            pass


def test_encode_errors_are_codec_errors() -> None:
    with pytest.raises(CodecError):
        pnio.ARBlockReq(0x10000, AR, 1, bytes(6), ACT, 0x111, 100, b"").encode()
    with pytest.raises(CodecError):
        pnio.object_uuid(0x10000, 1)
    with pytest.raises(CodecError):
        dcerpc.encode_packet(dcerpc.RpcHeader(0, OBJ, OBJ, ACT, 2**32, 0), b"")


# ------------------------------------------------------------- scapy interop

scapy_rpc = pytest.importorskip("scapy.contrib.pnio_rpc", reason="scapy is not installed")


def _scapy_request(opnum: int, blocks: list, endian: str = "big") -> bytes:
    from scapy.layers.dcerpc import DceRpc4

    return bytes(DceRpc4(ptype="request", flags1=0x20, opnum=opnum, seqnum=9, endian=endian, act_id=str(ACT),
                         object=str(OBJ), if_id=str(pnio.DEVICE_INTERFACE))
                 / scapy_rpc.PNIOServiceReqPDU(args_max=1024, blocks=blocks))


@pytest.mark.parametrize("endian", ["big", "little"])
def test_scapy_built_requests_decode(endian: str) -> None:
    bmp = b"\x05\x01\x00\x01\x10\x01\x03\xa2\x00\x00"
    connect = _scapy_request(0, [scapy_rpc.ARBlockReq(
        ARType=6, ARUUID=str(AR), SessionKey=1, CMInitiatorMacAdd="00:00:00:00:00:00",
        CMInitiatorObjectUUID=str(ACT), ARProperties_DeviceAccess=1, ARProperties_ParametrizationServer=1,
        ARProperties_State=1, CMInitiatorActivityTimeoutFactor=100, CMInitiatorStationName=b"scapy")], endian)
    pkt = dcerpc.decode_packet(connect)
    assert pkt.header.opnum == 0 and pkt.header.activity_uuid == ACT and pkt.header.object_uuid == OBJ
    ar = pnio.ARBlockReq.decode(pnio.decode_request_args(pkt.body, pkt.header.little_endian)[1])
    assert ar.ar_type == 6 and ar.properties == 0x111 and ar.station_name == b"scapy" and ar.ar_uuid == AR

    write = _scapy_request(3, [scapy_rpc.IODWriteReq(seqNum=2, ARUUID=str(AR), API=0x3A00, slotNumber=1,
                                                     subslotNumber=1, index=0x2F) / bmp], endian)
    pkt = dcerpc.decode_packet(write)
    w = pnio.IODWriteReq.decode(pnio.decode_request_args(pkt.body, pkt.header.little_endian)[1])
    assert w.data == bmp and w.address == pnio.RecordAddress() and w.seq_number == 2

    read = _scapy_request(2, [scapy_rpc.IODReadReq(seqNum=3, ARUUID=str(AR), API=0x3A00, slotNumber=1,
                                                   subslotNumber=1, index=0x2F, recordDataLength=240)], endian)
    pkt = dcerpc.decode_packet(read)
    r = pnio.IODReadReq.decode(pnio.decode_request_args(pkt.body, pkt.header.little_endian)[1])
    assert r.max_length == 240 and r.address.index == 0x2F


def test_our_responses_parse_in_scapy() -> None:
    from scapy.layers.dcerpc import DceRpc4

    head = dcerpc.RpcHeader(ptype=dcerpc.PT_RESPONSE, object_uuid=OBJ, interface_uuid=pnio.DEVICE_INTERFACE,
                            activity_uuid=ACT, sequence=5, opnum=2)
    data = b"\x05\x01\x00\x01\x42\x01\x00\x02"
    body = pnio.encode_response_args(pnio.OK, pnio.IODReadRes(1, AR, pnio.RecordAddress(), data).encode())
    pkt = DceRpc4(dcerpc.encode_packet(head, body))
    res = pkt[scapy_rpc.IODReadRes]
    assert res.index == 0x2F and res.API == 0x3A00 and res.recordDataLength == len(data)
    # scapy's IODReadRes does not know that record data follows the header block; check the NDR count instead
    assert pkt[scapy_rpc.PNIOServiceResPDU].args_length == 64 + len(data) and bytes(pkt).endswith(data)
    conn = pnio.encode_response_args(pnio.OK, pnio.ARBlockRes(6, AR, 1, bytes(6)).encode())
    pkt = DceRpc4(dcerpc.encode_packet(dcerpc.replace(head, opnum=0), conn))
    assert pkt[scapy_rpc.ARBlockRes].ARType == 6
