"""ProfinetTransport against the simulator's PROFINET face over real UDP sockets on loopback."""

from __future__ import annotations

import socket
import threading
import time
import uuid
from collections.abc import Iterator

import pytest

from akdctl.errors import NoAnswer, RecordError
from akdctl.protocol import dcerpc, pnio
from akdctl.sim.face_profinet import Injection, ProfinetFace
from akdctl.transport.base import LinkOptions
from akdctl.transport.profinet import PnioRecordLink, ProfinetTransport
from akdctl.transport.target import split_target
from akdctl.transport.trace import TracedRecordLink, Tracer
from tests.harness import wait_until

READ_930 = bytes.fromhex("05 01 00 01 10 01 03 A2 00 00")


class CountingDrive:
    """A parameter manager that counts what reaches it, to prove nothing is applied twice."""

    def __init__(self) -> None:
        self.requests: list[bytes] = []
        self.lock = threading.Lock()

    def handle_bmp(self, request: bytes) -> bytes:
        if request[6:8] == b"\x03\xc4":            # the face asks PNU 964 for its identity at start
            return request[:4] + bytes.fromhex("06 02 01 00 00 01")
        with self.lock:
            self.requests.append(request)
        if request[1] == 0x02:
            return request[:4] + b"\x00\x00"
        return request[:4] + b"\x42\x01" + len(self.requests).to_bytes(2, "big")


@pytest.fixture
def drive() -> CountingDrive:
    return CountingDrive()


def make_face(drive, **kwargs) -> ProfinetFace:
    face = ProfinetFace(drive, "127.0.0.1", 0, **kwargs)
    face.start()
    return face


@pytest.fixture
def face_factory(drive) -> Iterator:
    faces: list[ProfinetFace] = []

    def factory(**kwargs) -> ProfinetFace:
        face = make_face(drive, **kwargs)
        faces.append(face)
        return face

    yield factory
    for face in faces:
        face.stop()


def transport(port: int, query: str = "", timeout: float = 1.0, retries: int = 4) -> ProfinetTransport:
    target = split_target(f"pn://127.0.0.1:{port}{'?' + query if query else ''}")
    t = ProfinetTransport(target, LinkOptions(timeout=timeout, retries=retries, tracer=Tracer()))
    t.connect()
    t.record_link = PnioRecordLink(t)
    return t


def test_read_and_write_through_face(face_factory, drive) -> None:
    face = face_factory()
    t = transport(face.port)
    try:
        assert t.record_link.exchange(READ_930) == bytes.fromhex("05 01 00 01 42 01 00 01")
        change = bytes.fromhex("06 02 00 01 10 01 03 A2 00 00 42 01 00 02")
        assert t.record_link.exchange(change) == bytes.fromhex("06 02 00 01 00 00")
        assert drive.requests == [READ_930, change]
        assert len(face._ars) == 1
    finally:
        t.close()
    assert face._ars == {}          # released
    t.close()                       # twice is harmless


def test_busy_device_is_polled(face_factory, drive) -> None:
    face = face_factory(delay=0.15)
    t = transport(face.port)
    try:
        for _ in range(3):
            assert t.record_link.exchange(READ_930)[:4] == READ_930[:4]
    finally:
        t.close()
    assert face.stats.busy_answers > 0 and len(drive.requests) == 3


@pytest.mark.parametrize("spec", ["drop=3", "dup=2", "delay=4:0.4", "rxdrop=3", "drop=5,dup=3,delay=7:0.3,rxdrop=4"])
def test_injected_faults_complete_and_never_apply_twice(face_factory, drive, spec: str) -> None:
    face = face_factory(injection=Injection.parse(spec), delay=0.02)
    t = transport(face.port, timeout=2.0, retries=10)
    try:
        answers = [t.record_link.exchange(bytes([n + 1]) + READ_930[1:]) for n in range(12)]
    finally:
        t.close()
    # each request reached the parameter manager exactly once, and each answer is its own
    assert [r[0] for r in drive.requests] == list(range(1, 13))
    assert [a[0] for a in answers] == list(range(1, 13))
    assert face.stats.dropped + face.stats.duplicated + face.stats.delayed > 0


def test_fragmented_responses_reassembled(face_factory) -> None:
    face = face_factory(fragment=24)
    t = transport(face.port)
    try:
        assert t.record_link.exchange(READ_930)[:4] == READ_930[:4]
        im0 = t.read_im0_record()
    finally:
        t.close()
    assert im0.vendor_id == face.vendor_id and im0.order_id.startswith("AKD")


def test_read_implicit_im0_without_ar(face_factory) -> None:
    face = face_factory()
    target = split_target(f"pn://127.0.0.1:{face.port}")
    t = ProfinetTransport(target, LinkOptions(timeout=1.0, tracer=Tracer()))
    try:
        im0 = t.read_im0()
    finally:
        t.close()
    assert im0["profile_id"] == "0x3A00" and str(im0["software_revision"]).startswith("V")


def test_refused_ar_in_words(face_factory) -> None:
    face = face_factory(refuse_ar=True)
    target = split_target(f"pn://127.0.0.1:{face.port}")
    t = ProfinetTransport(target, LinkOptions(timeout=1.0, tracer=Tracer()))
    with pytest.raises(RecordError, match="device refuses device-access AR.*AR type.*DB 81 01 04"):
        t.connect()
    t.close()


def test_wrong_slot_is_record_error_in_words(face_factory) -> None:
    face = face_factory()
    t = transport(face.port, query="slot=2")
    try:
        with pytest.raises(RecordError, match="invalid slot"):
            t.record_link.exchange(READ_930)
    finally:
        t.close()


def test_silent_device_is_no_answer() -> None:
    silent = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    silent.bind(("127.0.0.1", 0))
    try:
        target = split_target(f"pn://127.0.0.1:{silent.getsockname()[1]}")
        t = ProfinetTransport(target, LinkOptions(timeout=0.4, retries=2, tracer=Tracer()))
        start = time.monotonic()
        with pytest.raises(NoAnswer, match="no answer to PNIO Connect within 0.4 s"):
            t.connect()
        assert time.monotonic() - start < 5          # bounded by the timeout, not a hang
        t.close()
    finally:
        silent.close()


def test_stale_and_foreign_replies_are_ignored() -> None:
    """A fake device answers every request first with a reply to an older sequence number and with
    another activity's reply, then with the right one: the client must pick the right one."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    stop = threading.Event()

    def serve() -> None:
        sock.settimeout(0.1)
        while not stop.is_set():
            try:
                data, peer = sock.recvfrom(65535)
            except OSError:
                continue
            pkt = dcerpc.decode_packet(data)
            req = pnio.ARBlockReq.decode(pnio.decode_request_args(pkt.body)[1])
            good = pnio.encode_response_args(pnio.OK, pnio.ARBlockRes(6, req.ar_uuid, 1, bytes(6)).encode(),
                                             little=True)
            head = dcerpc.replace(pkt.header, ptype=dcerpc.PT_RESPONSE, drep=dcerpc.DREP_LITTLE)
            sock.sendto(dcerpc.encode_packet(dcerpc.replace(head, sequence=head.sequence - 1), good), peer)
            sock.sendto(dcerpc.encode_packet(dcerpc.replace(head, activity_uuid=uuid.uuid4()), good), peer)
            sock.sendto(b"garbage", peer)
            sock.sendto(dcerpc.encode_packet(head, good), peer)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    t = ProfinetTransport(split_target(f"pn://127.0.0.1:{sock.getsockname()[1]}"),
                          LinkOptions(timeout=1.0, tracer=Tracer()))
    try:
        t.connect()
        assert t.rpc is not None and t.rpc.stale == 2
    finally:
        t._stop.set()
        t.ar_uuid = None        # the fake device does not implement Release
        t.close()
        stop.set()
        thread.join()
        sock.close()


def test_ar_timeout_and_keepalive(face_factory, drive) -> None:
    face = face_factory()
    # a keep-alive every third of 300 ms keeps the AR through a longer pause: each keep-alive goes out only after
    # 100 ms of silence, so six of them in a row span at least 600 ms, twice the AR's timeout
    t = transport(face.port, query="ar_timeout=3")
    try:
        quiet_from = face.stats.received
        wait_until(lambda: face.stats.received >= quiet_from + 6, "six keep-alives", timeout=10)
        assert t.record_link.exchange(READ_930)[:2] == READ_930[:2]
    finally:
        t.close()
    assert face.stats.ars_timed_out == 0
    # without keep-alive the device ends the AR: the next access is refused in words
    t = transport(face.port, query="ar_timeout=2")
    t._stop.set()
    t._keepalive.join()
    try:
        wait_until(lambda: face.stats.ars_timed_out == 1, "the device to end the silent AR", timeout=10)
        with pytest.raises(RecordError, match="access denied"):
            t.record_link.exchange(READ_930)
    finally:
        t.close()
    assert face.stats.ars_timed_out == 1


def test_pcap_meta_on_every_datagram(face_factory) -> None:
    face = face_factory()
    t = transport(face.port)
    try:
        TracedRecordLink(t.record_link, t.options.tracer).exchange(READ_930)  # the Connection's wrapper
    finally:
        t.close()
    rpc = [r for r in t.options.tracer.records if r.layer == "pnio-rpc"]
    assert rpc and all(r.meta["proto"] == "udp" for r in rpc)
    assert {r.direction for r in rpc} == {"tx", "rx"}
    assert any(r.layer == "bmp" for r in t.options.tracer.records)


def test_scapy_client_against_face(face_factory, drive) -> None:
    """scapy builds Connect/Write/Read independently of our codec; the face answers them correctly."""
    scapy_rpc = pytest.importorskip("scapy.contrib.pnio_rpc", reason="scapy is not installed")
    from scapy.layers.dcerpc import DceRpc4

    face = face_factory()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(2)
    act = uuid.uuid4()
    ar = uuid.uuid4()

    def call(opnum: int, seq: int, blocks: list):
        pkt = DceRpc4(ptype="request", flags1=0x20, opnum=opnum, seqnum=seq, endian="little", act_id=str(act),
                      object="dea00000-6c97-11d1-8271-000100010100",
                      if_id="dea00001-6c97-11d1-8271-00a02442df7d") / scapy_rpc.PNIOServiceReqPDU(
                          args_max=1024, blocks=blocks)
        sock.sendto(bytes(pkt), ("127.0.0.1", face.port))
        return DceRpc4(sock.recv(65535))

    try:
        res = call(0, 0, [scapy_rpc.ARBlockReq(
            ARType=6, ARUUID=str(ar), SessionKey=7, CMInitiatorMacAdd="02:00:00:00:00:01",
            CMInitiatorObjectUUID=str(uuid.uuid4()), ARProperties_DeviceAccess=1,
            ARProperties_ParametrizationServer=1, ARProperties_State=1, CMInitiatorActivityTimeoutFactor=100,
            CMInitiatorStationName=b"scapy")])
        assert res.ptype == 2 and res.endian == 1 and res.seqnum == 0
        assert res[scapy_rpc.PNIOServiceResPDU].status == 0
        assert res[scapy_rpc.ARBlockRes].ARType == 6 and str(res[scapy_rpc.ARBlockRes].ARUUID) == str(ar)
        res = call(3, 1, [scapy_rpc.IODWriteReq(seqNum=1, ARUUID=str(ar), API=0x3A00, slotNumber=1,
                                                subslotNumber=1, index=0x2F) / READ_930])
        assert res[scapy_rpc.PNIOServiceResPDU].status == 0 and res[scapy_rpc.IODWriteRes].recordDataLength == 10
        res = call(2, 2, [scapy_rpc.IODReadReq(seqNum=2, ARUUID=str(ar), API=0x3A00, slotNumber=1,
                                               subslotNumber=1, index=0x2F, recordDataLength=240)])
        assert res[scapy_rpc.PNIOServiceResPDU].status == 0
        assert bytes(res).endswith(bytes.fromhex("05 01 00 01 42 01 00 01"))
        assert drive.requests == [READ_930]
        # an IO controller AR (type 1) is refused with the status a device sends
        res = call(0, 3, [scapy_rpc.ARBlockReq(ARType=1, ARUUID=str(uuid.uuid4()), SessionKey=1,
                                               CMInitiatorMacAdd="02:00:00:00:00:01",
                                               CMInitiatorObjectUUID=str(uuid.uuid4()),
                                               CMInitiatorStationName=b"plc")])
        assert bytes(res[scapy_rpc.PNIOServiceResPDU])[:4] == bytes.fromhex("DB 81 01 04")
    finally:
        sock.close()


def test_read_implicit_cannot_reach_parameter_channel(face_factory) -> None:
    face = face_factory()
    t = ProfinetTransport(split_target(f"pn://127.0.0.1:{face.port}"), LinkOptions(timeout=1.0, tracer=Tracer()))
    try:
        with pytest.raises(RecordError, match="access denied"):
            t._read(pnio.RecordAddress(), 240, implicit=True)
    finally:
        t.close()


def test_bad_query_is_usage_error() -> None:
    from akdctl.errors import UsageError

    with pytest.raises(UsageError, match="slot"):
        ProfinetTransport(split_target("pn://127.0.0.1?slot=99999"), LinkOptions())
    with pytest.raises(UsageError, match="drop=N"):
        Injection.parse("drop=x")
