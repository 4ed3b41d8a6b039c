"""Parity: every motion step gives the same verdict as a CLI command and as a recipe step (one planner).

For each case the same request runs as ``akdctl --yes <command>`` and as a one-step recipe on a fresh
simulated drive in the same starting state; the verdict — accepted, or refused with the planner's words —
must be the same. (Exit codes differ only where the recipe format says so: a refusal found while
validating a recipe is "recipe invalid", exit 2, with FILE:LINE.)
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.harness import run_akdctl, run_akdctl_inproc

pytestmark = pytest.mark.slow  # runs the real CLI in subprocesses

ROOT = Path(__file__).resolve().parent.parent


def run(*args: str) -> tuple[int, str, str]:
    code, out, err = run_akdctl(*args, timeout=60)
    return code, out, err


def _core(err: str) -> str:
    """The planner's sentence from the command's one error line (without the target suffix)."""
    line = next(ln for ln in err.splitlines() if ln.startswith("akdctl: error:"))
    return line.removeprefix("akdctl: error: ").split(" [target ")[0]


def _toml(value: object) -> str:
    return "true" if value is True else "false" if value is False else json.dumps(value)


# (name, CLI args, recipe step keys, profile, limits config, home first)
CASES = [
    ("move absolute", ["move", "1.5"], {"action": "move", "target": 1.5}, "profidrive", "", True),
    ("move relative deg", ["move", "-90", "--relative", "--units", "deg"],
     {"action": "move", "target": -90, "unit": "deg", "relative": True}, "cia402", "", True),
    ("move unhomed pd", ["move", "1"], {"action": "move", "target": 1}, "profidrive", "", False),
    ("move unhomed pd relative", ["move", "1", "--relative"], {"action": "move", "target": 1, "relative": True},
     "profidrive", "", False),
    ("move unhomed cia", ["move", "1"], {"action": "move", "target": 1}, "cia402", "", False),
    ("move relative unhomed cia", ["move", "0.5", "--relative"], {"action": "move", "target": 0.5, "relative": True},
     "cia402", "", False),
    ("velocity wraps", ["move", "0.2", "--relative", "--velocity", "20000"],
     {"action": "move", "target": 0.2, "relative": True, "velocity": 20000}, "profidrive", "", True),
    ("accel unrepresentable", ["move", "1", "--relative", "--accel", "100"],
     {"action": "move", "target": 1, "relative": True, "accel": 100}, "profidrive", "", True),
    ("accel limit", ["move", "1", "--accel", "3000"], {"action": "move", "target": 1, "accel": 3000}, "cia402",
     "max_acceleration = 2000\n", True),
    ("velocity limit", ["move", "1", "--velocity", "500"], {"action": "move", "target": 1, "velocity": 500},
     "cia402", "max_velocity = 300\n", True),
    ("travel absolute", ["move", "3"], {"action": "move", "target": 3}, "profidrive", "travel = [-2.0, 2.0]\n", True),
    ("travel relative", ["move", "2.5", "--relative"], {"action": "move", "target": 2.5, "relative": True},
     "cia402", "travel = [-2.0, 2.0]\n", True),
    ("user units", ["move", "5", "--units", "user"], {"action": "move", "target": 5, "unit": "user"}, "profidrive",
     "", True),
    ("home", ["home", "--mode", "0"], {"action": "home", "mode": 0}, "profidrive", "", False),
    ("home mode range", ["home", "--mode", "99"], {"action": "home", "mode": 99}, "profidrive", "", False),
    ("home cia no method", ["home"], {"action": "home"}, "cia402", "", False),
    ("enable", ["enable"], {"action": "enable"}, "cia402", "", False),
]


def _prepare(target: str, home: bool, profile: str) -> None:
    """The starting state, set in this process: only the two runs compared are the CLI under test (subprocesses)."""
    assert run_akdctl_inproc("sim", "reset")[0] == 0
    assert run_akdctl_inproc("sim", "speed", "100000")[0] == 0
    if home:
        home_run = run_akdctl_inproc("-T", target, "--yes", "home", "--mode", "0" if profile == "profidrive" else "35")
        assert home_run.code == 0, home_run.err


@pytest.mark.parametrize("name, cli, step, profile, limits, home", CASES, ids=[c[0] for c in CASES])
def test_cli_and_recipe_give_the_same_verdict(tmp_path: Path, name: str, cli: list[str], step: dict[str, object],
                                              profile: str, limits: str, home: bool) -> None:
    cfg = tmp_path / "akd.toml"
    cfg.write_text('default_profile = "b"\n[profiles.b]\ntarget = "sim"\n[profiles.b.units]\nper_rev = 5.0\n'
                   + (f"[profiles.b.limits]\n{limits}" if limits else ""))
    target = f"sim?drive={profile}"
    common = ["--config", str(cfg), "-T", target, "--yes"]
    _prepare(target, home, profile)
    cli_code, _, cli_err = run(*common, *cli)
    recipe = tmp_path / "step.toml"
    recipe.write_text("[[step]]\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in step.items()))
    _prepare(target, home, profile)
    rec_code, _, rec_err = run(*common, "commission", str(recipe))
    assert (cli_code == 0) == (rec_code == 0), (name, cli_code, cli_err, rec_code, rec_err)
    if cli_code != 0:
        assert _core(cli_err) in rec_err, (name, cli_err, rec_err)
        assert rec_code in (cli_code, 2), (name, cli_code, rec_code)
