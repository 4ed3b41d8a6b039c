"""``sim serve`` faces: options declared as data, ready lines naming what was bound, the udp_multicast warning.

No test here sends a packet off the machine: sockets bind to 127.0.0.1 and the CAN face is not started."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import click
import pytest
from click.testing import CliRunner

from akdctl.cli import sim as cli_sim
from akdctl.sim import face_can, face_ethercat_udp, face_profinet
from akdctl.sim.drive import SimDrive
from akdctl.sim.face import Face
from tests.pn_calls import CaptureSocket


def test_every_face_declares_options_as_data_and_serve_accepts_exactly_them() -> None:
    serve = cli_sim.sim.commands["serve"]
    declared = {o.flag for module in cli_sim.FACES for o in module.OPTIONS}
    accepted = {opt for p in serve.params if isinstance(p, click.Option) for opt in p.opts} - {"--name", "--duration"}
    assert declared == accepted
    for module in cli_sim.FACES:
        assert not hasattr(module, "click"), f"{module.__name__} builds click options itself"


@pytest.mark.parametrize("module", [face_profinet, face_ethercat_udp])
def test_ready_line_names_the_bound_port(module: object, tmp_path: Path) -> None:
    drive = SimDrive("default", tmp_path)
    face = module.from_options(drive, **{module.OPTIONS[0].dest: "127.0.0.1:0"})  # type: ignore[attr-defined]
    assert isinstance(face, Face)
    face.start()
    try:
        match = re.search(r"udp 127\.0\.0\.1:(\d+)", face.describe())
        assert match is not None and int(match.group(1)) == face.port != 0  # type: ignore[attr-defined]
    finally:
        face.stop()


def test_udp_multicast_face_warns_that_the_bus_reaches_the_lan(tmp_path: Path) -> None:
    drive = SimDrive("default", tmp_path)
    lan = face_can.CanFace(drive, face_can.parse_spec("udp_multicast:239.74.163.2:1"))
    assert any("reachable from the LAN" in w for w in lan.warnings())
    assert face_can.CanFace(drive, face_can.parse_spec("slcan-pty:-:1")).warnings() == []


def test_virtual_can_face_warns_that_the_bus_is_process_local(tmp_path: Path) -> None:
    (warning,) = face_can.CanFace(SimDrive("default", tmp_path), face_can.parse_spec("virtual:0")).warnings()
    assert "exists only inside this process" in warning and "slcan-pty" in warning


def test_serve_help_says_udp_multicast_reaches_the_lan() -> None:
    result = CliRunner().invoke(cli_sim.sim, ["serve", "--help"], terminal_width=200)
    assert result.exit_code == 0
    assert "udp_multicast listens on all interfaces" in " ".join(result.output.split())


class _LanFace(Face):
    def start(self) -> None:
        pass

    def stop(self) -> None:
        pass

    def describe(self) -> str:
        return "can udp_multicast 239.74.163.2 node 1"

    def warnings(self) -> list[str]:
        return ["this CAN bus is reachable from the LAN"]


def test_serve_prints_ready_line_on_stdout_and_face_warnings_on_stderr(monkeypatch: pytest.MonkeyPatch) -> None:
    """The real udp_multicast face would join a multicast group on the LAN, so a stand-in face carries the warning."""
    from types import SimpleNamespace

    from akdctl.cli.main import cli

    fake = SimpleNamespace(OPTIONS=face_can.OPTIONS, from_options=lambda drive, **kw: _LanFace())
    monkeypatch.setattr(cli_sim, "FACES", (fake,))
    result = CliRunner().invoke(cli, ["sim", "serve", "--can", "udp_multicast:239.74.163.2:1", "--duration", "0"])
    assert result.exit_code == 0, result.output
    assert "listening: can udp_multicast 239.74.163.2 node 1\n" in result.stdout
    assert "akdctl: warning: this CAN bus is reachable from the LAN" in result.stderr


# ------------------------------------------------------------------ 17.1: a failing drive never ends a face
class _FailingDrive:
    """Makes the next ``count`` drive transactions raise ``exc``, as a state file locked by another process or a
    full disk does, then lets them through again (``SimDrive._begin``: the step every transaction takes, the
    faces' hot paths included)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.left, self.exc = 0, OSError(28, "No space left on device")
        original = SimDrive._begin

        def begin(drive: SimDrive, *args: object, **kwargs: object):  # type: ignore[no-untyped-def]
            if self.left > 0:
                self.left -= 1
                raise self.exc
            return original(drive, *args, **kwargs)

        monkeypatch.setattr(SimDrive, "_begin", begin)

    def fail(self, exc: BaseException | None = None, count: int = 1) -> None:
        self.exc, self.left = exc or self.exc, count


@pytest.fixture
def failing(monkeypatch: pytest.MonkeyPatch) -> _FailingDrive:
    return _FailingDrive(monkeypatch)


def _served(face: Face) -> Face:
    face.start()
    return face


def test_profinet_face_answers_a_failing_drive_with_a_record_error_and_keeps_serving(
        akd_inproc, failing: _FailingDrive, tmp_path: Path) -> None:
    from akdctl.errors import CommError

    face = _served(face_profinet.ProfinetFace(SimDrive("default", tmp_path), "127.0.0.1", 0))
    target = ("-T", f"pn://127.0.0.1:{face.port}", "--timeout", "2")
    try:
        failing.fail()
        code, _, err = akd_inproc(*target, "pnu", "get", "930")
        assert code != 0 and "resource unavailable" in err
        assert "akdctl: warning: profinet: a request failed" in err and "No space left on device" in err
        failing.fail(CommError("simulated drive 'default' is locked by another process for more than 5 s"))
        code, out, err = akd_inproc(*target, "pnu", "get", "930")  # "busy" (0xC2): the client asks again
        assert code == 0 and "930" in out, err
        assert akd_inproc(*target, "pnu", "get", "930")[0] == 0
    finally:
        face.stop()


def test_ethercat_udp_face_answers_a_failing_drive_with_an_sdo_abort_and_keeps_serving(
        akd_inproc, failing: _FailingDrive, tmp_path: Path) -> None:
    face = _served(face_ethercat_udp.from_options(SimDrive("default", tmp_path), ethercat_udp="127.0.0.1:0"))
    target = ("-T", f"ecat-udp://127.0.0.1:{face.port}/1001", "--timeout", "2")  # type: ignore[attr-defined]
    try:
        # every transaction fails until the read was answered: the face's own loop takes transactions too (its
        # heartbeat and emergencies), and one of those took a single failure before the request under load
        failing.fail(count=10**6)
        code, _, err = akd_inproc(*target, "sdo", "read", "0x1018:1")
        assert code == 1 and "0x08000000" in err
        failing.fail(count=0)
        code, out, err = akd_inproc(*target, "sdo", "read", "0x1018:1")
        assert code == 0 and "106" in out, err
    finally:
        face.stop()


def test_ethercat_raw_slave_answers_a_failing_drive_with_an_sdo_abort(failing: _FailingDrive, tmp_path: Path) -> None:
    from akdctl.protocol.coe import SdoAbort, decode_coe, decode_sdo
    from akdctl.protocol.mailbox import decode_mailbox
    from akdctl.sim.ecat_inject import WARMUP_REQUEST
    from akdctl.sim.face_ethercat_raw import EthercatRawFace

    worker = EthercatRawFace("pair0", SimDrive("default", tmp_path), face_ethercat_udp.Injector()).worker
    failing.fail()
    (reply,), lost = worker.answer(WARMUP_REQUEST)
    abort = decode_sdo(decode_coe(decode_mailbox(reply).data)[2], from_server=True)
    assert not lost and isinstance(abort, SdoAbort) and abort.code == 0x08000000
    (reply,), _ = worker.answer(WARMUP_REQUEST)
    assert not isinstance(decode_sdo(decode_coe(decode_mailbox(reply).data)[2], from_server=True), SdoAbort)


def test_can_face_answers_a_failing_drive_with_an_sdo_abort_and_keeps_serving(
        akd_inproc, failing: _FailingDrive, tmp_path: Path) -> None:
    import uuid

    channel = f"akd-{uuid.uuid4().hex[:10]}"
    face = _served(face_can.CanFace(SimDrive("default", tmp_path), face_can.parse_spec(f"virtual:{channel}:1")))
    target = ("-T", f"can://virtual/{channel}/1", "--timeout", "2")
    try:
        # every transaction fails until the read was answered: the face's own loop takes transactions too (its
        # heartbeat and emergencies), and one of those took a single failure before the request under load
        failing.fail(count=10**6)
        code, _, err = akd_inproc(*target, "sdo", "read", "0x1018:1")
        assert code == 1 and "0x08000000" in err
        failing.fail(count=0)
        code, out, err = akd_inproc(*target, "sdo", "read", "0x1018:1")
        assert code == 0 and "106" in out, err
    finally:
        face.stop()


def test_ethernetip_face_answers_a_failing_drive_with_a_cip_status_and_keeps_serving(
        akd_inproc, failing: _FailingDrive, tmp_path: Path) -> None:
    from akdctl.sim import face_ethernetip

    face = _served(face_ethernetip.EthernetIpFace(SimDrive("default", tmp_path), "127.0.0.1", 0, io_port=0))
    target = ("-T", f"eip://127.0.0.1:{face.port}", "--timeout", "2")
    try:
        failing.fail(count=5)
        code, _, err = akd_inproc(*target, "cip", "get", "0x25/1/1", "u8")
        assert code == 1, err
        failing.fail(count=0)
        code, out, err = akd_inproc(*target, "cip", "get", "0x25/1/1", "u8")
        assert code == 0, err
    finally:
        face.stop()


# ------------------------------------------------------------------ 17.2: a stray block download never sticks
STRAY_BLOCK_DOWNLOAD = bytes.fromhex("C6 00 20 01 00 00 00 00")  # 601#C6.00.20.01.00.00.00.00, as in the report


@pytest.fixture
def can_node(tmp_path: Path):  # type: ignore[no-untyped-def]
    """A CANopen face (node 1) on a private virtual channel, and a raw bus on the same channel."""
    import uuid

    import can

    channel = f"akd-{uuid.uuid4().hex[:10]}"
    face = _served(face_can.CanFace(SimDrive("default", tmp_path), face_can.parse_spec(f"virtual:{channel}:1")))
    bus = can.Bus(interface="virtual", channel=channel)
    try:
        yield channel, bus
    finally:
        bus.shutdown()
        face.stop()


def _sdo_reply(bus, timeout: float = 2.0) -> bytes:  # type: ignore[no-untyped-def]
    """The next frame the node sends on 0x581 (other traffic, e.g. the boot-up message, is skipped)."""
    import time

    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0:
        msg = bus.recv(left)
        if msg is not None and msg.arbitration_id == 0x581:
            return bytes(msg.data)
    raise AssertionError("the node sent no SDO reply")


def _send(bus, cob: int, data: bytes) -> None:  # type: ignore[no-untyped-def]
    import can

    bus.send(can.Message(arbitration_id=cob, data=data, is_extended_id=False))


def test_nmt_reset_forgets_a_stray_block_download(can_node, akd_inproc) -> None:  # type: ignore[no-untyped-def]
    channel, bus = can_node
    _send(bus, 0x601, STRAY_BLOCK_DOWNLOAD)
    assert _sdo_reply(bus)[0] & 0xE0 == 0xA0  # block download initiate response: the server waits for segments
    target = ("-T", f"can://virtual/{channel}/1", "--timeout", "1")
    code, _, err = akd_inproc(*target, "can", "nmt", "reset")
    assert code == 0, err
    code, out, err = akd_inproc(*target, "sdo", "read", "0x1018:1")
    assert code == 0 and "106" in out, err


def test_an_unfinished_block_download_is_aborted_after_the_sdo_timeout(
        can_node, akd_inproc, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    from akdctl.sim.can_sdo import BlockSdoServer

    monkeypatch.setattr(BlockSdoServer, "TRANSFER_TIMEOUT", 0.05)
    channel, bus = can_node
    _send(bus, 0x601, STRAY_BLOCK_DOWNLOAD)
    assert _sdo_reply(bus)[0] & 0xE0 == 0xA0
    abort = _sdo_reply(bus)  # CiA 301: the server aborts the transfer it waited for in vain
    assert abort[0] == 0x80 and abort[1:4] == bytes.fromhex("00 20 01") and abort[4:] == bytes.fromhex("00 00 04 05")
    code, out, err = akd_inproc("-T", f"can://virtual/{channel}/1", "--timeout", "1", "sdo", "read", "0x1018:1")
    assert code == 0 and "106" in out, err


# ------------------------------------------------------------------ 17.3: slcan-pty removes only its own link
def test_slcan_pty_never_replaces_an_existing_path(akd_inproc, tmp_path: Path) -> None:
    notes = tmp_path / "notes.txt"
    notes.write_text("keep me\n")
    code, out, err = akd_inproc("sim", "serve", "--can", f"slcan-pty:{notes}:1", "--duration", "0")
    assert code == 2 and "already exists and is left alone" in err and len(err.strip().splitlines()) == 1, err
    assert notes.read_text() == "keep me\n" and "listening" not in out


def test_slcan_pty_link_is_made_and_removed_only_while_it_is_ours(tmp_path: Path) -> None:
    from akdctl.sim.slcan_device import SlcanDeviceBus

    link = tmp_path / "akd-tty"
    bus = SlcanDeviceBus(link=str(link))
    assert os.readlink(link) == bus.tty_path
    bus.shutdown()
    assert not link.exists() and not link.is_symlink()
    bus = SlcanDeviceBus(link=str(link))
    link.unlink()
    link.write_text("someone else's file now\n")  # replaced while the face ran
    bus.shutdown()
    assert link.read_text() == "someone else's file now\n"


# ------------------------------------------------------------------ 17.4: PROFINET AR slots and timeout
def _connect_without_release(port: int, station: bytes) -> None:
    """One Device Access AR Connect, never released (a client that crashed)."""
    import socket
    import uuid

    from akdctl.protocol import dcerpc, pnio

    req = pnio.ARBlockReq(pnio.AR_TYPE_IOSAR, uuid.uuid4(), 1, b"\x02\x00\x00\x00\x00\x01", pnio.object_uuid(0, 0, 0),
                          pnio.DEVICE_ACCESS_PROPERTIES, 1000, station)  # activity timeout 100 s
    head = dcerpc.RpcHeader(ptype=dcerpc.PT_REQUEST, object_uuid=pnio.object_uuid(0x100, 1),
                            interface_uuid=pnio.DEVICE_INTERFACE, activity_uuid=uuid.uuid4(), sequence=0,
                            opnum=pnio.OP_CONNECT, flags1=dcerpc.FLAG_IDEMPOTENT)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(2)
        sock.sendto(dcerpc.encode_packet(head, pnio.encode_request_args(req.encode())), ("127.0.0.1", port))
        reply = dcerpc.decode_packet(sock.recv(4096))
    assert pnio.decode_response_args(reply.body, reply.header.little_endian)[0].ok


def test_profinet_ar_slots_and_timeout_are_options_and_a_full_device_names_the_holders(
        akd_inproc, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.harness import wait_until

    face = face_profinet.from_options(SimDrive("default", tmp_path), profinet="127.0.0.1:0", pn_ars=2,
                                      pn_ar_timeout=0.5)
    assert face is not None and face.max_ars == 2
    face.start()
    target = ("-T", f"pn://127.0.0.1:{face.port}", "--timeout", "2")
    try:
        _connect_without_release(face.port, b"crashed-tool-1")
        _connect_without_release(face.port, b"crashed-tool-2")
        code, _, err = akd_inproc(*target, "pnu", "get", "930")
        assert code == 1 and "out of AR resources (DB 81 40 04)" in err and "activity timeout" in err, err
        assert "profinet: Connect from 127.0.0.1" in err and "2 held: AR " in err
        assert "of crashed-tool-1 at 127.0.0.1" in err and "of crashed-tool-2" in err
        wait_until(lambda: not face._ars, "the face to drop the stale ARs after --pn-ar-timeout", timeout=10)
        code, out, err = akd_inproc(*target, "pnu", "get", "930")
        assert code == 0 and "930" in out, err
    finally:
        face.stop()


def test_profinet_face_defaults_keep_the_devices_behaviour() -> None:
    face = face_profinet.from_options(None, profinet="127.0.0.1:0")
    assert face is not None and face.max_ars == face_profinet.MAX_ARS and face.ar_timeout is None


def test_bad_ar_timeout_is_a_usage_error(akd_inproc) -> None:
    code, _, err = akd_inproc("sim", "serve", "--profinet", "127.0.0.1:0", "--pn-ar-timeout", "-1", "--duration", "0")
    assert code == 2 and "--pn-ar-timeout" in err



# ------------------------------------------------------------------ 14: sim serve with a CAN face
@pytest.mark.slow
@pytest.mark.parametrize("spec", ["virtual:0", "slcan-pty:-:1"])
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_serve_with_a_can_face_stops_on_a_signal(spec: str, signame: str) -> None:
    """The process ends by itself, cleanly, after the signal (the deadline only guards against a hang)."""
    import signal
    import subprocess

    from tests.harness import SimServer

    with SimServer("--can", spec) as server:
        proc = server.proc
        assert proc is not None
        proc.send_signal(getattr(signal, signame))
        try:
            code = proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            pytest.fail(f"sim serve --can {spec} still runs 10 s after {signame}")
        assert code == 0, server.stderr
        assert "Traceback" not in server.stderr
        if spec.startswith("virtual"):
            assert "virtual bus exists only inside this process" in server.stderr


# ------------------------------------------------------------------ 15: the faces' replies, packed without objects
@pytest.mark.parametrize("little", [False, True])
def test_profinet_replies_are_the_bytes_the_codecs_write(tmp_path: Path, little: bool) -> None:
    """The PROFINET face answers from a header view and packs its replies by patching the request's header;
    each reply must be exactly what ``encode_packet(replace(header, ...))``, ``encode_response_args`` and
    ``IODWriteRes``/``IODReadRes.encode()`` write, in either data representation."""
    import uuid
    from dataclasses import replace

    from akdctl.protocol import dcerpc, pnio

    face = face_profinet.ProfinetFace(SimDrive("default", tmp_path), "127.0.0.1", 0)
    sent: list[bytes] = []
    face._sock = CaptureSocket(sent)  # type: ignore[assignment]  # every reply goes through the socket's sendto
    ar, activity, address = uuid.uuid4(), uuid.uuid4(), pnio.RecordAddress()
    seq = iter(range(1, 100))

    def call(opnum: int, blocks: bytes, interface: uuid.UUID = pnio.DEVICE_INTERFACE,
             ptype: int = dcerpc.PT_REQUEST) -> tuple[dcerpc.RpcHeader, bytes]:
        head = dcerpc.RpcHeader(ptype=ptype, object_uuid=pnio.object_uuid(0x100, 1), interface_uuid=interface,
                                activity_uuid=activity, sequence=next(seq), opnum=opnum,
                                flags1=dcerpc.FLAG_IDEMPOTENT, flags2=0x01, serial=0x0203, interface_hint=7,
                                activity_hint=9, drep=dcerpc.DREP_LITTLE if little else dcerpc.DREP_BIG)
        return head, dcerpc.encode_packet(head, pnio.encode_request_args(blocks, little=little))

    def answer(head: dcerpc.RpcHeader, data: bytes) -> dcerpc.RpcPacket:
        sent.clear()
        face._datagram(data, ("127.0.0.1", 1))
        (frame,) = sent
        reply = dcerpc.decode_packet(frame)
        assert dcerpc.encode_packet(reply.header, reply.body) == frame
        assert reply.header == replace(
            head, ptype=reply.header.ptype, flags1=dcerpc.FLAG_NOFACK if reply.header.ptype == dcerpc.PT_RESPONSE
            else 0, flags2=0, server_boot=face.boot_time, fragment=0, body_length=len(reply.body))
        return reply

    def records(reply: dcerpc.RpcPacket) -> tuple[pnio.PnioStatus, bytes]:
        assert reply.header.ptype == dcerpc.PT_RESPONSE
        status, blocks = pnio.decode_response_args(reply.body, little)
        assert pnio.encode_response_args(status, blocks, little=little) == reply.body
        return status, blocks

    connect = pnio.ARBlockReq(pnio.AR_TYPE_IOSAR, ar, 1, b"\x02\0\0\0\0\x01", pnio.object_uuid(0, 0, 0),
                              pnio.DEVICE_ACCESS_PROPERTIES, 100, b"test").encode()
    assert records(answer(*call(pnio.OP_CONNECT, connect)))[0].ok
    read_930 = bytes.fromhex("01 01 00 01 10 01 03 A2 00 00")
    for write in (pnio.IODWriteReq(5, ar, address, read_930),
                  pnio.IODWriteReq(6, ar, pnio.RecordAddress(slot=3), read_930),    # wrong slot: 0xB2
                  pnio.IODWriteReq(7, uuid.uuid4(), address, read_930)):            # no such AR: 0xB6
        status, blocks = records(answer(*call(pnio.OP_WRITE, write.encode())))
        res = pnio.IODWriteRes.decode(blocks)
        assert res.encode() == blocks and status == res.status
        assert (res.seq_number, res.ar_uuid, res.address, res.record_length) == \
            (write.seq_number, write.ar_uuid, write.address, len(write.data))
    for read, data in ((pnio.IODReadReq(8, ar, address, 240), True),
                       (pnio.IODReadReq(9, ar, address, 240), False),              # nothing pending: 0xA0
                       (pnio.IODReadReq(10, pnio.NIL_UUID, pnio.RecordAddress(index=pnio.INDEX_IM0), 64), True)):
        opnum = pnio.OP_READ_IMPLICIT if read.address.index == pnio.INDEX_IM0 else pnio.OP_READ
        status, blocks = records(answer(*call(opnum, read.encode())))
        assert status.ok == data
        if data:
            res = pnio.IODReadRes.decode(blocks)
            assert res.encode() == blocks and (res.seq_number, res.ar_uuid, res.address) == \
                (read.seq_number, read.ar_uuid, read.address)
    assert pnio.IM0.decode(pnio.IODReadRes.decode(blocks).data).vendor_id == face.vendor_id
    head, data = call(pnio.OP_READ, pnio.IODReadReq(11, ar, address, 240).encode(),
                      interface=pnio.CONTROLLER_INTERFACE)
    assert answer(head, data).header.ptype == dcerpc.PT_REJECT
    head, data = call(pnio.OP_READ, b"", ptype=dcerpc.PT_PING)
    assert answer(head, data).header.ptype == dcerpc.PT_NOCALL


def test_gateway_replies_carry_the_station_and_emergencies_come_first(tmp_path: Path) -> None:
    """The gateway hands the mailbox over as it came and writes the station into every reply (the drive's
    emergencies carry address 0), each behind the 2-byte header: what decode/replace/encode_gateway wrote."""
    from akdctl.protocol import coe, mailbox as mbx

    drive = SimDrive("default", tmp_path)
    handler = face_ethercat_udp.GatewayHandler({1001: drive})
    with drive.transaction() as model:
        model.faults.raise_fault("F501")
    request = mbx.wrap_gateway(mbx.pack(mbx.MailboxType.COE, coe.upload_request(0x6041, 0), 1001, 3))
    replies = handler.handle(request)
    assert len(replies) == 2
    for reply in replies:
        mailbox = mbx.decode_gateway(reply)
        assert mailbox.address == 1001 and mbx.encode_gateway(mailbox) == reply
    emergency, answer = (mbx.decode_gateway(r) for r in replies)
    assert coe.decode_coe(emergency.data)[0] == coe.CoeService.EMERGENCY
    assert answer.counter == 3 and coe.decode_coe(answer.data)[0] == coe.CoeService.SDO_RESPONSE
    assert handler.handle(request[:-1]) == [] and handler.handle(request[:4] + b"\x00\x00" + request[6:]) == []


@pytest.mark.parametrize("delay, inject", [(0.0, ""), (30.0, ""), (0.0, "drop=3,dup=4,rxdrop=7")])
def test_profinet_plain_record_calls_are_answered_as_the_general_path_answers(tmp_path: Path,
                                                                              monkeypatch: pytest.MonkeyPatch,
                                                                              delay: float, inject: str) -> None:
    """Plain Write/Read record requests take the face's short ways (the one pass of ``_datagram`` over
    ``protocol/pnio_record.record_call_fields``, then ``plain_record_call``); with both switched off every request
    goes the general way. Seeded valid and mutated requests get the same frames both ways: wrong AR, slot, index,
    lengths, nothing pending (0xA0), retransmissions, a parameter manager that is still busy (0xB5: the delay) and
    fault injection on both directions."""
    import random
    import uuid

    from akdctl.protocol import dcerpc, pnio

    rng = random.Random(5)
    ar, address = uuid.uuid4(), pnio.RecordAddress()

    def call(opnum: int, blocks: bytes, sequence: int, little: bool) -> bytes:
        head = dcerpc.RpcHeader(ptype=dcerpc.PT_REQUEST, object_uuid=pnio.object_uuid(0x100, 1),
                                interface_uuid=pnio.DEVICE_INTERFACE, activity_uuid=uuid.UUID(int=sequence % 3),
                                sequence=sequence, opnum=opnum, drep=dcerpc.DREP_LITTLE if little else dcerpc.DREP_BIG)
        return dcerpc.encode_packet(head, pnio.encode_request_args(blocks, little=little))

    connect = pnio.ARBlockReq(pnio.AR_TYPE_IOSAR, ar, 1, b"\x02\0\0\0\0\x01", pnio.object_uuid(0, 0, 0),
                              pnio.DEVICE_ACCESS_PROPERTIES, 100, b"test").encode()
    requests = [call(pnio.OP_CONNECT, connect, 1, False)]
    for sequence in range(2, 400):
        little = rng.random() < 0.3
        if rng.random() < 0.5:
            pnu = rng.choice([930, 964, 947, 1, 2, 12345])
            bmp = bytes([rng.randint(1, 255), 1, 0, 1, 0x10, 1]) + pnu.to_bytes(2, "big") + b"\0\0"
            request = call(pnio.OP_WRITE, pnio.IODWriteReq(sequence, ar, address, bmp).encode(), sequence, little)
        else:
            request = call(pnio.OP_READ, pnio.IODReadReq(sequence, ar, address, rng.choice([240, 4, 0])).encode(),
                           sequence, little)
        kind = rng.random()
        if kind < 0.2:  # a byte of the DCE/RPC header, NDR arguments or record header changed
            # not of the sequence number (64..67): a raised one makes the activity's later calls older, discarded
            # (tests/test_pn_activity_calls.py), and too few would be answered to compare the two ways
            where = rng.randrange(min(len(request), 170) - 4)
            where += 4 if where >= 64 else 0
            request = request[:where] + bytes([rng.randrange(256)]) + request[where + 1:]
        elif kind < 0.3:
            request = request[:rng.randrange(len(request))]
        elif kind < 0.35:
            request += b"\0" * rng.randint(1, 4)
        requests.append(request)
        if rng.random() < 0.1:
            requests.append(request)  # a retransmission: the cached reply

    def frames(short_way: bool) -> list[bytes]:
        with monkeypatch.context() as patch:  # undoes only this patch, not the test's isolated state dir
            if not short_way:
                patch.setattr(face_profinet.pnio_record, "plain_record_call", lambda data: None)
            face = face_profinet.ProfinetFace(SimDrive("default", tmp_path / str(short_way)), "127.0.0.1", 0,
                                              delay=delay, injection=face_profinet.Injection.parse(inject or None))
            face._short_way = short_way
            general_way = face._general

            def counted(*args: Any) -> None:
                generals.append(short_way)
                general_way(*args)

            face._general = counted  # type: ignore[method-assign]
            face.boot_time = 1234
            sent: list[bytes] = []
            face._sock = CaptureSocket(sent)  # type: ignore[assignment]
            for request in requests:
                sent.append(b"--")
                face._datagram(request, ("127.0.0.1", 1))
        return sent

    generals: list[bool] = []
    short, general = frames(True), frames(False)
    assert short == general
    assert sum(1 for f in short if f[:2] == b"\x04\x02") > 250  # mostly answered responses, not only refusals
    one_pass = len(requests) - generals.count(True)  # answered by _datagram's one pass (or dropped on receipt)
    assert one_pass > 20 and generals.count(True) > 20  # both ways were taken


