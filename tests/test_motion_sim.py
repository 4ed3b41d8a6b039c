"""The simulated axis through the API: the manuals' sequences replayed as BMP bytes and SDO writes.

PROFIdrive requests are real base-mode request bytes answered by the simulated
parameter manager (PnuServer), as on the wire; CiA 402 objects go through the
model's object access (what the SDO server calls).
"""

from __future__ import annotations

import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.protocol import bmp
from akdctl.sim.model import DriveModel
from akdctl.sim.pnu_server import PnuServer


class Bmp:
    """A PROFIdrive client speaking real request bytes to the simulated parameter manager."""

    def __init__(self, model: DriveModel) -> None:
        self.model = model
        self.server = PnuServer(model)
        self.ref = 0

    def _send(self, request: bmp.ParameterRequest) -> bmp.ParameterResponse:
        raw = self.server.handle(bmp.encode_request(request))
        return bmp.decode_response(raw, request)

    def write(self, pnu: int, value: int, sub: int = 0) -> None:
        info = self.model.pnu_info(pnu)
        self.ref = bmp.next_reference(self.ref)
        fmt = info.wire_format
        req = bmp.ParameterRequest(self.ref, bmp.REQ_CHANGE, 0, (bmp.ParameterAddress(pnu, sub, 1),),
                                   (bmp.ParameterValue(fmt, (value & ((1 << info.bits) - 1),)),))
        resp = self._send(req)
        assert not resp.negative, resp

    def read(self, pnu: int) -> int:
        self.ref = bmp.next_reference(self.ref)
        req = bmp.ParameterRequest(self.ref, bmp.REQ_READ, 0, (bmp.ParameterAddress(pnu, 0, 1),))
        resp = self._send(req)
        value = resp.results[0].values[0]
        info = self.model.pnu_info(pnu)
        return bmp.to_signed(value, info.bits) if info.signed else value

    def zsw1(self) -> int:
        return self.read(2)


@pytest.fixture
def model() -> DriveModel:
    m = DriveModel()
    m.time_scale = 1.0
    m.component("motion").watchdog_s = 0  # these tests advance virtual time without requests
    return m


@pytest.fixture
def pd(model: DriveModel) -> Bmp:
    return Bmp(model)


def cw(model: DriveModel, word: int) -> None:
    model.object_write(0x6040, 0, struct.pack("<H", word))


def sword(model: DriveModel) -> int:
    return struct.unpack("<H", model.object_read(0x6041, 0))[0]


def obj(model: DriveModel, index: int, fmt: str, value: int, sub: int = 0) -> None:
    model.object_write(index, sub, struct.pack(fmt, value))


# ---------------------------------------------------------------- PROFIdrive general state machine
def test_velocity_mode_telegram1_sequence(model: DriveModel, pd: Bmp) -> None:
    """PROFINET manual 5.9: 0x0470 → 0x0476 → 0x0477 → 0x047F, NSOLL_A = 0x00A3 (60 rpm)."""
    states = []
    for word in sw.TELEGRAM1_ENABLE_SEQUENCE:
        pd.write(1, word)
        states.append(sw.profidrive_state(pd.zsw1()))
    assert states == ["S1", "S2", "S3", "S4"]
    pd.write(5, 0x00A3)
    model.advance(1.0)
    assert pd.read(6) == 0x00A3  # NIST_A follows the set point (x = 15, SPEC-NOTES 13)
    assert pd.zsw1() & sw.ZSW1_BIT10  # target velocity reached
    assert model.component("motion").velocity_rpm == pytest.approx(units.x_to_rpm(0xA3, 15))


def test_s7_sample_sequence_ends_in_s4(model: DriveModel, pd: Bmp) -> None:
    """SPEC-NOTES 6: 0x040E keeps S2 (ON still 0); 0x040F then takes the drive to S4."""
    states = []
    for word in sw.S7_ENABLE_SEQUENCE:
        pd.write(1, word)
        states.append(sw.profidrive_state(pd.zsw1()))
    assert states == ["S1", "S2", "S2", "S4"]
    assert pd.zsw1() & 0x0007 == 0x0007


def test_stw1_without_bit10_is_ignored(model: DriveModel, pd: Bmp) -> None:
    """SPEC-NOTES 7: without control by PLC the drive ignores the control word."""
    for word in (0x0006, 0x000F):
        pd.write(1, word)
    assert sw.profidrive_state(pd.zsw1()) == "S1"
    assert not pd.zsw1() & sw.ZSW1_CONTROL_REQUESTED


def test_fault_reaction_and_acknowledge_edge(model: DriveModel, pd: Bmp) -> None:
    """A fault while moving: quick stop, then S1 with bit 3; the rising edge of bit 7 acknowledges (note 7)."""
    for word in sw.TELEGRAM1_ENABLE_SEQUENCE:
        pd.write(1, word)
    pd.write(5, units.rpm_to_x(600, 15))
    model.advance(2.0)
    model.component("faults").raise_fault("F501")
    model.advance(1.0)
    motion = model.component("motion")
    assert motion.standstill
    assert pd.zsw1() & sw.ZSW1_FAULT and not pd.zsw1() & sw.ZSW1_OPERATION_ENABLED
    pd.write(1, 0x0476)
    assert pd.zsw1() & sw.ZSW1_FAULT  # no edge yet
    pd.write(1, 0x04F6)
    assert not pd.zsw1() & sw.ZSW1_FAULT
    assert sw.profidrive_state(pd.zsw1()) == "S1"


def test_jog_bits_8_and_9(model: DriveModel, pd: Bmp) -> None:
    """SPEC-NOTES 8: jog 1/2 with PNU 1004/1005, ramps 1006/1007; prerequisite bits 4/5/6 = 0."""
    for word in sw.S7_ENABLE_SEQUENCE:
        pd.write(1, word)
    pd.write(1004, units.rpm_to_x(120, 15))
    pd.write(1005, units.rpm_to_x(-60, 15))
    pd.write(1, 0x040F | sw.STW1_JOG1)
    model.advance(1.0)
    assert pd.read(6) == units.rpm_to_x(120, 15)
    pd.write(1, 0x040F)
    model.advance(1.0)
    assert pd.read(6) == 0
    pd.write(1, 0x040F | sw.STW1_JOG2)
    model.advance(1.0)
    assert pd.read(6) == units.rpm_to_x(-60, 15)
    pd.write(1, 0x040F)
    model.advance(1.0)
    # with bit 4 set the jog prerequisite fails: no motion
    pd.write(1, 0x041F | sw.STW1_JOG1)
    model.advance(1.0)
    assert pd.read(6) == 0


def _position_mode(pd: Bmp) -> None:
    pd.write(930, 2)
    pd.write(922, 9)  # telegram 9 carries SATZANW and the MDI signals (docs/fidelity.md F9)
    for word in sw.S7_ENABLE_SEQUENCE:
        pd.write(1, word)


@pytest.mark.parametrize("home_mode", [0, 3, 4, 5])
def test_homing_zsw1_bits(model: DriveModel, pd: Bmp, home_mode: int) -> None:
    """SPEC-NOTES 9: bit 11 starts HOME.MOVE; bits 10/11/13 clear while running, all set when done."""
    _position_mode(pd)
    model.component("motion").axis.pos = -0.8
    pd.write(1001, home_mode)
    pd.write(1, 0x040F | sw.STW1_START_HOMING)
    if home_mode != 0:
        model.advance(0.2)
        assert pd.zsw1() & (sw.ZSW1_BIT10 | sw.ZSW1_HOME_POSITION_SET | sw.ZSW1_DRIVE_STOPPED) == 0
    model.advance(120.0)
    done = sw.ZSW1_BIT10 | sw.ZSW1_HOME_POSITION_SET | sw.ZSW1_DRIVE_STOPPED
    assert pd.zsw1() & done == done
    assert model.component("motion").position_counts == 0  # home offset 0 at the reference


def test_homing_aborted_by_clearing_bit11(model: DriveModel, pd: Bmp) -> None:
    _position_mode(pd)
    pd.write(1001, 3)
    pd.write(1, 0x040F | sw.STW1_START_HOMING)
    model.advance(0.3)
    pd.write(1, 0x040F)
    model.advance(5.0)
    zsw1 = pd.zsw1()
    assert not zsw1 & sw.ZSW1_HOME_POSITION_SET and zsw1 & sw.ZSW1_DRIVE_STOPPED


def _home(model: DriveModel, pd: Bmp) -> None:
    pd.write(1001, 0)
    pd.write(1, 0x040F | sw.STW1_START_HOMING)
    pd.write(1, 0x040F)
    assert pd.zsw1() & sw.ZSW1_HOME_POSITION_SET


def test_program_mode_handshake(model: DriveModel, pd: Bmp) -> None:
    """Manual 5.10.1: SATZANW = task, bits 4/5 = 1, bit 6 edge; bit 13 while moving, bit 10 at the end."""
    _position_mode(pd)
    _home(model, pd)
    pd.write(32, 4)  # the simulator's task 4: absolute 5 rev
    pd.write(1, 0x043F)
    pd.write(1, 0x047F)
    zsw1 = pd.zsw1()
    assert zsw1 & sw.ZSW1_TASK_ACK and not zsw1 & sw.ZSW1_BIT10 and not zsw1 & sw.ZSW1_DRIVE_STOPPED
    assert pd.read(33) == 4
    model.advance(0.1)
    assert not pd.zsw1() & sw.ZSW1_DRIVE_STOPPED
    model.advance(10.0)
    assert pd.zsw1() & (sw.ZSW1_BIT10 | sw.ZSW1_DRIVE_STOPPED) == sw.ZSW1_BIT10 | sw.ZSW1_DRIVE_STOPPED
    assert model.component("motion").position_counts == 5 * 65536
    pd.write(1, 0x043F)
    assert not pd.zsw1() & sw.ZSW1_TASK_ACK


def test_program_mode_reject_and_intermediate_stop(model: DriveModel, pd: Bmp) -> None:
    _position_mode(pd)
    _home(model, pd)
    pd.write(32, 4)
    pd.write(1, 0x043F)
    pd.write(1, 0x047F)
    model.advance(0.2)
    pd.write(1, 0x045F)  # bit 5 = 0: intermediate stop
    model.advance(2.0)
    motion = model.component("motion")
    paused_at = motion.position_counts
    assert motion.standstill and 0 < paused_at < 5 * 65536
    pd.write(1, 0x047F)  # bit 5 = 1 again: continue
    model.advance(10.0)
    assert motion.position_counts == 5 * 65536
    pd.write(32, 3)  # absolute 0
    pd.write(1, 0x043F)
    pd.write(1, 0x047F)
    model.advance(0.2)
    pd.write(1, 0x046F)  # bit 4 = 0: reject the task, brake with ramp
    model.advance(5.0)
    assert motion.standstill and motion.axis.task is None and motion.position_counts > 0


def test_mdi_handshake(model: DriveModel, pd: Bmp) -> None:
    """Manual 5.10.2 / SPEC-NOTES 12: SATZANW bit 15, MDI_* signals loaded on the bit 6 edge, ZSW1 bit 12."""
    _position_mode(pd)
    _home(model, pd)
    pd.write(32, 0x8000)
    pd.write(34, -3 * 65536)
    pd.write(35, units.rpm_to_x(600, 32))
    pd.write(36, units.rpm_s_to_acc(10000))
    pd.write(37, units.rpm_s_to_acc(10000))
    pd.write(38, 1)  # absolute
    pd.write(1, 0x043F)
    assert not pd.zsw1() & sw.ZSW1_TASK_ACK
    pd.write(1, 0x047F)
    assert pd.zsw1() & sw.ZSW1_TASK_ACK
    assert pd.read(33) & 0x8000
    pd.write(1, 0x043F)  # drop bit 6 after bit 12: the drive clears bit 12, the task keeps running
    assert not pd.zsw1() & sw.ZSW1_TASK_ACK
    model.advance(10.0)
    assert model.component("motion").position_counts == -3 * 65536
    pd.write(38, 0)  # relative +1 rev
    pd.write(34, 65536)
    pd.write(1, 0x047F)
    model.advance(10.0)
    assert model.component("motion").position_counts == -2 * 65536


def test_mdi_refused_when_not_homed(model: DriveModel, pd: Bmp) -> None:
    """An MDI task the drive cannot run leaves ZSW1 bit 12 clear (manual 5.10.2)."""
    _position_mode(pd)
    pd.write(32, 0x8000)
    pd.write(34, 65536)
    pd.write(35, units.rpm_to_x(600, 32))
    pd.write(1, 0x043F)
    pd.write(1, 0x047F)
    assert not pd.zsw1() & sw.ZSW1_TASK_ACK


# ---------------------------------------------------------------- CiA 402
def test_cia402_enable_sequence(model: DriveModel) -> None:
    """EtherCAT manual 5.4: shutdown 0x06, switch on 0x07, enable operation 0x0F."""
    seen = [sw.cia402_state(sword(model))]
    for word in (sw.CW_SHUTDOWN, sw.CW_SWITCH_ON_CMD, sw.CW_ENABLE_OPERATION_CMD):
        cw(model, word)
        seen.append(sw.cia402_state(sword(model)))
    assert seen == ["switch on disabled", "ready to switch on", "switched on", "operation enabled"]
    cw(model, sw.CW_SWITCH_ON_CMD)
    assert sw.cia402_state(sword(model)) == "switched on"
    cw(model, sw.CW_DISABLE_VOLTAGE)
    assert sw.cia402_state(sword(model)) == "switch on disabled"


def _cia_enable(model: DriveModel, mode: int) -> None:
    obj(model, 0x6060, "<b", mode)
    for word in (sw.CW_SHUTDOWN, sw.CW_SWITCH_ON_CMD, sw.CW_ENABLE_OPERATION_CMD):
        cw(model, word)


def test_cia402_profile_position_handshake(model: DriveModel) -> None:
    _cia_enable(model, 1)
    assert struct.unpack("<b", model.object_read(0x6061, 0))[0] == 1
    obj(model, 0x607A, "<i", 3 * 65536)
    obj(model, 0x6081, "<I", 10 * 65536)
    obj(model, 0x6083, "<I", 100 * 65536)
    obj(model, 0x6084, "<I", 100 * 65536)
    cw(model, 0x001F)
    word = sword(model)
    assert word & sw.SW_BIT12 and not word & sw.SW_TARGET_REACHED
    cw(model, 0x000F)
    assert not sword(model) & sw.SW_BIT12
    model.advance(5.0)
    assert sword(model) & sw.SW_TARGET_REACHED
    assert model.object_value(0x6064, 0) == 3 * 65536
    obj(model, 0x607A, "<i", -65536)
    cw(model, 0x004F)
    cw(model, 0x005F)  # relative
    model.advance(5.0)
    assert model.object_value(0x6064, 0) == 2 * 65536


def test_cia402_profile_velocity_and_halt(model: DriveModel) -> None:
    _cia_enable(model, 3)
    obj(model, 0x60FF, "<i", 65536)  # 1 rev/s = 60 rpm
    model.advance(1.0)
    assert model.object_value(0x606C, 0) == 65536
    assert sword(model) & sw.SW_TARGET_REACHED
    cw(model, 0x010F)  # halt
    model.advance(1.0)
    assert model.object_value(0x606C, 0) == 0


@pytest.mark.parametrize("method", [35, 19, 3, 34])
def test_cia402_homing(model: DriveModel, method: int) -> None:
    """Homing mode 6: bit 4 starts; statusword bit 12 homing attained, bit 10 target reached."""
    _cia_enable(model, 6)
    obj(model, 0x6098, "<b", method)
    obj(model, 0x607C, "<i", 1000)  # home offset
    cw(model, 0x001F)
    model.advance(120.0)
    word = sword(model)
    assert word & sw.SW_BIT12 and word & sw.SW_TARGET_REACHED and not word & sw.SW_BIT13
    assert model.object_value(0x6064, 0) == 1000


def test_cia402_homing_error_for_unknown_method(model: DriveModel) -> None:
    _cia_enable(model, 6)
    obj(model, 0x6098, "<b", 0)
    cw(model, 0x001F)
    model.advance(1.0)
    assert sword(model) & sw.SW_BIT13


def test_cia402_quick_stop(model: DriveModel) -> None:
    _cia_enable(model, 3)
    obj(model, 0x60FF, "<i", 20 * 65536)
    model.advance(5.0)
    cw(model, sw.CW_QUICK_STOP_CMD)
    assert sw.cia402_state(sword(model)) == "quick stop active"
    model.advance(1.0)
    assert model.object_value(0x606C, 0) == 0
    assert sw.cia402_state(sword(model)) == "switch on disabled"  # 0x605A = 2


def test_software_limits_stop_velocity_motion(model: DriveModel) -> None:
    obj(model, 0x607D, "<i", -65536, sub=1)
    obj(model, 0x607D, "<i", 2 * 65536, sub=2)
    _cia_enable(model, 3)
    obj(model, 0x60FF, "<i", 5 * 65536)
    model.advance(30.0)
    assert model.object_value(0x6064, 0) == 2 * 65536
    assert model.object_value(0x606C, 0) == 0
    assert sword(model) & sw.SW_INTERNAL_LIMIT


def test_controlword_ignored_when_mapped_in_op(model: DriveModel) -> None:
    """SPEC-NOTES 23: with the controlword in the active RxPDO in OP an SDO write has no effect."""
    pdo = model.component("pdo")
    pdo.set_al_state("OP")
    assert pdo.controlword_in_active_rxpdo()
    cw(model, sw.CW_SHUTDOWN)
    assert sw.cia402_state(sword(model)) == "switch on disabled"


# ---------------------------------------------------------------- watchdog and persistence
def test_watchdog_stops_motion_after_silence(model: DriveModel, pd: Bmp) -> None:
    motion = model.component("motion")
    motion.watchdog_s = 1.0
    model.time_scale = 1000.0  # 1 s of wall time = 1000 virtual seconds
    for word in sw.TELEGRAM1_ENABLE_SEQUENCE:
        pd.write(1, word)
    pd.write(5, units.rpm_to_x(600, 15))
    model.advance(500.0)  # half the watchdog: still running
    assert pd.read(6) == units.rpm_to_x(600, 15)
    model.advance(1500.0)  # then silence longer than the watchdog
    assert motion.standstill and motion.watchdog_tripped
    assert pd.zsw1() & sw.ZSW1_WARNING
    assert abs(motion.axis.pos) < 600 / 60.0 * (500 + 1001)  # stopped 1000 s after the last request, not 1500 s
    pd.write(1, 0x047F)  # a new control word clears the warning and resumes the level-triggered set point
    assert not pd.zsw1() & sw.ZSW1_WARNING


def test_watchdog_aborted_task_is_not_target_reached(model: DriveModel, pd: Bmp) -> None:
    """ZSW1 bit 10 means "target reached" only at the target: a task the watchdog stopped (the tool of a
    ``move --no-wait`` exited) leaves bit 10 clear at standstill; the next completed task sets it again."""
    motion = model.component("motion")
    _position_mode(pd)
    _home(model, pd)
    motion.watchdog_s = 1.0
    model.time_scale = 1.0
    motion.tasks.tasks["4"]["rpm"] = 60.0  # the simulator's task 4 (absolute 5 rev), slowed to 5 s
    pd.write(32, 4)
    pd.write(1, 0x043F)
    pd.write(1, 0x047F)
    model.advance(30.0)  # nobody asks: the watchdog stops the axis after 1 s
    assert motion.standstill and motion.watchdog_tripped
    assert motion.position_counts != 5 * 65536
    zsw1 = pd.zsw1()
    assert zsw1 & sw.ZSW1_DRIVE_STOPPED and not zsw1 & sw.ZSW1_BIT10
    motion.watchdog_s = 0
    pd.write(1, 0x043F)
    pd.write(1, 0x047F)  # the same task again, this time to its end
    model.advance(30.0)
    assert motion.position_counts == 5 * 65536 and pd.zsw1() & sw.ZSW1_BIT10


def test_cia402_watchdog_aborted_move_is_not_target_reached(model: DriveModel) -> None:
    motion = model.component("motion")
    motion.axis.homed = True
    _cia_enable(model, 1)
    obj(model, 0x607A, "<i", 3 * 65536)
    obj(model, 0x6081, "<I", 1 * 65536)
    motion.watchdog_s = 1.0
    model.time_scale = 1.0
    cw(model, 0x001F)
    cw(model, 0x000F)
    model.advance(30.0)
    assert motion.standstill and motion.watchdog_tripped
    assert model.object_value(0x6064, 0) != 3 * 65536 and not sword(model) & sw.SW_TARGET_REACHED


def test_state_round_trip(model: DriveModel, pd: Bmp) -> None:
    _position_mode(pd)
    _home(model, pd)
    pd.write(32, 4)
    pd.write(1, 0x043F)
    pd.write(1, 0x047F)
    model.advance(0.3)
    again = DriveModel.from_state(model.to_state())
    again.component("motion").watchdog_s = 0
    a, b = model.component("motion"), again.component("motion")
    assert (a.axis.pos, a.axis.vel, a.state, a.axis.task) == (b.axis.pos, b.axis.vel, b.state, b.axis.task)
    model.advance(10.0)
    again.advance(10.0)
    assert a.position_counts == b.position_counts == 5 * 65536


@settings(max_examples=60, deadline=None)
@given(target=st.floats(-50, 50), rpm=st.floats(1, 3000), acc=st.floats(10, 50000), dec=st.floats(10, 50000),
       start_v=st.floats(-30, 30), steps=st.lists(st.floats(0.0005, 3.0), min_size=1, max_size=30))
def test_position_generator_reaches_target_without_overshoot(target: float, rpm: float, acc: float, dec: float,
                                                              start_v: float, steps: list[float]) -> None:
    """Whatever the tick pattern, a finite move ends exactly at its target, at standstill."""
    m = DriveModel()
    motion = m.component("motion")
    motion.watchdog_s = 0
    axis = motion.axis
    axis.vel = start_v if abs(start_v) > 1e-3 else 0.0
    axis.gen = {"kind": "position", "target": target, "v": rpm / 60, "acc": acc / 60, "dec": dec / 60}
    axis.activity = "task"
    for h in steps:
        m.advance(h)
    # Braking from start_v at a low deceleration can overshoot by hundreds of revolutions, which
    # takes hours at 1 rpm to come back from: advance until the move ends (bounded).
    for _ in range(1000):
        m.advance(10_000.0)
        if axis.gen is None:
            break
    assert axis.gen is None and axis.vel == 0.0
    assert axis.pos == pytest.approx(target, abs=1e-6)
