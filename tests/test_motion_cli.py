"""Motion commands through the real CLI (subprocesses), both profiles, and the safety guarantees.

Fast flows run the simulator at 100000× wall time (`sim speed`); the tests that
interrupt, fault or silence a running motion run it in real time so the motion
is still going when the test acts. No assertion depends on timing: each waits
for a state with a deadline.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import signal
import subprocess
from pathlib import Path

import pytest

from akdctl.sim.drive import SimDrive
from tests.harness import finish, run_akdctl_inproc, wait_until
from tests.harness import run_akdctl as run
from tests.harness import start_akdctl as popen

pytestmark = pytest.mark.slow
PROFILES = ["sim?drive=profidrive", "sim?drive=cia402"]


def ok(*args: str) -> dict:
    code, out, err = run("--json", *args)
    assert code == 0, (args, code, err)
    return json.loads(out)


def motion_state() -> dict:
    with SimDrive("default").transaction() as model:
        motion = model.component("motion")
        return {"standstill": motion.standstill, "activity": motion.axis.activity, "state": motion.state,
                "velocity_rpm": motion.velocity_rpm, "pos": motion.axis.pos}


@pytest.fixture
def fast() -> None:
    assert run_akdctl_inproc("sim", "speed", "100000")[0] == 0  # set-up, in-process: the flows are the CLI runs


@pytest.fixture
def realtime() -> None:
    assert run_akdctl_inproc("sim", "speed", "--realtime")[0] == 0


# ---------------------------------------------------------------- flows, both profiles
@pytest.mark.parametrize("target", PROFILES)
def test_enable_home_move_jog_stop_disable(fast: None, target: str) -> None:
    t = ["-T", target]
    assert ok(*t, "status")["status"]["enabled"] is False
    enabled = ok(*t, "--yes", "enable")["status"]
    assert enabled["enabled"] and enabled["state"] in ("S4", "operation enabled")
    homed = ok(*t, "--yes", "home", "--mode", "4" if "profidrive" in target else "3")["status"]
    assert homed["position_counts"] == 0 and homed["standstill"]
    doc = ok(*t, "--yes", "move", "2.5")
    assert doc["target"] == target and doc["position_target"] == 2.5  # the drive keeps its key; the move its own
    moved = doc["status"]
    assert moved["position_counts"] == int(2.5 * 65536) and moved["target_reached"]
    moved = ok(*t, "--yes", "move", "-90", "--relative", "--units", "deg")["status"]
    assert moved["position_counts"] == int(2.25 * 65536)
    moved = ok(*t, "--yes", "move", "1000", "--units", "counts")["status"]
    assert moved["position_counts"] == 1000
    jogged = ok(*t, "--yes", "jog", "-60", "--distance", "0.5")["status"]
    assert jogged["position_counts"] == 1000 + 32768
    jogged = ok(*t, "--yes", "jog", "30", "--for", "100ms")["status"]
    assert jogged["standstill"] and jogged["position_counts"] > 1000 + 32768
    assert ok(*t, "stop")["status"]["standstill"]
    assert ok(*t, "stop", "--quick")["status"]["enabled"] is False
    assert ok(*t, "--yes", "enable")["status"]["enabled"]
    assert ok(*t, "disable")["status"]["enabled"] is False
    assert motion_state()["standstill"]


def test_status_lists_every_bit_in_words(fast: None) -> None:
    code, out, _ = run("status")
    assert code == 0
    for words in ("switching on inhibited", "control requested by the master", "quick stop not activated"):
        assert words in out
    data = ok("-T", "sim?drive=cia402", "status")
    assert [b["bit"] for b in data["status"]["bits"]] == list(range(16))
    assert data["status"]["state"] == "switch on disabled"


def test_user_units_from_the_profile(fast: None, tmp_path: Path) -> None:
    cfg = tmp_path / "akd.toml"
    cfg.write_text('[profiles.bench]\ntarget = "sim"\n[profiles.bench.units]\nname = "mm"\nper_rev = 5.0\n')
    t = ["--config", str(cfg), "--profile", "bench"]
    ok(*t, "--yes", "home", "--mode", "0")
    assert ok(*t, "--yes", "move", "12.5")["status"]["position_counts"] == int(2.5 * 65536)


# ---------------------------------------------------------------- consent and limits
def test_no_tty_and_no_yes_refuses_with_reason(fast: None) -> None:
    writes = SimDrive("default").snapshot()["writes"]
    for args in (["enable"], ["jog", "60", "--for", "1s"], ["home"], ["move", "1", "--relative"]):
        code, _, err = run(*args)
        assert code == 4, (args, err)
        assert "consent" in err or "not homed" in err
    code, _, err = run("enable")
    assert "sim" in err and "--yes" in err
    assert SimDrive("default").snapshot()["writes"] == writes  # nothing reached the drive


def test_profile_limits_are_enforced_before_anything_is_sent(fast: None, tmp_path: Path) -> None:
    cfg = tmp_path / "akd.toml"
    cfg.write_text('[profiles.bench]\ntarget = "sim"\n[profiles.bench.limits]\nmax_velocity = 300\n'
                   'max_acceleration = 2000\ntravel = [-2.0, 2.0]\n')
    t = ["--config", str(cfg), "--profile", "bench", "--yes"]
    ok(*t, "home", "--mode", "0")
    writes = SimDrive("default").snapshot()["writes"]
    cases = [
        (["move", "1", "--velocity", "500"], "max_velocity"),
        (["move", "1", "--accel", "5000"], "max_acceleration"),
        (["move", "3"], "travel"),
        (["move", "2.5", "--relative"], "travel"),
        (["jog", "600", "--for", "1s"], "max_velocity"),
        (["jog", "60", "--distance", "-3"], "travel"),
    ]
    for args, words in cases:
        code, _, err = run(*t, *args)
        assert code == 4 and words in err, (args, err)
    assert SimDrive("default").snapshot()["writes"] == writes
    assert ok(*t, "move", "1.5")["status"]["position_counts"] == int(1.5 * 65536)


# ---------------------------------------------------------------- refusals in words
def test_refuses_with_fault_present(fast: None) -> None:
    assert run("sim", "fault", "F501")[0] == 0
    code, _, err = run("--yes", "move", "1", "--relative")
    assert code == 4 and "F501" in err and "fault ack" in err


def test_refuses_absolute_move_when_not_homed(fast: None) -> None:
    for target in PROFILES:
        code, _, err = run("-T", target, "--yes", "move", "1")
        assert code == 4 and "not homed" in err


def test_refuses_when_stw1_bit10_not_honoured(fast: None) -> None:
    with SimDrive("default").transaction() as model:
        model.component("motion").pd.plc_control_allowed = False
    code, _, err = run("-T", "sim?drive=profidrive", "--yes", "enable")
    assert code == 4 and "bit 10" in err


def test_refuses_when_controlword_is_mapped_in_op(fast: None) -> None:
    """SPEC-NOTES 23: the default fixed RxPDO 0x1701 holds 0x6040; in OP an SDO controlword does nothing."""
    with SimDrive("default").transaction() as model:
        model.component("pdo").set_al_state("OP")
    code, _, err = run("-T", "sim?drive=cia402", "--yes", "enable")
    assert code == 4 and "SPEC-NOTES 23" in err and "0x1701" in err
    assert motion_state()["state"] == "switch_on_disabled"


# ---------------------------------------------------------------- Ctrl-C, faults, silence while moving
@pytest.mark.parametrize("target", PROFILES)
@pytest.mark.parametrize("command", ["move", "jog", "home"])
def test_sigint_stops_the_axis_and_exits_130(realtime: None, target: str, command: str) -> None:
    t = ["-T", target, "--yes"]
    if command == "move":
        ok(*t, "home", "--mode", "0" if "profidrive" in target else "35")
        args = ["move", "100", "--velocity", "60"]
    elif command == "jog":
        args = ["jog", "60", "--for", "60s"]
    else:
        with SimDrive("default").transaction() as model:
            model.component("motion").axis.pos = -100.0  # far from the home switch: a long search
        args = ["home", "--mode", "3" if "profidrive" in target else "19"]
    proc = popen(*t, *args)
    try:
        wait_until(lambda: not motion_state()["standstill"], "the axis to move")
        proc.send_signal(signal.SIGINT)
        code, _, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert code == 130, err
    assert "interrupted" in err and "stopped" in err
    assert motion_state()["standstill"]


def test_injected_fault_during_move_reports_number_and_text(realtime: None) -> None:
    ok("--yes", "home", "--mode", "0")
    proc = popen("--yes", "move", "100", "--velocity", "60")
    try:
        wait_until(lambda: not motion_state()["standstill"], "the axis to move")
        assert run("sim", "fault", "F501")[0] == 0
        code, _, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert code == 1, err
    assert "F501" in err and "over" in err.lower()  # F501 bus over-voltage, text from the fault table
    assert motion_state()["standstill"]


def test_drive_that_stops_answering_mid_move_exits_3(realtime: None) -> None:
    """Hold the simulated drive's lock: the tool gets no answer, exits 3, and the drive's watchdog stops the axis."""
    drive = SimDrive("default")
    proc = popen("-T", "sim?drive=cia402", "--yes", "move", "100", "--relative", "--velocity", "60")
    try:
        wait_until(lambda: not motion_state()["standstill"], "the axis to move")
        fd = os.open(drive.lock_path, os.O_RDWR)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=7.0)  # the tool gives up (exit 3) while the lock is held
        finally:
            os.close(fd)
        code, _, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert code == 3, err
    assert "locked" in err or "answer" in err
    wait_until(lambda: motion_state()["standstill"], "the watchdog to stop the axis", timeout=10)


def test_watchdog_stops_motion_when_the_tool_is_killed(realtime: None) -> None:
    proc = popen("--yes", "jog", "60", "--for", "60s")
    try:
        wait_until(lambda: not motion_state()["standstill"], "the axis to move")
        proc.kill()  # kill -9: no chance to stop the axis
        proc.communicate()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    wait_until(lambda: motion_state()["standstill"], "the drive watchdog to stop the axis", timeout=10)
    code, out, _ = run("status", "--json")
    assert json.loads(out)["status"]["warning"] is True


def test_sim_speed_shows_and_sets(tmp_path: Path) -> None:
    data = ok("sim", "speed", "250", "--watchdog", "2.5")
    assert data["time_scale"] == 250 and data["watchdog_s"] == 2.5
    assert ok("sim", "speed", "--realtime")["time_scale"] == 1
    assert run("sim", "speed", "0")[0] == 2
