"""Issue 14 (``home --mode 999`` checked before anything is enabled) and 17.14 (``jog --for`` bounded, documented).

The planner (akdctl/drive/motion_plan.py ``check_request``) refuses both before a transport is opened; the
end-to-end tests prove it on the simulated drive's write counter and enabling words.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from akdctl.catalog import objects, pnus
from akdctl.drive.axis.cia402 import Cia402Axis
from akdctl.drive.axis.profidrive import ProfidriveAxis
from akdctl.drive.motion_plan import MAX_JOG_S
from akdctl.protocol.datatypes import get_type
from akdctl.sim.drive import SimDrive
from tests.harness import ROOT, run_akdctl


def test_home_mode_ranges_are_the_catalogue_limits() -> None:
    """One range per field, the catalogue's: PNU 1001's limits, 0x6098's data type."""
    info = pnus.lookup(1001)
    assert info is not None and ProfidriveAxis.HOME_MODE_RANGE == (info.minimum, info.maximum)
    entry = objects.lookup(0x6098, 0)
    assert entry is not None
    kind = get_type(entry.short_type)
    assert Cia402Axis.HOME_MODE_RANGE == (kind.minimum, kind.maximum)


def test_the_jog_maximum_is_documented() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert f"`jog --for` longer than {MAX_JOG_S:g} s" in readme


def _drive() -> tuple[int, int, str]:
    state = SimDrive("default").snapshot()
    motion = state["components"]["motion"]
    return state["writes"], motion["enabling_words"], motion["state"]


@pytest.mark.slow
@pytest.mark.parametrize("target, words", [("sim?drive=profidrive", "HOME.MODE (PNU 1001): expected 0..20"),
                                           ("sim?drive=cia402", "0x6098: expected -128..127")])
def test_home_mode_out_of_range_touches_nothing(target: str, words: str) -> None:
    before = _drive()
    code, _, err = run_akdctl("-T", target, "--yes", "home", "--mode", "999")
    assert code == 2 and "homing mode 999 is out of range" in err and words in err, err
    assert _drive() == before  # no write at all: not enabled, no mode change


@pytest.mark.slow
@pytest.mark.parametrize("duration", ["999999999s", "61s", "2min", "0s"])
def test_jog_duration_beyond_the_maximum_touches_nothing(duration: str) -> None:
    before = _drive()
    code, _, err = run_akdctl("--yes", "jog", "10", "--for", duration)
    assert code == 2 and f"at most {MAX_JOG_S:g} s" in err, err
    assert _drive() == before


def test_the_help_names_the_jog_maximum(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from akdctl.cli.main import cli

    result = CliRunner().invoke(cli, ["jog", "--help"])
    assert f"at most {MAX_JOG_S:g} s" in " ".join(result.output.split())


@pytest.mark.slow
def test_the_profile_bounds_a_timed_jog_below_the_tool_maximum(tmp_path: Path) -> None:
    """17.14 "bound durations by the profile": ``max_jog_duration`` in the profile's limits, exit 4 like every
    profile limit, nothing written."""
    (tmp_path / "akdctl").mkdir()
    (tmp_path / "akdctl" / "config.toml").write_text(
        '[profiles.bench]\ntarget = "sim"\n[profiles.bench.limits]\nmax_jog_duration = 5\n', encoding="utf-8")
    env = {"XDG_CONFIG_HOME": str(tmp_path)}
    before = _drive()
    code, _, err = run_akdctl("--profile", "bench", "--yes", "jog", "10", "--for", "6s", env=env)
    assert code == 4 and "max_jog_duration 5 s" in err, err
    assert _drive() == before
    code, _, err = run_akdctl("--profile", "bench", "--yes", "jog", "10", "--for", "50ms", env=env)
    assert code == 0, err
