"""The simulated AKD against the PROFINET manuals (issue 16 items 1-6): each test quotes the statement it checks.

Manuals (the project's seed manuals): ``000`` AKD PROFINET Communication (Oct 2011), ``004`` AKD PROFINET RT
Communication (edition B), ``003`` AKD PROFINET RT Kommunikation (German, later). Rulings of our own are
docs/fidelity.md F1..; SPEC-NOTES numbers are named where a test relies on one.
"""

from __future__ import annotations

import json

import pytest

from akdctl.errors import RecordError
from akdctl.protocol import pnio
from akdctl.sim.drive import SimDrive
from akdctl.sim.face_profinet import ProfinetFace
from akdctl.transport.base import LinkOptions
from akdctl.transport.profinet import PnioRecordLink, ProfinetTransport
from akdctl.transport.sim import SimRecordLink
from akdctl.transport.target import split_target
from akdctl.transport.trace import Tracer

READ_930 = bytes.fromhex("05 01 00 01 10 01 03 A2 00 00")


# ---------------------------------------------------------------------------------------------------- item 4
def test_bmp_reserved_reference_and_unknown_request_id_are_refused_by_the_record_layer() -> None:
    """``000`` 3.5 "Record data fields": "Request reference Unsigned8 0x00 reserved, 0x01 – 0xFF"; "Request ID
    0x01 Request parameter, 0x02 Change parameter"; "Response ID 0x01, 0x02, 0x81, 0x82" - nothing else.
    ``reference/profidrive_reference.md`` (PDRV V4.2 table 169): Error_Code_1 "0xB7 invalid range (error in
    base-mode request header)". docs/fidelity.md F1: such a request gets no response; the write fails with 0xB7.
    """
    link = SimRecordLink(SimDrive("f1"))
    assert link.exchange(READ_930)[:2] == b"\x05\x01"                    # a valid request is answered
    for request in (b"\x00" + READ_930[1:], READ_930[:1] + b"\x03" + READ_930[2:]):
        with pytest.raises(RecordError) as info:
            link.exchange(request)
        assert info.value.code == pnio.rw_error(True, 0xB7).value       # DF 80 B7 00
        assert "invalid range" in info.value.message


def test_bmp_header_refusal_over_the_pnio_face() -> None:
    """The same rule on the wire: the PNIO face answers the record write with PNIOStatus DF 80 B7 00."""
    face = ProfinetFace(SimDrive("f1-face"), "127.0.0.1", 0)
    face.start()
    transport = ProfinetTransport(split_target(f"pn://127.0.0.1:{face.port}"),
                                  LinkOptions(timeout=1.0, retries=2, tracer=Tracer()))
    try:
        transport.connect()
        link = PnioRecordLink(transport)
        assert link.exchange(READ_930)[:2] == b"\x05\x01"
        with pytest.raises(RecordError) as info:
            link.exchange(b"\x00" + READ_930[1:])
        assert "B7" in info.value.message and info.value.code == pnio.rw_error(True, 0xB7).value
        assert link.exchange(READ_930)[:2] == b"\x05\x01"                # the channel still works afterwards
    finally:
        transport.close()
        face.stop()


# ---------------------------------------------------------------------------------------------------- item 5
def _ok(akd_inproc, *args: str) -> dict:
    code, out, err = akd_inproc("--json", *args)
    assert code == 0, (args, code, err)
    return json.loads(out)


def test_off1_and_off3_report_s5_switching_off(akd_inproc) -> None:
    """``004`` 5.4: "The S7 application must set the bits in control word 1 to go through the PROFIdrive standard
    state machine" (S1..S5, SPEC-NOTES 6); the profile's S5 "switching off" is the state of both the OFF1 ramp stop
    (STW1 bit 0 = 0) and the OFF3 quick stop (bit 2 = 0), with ZSW1 bits 0/1 set and bit 2 (operation enabled)
    clear. docs/fidelity.md F2. Velocity mode (PNU 930 = 1), telegram 1 enable sequence of ``004`` 5.9.
    """
    _ok(akd_inproc, "sim", "speed", "--realtime", "--watchdog", "0")
    _ok(akd_inproc, "--yes", "pnu", "set", "1007=1")               # DRV.DEC 1 rpm/s: the OFF1 ramp outlasts the test
    for word in ("0x0470", "0x0476", "0x0477", "0x047F"):
        _ok(akd_inproc, "--yes", "pnu", "set", f"1={word}")
    _ok(akd_inproc, "--yes", "pnu", "set", "5=1638")                 # 600 rpm (x = 15)
    _ok(akd_inproc, "sim", "speed", "100000")
    _ok(akd_inproc, "sim", "speed", "--realtime")                    # at speed now
    assert _ok(akd_inproc, "status")["status"]["state"] == "S4"
    _ok(akd_inproc, "--yes", "pnu", "set", "1=0x0476")               # OFF1: ON cleared, ramp along DRV.DEC
    status = _ok(akd_inproc, "status")["status"]
    assert status["state"] == "S5" and status["state_text"] == "switching off"
    assert status["word"] & 0x0047 == 0x0003 and status["word"] & 0x0020   # bits 0,1; not 2, 6; bit 5 set (OFF1)
    assert not status["standstill"]
    _ok(akd_inproc, "--yes", "pnu", "set", "1=0x0472")               # OFF3 while the ramp runs: quick stop
    status = _ok(akd_inproc, "status")["status"]
    assert status["state"] == "S5" or status["standstill"]           # the quick stop may already have ended
    _ok(akd_inproc, "sim", "speed", "100000")
    status = _ok(akd_inproc, "status")["status"]
    assert status["standstill"] and status["state"] == "S1"          # OFF3 ends in S1 (switching on inhibited)


def test_zsw1_of_s5_in_the_model() -> None:
    """The same through the model's bytes, without wall time: OFF1 ramp and OFF3 quick stop show 0x..33 / 0x..13."""
    import struct

    from akdctl.profiles import statusword as sw
    from akdctl.sim.model import DriveModel

    model = DriveModel()
    model.motion.watchdog_s = 0
    stw1 = lambda word: model.pnu_write_raw(1, 0, 0x42, [word])  # noqa: E731
    for word in sw.TELEGRAM1_ENABLE_SEQUENCE:
        stw1(word)
    model.pnu_write_raw(1007, 0, 0x42, [10])
    model.pnu_write_raw(5, 0, 0x42, [1638])
    model.advance(10.0)
    stw1(0x0476)                                                     # OFF1
    model.advance(1.0)
    zsw1 = model.pnu_read_raw(2, 0, 1)[1][0]
    assert zsw1 & 0x7F == 0x33 and sw.profidrive_state(zsw1, 0x0476) == "S5"
    assert sw.profidrive_state(zsw1, 0x047F) == "S3"                 # the same bits with ON set would be S3
    stw1(0x0472)                                                     # OFF3
    zsw1 = model.pnu_read_raw(2, 0, 1)[1][0]
    assert zsw1 & 0x7F == 0x13 and sw.profidrive_state(zsw1) == "S5"
    model.advance(10.0)
    assert sw.profidrive_state(model.pnu_read_raw(2, 0, 1)[1][0]) == "S1"
    assert struct.unpack("<H", model.object_read(0x6041, 0))[0] & 0x4F == 0x40   # CiA 402 view: switch on disabled


# ---------------------------------------------------------------------------------------------------- item 3
def test_position_rendering_follows_pnu_1002(akd_inproc) -> None:
    """``004`` 5.12.2 / ``003`` 6.12.2: "In the default configuration, the resolution per revolution is 2^16
    (65536) counts. The number of singleturn bits (default 16) can be changed through PNU 1002." With 20 bits,
    1.5 rev is 1572864 counts - shown as 1.5 rev, not as 24 rev (which 16 bits would make of it)."""
    assert akd_inproc("--yes", "pnu", "set", "1002=20", "34=1572864")[0] == 0
    code, out, _ = akd_inproc("pnu", "get", "34")
    assert code == 0 and "1.5 rev" in out and "24 rev" not in out
    code, out, _ = akd_inproc("pnu", "get", "34", "1002")
    assert code == 0 and "1.5 rev" in out


def test_sixty_rpm_is_163_the_manuals_example_truncates(akd_inproc) -> None:
    """``004`` 5.12.1: "E.g. if the S7 wants to set a velocity of 60 rpm in the cyclic channel in needs to
    convert: (60 / 12000) * 2^15 = 163". The exact value is 163.84, so the example truncates (toward zero);
    rounding to nearest would give 164 (docs/fidelity.md F6). 1 rps is "0x00A3" in 5.9 - the same 163."""
    from akdctl.profiles import units

    assert 60 / 12000 * 2**15 == 163.84
    assert units.rpm_to_x(60, 15) == 163 == 0x00A3 and units.rpm_to_x(-60, 15) == -163
    _ok(akd_inproc, "sim", "speed", "100000")
    plan = _ok(akd_inproc, "--yes", "jog", "60", "--for", "0.5s")["plan"]
    assert plan["velocity"]["raw"] == 163                              # the jog set point PNU 1004 as written
    with SimDrive("default").transaction() as model:                   # NIST_A of a drive at 60 rpm reads 163
        model.motion.axis.vel = 1.0
        assert model.pnu_read_raw(6, 0, 1)[1] == [163]


# ---------------------------------------------------------------------------------------------------- item 1
def test_stw2_zsw2_xist_a_are_pnus_and_free_mappable(akd_inproc) -> None:
    """``004`` 5.8: "The signals are also available in the PNU list. Each signal can be read/write with the same
    PNU number"; 5.6: "All supported PROFIdrive and manufacture specific signals can be mapped into telegram 0";
    5.11.4: telegram 9 carries STW2, ZSW2 and XIST_A (SPEC-NOTES 10), ``003`` 6.11.6 telegram 351 XIST_A
    (SPEC-NOTES 11). So signals 3, 4, 28 are PNUs 3, 4, 28 (docs/fidelity.md F7)."""
    data = _ok(akd_inproc, "pnu", "get", "3", "4", "28")
    assert [p["name"] for p in data["parameters"]] == ["STW2", "ZSW2", "XIST_A"]
    assert _ok(akd_inproc, "--yes", "pnu", "set", "3=0x1000")["written"][0]["values"] == [0x1000]
    assert akd_inproc("--yes", "pnu", "set", "28=5")[0] == 2                 # an actual value: read only
    assert [3, 4, 28] == [n for n in _ok(akd_inproc, "telegram", "show")["signal_list"] if n in (3, 4, 28)]
    assert any(p["pnu"] == 28 for p in _ok(akd_inproc, "pnu", "list", "--drive")["parameters"])
    _ok(akd_inproc, "--yes", "telegram", "set", "0")
    mapped = _ok(akd_inproc, "--yes", "telegram", "map", "--actual", "2,6,28", "--setpoint", "1,3,5")
    assert [w["name"] for w in mapped["actual"]] == ["ZSW1", "NIST_A", "XIST_A", "XIST_A"]
    for number, setpoint, actual in ((9, {"STW2"}, {"ZSW2", "XIST_A"}), (351, set(), {"XIST_A"})):
        state = _ok(akd_inproc, "--yes", "telegram", "set", str(number))
        assert setpoint <= {w["name"] for w in state["setpoint"]} and actual <= {w["name"] for w in state["actual"]}


def test_xist_a_counts_follow_pnu_1002(akd_inproc) -> None:
    """``004`` 5.12.2: positions count 2^PNU1002 per revolution; XIST_A at 1.5 rev is 98304 with 16 bits and
    1572864 with 20, and ``status`` shows the position from it."""
    with SimDrive("default").transaction() as model:
        model.motion.axis.pos = 1.5
    assert _ok(akd_inproc, "pnu", "get", "28")["parameters"][0]["values"] == [98304]
    _ok(akd_inproc, "--yes", "pnu", "set", "1002=20")
    assert _ok(akd_inproc, "pnu", "get", "28")["parameters"][0]["values"] == [1572864]
    status = _ok(akd_inproc, "status")["status"]
    assert status["position_rev"] == 1.5 and status["counts_per_rev"] == 1 << 20


@pytest.mark.slow
def test_status_over_profinet_shows_the_position() -> None:
    """Through the real CLI and the PNIO face: ``-T pn://… status`` has no object channel, and shows the position
    from XIST_A (PNU 28)."""
    from tests.harness import SimServer, run_akdctl

    with SimDrive("default").transaction() as model:
        model.motion.axis.pos = 2.25
    with SimServer("--profinet", "127.0.0.1:0") as server:
        code, out, err = run_akdctl("-T", f"pn://{server.host}:{server.port}", "--json", "status")
    assert code == 0, err
    status = json.loads(out)["status"]
    assert status["position_rev"] == 2.25 and status["position_counts"] == 2.25 * 65536


# ---------------------------------------------------------------------------------------------------- item 6
def _homed_position_mode(model) -> None:
    from akdctl.profiles import statusword as sw

    model.motion.watchdog_s = 0
    model.pnu_write_raw(930, 0, 0x42, [2])
    for word in sw.S7_ENABLE_SEQUENCE:
        model.pnu_write_raw(1, 0, 0x42, [word])
    model.pnu_write_raw(1001, 0, 0x42, [0])
    model.pnu_write_raw(1, 0, 0x42, [0x040F | sw.STW1_START_HOMING])
    model.pnu_write_raw(1, 0, 0x42, [0x040F])


@pytest.mark.parametrize("telegram, satzanw, starts", [
    (1, 4, False), (7, 4, True), (9, 4, True),                   # program mode: SATZANW in the telegram
    (1, 0x8000, False), (7, 0x8000, False), (9, 0x8000, True),   # MDI: the MDI signals in the telegram
    (350, 4, False), (351, 0x8000, False),
])
def test_program_mode_and_mdi_need_their_telegram(telegram: int, satzanw: int, starts: bool) -> None:
    """``004`` 5.10.1 Requirements: "Standard telegram 7 needs to be configured"; 5.10.2 Requirements: "Standard
    telegram 9 needs to be configured" (the same in ``000`` 5.9.1/5.9.2 and ``003`` 6.10.1/6.10.2); 5.10.2: "If an
    error occurs or the configured motion task can not be executed, bit 12 in ZSW1 will not be set".
    docs/fidelity.md F9: the selected telegram must carry the submode's signals; otherwise no task starts."""
    from akdctl.profiles import statusword as sw
    from akdctl.sim.model import DriveModel

    model = DriveModel()
    _homed_position_mode(model)
    model.pnu_write_raw(922, 0, 0x42, [telegram])
    model.pnu_write_raw(32, 0, 0x42, [satzanw])
    model.pnu_write_raw(34, 0, 0x43, [65536])
    model.pnu_write_raw(35, 0, 0x43, [(600 << 32) // 12000])
    model.pnu_write_raw(36, 0, 0x42, [13])
    model.pnu_write_raw(37, 0, 0x42, [13])
    model.pnu_write_raw(1, 0, 0x42, [0x043F])
    model.pnu_write_raw(1, 0, 0x42, [0x047F])                    # bit 6 edge: activate the traversing task
    zsw1 = model.pnu_read_raw(2, 0, 1)[1][0]
    assert bool(zsw1 & sw.ZSW1_TASK_ACK) is starts
    model.advance(5.0)
    assert (model.motion.position_counts != 0) is starts


def test_telegram_0_with_the_signals_counts() -> None:
    """5.6: every signal "can be mapped into telegram 0": a free telegram carrying SATZANW and MDI_* serves MDI."""
    from akdctl.catalog import telegrams as tc
    from akdctl.profiles import statusword as sw
    from akdctl.sim.model import DriveModel

    model = DriveModel()
    _homed_position_mode(model)
    model.pnu_write_raw(922, 0, 0x42, [0])
    model.pnu_write_raw(915, 0, 0x42, tc.expand_words([1, 32, 34, 35, 36, 37, 38]))
    for pnu, fmt, value in ((32, 0x42, 0x8000), (34, 0x43, 65536), (35, 0x43, (600 << 32) // 12000),
                            (36, 0x42, 13), (37, 0x42, 13)):
        model.pnu_write_raw(pnu, 0, fmt, [value])
    model.pnu_write_raw(1, 0, 0x42, [0x043F])
    model.pnu_write_raw(1, 0, 0x42, [0x047F])
    assert model.pnu_read_raw(2, 0, 1)[1][0] & sw.ZSW1_TASK_ACK


def test_move_selects_telegram_9(akd_inproc) -> None:
    """akdctl's ``move`` (MDI) selects telegram 9 when the drive has a telegram without the MDI signals, after
    consent, and the consent text says so (docs/fidelity.md F9)."""
    _ok(akd_inproc, "sim", "speed", "100000")
    assert _ok(akd_inproc, "telegram", "show")["telegram"] == 1
    _ok(akd_inproc, "--yes", "home", "--mode", "0")
    result = _ok(akd_inproc, "--yes", "move", "2")
    assert "telegram 9" in result["plan"]["mode"]
    assert result["status"]["position_rev"] == 2.0 and result["status"]["target_reached"]
    assert _ok(akd_inproc, "telegram", "show")["telegram"] == 9


def test_units_of_5_12() -> None:
    """``004`` 5.12.1 "a value of 2^32 for MDI_VELOCITY is equal 12000 rpm"; 5.12.3 "x = 16 is equal to 100% and
    means 50000000 rpm /sec^2"; 5.12.4 "for 3 amps AKD ... -182 ... (9/2^14) * (-182) = -0.1 Arms" (SPEC-NOTES 13)."""
    from akdctl.profiles import units

    assert units.x_to_rpm(1 << 32, 32) == 12000 and units.x_to_rpm(1 << 15, 15) == 12000
    assert units.acc_to_rpm_s(1 << 16) == 50_000_000
    assert round(units.current_to_amps(-182, 9.0), 1) == -0.1
