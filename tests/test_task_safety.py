"""Issue 23 item 6: tasks follow the planner's rules at set time and at start time, the `task start` consent
names the target and the speed, and reading the table is never a motion (no consent; the working set points
it overwrites are restored; refused while the axis moves). In process against the simulator (akd_inproc)."""

from __future__ import annotations

import json
from pathlib import Path

from akdctl.sim.drive import SimDrive


def _ok(akd_inproc, *args: str) -> dict:
    code, out, err = akd_inproc("--json", *args)
    assert code == 0, (args, code, err)
    return json.loads(out)


def _writes() -> int:
    return SimDrive("default").snapshot()["writes"]


def _limits(tmp_path: Path, body: str) -> list[str]:
    cfg = tmp_path / "akd.toml"
    cfg.write_text('[profiles.bench]\ntarget = "sim"\n[profiles.bench.limits]\n' + body)
    return ["--config", str(cfg), "--profile", "bench"]


def test_set_refuses_what_move_would_refuse(akd_inproc, tmp_path: Path) -> None:
    before = _writes()
    code, _, err = akd_inproc("--yes", "task", "set", "5", "--position", "1", "--velocity", "20000", "--accel",
                              "2000")
    assert code == 2 and "motion task 5" in err and "MDI_VELOCITY" in err, err        # as `move --velocity 20000`
    move = akd_inproc("--yes", "move", "1", "--relative", "--velocity", "20000")
    assert move[0] == 2 and "MDI_VELOCITY" in move[2]
    t = _limits(tmp_path, "max_velocity = 300\nmax_acceleration = 1000\ntravel = [-3.0, 3.0]\n")
    for args, words in ((["--velocity", "500", "--accel", "500"], "max_velocity 300"),
                        (["--velocity", "100", "--accel", "2000"], "max_acceleration 1000"),
                        (["--velocity", "100", "--accel", "500", "--position", "4"], "travel")):
        position = [] if "--position" in args else ["--position", "1"]
        code, _, err = akd_inproc(*t, "--yes", "task", "set", "5", *position, *args)
        assert code == 4 and words in err and "motion task 5" in err, (args, err)
    assert _writes() == before


def test_start_holds_a_stored_task_to_the_same_rules(akd_inproc, tmp_path: Path) -> None:
    """A task stored before the limits existed is refused at start with the words `task set` would use."""
    _ok(akd_inproc, "sim", "speed", "100000")
    _ok(akd_inproc, "--yes", "home", "--mode", "0")
    _ok(akd_inproc, "--yes", "task", "set", "6", "--position", "1", "--velocity", "600", "--accel", "5000")
    t = _limits(tmp_path, "max_velocity = 300\n")
    at_set = akd_inproc(*t, "--yes", "task", "set", "6", "--position", "1", "--velocity", "600", "--accel", "5000")
    at_start = akd_inproc(*t, "--yes", "task", "start", "6")
    assert at_set[0] == at_start[0] == 4
    assert "motion task 6" in at_start[2] and "max_velocity 300" in at_start[2]
    assert _ok(akd_inproc, "status")["status"]["position_rev"] == 0.0


def test_start_consent_names_the_target_and_the_speed(akd_inproc) -> None:
    _ok(akd_inproc, "sim", "speed", "100000")
    _ok(akd_inproc, "--yes", "home", "--mode", "0")
    code, _, err = akd_inproc("task", "start", "4")          # no terminal, no --yes: the refusal shows the consent
    assert code == 4 and "to 5 rev" in err and "1200 rpm" in err, err
    dry = _ok(akd_inproc, "--yes", "task", "start", "4")
    assert "1200 rpm" in dry["plan"]["what"]


def test_reading_the_table_is_never_a_motion(akd_inproc) -> None:
    _ok(akd_inproc, "sim", "speed", "100000")
    _ok(akd_inproc, "-T", "sim?drive=cia402", "--yes", "sdo", "write", "0x607A:0", "12345")
    _ok(akd_inproc, "--yes", "enable")
    # no --yes and no terminal: a read asks nothing
    shown = _ok(akd_inproc, "task", "show", "4")
    assert shown["position_rev"] == 5.0 and "wrote them back" in shown["note"]
    assert _ok(akd_inproc, "task", "list")["tasks"]
    back = _ok(akd_inproc, "sdo", "read", "0x607A:0")
    assert back["value"] == 12345, back                       # the working target position as it was


def test_reading_the_table_of_a_moving_axis_is_refused(akd_inproc) -> None:
    _ok(akd_inproc, "sim", "speed", "1")
    _ok(akd_inproc, "--yes", "home", "--mode", "0")
    _ok(akd_inproc, "--yes", "move", "50", "--velocity", "60", "--no-wait")
    code, _, err = akd_inproc("task", "list")
    assert code == 4 and "the axis is moving" in err, err
    akd_inproc("stop")


def test_set_dry_run_shows_the_plan_and_writes_nothing(akd_inproc) -> None:
    before = _writes()
    plan = _ok(akd_inproc, "task", "set", "5", "--position", "1", "--velocity", "300", "--accel", "2000",
               "--dry-run")["plan"]
    assert [w["address"] for w in plan["writes"]][-1] == "0x3431:0 (MT.SET)"
    assert any("MT.P" in text for text in plan["needs_consent"])      # set points: consent, as before
    assert _writes() == before
