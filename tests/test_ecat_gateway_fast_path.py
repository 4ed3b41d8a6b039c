"""The served ETG.8200 upload's memos (issue 29) answer what the general path answers, byte for byte.

* ``GatewayHandler`` keeps each distinct datagram's mailbox and station (``_learn``), joins every reply to the
  gateway header of its size and answers a datagram and those that follow in one frame (``serve``): held here to
  the gateway as it was first written (a reference kept in this file: unwrap, look up the station, injector,
  repeats, the drive, wrap each reply), over two drives in the same state, for uploads, repeats, downloads,
  segmented transfers and their toggles, aborts, unknown objects and stations, and malformed datagrams;
* ``SdoServer`` keeps the plan of each distinct plain upload initiate (``_plan``): the value is still read from the
  model on every request (a write shows at once), a request that is not bytes is answered alike, and the memo is
  bounded;
* the codecs' new pieces equal the encoders they cut: ``mailbox.gateway_header`` and
  ``coe.expedited_upload_templates``.
"""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.protocol import coe
from akdctl.protocol import mailbox as mbx
from akdctl.protocol.coe import CoeService
from akdctl.protocol.errors import CodecError
from akdctl.sim import face_ethercat_udp, sdo_server
from akdctl.sim.drive import SimDrive, factory_model
from akdctl.sim.ecat_inject import Injector, failure_reply, mailbox_error_reply, sdo_abort_reply
from akdctl.sim.face import request_failed
from akdctl.sim.face_ethercat_udp import EthercatUdpFace, GatewayHandler
from akdctl.sim.mailbox_repeat import MailboxRepeats
from akdctl.sim.sdo_server import SdoServer

PEER = ("127.0.0.1", 5000)


class ReferenceGateway:
    """The gateway's rule as first written: every datagram unwrapped and every reply wrapped by the codec."""

    def __init__(self, stations: dict[int, SimDrive], injector: Injector | None = None) -> None:
        self.stations = stations
        self.injector = injector or Injector()
        self.repeats = MailboxRepeats()

    def handle(self, datagram: bytes, peer: object = None) -> list[bytes]:
        try:
            raw = mbx.unwrap_gateway(datagram)
        except CodecError:
            return []
        address = raw[2] | raw[3] << 8
        drive = self.stations.get(address)
        if drive is None:
            return []
        replies: list[bytes] | None = None
        if self.injector.every:
            fault = self.injector.decide()
            if fault == "drop":
                return []
            if fault == "mbxerr":
                replies = [mailbox_error_reply(raw)]
            elif fault == "abort" and (abort := sdo_abort_reply(raw)) is not None:
                replies = [abort]
        if replies is None:
            try:
                replies = self.repeats.answer((peer, address), raw, drive.handle_mailbox)
            except CodecError:
                replies = [mailbox_error_reply(raw, 1)]
            except Exception as exc:  # noqa: BLE001 - as the gateway
                request_failed("ethercat-udp", exc)
                replies = failure_reply(raw)
        out = []
        for reply in replies:
            if len(reply) < mbx.HEADER_SIZE:
                continue
            if reply[2] | reply[3] << 8 != address:
                reply = reply[:2] + raw[2:4] + reply[4:]
            try:
                out.append(mbx.wrap_gateway(reply))
            except CodecError:
                continue
        return out


def _sdo(payload: bytes, counter: int, station: int = 1001, service: int = CoeService.SDO_REQUEST) -> bytes:
    return mbx.wrap_gateway(mbx.pack(mbx.MailboxType.COE, coe.encode_coe(service, payload), station, counter))


def _upload(index: int, subindex: int, counter: int, station: int = 1001) -> bytes:
    return _sdo(coe.encode_sdo(coe.SdoUploadInitiate(index, subindex)), counter, station)


ADDRESSES = [(0x1018, 1), (0x1018, 4), (0x1018, 0), (0x1000, 0), (0x6041, 0), (0x6081, 0), (0x2033, 0),
             (0x1008, 0), (0x1001, 0), (0x1018, 9), (0x7FFF, 0), (0x0002, 0), (0x1026, 1)]


def _script() -> list[bytes]:
    """Datagrams a master (and a hostile network) sends: every kind of request and answer."""
    out: list[bytes] = []
    counter = 0

    def nxt() -> int:
        nonlocal counter
        counter = mbx.next_counter(counter)
        return counter

    for index, subindex in ADDRESSES:
        first = _upload(index, subindex, nxt())
        out += [first, first]  # the second is a repeat: answered from the first, not executed
        out.append(_upload(index, subindex, 0))  # no counter: never a repeat
    # a write, then the upload of the same object by the same datagram as before: the new value
    out.append(_sdo(coe.encode_sdo(coe.SdoDownloadInitiate(0x6081, 0, (4321).to_bytes(4, "little"), 4, True)), nxt()))
    out.append(_upload(0x6081, 0, 1))
    out.append(_upload(0x6081, 0, 2))
    # a long value written in segments, read back in segments; a wrong toggle aborts
    long = bytes(range(256)) * 5
    out.append(_sdo(coe.encode_sdo(coe.SdoDownloadInitiate(0x2032, 0, long[:400], len(long), False)), nxt()))
    toggle, rest = 0, long[400:]
    while rest:
        chunk, rest = rest[:400], rest[400:]
        out.append(_sdo(coe.encode_sdo(coe.SdoDownloadSegment(toggle, chunk, not rest)), nxt()))
        toggle ^= 1
    out.append(_upload(0x2032, 0, nxt()))
    for toggle in (0, 1, 1, 0):
        out.append(_sdo(coe.encode_sdo(coe.SdoUploadSegment(toggle)), nxt()))
    out.append(_sdo(coe.encode_sdo(coe.SdoUploadSegment(0)), nxt()))  # no transfer in progress
    # a plain upload ends a transfer in progress: the next segment finds none (upload and download alike)
    out.append(_upload(0x2032, 0, nxt()))
    out.append(_sdo(coe.encode_sdo(coe.SdoUploadSegment(0)), nxt()))
    out.append(_upload(0x1018, 1, nxt()))
    out.append(_sdo(coe.encode_sdo(coe.SdoUploadSegment(1)), nxt()))
    out.append(_sdo(coe.encode_sdo(coe.SdoDownloadInitiate(0x2032, 0, long[:400], 600, False)), nxt()))
    out.append(_upload(0x1018, 1, nxt()))
    out.append(_sdo(coe.encode_sdo(coe.SdoDownloadSegment(0, long[:200], True)), nxt()))
    # an abort from the master, a block upload (unknown command), complete access, a response sent to the slave
    out.append(_sdo(coe.encode_sdo(coe.SdoAbort(0x1018, 1, coe.ABORT_GENERAL)), nxt()))
    out.append(_sdo(bytes([0xA0, 0x18, 0x10, 1, 0, 0, 0, 0]), nxt()))
    out.append(_sdo(bytes([0x50, 0x18, 0x10, 0, 0, 0, 0, 0]), nxt()))
    out.append(_sdo(coe.encode_sdo(coe.SdoUploadInitiate(0x1018, 1)), nxt(), service=CoeService.SDO_RESPONSE))
    # an unknown station, another mailbox type, a channel, malformed datagrams, trailing bytes
    plain = _upload(0x1018, 1, 3)
    out.append(_upload(0x1018, 1, nxt(), station=1002))
    out.append(plain[:7] + bytes([(plain[7] & 0xF0) | mbx.MailboxType.SOE]) + plain[8:])
    out.append(plain[:6] + b"\x01" + plain[7:])
    out += [b"", b"\x01", plain[:-1], plain[:1] + b"\x10" + plain[2:], plain[:2] + b"\x09" + plain[3:],
            plain + b"\x00\x00", plain[:8] + b"\x00"]
    out.append(mbx.wrap_gateway(mbx.pack(mbx.MailboxType.COE, b"\x00", 1001, nxt())))  # CoE data too short
    out.append(_sdo(b"\x40\x18", nxt()))  # an SDO too short
    return out


def _drives(tmp_path: Path) -> tuple[SimDrive, SimDrive]:
    """Two drives in the same state: one behind each gateway."""
    drives = []
    for side in ("fast", "reference"):
        directory = tmp_path / side
        directory.mkdir()
        drives.append(SimDrive("gw", directory))
    return drives[0], drives[1]


@pytest.mark.parametrize("keeps_lock", [False, True])
def test_the_gateway_answers_every_datagram_as_the_reference(tmp_path: Path, keeps_lock: bool) -> None:
    fast_drive, ref_drive = _drives(tmp_path)
    if keeps_lock:
        fast_drive.serve_faces()
        ref_drive.serve_faces()
    fast, ref = GatewayHandler({1001: fast_drive}), ReferenceGateway({1001: ref_drive})
    script = _script()
    for round_ in range(2):  # the second round finds every datagram in the memos
        for n, datagram in enumerate(script):
            got, want = fast.handle(datagram, PEER), ref.handle(datagram, PEER)
            assert got == want, (round_, n, datagram.hex())
    assert fast.repeats.repeats == ref.repeats.repeats > 0
    assert fast._mailboxes and fast._headers  # the memos were made and used


def test_the_gateway_with_injected_faults_answers_as_the_reference(tmp_path: Path) -> None:
    fast_drive, ref_drive = _drives(tmp_path)
    inject = "drop=3,mbxerr=4,abort=5"
    fast = GatewayHandler({1001: fast_drive}, Injector.parse(inject, "--ecat-inject"))
    ref = ReferenceGateway({1001: ref_drive}, Injector.parse(inject, "--ecat-inject"))
    for datagram in _script()[:40]:
        assert fast.handle(datagram, PEER) == ref.handle(datagram, PEER)


def test_a_drive_failure_is_answered_as_the_reference(tmp_path: Path) -> None:
    class Failing(SimDrive):
        def handle_mailbox(self, mailbox: bytes) -> list[bytes]:
            raise RuntimeError("state file unwritable")

    fast = GatewayHandler({1001: Failing("gw", tmp_path)})
    ref = ReferenceGateway({1001: Failing("gw", tmp_path)})
    for datagram in (_upload(0x1018, 1, 1), _upload(0x1018, 1, 0)):
        assert fast.handle(datagram, PEER) == ref.handle(datagram, PEER) != []


def test_the_gateways_memo_is_bounded_and_keeps_answering(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(face_ethercat_udp, "MAILBOXES_KEPT", 8)
    fast_drive, ref_drive = _drives(tmp_path)
    fast, ref = GatewayHandler({1001: fast_drive}), ReferenceGateway({1001: ref_drive})
    for subindex in range(30):
        datagram = _upload(0x1018, subindex % 6, subindex % 7 + 1)
        assert fast.handle(datagram, PEER) == ref.handle(datagram, PEER)
        assert len(fast._mailboxes) <= 8


def test_a_datagram_that_is_not_bytes_is_answered_alike(tmp_path: Path) -> None:
    fast_drive, ref_drive = _drives(tmp_path)
    fast, ref = GatewayHandler({1001: fast_drive}), ReferenceGateway({1001: ref_drive})
    for datagram in (_upload(0x1018, 1, 1), _upload(0x1018, 4, 2)):
        assert fast.handle(bytearray(datagram), PEER) == ref.handle(datagram, PEER)
        assert fast.handle(memoryview(bytearray(datagram)), PEER) == ref.handle(datagram, PEER)
    assert not fast._mailboxes  # only bytes are kept (a bytearray is no dict key)
    for datagram in (_upload(0x1018, 1, 3), _upload(0x1018, 1, 3)[:-1]):  # kept as bytes, then met as a view
        assert fast.handle(datagram, PEER) == ref.handle(datagram, PEER)
        assert fast.handle(memoryview(datagram), PEER) == ref.handle(datagram, PEER)


def test_the_face_serves_on_after_bad_datagrams_and_stops(tmp_path: Path) -> None:
    """Over a real socket: the one frame that serves the datagrams that follow skips what it drops and answers the
    next request; stop() wakes it."""
    with _served_gateway(tmp_path) as (face, client):
        for bad in (b"\x01", _upload(0x1018, 1, 1, station=1002), _upload(0x1018, 1, 1)[:-1]):
            client.sendto(bad, (face.host, face.port))
        reference = ReferenceGateway({1001: factory_drive(tmp_path)})
        for counter in (1, 2, 3):
            request = _upload(0x1018, 1, counter)
            client.sendto(request, (face.host, face.port))
            assert client.recvfrom(2048)[0] == reference.handle(request, PEER)[0]
    assert not face._threads and face.error is None


@contextlib.contextmanager
def _served_gateway(tmp_path: Path) -> Iterator[tuple[EthercatUdpFace, socket.socket]]:
    """Station 1001 served by a started ETG.8200 face on loopback, and a UDP client socket (5 s timeout) for it;
    both closed at the end."""
    drive = SimDrive("gw", tmp_path)
    drive.serve_faces()
    face = EthercatUdpFace("127.0.0.1", 0, GatewayHandler({1001: drive}))
    face.start()
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.settimeout(5.0)
    try:
        yield face, client
    finally:
        client.close()
        face.stop()



def test_the_largest_gateway_frame_is_answered_whole(tmp_path: Path) -> None:
    """A gateway frame of the most bytes its header can say (2 + 0x7FF = 2049) reaches the gateway whole over the
    socket: the face once received at most 2048 bytes, so such a frame was cut and refused."""
    mailbox = mbx.pack(mbx.MailboxType.COE, coe.upload_request(0x1018, 1).ljust(0x7FF - mbx.HEADER_SIZE, b"\0"),
                       1001, 1)
    request = mbx.wrap_gateway(mailbox)
    assert len(request) == mbx.MAX_GATEWAY_DATAGRAM
    with _served_gateway(tmp_path) as (face, client):
        expected = ReferenceGateway({1001: factory_drive(tmp_path)}).handle(request, PEER)
        assert expected, "the reference gateway answers the frame"
        client.sendto(request, (face.host, face.port))
        assert client.recvfrom(4096)[0] == expected[0]

def factory_drive(tmp_path: Path) -> SimDrive:
    directory = tmp_path / "reference"
    directory.mkdir(exist_ok=True)
    return SimDrive("gw", directory)


# --- the SDO server's plans ---------------------------------------------------------------------------------------


def _mailbox(index: int, subindex: int, counter: int = 3) -> bytes:
    return mbx.pack(mbx.MailboxType.COE, coe.upload_request(index, subindex), 1001, counter)


def test_a_plan_reads_the_value_every_time() -> None:
    model = factory_model("plans")
    server = SdoServer(model)
    request = _mailbox(0x6081, 0)
    before = server.handle(request)
    model.object_write(0x6081, 0, (777).to_bytes(4, "little"))
    after = server.handle(request)
    assert request in server._plans and before != after
    assert coe.decode_sdo(after[0][8:], from_server=True).data == (777).to_bytes(4, "little")


def test_a_plan_follows_the_values_length() -> None:
    """One object read with values of every length through one plan: expedited 1..4 bytes, normal beyond, and
    an abort when the model fails; each the answer of a fresh server's general path."""
    values = [b"\x01", b"\x01\x02", b"\x01\x02\x03", b"\x01\x02\x03\x04", b"12345", b"", None]

    class Reader:
        value: bytes | None = None

        def object_read(self, index: int, subindex: int) -> bytes:
            if self.value is None:
                raise sdo_server.SdoAccessError(coe.ABORT_NO_OBJECT)
            return self.value

        def object_write(self, index: int, subindex: int, data: bytes) -> None:
            pass

    reader = Reader()
    server = SdoServer(reader)  # type: ignore[arg-type]
    for value in values:
        reader.value = value
        for counter in (1, 2):
            request = _mailbox(0x2000, 1, counter)
            general = SdoServer(reader)  # type: ignore[arg-type]
            _mtype, _counter, _address, data = mbx.split(request)
            answer = general._sdo(data[coe.COE_HEADER_SIZE:])
            assert answer is not None
            service = CoeService.SDO_REQUEST if isinstance(answer, coe.SdoAbort) else CoeService.SDO_RESPONSE
            want = [general._reply(sdo_server._Request(1001, counter), service, coe.encode_sdo(answer))]
            assert server.handle(request) == want, value


def test_the_servers_plans_are_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sdo_server, "PLANS_KEPT", 4)
    model = factory_model("plans")
    server, general = SdoServer(model), SdoServer(factory_model("plans"))
    for n in range(20):
        request = _mailbox(0x1018, n % 5, n % 7 + 1)
        assert server.handle(request) == general.handle(bytearray(request))
        assert server.handle(memoryview(bytearray(request))) == general.handle(memoryview(request))
        assert len(server._plans) <= 4
    assert not general._plans  # a bytearray is answered without a plan


# --- the codecs -------------------------------------------------------------------------------------------------


@given(st.binary(min_size=6, max_size=0x7FF))
def test_the_gateway_header_is_wrap_gateways(mailbox: bytes) -> None:
    assert mbx.gateway_header(len(mailbox)) + mailbox == mbx.wrap_gateway(mailbox)


def test_a_gateway_header_too_long_is_refused_as_wrap_gateway_refuses_it() -> None:
    for call in (lambda: mbx.gateway_header(0x800), lambda: mbx.wrap_gateway(bytes(0x800))):
        with pytest.raises(mbx.MailboxError):
            call()


@given(st.integers(0, 0xFFFF), st.integers(0, 7), st.integers(0, 0xFFFF), st.integers(0, 0xFF),
       st.binary(min_size=1, max_size=4))
def test_the_upload_templates_equal_the_pack(address: int, counter: int, index: int, subindex: int,
                                             value: bytes) -> None:
    templates = coe.expedited_upload_templates(address, counter, index, subindex)
    assert sorted(templates) == [1, 2, 3, 4]
    head, tail = templates[len(value)]
    assert head + value + tail == coe.pack_expedited_upload_mailbox(address, counter, index, subindex, value)


def test_masters_and_stations_sharing_counters_are_answered_as_the_reference(tmp_path: Path) -> None:
    """Several masters behind one gateway, two stations, the same counters reused by each, repeats from each and
    mailboxes without a counter, interleaved; every peer a new (address, port) tuple as a socket returns it (equal
    to the last one, not the same object): the link used last is found by comparing, the others by lookup."""
    for side in ("a", "b"):
        (tmp_path / side).mkdir()
    fast_drives, ref_drives = _drives(tmp_path / "a"), _drives(tmp_path / "b")  # two stations behind each gateway
    fast = GatewayHandler({1001: fast_drives[0], 1002: fast_drives[1]})
    ref = ReferenceGateway({1001: ref_drives[0], 1002: ref_drives[1]})
    steps = []
    reads_new: dict[int, int] = {}  # step -> the value its answer must carry (not the reference's word: its rule)
    value = 1000
    for counter in (1, 2, 1, 3, 0, 3):
        for port, station in ((5000, 1001), (5001, 1001), (5000, 1002), (5002, 1002)):
            upload = _upload(0x6081, 0, counter, station)
            steps += [(port, upload), (port, upload)]  # the second one a repeat (unless no counter)
            value += 1
            write = coe.encode_sdo(coe.SdoDownloadInitiate(0x6081, 0, value.to_bytes(4, "little"), 4, True))
            steps.append((port + 9, _sdo(write, 0, station)))  # a third master writes, without a counter
            steps.append((port + 7, upload))  # another master, the same bytes: executed, it reads the new value
            reads_new[len(steps) - 1] = value
            steps.append((port, _sdo(write, counter, station)))  # the same counter again, other bytes: executed
    for n, (port, datagram) in enumerate(steps):
        peer = (".".join(("127", "0", "0", "1")), int(str(port)))  # new objects each time, as recvfrom makes them
        got = fast.handle(datagram, peer)
        assert got == ref.handle(datagram, peer), (n, port, datagram.hex())
        if n in reads_new:
            assert got[0][-4:] == reads_new[n].to_bytes(4, "little"), n
    assert fast.repeats.repeats == ref.repeats.repeats > 0
    for side_fast, side_ref in zip(fast_drives, ref_drives):
        assert side_fast.snapshot()["objects"] == side_ref.snapshot()["objects"]


def test_frames_follow_the_replies_emergencies_and_writes_included(tmp_path: Path) -> None:
    """The gateway keeps the last frame per datagram by the reply object it framed (the SDO server answers an
    unchanged value with the same object): a fault's emergency ahead of the answer (address 0, rewritten to the
    station's) and a value written between polls are framed anew, and every frame equals the reference's."""
    fast_drive, ref_drive = _drives(tmp_path)
    fast, ref = GatewayHandler({1001: fast_drive}), ReferenceGateway({1001: ref_drive})
    polls = [_upload(0x6081, 0, counter) for counter in range(1, 8)]

    def poll_all() -> list[list[bytes]]:
        out = []
        for datagram in polls:
            got = fast.handle(datagram, PEER)
            assert got == ref.handle(datagram, PEER), datagram.hex()
            out.append(got)
        return out

    first = poll_all()
    assert poll_all() == first
    for drive in (fast_drive, ref_drive):
        with drive.transaction() as model:
            model.faults.raise_fault("F501")
    with_emergency = poll_all()
    assert len(with_emergency[0]) == 2 and with_emergency[0][0][4:6] == (1001).to_bytes(2, "little")
    assert poll_all() == first  # delivered once; the answers as before
    value = coe.encode_sdo(coe.SdoDownloadInitiate(0x6081, 0, (2468).to_bytes(4, "little"), 4, True))
    assert fast.handle(_sdo(value, 0), PEER) == ref.handle(_sdo(value, 0), PEER)
    after = poll_all()
    assert all(frames[0][-4:] == (2468).to_bytes(4, "little") for frames in after)
