"""Issue 13, one test per row of its table, through the real CLI (subprocesses, stdin not a terminal).

Each test checks the exit code, the message, and what the simulated drive saw: its write counter
(``writes``), the control words with "enable operation" it received (``enabling_words``), or that the
axis ended at standstill. Rulings relied on: SPEC-NOTES 13 (MDI/NSOLL scalings), 23 (controlword owned by
process data in OP).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from akdctl.sim.drive import SimDrive
from tests.harness import start_akdctl
from test_motion_cli import fast, finish, ok, realtime, run, wait_until  # noqa: F401 (fixtures)

pytestmark = pytest.mark.slow  # runs the real CLI in subprocesses

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "commission-sim.toml"


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT))
    return env


def popen(*args: str, ignore_sigint: bool = False) -> subprocess.Popen[str]:
    return start_akdctl(*args, ignore_sigint=ignore_sigint)  # tests/harness.py: the one way to start akdctl


def sim() -> dict:
    """writes, enabling control words, and the axis's motion state of the default simulated drive."""
    state = SimDrive("default").snapshot()
    motion = state["components"]["motion"]
    return {"writes": state["writes"], "enabling": motion["enabling_words"], "state": motion["state"],
            "mode": motion["mode"], "standstill": abs(motion["vel"]) < 1e-9 and motion["gen"] is None,
            "pos": motion["pos"]}


def config(tmp_path: Path, body: str) -> list[str]:
    path = tmp_path / "akd.toml"
    path.write_text('default_profile = "bench"\n[profiles.bench]\ntarget = "sim"\n' + body)
    return ["--config", str(path)]


def recipe(tmp_path: Path, steps: str) -> str:
    path = tmp_path / "r.toml"
    path.write_text('[recipe]\nname = "row"\n\n' + steps)
    return str(path)


# ---------------------------------------------------------------- row 1: MDI_VELOCITY full scale
def test_row1_velocity_beyond_mdi_full_scale_is_refused_not_wrapped(fast: None, tmp_path: Path) -> None:
    """SPEC-NOTES 13: MDI_VELOCITY is X4 with 2^32 = 12000 rpm; 20000 rpm would wrap to 8000."""
    ok("--yes", "home", "--mode", "0")
    before = sim()
    code, _, err = run("--yes", "move", "0.2", "--relative", "--velocity", "20000")
    assert code == 2, err
    assert "MDI_VELOCITY" in err and "largest representable value is 11999.99" in err
    path = recipe(tmp_path, '[[step]]\naction = "move"\ntarget = 0.2\nrelative = true\nvelocity = 20000\n')
    code, _, err = run("--yes", "commission", path)
    assert code == 2 and "MDI_VELOCITY" in err and "r.toml:8" in err, err
    assert sim()["writes"] == before["writes"]


# ---------------------------------------------------------------- row 2: MDI_ACC X2 scaling
def test_row2_acceleration_is_checked_as_the_drive_executes_it(fast: None, tmp_path: Path) -> None:
    """SPEC-NOTES 13: MDI_ACC is X2 with x = 16 (2^16 = 50,000,000 rpm/s): one step is 762.94 rpm/s."""
    t = config(tmp_path, "[profiles.bench.limits]\nmax_acceleration = 500\n")
    ok(*t, "--yes", "home", "--mode", "0")
    before = sim()
    code, _, err = run(*t, "--yes", "move", "1", "--relative", "--accel", "100")
    assert code == 2 and "MDI_ACC" in err and "762.939" in err, err
    code, _, err = run(*t, "--yes", "move", "1", "--relative")  # the default, capped at 500, is not representable
    assert code == 2 and "762.939" in err, err
    code, _, err = run(*t, "--yes", "move", "1", "--relative", "--accel", "800")
    assert code == 4 and "max_acceleration 500" in err, err
    assert sim()["writes"] == before["writes"]
    # Representable, within the limit: executed exactly as planned, and said so in the JSON plan.
    t2 = config(tmp_path, "[profiles.bench.limits]\nmax_acceleration = 800\n")
    data = ok(*t2, "--yes", "move", "1", "--relative", "--accel", "770")
    assert data["plan"]["accel"]["raw"] == 1 and data["plan"]["accel"]["executed"] == pytest.approx(762.939453)


# ---------------------------------------------------------------- row 3: raw writes of control word / set points
def test_row3_raw_control_word_and_set_point_writes_need_consent(fast: None) -> None:
    before = sim()
    code, _, err = run("pnu", "set", "5=8000", "1=0x047F")
    assert code == 4 and "PNU 1 (STW1)" in err and "--yes" in err and "nothing was written" in err, err
    code, _, err = run("sdo", "write", "0x60FF:0", "1000")
    assert code == 4 and "0x60FF:0" in err, err
    code, _, err = run("sdo", "write", "0x6040:0", "15")
    assert code == 4 and "0x6040:0 (Controlword)" in err, err
    after = sim()
    assert after["writes"] == before["writes"] and after["enabling"] == before["enabling"] and after["standstill"]
    # Not gated: a mode change of a disabled drive; gated once the drive is enabled.
    assert run("pnu", "set", "930=2")[0] == 0
    ok("--yes", "enable")
    code, _, err = run("pnu", "set", "930=1")
    assert code == 4 and "operating mode of an enabled drive" in err, err
    before = sim()
    for args in (["telegram", "set", "7"], ["sdo", "write", "0x1C12:0", "0"], ["pdo", "map", "--rx", "0x1701"]):
        code, _, err = run(*args)
        assert code == 4 and "mapping of an enabled drive" in err, (args, err)
    assert sim()["writes"] == before["writes"]


def test_enable_commands_no_motion_even_with_a_loaded_set_point(fast: None) -> None:
    """CiA 402 profile velocity follows 0x60FF once enabled: enable must hold it (halt) — "no motion commanded"."""
    ok("-T", "sim?drive=cia402", "--yes", "sdo", "write", "0x60FF:0", "100000")
    status = ok("-T", "sim?drive=cia402", "--yes", "enable")["status"]
    assert status["enabled"] and status["mode"] == 3
    time.sleep(0.2)
    assert sim()["standstill"]


# ---------------------------------------------------------------- row 4: recipe vs CLI homed rule on CiA 402
def test_row4_recipe_move_on_unhomed_cia402_is_refused_like_the_command(fast: None, tmp_path: Path) -> None:
    path = recipe(tmp_path, '[[step]]\naction = "enable"\n\n[[step]]\naction = "move"\ntarget = 1\n')
    code, out, err = run("-T", "sim?drive=cia402", "--yes", "--json", "commission", path)
    assert code == 4 and "not homed" in err, err
    assert json.loads(out)["result"] == "failed"
    code, _, err = run("-T", "sim?drive=cia402", "--yes", "move", "1")
    assert code == 4 and "not homed" in err
    state = sim()
    assert state["standstill"] and state["pos"] == 0.0


# ---------------------------------------------------------------- row 5: signals in commission and motion commands
def test_row5_sigterm_during_commission_stops_disables_and_reports_interrupted(realtime: None,
                                                                               tmp_path: Path) -> None:
    path = recipe(tmp_path, '[[step]]\naction = "home"\nmode = 0\n\n'
                            '[[step]]\naction = "move"\ntarget = 100\nvelocity = 60\n')
    report = tmp_path / "report.json"
    proc = popen("--yes", "commission", path, "--report", str(report))
    wait_until(lambda: not sim()["standstill"], "the axis to move")
    proc.send_signal(signal.SIGTERM)
    code, _, err = finish(proc)
    assert code == 128 + signal.SIGTERM, err
    assert "SIGTERM" in err and "interrupted" in err
    data = json.loads(report.read_text())
    assert data["result"] == "interrupted" and data["exit_code"] == 143
    assert "disabled" in data["safe_state"]
    state = sim()
    assert state["standstill"] and state["state"] in ("ready", "switch_on_disabled")  # power stage off


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGHUP])
def test_row5_signal_stops_a_jog_also_when_sigint_was_inherited_ignored(realtime: None, sig: int) -> None:
    proc = popen("--yes", "jog", "60", "--for", "60s", ignore_sigint=True)
    wait_until(lambda: not sim()["standstill"], "the axis to move")
    proc.send_signal(sig)
    code, _, err = finish(proc)
    assert code == 128 + sig, err
    assert "interrupted" in err and "stopped" in err
    assert sim()["standstill"]


# ---------------------------------------------------------------- row 6: NaN/inf on the command line
@pytest.mark.parametrize("args", [["move", "nan"], ["move", "inf", "--relative"], ["jog", "100", "--distance", "inf"],
                                  ["jog", "nan", "--for", "1s"], ["move", "1", "--velocity", "nan"],
                                  ["jog", "60", "--for", "1s", "--accel", "-inf"], ["home", "--timeout", "nan"]])
def test_row6_nan_and_inf_exit_2_before_anything_is_written(fast: None, args: list[str]) -> None:
    before = sim()
    code, _, err = run("--yes", *args)
    assert code == 2, err
    assert "finite" in err or "must be" in err
    assert "internal error" not in err
    after = sim()
    assert after["writes"] == before["writes"] and after["enabling"] == before["enabling"]


# ---------------------------------------------------------------- row 7: config validated on load
@pytest.mark.parametrize("body, words", [
    ("[profiles.bench.limits]\nmax_velocty = 10\n", "profiles.bench.limits.max_velocty: unknown key; did you mean "
                                                    "'max_velocity'?"),
    ("[profiles.bench.limits]\nmax_velocity = nan\n", "profiles.bench.limits.max_velocity: must be a finite number"),
    ("[profiles.bench.units]\nper_rev = -5\n", "profiles.bench.units.per_rev: must be greater than 0"),
    ('[profiles.bench.limits]\nmax_velocity = "fast"\n', "profiles.bench.limits.max_velocity: must be a number"),
    ("[profiles.bench.limits]\ntravel = [2.0, -2.0]\n", "profiles.bench.limits.travel: min 2 must be less than"),
])
def test_row7_config_mistakes_exit_2_naming_file_profile_and_key(fast: None, tmp_path: Path, body: str,
                                                                 words: str) -> None:
    t = config(tmp_path, body)
    before = sim()
    code, _, err = run(*t, "--yes", "move", "1", "--relative")
    assert code == 2 and words in err and "akd.toml" in err, err
    assert sim()["writes"] == before["writes"]


# ---------------------------------------------------------------- row 9: --no-wait is honest
def test_row9_no_wait_says_what_stops_the_move(fast: None) -> None:
    ok("--yes", "home", "--mode", "0")
    code, out, err = run("--yes", "--json", "move", "5", "--velocity", "60", "--no-wait")
    assert code == 0, err
    assert "watchdog" in err and "watchdog" in json.loads(out)["note"]


# ---------------------------------------------------------------- row 10: recipe channels against the target
@pytest.mark.parametrize("dry", [True, False])
def test_row10_recipe_channels_checked_against_the_target(dry: bool) -> None:
    before = sim()
    started = time.monotonic()
    code, _, err = run("-T", "pn://127.0.0.1", "--yes", "commission", *(["--dry-run"] if dry else []), str(EXAMPLE))
    assert code == 2, err
    assert "step 5 (map)" in err and "object channel" in err and "pn://127.0.0.1" in err
    assert "nothing was written" in err
    assert time.monotonic() - started < 20  # refused at validation, not after a connection timeout
    assert sim()["writes"] == before["writes"]


# ---------------------------------------------------------------- row 11: unhomed PROFIdrive move
def test_row11_unhomed_profidrive_move_refused_with_a_true_hint_and_mode_unchanged(fast: None) -> None:
    mode = sim()["mode"]
    for args in (["move", "1"], ["move", "1", "--relative"]):
        code, _, err = run("-T", "sim?drive=profidrive", "--yes", *args)
        assert code == 4 and "not homed" in err and "--relative" not in err and "akdctl home" in err, err
    after = sim()
    assert after["mode"] == mode and after["enabling"] == 0 and after["state"] == "switch_on_disabled"
