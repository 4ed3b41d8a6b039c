"""``akdctl task list|show|set|start`` through the real CLI (issue 16 item 2), in process against the simulator.

``004`` 5.10 "Position Mode": "The motion tasks, which are configured by MT parameters in AKD, can be
accessed"; 5.10.1 "Submode Program mode": "The Program mode can be used to start/switch to a specific predefined
motion task via I/O messaging ... For addressing the motion task signal SATZANW is used"; Requirements: S4,
position mode, telegram 7 (docs/fidelity.md F9), homed, "Motion task needs to be configured". The table is read
and written through the AKD's CoE objects (docs/fidelity.md F11); ``task start`` takes the one planner and consent
of ``move``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from akdctl.sim.drive import SimDrive


def _ok(akd_inproc, *args: str) -> dict:
    code, out, err = akd_inproc("--json", *args)
    assert code == 0, (args, code, err)
    return json.loads(out)


def _writes() -> int:
    return SimDrive("default").snapshot()["writes"]


def test_the_simulators_table_is_visible(akd_inproc) -> None:
    tasks = {t["task"]: t for t in _ok(akd_inproc, "task", "list")["tasks"]}
    assert sorted(tasks) == [1, 2, 3, 4]                                   # the simulator's starting table
    assert tasks[4]["position_rev"] == 5.0 and not tasks[4]["relative"] and tasks[4]["velocity_rpm"] == 1200
    assert tasks[1]["relative"] and tasks[1]["position_rev"] == 1.0
    assert _ok(akd_inproc, "task", "show", "2")["position_rev"] == -1.0
    assert not _ok(akd_inproc, "task", "show", "9")["configured"]


def test_set_stores_a_task_through_mt_set(akd_inproc) -> None:
    stored = _ok(akd_inproc, "--yes", "task", "set", "7", "--position", "2.5", "--velocity", "300",
                 "--accel", "2000", "--relative")
    assert stored["configured"] and stored["relative"] and stored["position_rev"] == 2.5
    assert stored["velocity_rpm"] == pytest.approx(300, abs=1e-3) and stored["raw"]["velocity"] == 327680
    assert 7 in [t["task"] for t in _ok(akd_inproc, "task", "list")["tasks"]]
    with SimDrive("default").transaction() as model:                       # the simulator's own table holds it
        assert model.motion.tasks.get(7)["position"] == 2.5


def test_set_needs_consent_and_writes_nothing_without_it(akd_inproc) -> None:
    before = _writes()
    code, _, err = akd_inproc("task", "set", "7", "--position", "1", "--velocity", "60", "--accel", "100")
    assert code == 4 and "MT.P" in err and "nothing was written" in err
    assert _writes() == before


def test_start_runs_the_task_in_program_mode(akd_inproc) -> None:
    """5.10.1 "Start a motion task": SATZANW, STW1 bits 4/5, bit 6 edge; "after the target position is reached,
    ZSW 1 Bit 10 is set". akdctl selects telegram 7 first when the drive has telegram 1 (docs/fidelity.md F9)."""
    _ok(akd_inproc, "sim", "speed", "100000")
    _ok(akd_inproc, "--yes", "home", "--mode", "0")
    _ok(akd_inproc, "--yes", "task", "set", "6", "--position", "-2", "--velocity", "600", "--accel", "5000")
    result = _ok(akd_inproc, "--yes", "task", "start", "6")
    assert "telegram 7" in result["plan"]["mode"] and "motion task 6" in result["plan"]["what"]
    status = result["status"]
    assert status["position_rev"] == -2.0 and status["target_reached"] and status["standstill"]
    assert _ok(akd_inproc, "telegram", "show")["telegram"] == 7
    assert _ok(akd_inproc, "pnu", "get", "33")["parameters"][0]["values"] == [6]   # AKTSATZ


def test_start_refuses_like_move(akd_inproc, tmp_path: Path) -> None:
    """The planner's rules: consent, homed (5.10.1 "Axis needs to be homed"), a configured task, the profile's
    limits as the stored task would execute them - all before the axis moves."""
    _ok(akd_inproc, "sim", "speed", "100000")
    code, _, err = akd_inproc("task", "start", "4")
    assert code == 4 and "consent" in err                                   # no terminal, no --yes
    code, _, err = akd_inproc("--yes", "task", "start", "4")
    assert code == 4 and "not homed" in err
    _ok(akd_inproc, "--yes", "home", "--mode", "0")
    code, _, err = akd_inproc("--yes", "task", "start", "9")
    assert code == 4 and "not configured" in err
    assert akd_inproc("--yes", "task", "start", "200")[0] == 2
    cfg = tmp_path / "akd.toml"
    cfg.write_text('[profiles.bench]\ntarget = "sim"\n[profiles.bench.limits]\nmax_velocity = 1000\n'
                   'travel = [-3.0, 3.0]\n')
    t = ["--config", str(cfg), "--profile", "bench", "--yes"]
    code, _, err = akd_inproc(*t, "task", "start", "4")                   # 1200 rpm > 1000
    assert code == 4 and "max_velocity" in err and "motion task 4" in err
    _ok(akd_inproc, "--yes", "task", "set", "8", "--position", "4", "--velocity", "600", "--accel", "5000")
    code, _, err = akd_inproc(*t, "task", "start", "8")                   # ends at 4 rev > travel 3
    assert code == 4 and "travel" in err
    assert _ok(akd_inproc, "status")["status"]["position_rev"] == 0.0      # nothing moved


def test_start_is_refused_on_cia402_with_the_reason(akd_inproc) -> None:
    code, _, err = akd_inproc("-T", "sim?drive=cia402", "--yes", "task", "start", "4")
    assert code == 2 and "documents no way to start a stored motion task" in err


@pytest.mark.slow
def test_over_profinet_start_works_and_the_table_says_why_not() -> None:
    """pn:// has only the parameter channel: the PROFINET manuals give the table no PNU (F11), so list refuses with
    the reason; start runs (no profile limits to check)."""
    from tests.harness import SimServer, run_akdctl

    assert run_akdctl("sim", "speed", "100000").code == 0
    assert run_akdctl("--yes", "home", "--mode", "0").code == 0
    with SimServer("--profinet", "127.0.0.1:0") as server:
        target = ["-T", f"pn://{server.host}:{server.port}"]
        code, _, err = run_akdctl(*target, "task", "list")
        assert code == 2 and "no parameter for the motion task table" in err
        code, out, err = run_akdctl(*target, "--json", "--yes", "task", "start", "3")
        assert code == 0, err
        assert json.loads(out)["status"]["position_rev"] == 0.0 and json.loads(out)["status"]["target_reached"]
