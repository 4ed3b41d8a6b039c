"""Every broken recipe is rejected with file, line and what was expected — and no write reaches the sim."""

from __future__ import annotations

from pathlib import Path

import pytest

from akdctl.errors import EXIT_OK, EXIT_SAFETY, EXIT_USAGE


def writes() -> int:
    from akdctl.sim.drive import SimDrive

    return int(SimDrive("default").snapshot().get("writes", 0))


@pytest.fixture
def primed(akd_inproc) -> int:
    """A sim that has seen one write, so 'unchanged' is a real comparison."""
    assert akd_inproc("pnu", "set", "1001=3")[0] == EXIT_OK  # not a gated address (akdctl.drive.gate)
    return writes()


GOOD_FIRST = '[recipe]\nname = "t"\n\n[[step]]\naction = "set"\npnu = "930"\nvalue = 2\n\n'

CASES = [
    # (recipe text after a good first step, expected "file:line" line number, words in the message)
    ('[[step]]\naction = "fly"\n', 10, "unknown action 'fly'"),
    ('[[step]]\naction = "set"\npnu = "9999"\nvalue = 1\n', 11, "unknown PNU 9999"),
    ('[[step]]\naction = "set"\nobject = "0x7777:0"\nvalue = 1\n', 11, "unknown object 0x7777:0"),
    ('[[step]]\naction = "set"\nobject = "0x6060:9"\nvalue = 1\n', 11, "unknown subindex 0x6060:9"),
    ('[[step]]\naction = "set"\npnu = "930"\nvalue = "fast"\n', 12, "takes integers"),
    ('[[step]]\naction = "set"\nobject = "0x6060:0"\nvalue = 1.5\n', 12, "takes an integer"),
    ('[[step]]\naction = "set"\npnu = "930"\nvalue = 7\n', 12, "is outside 0..2"),
    ('[[step]]\naction = "set"\nobject = "0x6060:0"\nvalue = 300\n', 12, "out of range"),
    ('[[step]]\naction = "set"\npnu = "930"\n', 9, "missing key 'value'"),
    ('[[step]]\naction = "move"\nvelocity = 10\n', 9, "missing key 'target'"),
    ('[[step]]\nname = "no action"\n', 9, "missing key 'action'"),
    ('[[step]]\naction = "set"\npnu = "930"\nvalue = 1\ncolour = "red"\n', 13, "unknown key 'colour'"),
    ('[[step]]\naction = "set"\npnu = "964"\nvalue = [1]\n', 11, "read-only"),
    ('[[step]]\naction = "set"\npnu = "STW1"\nvalue = 1151\n', 11, "never written by a set step"),
    ('[[step]]\naction = "set"\nobject = "0x6040:0"\nvalue = 15\n', 11, "never written by a set step"),
    ('[[step]]\naction = "telegram"\ntelegram = 4\n', 11, "telegram 4 is not one the AKD offers"),
    ('[[step]]\naction = "wait"\nseconds = "long"\n', 11, "'seconds' must be an integer or a number"),
    ('[[step]]\naction = "wait"\nseconds = 99999\n', 11, "at most 3600"),
    ('[[step]]\naction = "move"\ntarget = 1\nunit = "furlong"\n', 12, "'unit' 'furlong'"),
    ('[[step]]\naction = "map"\nrx = ["0x1704"]\n', 11, "0x1704 is not a PDO of the AKD"),
    ('[[step]]\naction = "map"\nrx = ["0x1600=0x6040:0/16,0x607A:0/32,0x60FF:0/32"]\n', 11, "at most 8"),
    ('[[step]]\naction = "map"\nsetpoint = ["ZSW1"]\n', 11, "actual signal"),
    ('[[step]]\naction = "expect"\npnu = "930"\n', 9, "give 'value'"),
    ('[[step]]\naction = "restore"\nfile = "missing.toml"\n', 11, "no such file"),
    ('[[step]]\naction = "restore"\nfile = "../outside.toml"\n', 11, "outside the recipe's folder"),
    ('[[step]]\naction = "include"\nfile = "../outside.toml"\n', 11, "outside the recipe's folder"),
    ('[[step]]\naction = "include"\nfile = "nothere.toml"\n', 11, "no such recipe file"),
    ('[[step]]\naction = "backup"\nfile = "/etc/backup.toml"\n', 11, "relative path"),
    ('[[step]]\naction = "backup"\nfile = "b.txt"\n', 11, ".toml or .json"),
    ('[[step]]\naction = "set"\nrun = "rm -rf /"\n', 11, "unknown key 'run'"),
    ('[extra]\nshell = "ls"\n', 9, "unknown top-level key 'extra'"),
    ('[[step]]\naction = "set"\npnu = "930"\nvalue = 2\n[[step]\n', 13, "not valid TOML"),
]


@pytest.mark.parametrize("tail, line, words", CASES, ids=[c[2][:40] for c in CASES])
def test_broken_recipe_rejected_precisely_without_writes(akd_inproc, tmp_path: Path, primed: int,
                                                         tail: str, line: int, words: str) -> None:
    folder = tmp_path / "recipes"
    folder.mkdir()
    (tmp_path / "outside.toml").write_text('[[step]]\naction = "save"\n')
    recipe = folder / "broken.toml"
    recipe.write_text(GOOD_FIRST + tail)
    code, out, err = akd_inproc("--yes", "commission", str(recipe))
    assert code == EXIT_USAGE, err
    first = [ln for ln in err.splitlines() if ln.startswith("akdctl: error:")]
    assert len(first) == 1 and "Traceback" not in err
    assert "nothing was written" in first[0]
    assert f"broken.toml:{line}:" in err, err
    assert words in err, err
    assert writes() == primed  # the good first step was not run either


def test_every_problem_is_listed(akd_inproc, tmp_path: Path, primed: int) -> None:
    recipe = tmp_path / "r.toml"
    recipe.write_text('[[step]]\naction = "fly"\n\n[[step]]\naction = "set"\npnu = "9999"\nvalue = 1\n')
    code, _, err = akd_inproc("commission", str(recipe))
    assert code == EXIT_USAGE
    assert "r.toml:2: step 1 (fly)" in err and "r.toml:6: step 2 (set): unknown PNU 9999" in err
    assert "(and 1 more problem)" in err
    assert writes() == primed


def test_wrong_files(akd_inproc, tmp_path: Path, primed: int) -> None:
    code, _, err = akd_inproc("commission", str(tmp_path / "nope.toml"))
    assert code == EXIT_USAGE and "no such recipe file" in err
    other = tmp_path / "recipe.yaml"
    other.write_text("steps: []\n")
    code, _, err = akd_inproc("commission", str(other))
    assert code == EXIT_USAGE and "a recipe is a .toml file" in err
    empty = tmp_path / "empty.toml"
    empty.write_text('[recipe]\nname = "x"\n')
    code, _, err = akd_inproc("commission", str(empty))
    assert code == EXIT_USAGE and "no steps" in err
    binary = tmp_path / "bin.toml"
    binary.write_bytes(b"\xff\xfe\x00\x01")
    code, _, err = akd_inproc("commission", str(binary))
    assert code == EXIT_USAGE and "not a text file" in err
    good = tmp_path / "good.toml"
    good.write_text(GOOD_FIRST)
    code, _, err = akd_inproc("commission", str(good), "--report", str(tmp_path / "r.html"))
    assert code == EXIT_USAGE and ".json" in err
    assert writes() == primed


def test_include_inside_folder_and_outside_with_option(akd_inproc, tmp_path: Path, primed: int) -> None:
    folder = tmp_path / "recipes"
    (folder / "parts").mkdir(parents=True)
    (folder / "parts" / "mode.toml").write_text('[[step]]\naction = "set"\npnu = "930"\nvalue = 2\n')
    (tmp_path / "shared.toml").write_text('[[step]]\naction = "expect"\npnu = "930"\nvalue = 2\n')
    recipe = folder / "main.toml"
    recipe.write_text('[[step]]\naction = "include"\nfile = "parts/mode.toml"\n\n'
                      '[[step]]\naction = "include"\nfile = "../shared.toml"\n')
    code, _, err = akd_inproc("commission", str(recipe))
    assert code == EXIT_USAGE and "outside the recipe's folder" in err
    assert writes() == primed
    code, out, err = akd_inproc("commission", "--allow-outside-includes", str(recipe))
    assert code == EXIT_OK, err
    assert "mode.toml" not in err


def test_include_loop_is_rejected(akd_inproc, tmp_path: Path) -> None:
    (tmp_path / "a.toml").write_text('[[step]]\naction = "include"\nfile = "b.toml"\n')
    (tmp_path / "b.toml").write_text('[[step]]\naction = "include"\nfile = "a.toml"\n')
    code, _, err = akd_inproc("commission", str(tmp_path / "a.toml"))
    assert code == EXIT_USAGE and "include loop" in err


def test_profile_limits_are_checked_before_anything_is_written(akd_inproc, tmp_path: Path, primed: int,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    config = tmp_path / "config.toml"
    config.write_text('default_profile = "bench"\n[profiles.bench]\ntarget = "sim"\n'
                      '[profiles.bench.limits]\nmax_velocity = 100\ntravel = [-3.0, 3.0]\n')
    recipe = tmp_path / "fast.toml"
    recipe.write_text(GOOD_FIRST + '[[step]]\naction = "move"\ntarget = 1\nvelocity = 500\n')
    code, _, err = akd_inproc("--config", str(config), "--yes", "commission", str(recipe))
    assert code == EXIT_USAGE and "exceeds the profile's max_velocity 100 rpm" in err and "fast.toml:12" in err
    recipe.write_text(GOOD_FIRST + '[[step]]\naction = "move"\ntarget = 10\nvelocity = 50\n')
    code, _, err = akd_inproc("--config", str(config), "--yes", "commission", str(recipe))
    assert code == EXIT_USAGE and "outside the profile's travel" in err
    assert writes() == primed


def test_motion_without_consent_is_refused_before_any_write(akd, tmp_path: Path, primed: int) -> None:
    recipe = tmp_path / "m.toml"
    recipe.write_text(GOOD_FIRST + '[[step]]\naction = "enable"\n')
    code, _, err = akd("commission", str(recipe))  # subprocess: stdin is not a TTY
    assert code == EXIT_SAFETY
    assert "--yes" in err
    assert writes() == primed


def test_dry_run_prints_the_plan_and_touches_nothing(akd_inproc, tmp_path: Path, primed: int) -> None:
    import json

    root = Path(__file__).resolve().parent.parent
    code, out, err = akd_inproc("--json", "commission", "--dry-run", str(root / "examples" / "commission-sim.toml"),
                                "--report", str(tmp_path / "plan.xml"))
    assert code == EXIT_OK, err
    data = json.loads(out)
    assert data["result"] == "planned" and data["counts"]["planned"] == len(data["steps"])
    assert {s["action"] for s in data["steps"]} >= {"set", "telegram", "map", "enable", "home", "move",
                                                   "check_faults", "backup"}
    assert (tmp_path / "plan.xml").exists()
    assert writes() == primed
