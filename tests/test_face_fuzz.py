"""Bounded, seeded fuzz of every ``sim serve`` face, in this process: a few hundred hostile datagrams or frames each
(random bytes and mutations of valid requests), then one valid request that must still be answered.

The counts are small so CI runs them on every change; ``AKDCTL_FUZZ_COUNT`` raises them for a longer local run and
``AKDCTL_FUZZ_SEED`` replays another seed. Everything stays on loopback or python-can's in-process virtual bus.
"""

from __future__ import annotations

import os
import random
import socket
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from akdctl.sim.drive import SimDrive

COUNT = int(os.environ.get("AKDCTL_FUZZ_COUNT", "300"))
SEED = int(os.environ.get("AKDCTL_FUZZ_SEED", "1917"))


def hostile(rng: random.Random, valid: list[bytes], count: int = COUNT) -> Iterator[bytes]:
    """``count`` inputs: random bytes, and valid requests with bytes flipped, cut, extended or spliced."""
    for _ in range(count):
        kind = rng.randrange(5)
        if kind == 0 or not valid:
            yield rng.randbytes(rng.randrange(0, 96))
            continue
        data = bytearray(rng.choice(valid))
        if kind == 1:
            for _ in range(rng.randint(1, 4)):
                if data:
                    data[rng.randrange(len(data))] = rng.randrange(256)
        elif kind == 2:
            del data[rng.randrange(len(data) + 1):]
        elif kind == 3:
            data += rng.randbytes(rng.randrange(1, 64))
        else:
            other = rng.choice(valid)
            cut = rng.randrange(len(data) + 1)
            data = data[:cut] + other[rng.randrange(len(other) + 1):]
        yield bytes(data)


@pytest.fixture
def rng() -> random.Random:
    return random.Random(SEED)


@pytest.fixture
def drive(tmp_path: Path) -> SimDrive:
    return SimDrive("default", tmp_path)


def _quiet(receive: Callable[[float], object], quiet_for: float = 0.3, deadline: float = 20.0) -> None:
    """Wait until ``receive`` (a reader with a timeout) has returned nothing for ``quiet_for`` seconds: every answer
    to the fuzz has arrived, so none is taken for the answer to the valid request that follows."""
    end = time.monotonic() + deadline
    while time.monotonic() < end:
        if receive(quiet_for) is None:
            return
    raise AssertionError("the face kept sending for 20 s after the fuzz")


# ------------------------------------------------------------------ ETG.8200 mailbox gateway
def test_ethercat_udp_gateway_survives_fuzz(drive: SimDrive, rng: random.Random, akd_inproc) -> None:
    from akdctl.sim import face_ethercat_udp

    face = face_ethercat_udp.from_options(drive, ethercat_udp="127.0.0.1:0")
    assert face is not None
    upload = bytes.fromhex("10 50 0a 00 e9 03 00 03 00 20 40 18 10 01 00 00 00 00")  # 0x1018:1, station 1001
    download = bytes.fromhex("10 50 0a 00 e9 03 00 03 00 20 2f 60 60 00 03 00 00 00")  # 0x6060 = 3
    info = bytes.fromhex("0c 50 08 00 e9 03 00 03 00 80 01 00 00 00")  # SDO information: list
    for datagram in hostile(rng, [upload, download, info]):
        assert all(isinstance(reply, bytes) for reply in face.handler.handle(datagram))
    face.start()
    try:
        code, out, err = akd_inproc("-T", f"ecat-udp://127.0.0.1:{face.port}/1001", "--timeout", "2",
                                    "sdo", "read", "0x1018:1")
        assert code == 0 and "106" in out, err
    finally:
        face.stop()


# ------------------------------------------------------------------ raw EtherCAT slave
def test_ethercat_raw_slave_survives_fuzz(drive: SimDrive, rng: random.Random) -> None:
    from akdctl.protocol import ethercat as ec
    from akdctl.sim.ecat_inject import Injector, WARMUP_REQUEST
    from akdctl.sim.face_ethercat_raw import EthercatRawFace

    face = EthercatRawFace("fuzz0", drive, Injector())
    src = b"\x00\x11\x22\x33\x44\x55"

    def frame(*datagrams: ec.Datagram) -> bytes:
        return ec.encode_frame(list(datagrams), src=src, dst=b"\xff" * 6)

    brd = frame(ec.Datagram(ec.Cmd.BRD, 0, 0x0000, b"\0\0"))
    valid = [brd,
             frame(ec.Datagram(ec.Cmd.APWR, 0, 0x0120, b"\x02\x00")),  # AL control: PRE-OP
             frame(ec.Datagram(ec.Cmd.APWR, 0, 0x0800, bytes(8))),  # SM0 settings
             frame(ec.Datagram(ec.Cmd.APWR, 0, 0x1000, WARMUP_REQUEST.ljust(64, b"\0"))),  # a mailbox to SM0
             frame(ec.Datagram(ec.Cmd.APRD, 0, 0x1C00, bytes(64)))]
    for data in hostile(rng, valid):
        reply = face.handle_frame(data)
        if reply is not None:
            ec.decode_frame(reply)
        while (request := face.esc.take_request(0)) is not None:  # the application answers what reached SM0
            face.esc.post_replies(*face.worker.answer(request))
    reply = face.handle_frame(brd)
    assert reply is not None and ec.decode_frame(reply)[2][0].wkc == 1  # the slave still counts itself
    (answer,), lost = face.worker.answer(WARMUP_REQUEST)
    assert not lost and answer[5] & 0x0F == 3  # a CoE reply to the SDO upload


# ------------------------------------------------------------------ PROFINET
def _pn_datagrams() -> list[bytes]:
    from akdctl.protocol import dcerpc, pnio

    ar = uuid.uuid4()
    addr = pnio.RecordAddress()

    def call(opnum: int, blocks: bytes) -> bytes:
        head = dcerpc.RpcHeader(ptype=dcerpc.PT_REQUEST, object_uuid=pnio.object_uuid(0x100, 1),
                                interface_uuid=pnio.DEVICE_INTERFACE, activity_uuid=uuid.uuid4(), sequence=1,
                                opnum=opnum, flags1=dcerpc.FLAG_IDEMPOTENT)
        return dcerpc.encode_packet(head, pnio.encode_request_args(blocks))

    connect = pnio.ARBlockReq(pnio.AR_TYPE_IOSAR, ar, 1, b"\x02\0\0\0\0\x01", pnio.object_uuid(0, 0, 0),
                              pnio.DEVICE_ACCESS_PROPERTIES, 10, b"fuzz").encode()
    return [call(pnio.OP_CONNECT, connect),
            call(pnio.OP_WRITE, pnio.IODWriteReq(1, ar, addr, bytes.fromhex("01 01 00 01 10 01 03 A2 00 00")).encode()),
            call(pnio.OP_READ, pnio.IODReadReq(2, ar, addr, 240).encode()),
            call(pnio.OP_READ_IMPLICIT, pnio.IODReadReq(3, pnio.NIL_UUID, pnio.RecordAddress(index=pnio.INDEX_IM0),
                                                        64).encode()),
            call(pnio.OP_RELEASE, b"")]


def test_profinet_face_survives_fuzz(drive: SimDrive, rng: random.Random, akd_inproc) -> None:
    from akdctl.sim.face_profinet import ProfinetFace

    face = ProfinetFace(drive, "127.0.0.1", 0, max_ars=64)  # fuzzed Connects may open ARs: leave room for ours
    face.start()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))

    def receive(timeout: float) -> bytes | None:
        sock.settimeout(timeout)
        try:
            return sock.recv(65535)
        except socket.timeout:
            return None

    try:
        for datagram in hostile(rng, _pn_datagrams()):
            if len(datagram) >= 56 and rng.random() < 0.8:  # a fresh activity UUID: a new call, not a cached one
                datagram = datagram[:40] + rng.randbytes(16) + datagram[56:]
            sock.sendto(datagram, ("127.0.0.1", face.port))
        _quiet(receive)
        assert face.stats.received and face.ready and face.error is None and all(t.is_alive() for t in face._threads)
        code, out, err = akd_inproc("-T", f"pn://127.0.0.1:{face.port}", "--timeout", "2", "pnu", "get", "930")
        assert code == 0 and "930" in out, err
    finally:
        sock.close()
        face.stop()


# ------------------------------------------------------------------ CANopen
def test_can_face_survives_fuzz(drive: SimDrive, rng: random.Random, akd_inproc) -> None:
    import can

    from akdctl.sim.face_can import CanFace, parse_spec

    channel = f"akd-fuzz-{uuid.uuid4().hex[:8]}"
    face = CanFace(drive, parse_spec(f"virtual:{channel}:1"))
    face.start()
    bus = can.Bus(interface="virtual", channel=channel)
    cobs = [0x000, 0x080, 0x601, 0x601, 0x601, 0x701, 0x201, 0x301, 0x401, 0x501, 0x7E5]
    valid = [bytes.fromhex(h) for h in ("40 18 10 01 00 00 00 00", "2F 60 60 00 03 00 00 00", "C6 00 20 01 00 00 00 00",
                                        "A4 18 10 01 7F 00 00 00", "21 08 10 00 10 00 00 00", "60 00 00 00 00 00 00 00")]

    def receive(timeout: float) -> can.Message | None:
        return bus.recv(timeout)

    try:
        for data in hostile(rng, valid):
            cob = rng.choice(cobs) if rng.random() < 0.9 else rng.randrange(0x800)
            remote = cob == 0x701 and rng.random() < 0.5
            bus.send(can.Message(arbitration_id=cob, data=b"" if remote else data[:8], is_remote_frame=remote,
                                 dlc=rng.randrange(9) if remote else None, is_extended_id=False))
        _quiet(receive)
        target = ("-T", f"can://virtual/{channel}/1", "--timeout", "2")
        # The fuzz may have stopped the node (NMT) or left a transfer open: a reset is the valid way back.
        code, _, err = akd_inproc(*target, "can", "nmt", "reset")
        assert code == 0, err
        code, out, err = akd_inproc(*target, "sdo", "read", "0x1018:1")
        assert code == 0 and "106" in out, err
    finally:
        bus.shutdown()
        face.stop()


# ------------------------------------------------------------------ EtherNet/IP
def test_ethernetip_face_survives_fuzz(drive: SimDrive, rng: random.Random, akd_inproc) -> None:
    from akdctl.protocol import cip, enip
    from akdctl.sim.face_ethernetip import EthernetIpFace

    face = EthernetIpFace(drive, "127.0.0.1", 0, io_port=0)
    face.start()
    message = cip.request(cip.GET_ATTRIBUTE_SINGLE, 1, 1, 7).encode()
    rr = enip.unconnected(message).encode()
    valid = [enip.Packet(enip.REGISTER_SESSION, enip.register_session_data()).encode(),
             enip.Packet(enip.SEND_RR_DATA, rr, session=1).encode(),
             enip.Packet(enip.LIST_IDENTITY, b"").encode(),
             enip.Packet(enip.LIST_SERVICES, b"").encode()]
    try:
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for n, data in enumerate(hostile(rng, valid)):
            if n % 3 == 0:
                udp.sendto(data, ("127.0.0.1", face.port if n % 2 else face.io_port))
                continue
            with socket.create_connection(("127.0.0.1", face.port), timeout=2) as tcp:
                tcp.sendall(data)
                tcp.shutdown(socket.SHUT_WR)  # a header announcing more bytes than sent ends at EOF
                tcp.settimeout(2)
                while tcp.recv(4096):
                    pass
        udp.close()
        code, out, err = akd_inproc("-T", f"eip://127.0.0.1:{face.port}", "--timeout", "2", "--json", "info")
        assert code == 0 and '"vendor": 452' in out, err
    finally:
        face.stop()


# ------------------------------------------------------------------ AKD ASCII channel (issue 24)
def test_akd_ascii_face_survives_fuzz(drive: SimDrive, rng: random.Random, akd_inproc) -> None:
    from akdctl.sim.face_akd import AkdFace

    face = AkdFace(drive, "127.0.0.1", 0, clients=4)
    face.start()
    valid = [b"VL.KP\r\n", b"VL.KP 1.5\r\n", b"DRV.INFO\r\n", b"DRV.HELP HOME.MODE\r\n", b"\xff\xfc\x1fDRV.ACTIVE\n",
             b"HOME.MODE 3\r", b"DRV.EN\r\n", b"REC.OFF\r\n", b"\xff\xfa\x1f\x00\x50\x00\x18\xff\xf0MT.LIST\r\n"]
    try:
        with socket.create_connection(("127.0.0.1", face.port), timeout=2) as tcp:
            # The wait only paces the inputs and drains what the face says (no reply is asserted; a late one is read
            # after the next input): most fuzzed lines are cut short and get none, so each such wait runs out --
            # 300 inputs made 50 ms waits ~6 s of idling.
            tcp.settimeout(0.01)
            for data in hostile(rng, valid):
                tcp.sendall(data.replace(b"DRV.EN", b"DRV.XX"))   # nothing powers the simulated axis here
                try:
                    tcp.recv(65536)
                except socket.timeout:
                    pass
        code, out, err = akd_inproc("-T", f"akd://127.0.0.1:{face.port}", "--timeout", "2", "param", "get", "VL.KP")
        assert code == 0 and "[A/(rad/s)]" in out, err
    finally:
        face.stop()


# ------------------------------------------------------------------ Modbus TCP (issue 24)
def test_modbus_face_survives_fuzz(drive: SimDrive, rng: random.Random, akd_inproc) -> None:
    pytest.importorskip("pymodbus")
    import struct

    from akdctl.sim.face_modbus import ModbusFace

    face = ModbusFace(drive, "127.0.0.1", 0)
    face.start()

    def adu(pdu: bytes, tid: int = 1) -> bytes:
        return struct.pack(">HHHB", tid, 0, len(pdu) + 1, 1) + pdu

    valid = [adu(bytes.fromhex("03 0368 0002")), adu(bytes.fromhex("10 0368 0002 04 0000 05dc")),
             adu(bytes.fromhex("06 0368 0005")), adu(bytes.fromhex("03 0000 007d")), adu(bytes.fromhex("2b 0e 01 00"))]
    try:
        for n, data in enumerate(hostile(rng, valid, count=max(60, COUNT // 5))):
            with socket.create_connection(("127.0.0.1", face.port), timeout=2) as tcp:
                tcp.sendall(data)
                tcp.shutdown(socket.SHUT_WR)
                tcp.settimeout(0.5)
                try:
                    while tcp.recv(4096):
                        pass
                except (socket.timeout, ConnectionResetError):
                    pass
        code, out, err = akd_inproc("-T", f"mb://127.0.0.1:{face.port}", "--timeout", "2", "param", "get", "VL.KP")
        assert code == 0 and "[A/(rad/s)]" in out, err
    finally:
        face.stop()
