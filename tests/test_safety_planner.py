"""The planner's quantisation (SPEC-NOTES 13 scalings, CiA 402 object ranges), the write gate's table, and the
stop-signal guard — in process, no drive."""

from __future__ import annotations

import math
import signal

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.cli.signals import stop_signals
from akdctl.drive import gate
from akdctl.drive.axis.cia402 import Cia402Axis
from akdctl.drive.axis.profidrive import ProfidriveAxis
from akdctl.drive.motion_plan import REL_TOL, MotionRequest, check_request, quantise
from akdctl.drive.operation import PlannedWrite, WritePlan
from akdctl.errors import Interrupted, SafetyRefusal, UsageError

MDI = ProfidriveAxis.motion_scales("position")
JOG = ProfidriveAxis.motion_scales("velocity")
PP = Cia402Axis.motion_scales("position")
STEP = 50_000_000 / 65536  # one MDI_ACC step, rpm/s (SPEC-NOTES 13)


class Conn:
    def __init__(self, limits: dict | None = None, units: dict | None = None) -> None:
        class Profile:
            pass

        self.profile = Profile()
        self.profile.limits = dict(limits or {})  # type: ignore[attr-defined]
        self.profile.units = dict(units or {})  # type: ignore[attr-defined]


def test_mdi_acc_steps_are_honest() -> None:
    with pytest.raises(UsageError, match=r"nearest representable value is 762\.939"):
        quantise(MDI.accel, 100, "acceleration")
    with pytest.raises(UsageError, match=r"762\.939 and 1525\.88"):
        quantise(MDI.accel, 1000, "acceleration")
    assert quantise(MDI.accel, 1000, "acceleration", explicit=False).raw == 1  # a default: largest at or below
    assert quantise(MDI.accel, 4 * STEP, "acceleration").raw == 4


def test_mdi_velocity_full_scale_and_jog_n2() -> None:
    with pytest.raises(UsageError, match="largest representable"):
        quantise(MDI.velocity, 20000, "velocity")
    assert quantise(JOG.velocity, 60, "velocity").raw == 163  # SPEC-NOTES 13: 60 rpm -> 163 (truncated)
    assert quantise(JOG.velocity, -60, "velocity").raw == -163
    with pytest.raises(UsageError, match=r"4\.76.* and 5\.12"):  # 0.366 rpm steps: 5 rpm is 4.8 % off
        quantise(JOG.velocity, 5, "velocity")


def test_cia402_ranges() -> None:
    assert quantise(PP.velocity, 60, "velocity").raw == 65536  # 1 rev/s = 65536 counts/s
    with pytest.raises(UsageError, match="0x6081"):
        quantise(PP.velocity, 1e9, "velocity")


@given(st.floats(min_value=1e-3, max_value=5e7), st.sampled_from([MDI.accel, MDI.velocity, JOG.velocity, PP.accel]))
def test_never_rounded_up(value: float, scale: object) -> None:
    try:
        q = quantise(scale, value, "x")
    except UsageError:
        return
    assert q.executed <= value * (1 + 1e-12) and value - q.executed <= REL_TOL * value


def test_limits_hold_for_the_executed_default() -> None:
    conn = Conn({"max_acceleration": 500})
    with pytest.raises(UsageError, match="762.939"):
        check_request(conn, MotionRequest("move", target=1, relative=True), ProfidriveAxis)
    plan = check_request(conn, MotionRequest("move", target=1, relative=True), Cia402Axis)
    assert plan.accel is not None and plan.accel.executed <= 500
    with pytest.raises(SafetyRefusal, match="max_acceleration 500"):
        check_request(conn, MotionRequest("move", target=1, accel=600), Cia402Axis)


@pytest.mark.parametrize("request_", [MotionRequest("move", target=math.nan), MotionRequest("move", target=1,
                                      velocity=math.inf), MotionRequest("jog", velocity=60, duration_s=61),
                                      MotionRequest("jog", velocity=60), MotionRequest("home", timeout_s=-1)])
def test_bad_requests_exit_2(request_: MotionRequest) -> None:
    with pytest.raises(UsageError):
        check_request(Conn(), request_, ProfidriveAxis)


def test_user_units_and_absolute_travel() -> None:
    conn = Conn({"travel": [-2.0, 2.0]}, {"per_rev": 5.0})
    check_request(conn, MotionRequest("move", target=9.5), Cia402Axis)  # 1.9 rev
    with pytest.raises(SafetyRefusal, match="travel"):
        check_request(conn, MotionRequest("move", target=10.5), Cia402Axis)


def test_gate_table() -> None:
    assert gate.classify_pnu(1) is not None and not gate.classify_pnu(1).when_enabled  # type: ignore[union-attr]
    assert gate.classify_pnu(930).when_enabled  # type: ignore[union-attr]
    assert gate.classify_pnu(1001) is None and gate.classify_object(0x6098, 0) is None
    assert gate.classify_object(0x1600, 1).when_enabled  # type: ignore[union-attr]
    assert not gate.classify_object(0x607A, 0).when_enabled  # type: ignore[union-attr]
    mode = gate.classify_pnu(930)
    plan = lambda enabled: WritePlan("pnu set", "sim", [PlannedWrite("PNU 930", 2, "2", mode)], enabled=enabled)  # noqa: E731
    assert plan(False).needing_consent == [] and plan(None).needing_consent == [mode]  # unknown counts as enabled
    assert gate.needing_consent([mode], False) == [] and gate.needing_consent([mode, None], None) == [mode]


def test_stop_signals_exit_code_and_restore() -> None:
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with pytest.raises(Interrupted) as info, stop_signals() as stop:
            signal.raise_signal(signal.SIGHUP)  # ignored before: handled now
            assert stop()
            raise Interrupted("interrupted during move; axis stopped")
        assert info.value.exit_code == 128 + signal.SIGHUP and "SIGHUP" in info.value.message
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
