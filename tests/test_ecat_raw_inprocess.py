"""Our raw master against our simulated slave without root: the master's socket is one end of a socketpair and the
raw face's frame handler serves the other end in a thread. Covers bring-up (count, addresses, SII, SM0/SM1,
PRE-OP), SDO through the mailbox, the repeat request after lost reply frames, aborts and a silent bus."""

from __future__ import annotations

import socket
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from akdctl.connection import Connection
from akdctl.errors import NoAnswer, SdoAborted
from akdctl.protocol import ethercat as ec
from akdctl.sim.drive import SimDrive
from akdctl.sim.ecat_inject import Injector
from akdctl.sim.face_ethercat_raw import EthercatRawFace, quick_request
from akdctl.transport.base import LinkOptions
from akdctl.transport.ethercat_raw import EcatMaster, EthercatRawTransport
from akdctl.transport.registry import parse_target
from akdctl.transport.trace import Tracer


class Wire:
    """A slave face served over a socketpair."""

    def __init__(self, drive: SimDrive, inject: str = "", silent: bool = False) -> None:
        self.master_end, self.slave_end = socket.socketpair(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.face = EthercatRawFace("pair0", drive, Injector.parse(inject))
        self.face.esc.quick = quick_request  # uploads answered on the frame thread, as the served face does
        self.silent = silent
        self.stop = threading.Event()
        self.slave_end.settimeout(0.05)
        self.face.spawn(self.face.worker.serve, "ecat-raw-app", self.stop)  # the face's thread, our stop event
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stop.is_set():
            try:
                frame = self.slave_end.recv(4096)
            except (socket.timeout, OSError):
                continue
            reply = None if self.silent else self.face.handle_frame(frame)
            if reply is not None:
                self.slave_end.send(reply)
            self.face.worker.answer_quick()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.face.join(timeout=5)
        self.master_end.close()
        self.slave_end.close()


def transport(wire: Wire, tracer: Tracer | None = None) -> EthercatRawTransport:
    target = parse_target("ecat://pair0/0")
    options = LinkOptions(timeout=0.5, retries=2, tracer=tracer or Tracer())
    t = EthercatRawTransport(target, options)
    t.master = EcatMaster("pair0", options.tracer, options.timeout, options.retries, sock=wire.master_end)
    return t


@pytest.fixture
def drive(tmp_path: Path) -> SimDrive:
    return SimDrive("default", tmp_path)


@pytest.fixture
def wire(drive: SimDrive) -> Iterator[Wire]:
    w = Wire(drive)
    try:
        yield w
    finally:
        w.close()


def test_bring_up_and_sdo(wire: Wire) -> None:
    tracer = Tracer()
    t = transport(wire, tracer)
    conn = Connection.over(t)
    conn.transport()
    assert t.slave is not None and t.slave.al_status == ec.AlState.PREOP and t.slave.station == 0x1001
    assert t.slave.sii is not None and t.slave.sii.is_akd
    assert conn.has_objects
    assert conn.objects().upload(0x1018, 1) == b"\x6a\0\0\0"
    conn.objects().download(0x6060, 0, b"\x03")
    assert conn.objects().upload(0x6060, 0) == b"\x03"
    with pytest.raises(SdoAborted) as info:
        conn.objects().upload(0x5FFF, 0)
    assert info.value.code == 0x06020000
    frames = [r for r in tracer.records if r.layer == "ecat"]
    assert frames and all(r.meta == {"proto": "ethernet"} and r.data[12:14] == b"\x88\xa4" for r in frames)
    slaves = t.master.scan()  # type: ignore[union-attr]
    assert len(slaves) == 1 and slaves[0].sii is not None and slaves[0].sii.serial == 2575499411
    t.close()


def test_lost_reply_frames_recovered_by_repeat(drive: SimDrive) -> None:
    w = Wire(drive, "drop=2")
    try:
        t = transport(w)
        conn = Connection.over(t)
        conn.transport()
        assert conn.has_objects
        for _ in range(4):
            assert conn.objects().upload(0x1018, 1) == b"\x6a\0\0\0"
        assert t.link is not None and t.link.repeats >= 1 and w.face.esc.stats.repeats >= 1
        t.close()
    finally:
        w.close()


def test_injected_abort(drive: SimDrive) -> None:
    w = Wire(drive, "abort=1")
    try:
        t = transport(w)
        conn = Connection.over(t)
        conn.transport()
        assert conn.has_objects
        with pytest.raises(SdoAborted) as info:
            conn.objects().upload(0x1018, 1)
        assert info.value.code == 0x08000000
        t.close()
    finally:
        w.close()


def test_silent_bus_is_no_answer(drive: SimDrive) -> None:
    w = Wire(drive, silent=True)
    try:
        t = transport(w)
        with pytest.raises(NoAnswer):
            Connection.over(t).transport()
        t.close()
    finally:
        w.close()


def _model_al_state(drive: SimDrive) -> str:
    with drive.transaction() as model:
        return str(model.component("pdo").al_state)  # type: ignore[union-attr]


def _statusword(conn: Connection) -> int:
    return int.from_bytes(conn.objects().upload(0x6041, 0), "little")


def test_model_follows_the_esc_al_state_and_refuses_sdo_control_in_op(wire: Wire, drive: SimDrive) -> None:
    """One AL state (SPEC-NOTES 23): the master's AL transitions reach the model, so in OP with the controlword in
    the assigned RxPDO (the ESI default 0x1701) an SDO controlword has no effect, as on every other link."""
    assert _model_al_state(drive) == "INIT"  # the slave powered on with the face
    t = transport(wire)
    conn = Connection.over(t)
    conn.transport()
    assert t.master is not None and t.slave is not None
    assert _model_al_state(drive) == "PREOP"
    for state in (ec.AlState.SAFEOP, ec.AlState.OP):
        status, code = t.master.request_state(t.slave.station, state)
        assert status & 0x0F == state and code == 0
    assert _model_al_state(drive) == "OP"
    assert conn.has_objects
    before = _statusword(conn)
    for word in (0x06, 0x07, 0x0F):
        conn.objects().download(0x6040, 0, word.to_bytes(2, "little"))
    assert _statusword(conn) == before and before & 0x6F != 0x27  # not "operation enabled"
    t.master.request_state(t.slave.station, ec.AlState.PREOP)
    assert _model_al_state(drive) == "PREOP"
    for word in (0x06, 0x07, 0x0F):
        conn.objects().download(0x6040, 0, word.to_bytes(2, "little"))
    assert _statusword(conn) & 0x6F == 0x27  # in PRE-OP the SDO controlword is obeyed
    t.close()


def test_esc_al_status_shows_the_models_al_state(wire: Wire, drive: SimDrive) -> None:
    """A change of the model's AL state made elsewhere (another process, a test) is what AL status 0x0130 shows."""
    t = transport(wire)
    conn = Connection.over(t)
    conn.transport()
    assert t.master is not None and t.slave is not None
    with drive.transaction() as model:
        model.component("pdo").set_al_state("SAFEOP")  # type: ignore[union-attr]
    status, code = t.master.al_status(t.slave.station)
    assert status & 0x0F == ec.AlState.SAFEOP and code == 0
    t.close()


def test_face_stop_leaves_the_model_in_preop(drive: SimDrive) -> None:
    w = Wire(drive)
    try:
        t = transport(w)
        conn = Connection.over(t)
        conn.transport()
        assert t.master is not None and t.slave is not None
        t.master.request_state(t.slave.station, ec.AlState.SAFEOP)
        assert _model_al_state(drive) == "SAFEOP"
        t.close()
    finally:
        w.close()
    w.face.stop()
    assert _model_al_state(drive) == "PREOP"


def test_sync_managers_that_disagree_with_the_sii_are_configured_again(wire: Wire) -> None:
    """Issue 17.5: fuzzed ESC writes left a 1-byte SM0; the master trusted the registers until `ecat state INIT`.
    Now every open checks SM0/SM1 against the SII's mailbox words and re-establishes the mailbox from them."""
    first = transport(wire)
    conn = Connection.over(first)
    assert conn.objects().upload(0x1018, 1) == b"\x6a\0\0\0"
    assert first.master is not None and first.slave is not None
    first.master.fpwr(first.slave.station, ec.REG_SM0 + 2, b"\x01\x00")  # SM0 length 1, as the fuzzer left it
    sm0 = ec.SyncManager.decode(first.master.fprd(first.slave.station, ec.REG_SM0, 8))
    assert sm0.length == 1
    first.open_mailbox()  # what the next command's open does (a new process would also count the slaves)
    assert first.link is not None and first.link.sm0.length == first.link.mailbox_size > 1
    assert Connection.over(first).objects().upload(0x1018, 1) == b"\x6a\0\0\0"
    first.close()


def test_an_upload_reads_only_the_reply_and_polls_small_frames(wire: Wire) -> None:
    """Issue 15 deliver-3: per upload one SM0 write, small status+header polls, one read of the reply's
    length plus the buffer's last byte; never the whole 512-byte SM1 on a poll."""
    tracer = Tracer()
    t = transport(wire, tracer)
    conn = Connection.over(t)
    objects = conn.objects()
    objects.upload(0x1018, 1)
    start = len(tracer.records)
    for _ in range(20):
        assert objects.upload(0x1018, 1) == b"\x6a\0\0\0"
    frames = [r for r in tracer.records[start:] if r.layer == "ecat" and r.direction == "tx"]
    assert t.link is not None
    sm1 = t.link.sm1
    reads = []
    for record in frames:
        _dst, _src, datagrams = ec.decode_frame(record.data)
        for d in datagrams:
            if d.cmd == ec.Cmd.FPRD and d.ado == sm1.start:
                reads.append(len(d.data))
    assert reads and max(reads) < 64  # header peeks (6) and exact reply reads (16), no full buffer
    assert len(frames) / 20 <= 5  # no more than pysoem's ~5.4 frames per upload on the same slave
    t.close()


def test_a_reply_longer_than_the_poll_read_is_fetched_again_whole(wire: Wire) -> None:
    t = transport(wire)
    conn = Connection.over(t)
    objects = conn.objects()
    text = bytes(65 + i % 26 for i in range(200))
    objects.download(0x2032, 0, text)  # DRV.CUSTOMIDENTIFIER: a normal transfer's reply is 216 bytes
    assert objects.upload(0x2032, 0) == text
    assert t.link is not None and t.link.rereads >= 1
    rereads = t.link.rereads
    for _ in range(3):
        assert objects.upload(0x2032, 0) == text  # the poll now reads that much: no repeat needed
        assert objects.upload(0x1018, 1) == b"\x6a\0\0\0"
    assert t.link.rereads <= rereads + 3
    t.close()
