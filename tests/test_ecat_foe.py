"""FoE through our raw master against the simulated slave (in-process, no root): the firmware sequence INIT ->
bootstrap mailbox -> BOOT -> FoE write -> INIT -> restart -> PRE-OP, file read-back, refusals in words, and the
FoE client's packet rules against a scripted slave (BUSY, wrong packet numbers, errors, silence)."""

from __future__ import annotations


import pytest

from akdctl.channels.foe_client import FoeClient, FoeRefusedError, foe_error_words
from akdctl.connection import Connection
from akdctl.drive import ecat_files, firmware
from akdctl.errors import DriveError, MalformedReply, NoAnswer, SafetyRefusal, UsageError
from akdctl.links import MailboxLink
from akdctl.protocol import ethercat as ec
from akdctl.protocol import foe
from akdctl.protocol import mailbox as mbx
from akdctl.sim.drive import SimDrive
from tests.test_ecat_raw_inprocess import Wire, drive, transport, wire  # noqa: F401 - drive, wire: fixtures

IMAGE = bytes(range(256)) * 9 + b"\x00\x01tail"  # binary, not a multiple of the packet size


def _conn(wire: Wire) -> Connection:
    return Connection.over(transport(wire))


def test_firmware_sequence_boot_foe_restart(wire: Wire, drive: SimDrive, monkeypatch: pytest.MonkeyPatch) -> None:
    import akdctl.sim.face_ethercat_raw as face

    monkeypatch.setattr(face, "REBOOT_SECONDS", 0.3)
    conn = _conn(wire)
    request = firmware.FirmwareRequest("/tmp/AKD_fw.i00", IMAGE)
    plan = firmware.plan(conn, request)
    assert plan.needing_consent and "restarts" in plan.consent_text
    assert any("FoE file 'AKD_fw.i00'" in line for line in plan.lines())
    states: list[int] = []
    result = firmware.execute(conn, plan, lambda done, total: states.append(wire.face.esc.al_status & 0x0F))
    assert set(states) == {ec.AlState.BOOT}  # every packet went while the slave was in BOOT
    assert result["download"]["packets"] == len(IMAGE) // (512 - 12) + 1
    assert result["restart_s"] >= 0.3 and result["same_drive"]
    assert result["after"]["al_state"] == "PREOP" and "restarted" in result["verdict"]
    with drive.transaction() as model:
        assert model.foe.files["AKD_fw.i00"] == IMAGE
    # and read back over the open mailbox
    assert ecat_files.read_file(conn, "AKD_fw.i00", 0, 1 << 20) == IMAGE
    conn.close()


def test_a_powered_drive_is_refused_before_anything_changes(wire: Wire) -> None:
    conn = _conn(wire)
    objects = conn.objects()
    for word in (0x06, 0x07, 0x0F):
        objects.download(0x6040, 0, word.to_bytes(2, "little"))
    with pytest.raises(SafetyRefusal, match="power stage is on"):
        firmware.plan(conn, firmware.FirmwareRequest("fw.bin", IMAGE))
    assert wire.face.esc.al_status & 0x0F == ec.AlState.PREOP
    objects.download(0x6040, 0, (0).to_bytes(2, "little"))
    conn.close()


@pytest.mark.parametrize("data, words", [(b"", "empty"), (b"PK\x03\x04rest", "ZIP"), (b"hello firmware\n", "text"),
                                         (b"\x7fELF\x02\x01", "ELF")])
def test_files_that_cannot_be_firmware_are_refused(data: bytes, words: str) -> None:
    with pytest.raises(UsageError, match=words):
        firmware.check_file(data, "x.bin", "x.bin")


def test_read_of_a_missing_file_names_the_slaves_code(wire: Wire) -> None:
    conn = _conn(wire)
    with pytest.raises(FoeRefusedError, match="0x8001 Not found") as info:
        ecat_files.read_file(conn, "nothing.bin", 0, 1000)
    assert info.value.exit_code == 1 and info.value.code == 0x8001
    conn.close()


def test_boot_serves_only_foe(wire: Wire) -> None:
    t = transport(wire)
    t.open_bus()
    link = t.enter_boot()
    link.send(mbx.pack(mbx.MailboxType.COE, bytes.fromhex("0020 4018 1001 00000000"), 0, 1))
    reply = link.receive(1.0)
    assert reply is not None and reply[5] & 0x0F == 0  # a mailbox error: CoE is not served in BOOT
    t.leave_boot(5.0)
    t.close()


# ---------------------------------------------------------------------- the client against a scripted slave

class Scripted(MailboxLink):
    """A slave that answers each FoE frame with ``answer(frame)`` (None: silence)."""

    def __init__(self, answer) -> None:  # type: ignore[no-untyped-def]
        self.answer, self.sent, self.pending = answer, [], []  # type: ignore[var-annotated]

    def send(self, mailbox: bytes) -> None:
        frame = foe.decode_foe(mbx.split(mailbox)[3])
        self.sent.append(frame)
        for reply in self.answer(frame) or []:
            self.pending.append(mbx.pack(mbx.MailboxType.FOE, foe.encode_foe(reply), 0, 1))

    def receive(self, timeout: float) -> bytes | None:
        return self.pending.pop(0) if self.pending else None


def _acking(busy_first: int = 0, wrong_at: int | None = None, error_at: int | None = None):  # type: ignore[no-untyped-def]
    seen = {"busy": busy_first}

    def answer(frame: foe.FoeFrame) -> list[foe.FoeFrame]:
        if frame.opcode == foe.FoeOpcode.WRITE:
            return [foe.ack(0)]
        if frame.opcode == foe.FoeOpcode.DATA:
            if frame.value == error_at:
                return [foe.error(foe.ERR_DISK_FULL, "flash full")]
            if seen["busy"]:
                seen["busy"] -= 1
                return [foe.busy(1, 10)]
            return [foe.ack(frame.value + (1 if frame.value == wrong_at else 0))]
        return []
    return answer


def test_busy_resends_the_same_packet() -> None:
    link = Scripted(_acking(busy_first=3))
    client = FoeClient(link, 64, timeout=0.5)
    assert client.write("f", bytes(100)) == 2  # 52 + 48 bytes: the short second packet ends the file
    datas = [f.value for f in link.sent if f.opcode == foe.FoeOpcode.DATA]
    assert datas[:4] == [1, 1, 1, 1] and client.busy_count == 3


def test_exact_multiple_ends_with_an_empty_packet() -> None:
    link = Scripted(_acking())
    FoeClient(link, 64, timeout=0.5).write("f", bytes(104))
    datas = [f for f in link.sent if f.opcode == foe.FoeOpcode.DATA]
    assert [len(f.data) for f in datas] == [52, 52, 0]


def test_a_wrong_ack_number_stops_the_transfer_and_tells_the_slave() -> None:
    link = Scripted(_acking(wrong_at=2))
    with pytest.raises(MalformedReply, match="acknowledged packet 3 when packet 2 was sent"):
        FoeClient(link, 64, timeout=0.5).write("f", bytes(200))
    assert link.sent[-1].opcode == foe.FoeOpcode.ERROR and link.sent[-1].value == foe.ERR_PACKET_NUMBER


def test_an_error_mid_transfer_is_code_and_words() -> None:
    link = Scripted(_acking(error_at=2))
    with pytest.raises(FoeRefusedError, match=r"packet 2 .*0x8003 Disk full.*flash full"):
        FoeClient(link, 64, timeout=0.5).write("f", bytes(200))


def test_a_silent_slave_is_no_answer_within_the_timeout() -> None:
    link = Scripted(lambda frame: [])
    with pytest.raises(NoAnswer, match="did not answer the FoE write request"):
        FoeClient(link, 64, timeout=0.2).write("f", bytes(10))


def test_a_slave_that_stays_busy_is_bounded() -> None:
    link = Scripted(lambda frame: [foe.ack(0)] if frame.opcode == foe.FoeOpcode.WRITE else [foe.busy(0, 1)])
    client = FoeClient(link, 64, timeout=0.2)
    client.busy_timeout = 0.3
    with pytest.raises(NoAnswer, match="stayed busy"):
        client.write("f", bytes(10))


def test_error_words_without_the_base() -> None:
    assert foe_error_words(0x0005) == "FoE error 0x0005 Packet number wrong"
    assert "0x8009 Not in bootstrap" in foe_error_words(0x8009)


def test_mailbox_error_is_a_drive_refusal() -> None:
    class Refusing(Scripted):
        def send(self, mailbox: bytes) -> None:
            self.pending.append(mbx.pack(0, mbx.encode_error_reply(mbx.MailboxErrorReply(2)), 0, 1))

    with pytest.raises(DriveError, match="mailbox error 2"):
        FoeClient(Refusing(None), 64, timeout=0.5).read("x")


def test_a_foe_error_mid_transfer_leaves_the_drive_in_init_and_answering(wire: Wire,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """The simulated drive keeps at most 256 KiB of files: a larger image is refused with 0x8003 part-way; the
    slave is still taken out of BOOT and answers again (a known state)."""
    import akdctl.sim.face_ethercat_raw as face

    monkeypatch.setattr(face, "REBOOT_SECONDS", 0.2)
    conn = _conn(wire)
    big = bytes(range(251)) * 1200  # 301,200 bytes
    plan = firmware.plan(conn, firmware.FirmwareRequest("big.bin", big))
    with pytest.raises(FoeRefusedError, match=r"at packet \d+ .*0x8003 Disk full") as info:
        firmware.execute(conn, plan)
    assert info.value.exit_code == 1
    t = conn.transport()
    assert t.master.al_status(t.slave.station)[0] & 0x0F == ec.AlState.INIT  # type: ignore[attr-defined]
    conn.close()


def test_a_drive_that_never_comes_back_is_exit_3_in_one_line(wire: Wire, monkeypatch: pytest.MonkeyPatch) -> None:
    import akdctl.sim.face_ethercat_raw as face

    monkeypatch.setattr(face, "REBOOT_SECONDS", 30.0)
    conn = _conn(wire)
    plan = firmware.plan(conn, firmware.FirmwareRequest("fw.bin", IMAGE, restart_timeout=0.6))
    with pytest.raises(NoAnswer, match="did not answer again within 0.6 s after leaving BOOT") as info:
        firmware.execute(conn, plan)
    assert info.value.exit_code == 3 and "\n" not in str(info.value)
    conn.close()


def test_the_slave_answers_any_source_mac(wire: Wire) -> None:
    """SOEM's, IgH's and many masters' source MACs are locally administered (bit 1 of byte 0): still served."""
    for src in (b"\x02\x00\x00\x00\x00\x01", b"\x01\x01\x01\x01\x01\x01", b"\x00\x1b\x21\xaa\xbb\xcc"):
        frame = ec.encode_frame([ec.Datagram(ec.Cmd.BRD, 0, ec.REG_TYPE, bytes(2))], src=src)
        reply = wire.face.handle_frame(frame)
        assert reply is not None
        _dst, back_src, datagrams = ec.decode_frame(reply)
        assert datagrams[0].wkc == 1 and back_src[0] == src[0] | 0x02


def test_a_busy_slave_gets_each_packet_again(wire: Wire, drive: SimDrive, monkeypatch: pytest.MonkeyPatch) -> None:
    """``sim serve --ecat-foe-busy 2``: every DATA packet in BOOT is answered twice with BUSY first."""
    import akdctl.sim.face_ethercat_raw as face

    monkeypatch.setattr(face, "REBOOT_SECONDS", 0.2)
    wire.face.worker.foe_busy = 2
    conn = _conn(wire)
    result = firmware.execute(conn, firmware.plan(conn, firmware.FirmwareRequest("busy.bin", IMAGE)))
    packets = result["download"]["packets"]
    assert result["download"]["busy"] == 2 * packets
    with drive.transaction() as model:
        assert model.foe.files["busy.bin"] == IMAGE
    conn.close()


def test_progress_on_a_terminal_shows_bytes_and_eta(monkeypatch: pytest.MonkeyPatch) -> None:
    """A rich bar (bytes done/total, speed, time remaining) on a terminal; plain lines when piped."""
    import io
    import os
    import pty
    import sys
    import threading

    from akdctl.cli.ecat_foe import TransferProgress

    master, slave = pty.openpty()
    tty = os.fdopen(slave, "w", buffering=1)
    received: list[bytes] = []

    def drain() -> None:
        # Everything the terminal received, read while it is written (a full pty buffer would block the bar) and
        # until the last writer closes it (EIO): one read may return only the first of rich's writes.
        while True:
            try:
                data = os.read(master, 65536)
            except OSError:
                return
            if not data:
                return
            received.append(data)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    monkeypatch.setattr(sys, "stderr", tty)
    monkeypatch.setenv("COLUMNS", "120")
    with TransferProgress("FoE write fw.bin", 300_000, quiet=False) as progress:
        assert progress.terminal
        for done in range(0, 300_001, 30_000):
            progress(done, 300_000)
    tty.close()
    reader.join(timeout=10)
    os.close(master)
    assert not reader.is_alive(), "the terminal reader did not see the terminal close"
    shown = b"".join(received).decode("utf-8", "replace")
    assert "FoE write fw.bin" in shown and "kB" in shown
    piped = io.StringIO()
    monkeypatch.setattr(sys, "stderr", piped)
    with TransferProgress("FoE read x", None, quiet=False) as progress:
        progress(1000, None)
    assert piped.getvalue() == "akdctl: FoE read x: 1000 bytes\n"
