"""``sim serve`` faces: options declared as data, ready lines naming what was bound, the udp_multicast warning.

No test here sends a packet off the machine: sockets bind to 127.0.0.1 and the CAN face is not started."""

from __future__ import annotations

import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from akdctl.cli import sim as cli_sim
from akdctl.sim import face_can, face_ethercat_udp, face_profinet
from akdctl.sim.drive import SimDrive
from akdctl.sim.face import Face


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
    assert face_can.CanFace(drive, face_can.parse_spec("virtual:bench:1")).warnings() == []


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
    full disk does, then lets them through again."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.left, self.exc = 0, OSError(28, "No space left on device")
        original = SimDrive.transaction

        def transaction(drive: SimDrive, *args: object, **kwargs: object):  # type: ignore[no-untyped-def]
            if self.left > 0:
                self.left -= 1
                raise self.exc
            return original(drive, *args, **kwargs)

        monkeypatch.setattr(SimDrive, "transaction", transaction)

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
        failing.fail()
        code, _, err = akd_inproc(*target, "sdo", "read", "0x1018:1")
        assert code == 1 and "0x08000000" in err
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
        failing.fail()
        code, _, err = akd_inproc(*target, "sdo", "read", "0x1018:1")
        assert code == 1 and "0x08000000" in err
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
