"""The recipe's ``scope`` step: the same request and plan as ``akdctl scope`` (CLI-recipe parity), consent for a
recorded jog, files below the output directory, and bounds that fail with exit 5."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from akdctl.errors import EXIT_CHECK, EXIT_SAFETY, EXIT_USAGE

STEP = """
[recipe]
name = "scope"

[[step]]
action = "scope"
signals = ["VL.FB", "PL.ERR"]
jog = 600
jog_for = 0.4
{extra}
"""


def _recipe(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "r.toml"
    path.write_text(STEP.format(extra=extra))
    return path


def test_cli_and_recipe_build_the_same_request_and_plan() -> None:
    from akdctl.connection import Connection
    from akdctl.drive import scope as op
    from akdctl.recipe.loader import RawStep
    from akdctl.recipe.schema import Context, validate_step
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.target import split_target

    conn = Connection(split_target("sim"), LinkOptions())
    raw = RawStep({"action": "scope", "signals": ["VL.FB", "PL.ERR"], "jog": 300, "jog_for": 0.5, "rate": 50,
                   "trigger": "rise:VL.FB:100", "pretrigger": 10}, Path("r.toml"), 4, number=1)
    step = validate_step(raw, Context(folder=Path("."), conn=conn))
    cli = op.build_request(["VL.FB", "PL.ERR"], rate_hz=50, trigger="rise:VL.FB:100", pretrigger=10, jog_rpm=300,
                           jog_s=0.5)
    assert step.params["request"] == cli and step.motion
    recipe_plan, cli_plan = op.plan(conn, step.params["request"]), op.plan(conn, cli)
    assert recipe_plan.to_json() == cli_plan.to_json()
    assert recipe_plan.data["motion"].to_json() == cli_plan.data["motion"].to_json()
    conn.close()


def test_a_recipe_records_a_jog_and_checks_its_bounds(akd_inproc, tmp_path: Path) -> None:
    recipe = _recipe(tmp_path, 'max_following_error = 0.05\nmax_settle_time = 1.0\nsettle_band = 0.001\n'
                               'csv = "jog.csv"\nsvg = "jog.svg"\njson = "jog.json"')
    out_dir, report = tmp_path / "out", tmp_path / "report.json"
    code, _out, err = akd_inproc("-y", "commission", str(recipe), "--output-dir", str(out_dir), "--report", str(report))
    assert code == 0, err
    details = json.loads(report.read_text())["steps"][0]["details"]
    assert 0 < details["measured"]["following_error_max"] <= 0.05
    assert 0 < details["measured"]["settle_time"] <= 1.0
    assert (out_dir / "jog.csv").read_text().startswith("# akdctl scope:")
    assert "<svg" in (out_dir / "jog.svg").read_text()
    assert json.loads((out_dir / "jog.json").read_text())["events"]["jog_end"] > 0


def test_a_broken_bound_fails_the_recipe_with_exit_5(akd_inproc, tmp_path: Path) -> None:
    recipe = _recipe(tmp_path, "max_following_error = 0.0001")
    code, out, err = akd_inproc("-y", "commission", str(recipe), "--output-dir", str(tmp_path / "o"))
    assert code == EXIT_CHECK and "following error reached" in out + err


def test_a_recorded_jog_needs_consent(akd_inproc, tmp_path: Path) -> None:
    code, _out, err = akd_inproc("commission", str(_recipe(tmp_path)))
    assert code == EXIT_SAFETY and "nothing was written" in err


@pytest.mark.parametrize("extra, words", [
    ("max_settle_time = 1.0", "settle band"),
    ('csv = "../x.csv"', "below the output directory"),
    ('trigger = "sideways"', "trigger"),
    ("max_following_error = 1\nsamples = 1", "--samples"),
])
def test_bad_scope_steps_are_refused_before_anything_runs(akd_inproc, tmp_path: Path, extra: str,
                                                           words: str) -> None:
    code, _out, err = akd_inproc("commission", str(_recipe(tmp_path, extra)), "--dry-run")
    assert code == EXIT_USAGE and words in err
