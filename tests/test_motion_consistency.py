"""Issue 23 item 22, the motion part: one spelling of durations, one rendering of homed, an interrupted CiA 402
move that leaves nothing held (the PROFIdrive view of the same drive says standstill), "axis stopped" said once."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import pytest

from akdctl.sim.drive import SimDrive
from tests.harness import finish, run_akdctl_inproc, wait_until
from tests.harness import run_akdctl as run
from tests.harness import start_akdctl as popen

pytestmark = pytest.mark.slow


def _moving() -> bool:
    with SimDrive("default").transaction() as model:
        return not model.component("motion").standstill


@pytest.mark.parametrize("argv", [["--timeout", "2s", "status"], ["status", "--timeout", "500ms"],
                                  ["-y", "home", "--mode", "0", "--max-time", "30s"],
                                  ["-y", "home", "--mode", "0", "--timeout", "1m"],
                                  ["-y", "jog", "10", "--for", "200ms"]])
def test_durations_are_spelled_one_way(argv: list[str]) -> None:
    assert run_akdctl_inproc("sim", "speed", "100000").code == 0  # set-up, in-process
    result = run(*argv)
    assert result.code == 0, result.err


def test_homed_is_rendered_once_as_yes() -> None:
    assert run_akdctl_inproc("sim", "speed", "100000").code == 0  # set-up, in-process
    out = run("-y", "home", "--mode", "0").out
    assert [line.split() for line in out.splitlines() if line.split()[:1] == ["homed"]] == [["homed", "yes"]], out


def test_an_interrupted_cia402_move_holds_nothing_and_both_views_say_standstill() -> None:
    assert run_akdctl_inproc("sim", "speed", "--realtime").code == 0
    assert run("-T", "sim?drive=cia402", "-y", "home", "--mode", "35").code == 0
    proc = popen("-T", "sim?drive=cia402", "-y", "move", "10", "--velocity", "60")
    wait_until(_moving, "the move to start")
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    result = finish(proc)
    assert result.code == 130 and "axis stopped" in result.err, result.err
    import json

    pd = json.loads(run("-T", "sim?drive=profidrive", "--json", "status").out)["status"]
    cia = json.loads(run("-T", "sim?drive=cia402", "--json", "status").out)["status"]
    assert pd["standstill"] and cia["standstill"] and pd["velocity_rpm"] == 0.0
    assert not cia["control"] & 0x100            # no halt left that a later controlword would lift
    time.sleep(0.5)
    again = json.loads(run("-T", "sim?drive=cia402", "--json", "status").out)["status"]
    assert again["position_rev"] == cia["position_rev"]          # nothing resumed the interrupted move


def test_an_interrupted_commission_says_axis_stopped_once(tmp_path: Path) -> None:
    recipe = tmp_path / "r.toml"
    recipe.write_text('[recipe]\nname = "x"\n\n[[step]]\naction = "home"\nmode = 0\n\n'
                      '[[step]]\naction = "move"\ntarget = 100\nvelocity = 60\n')
    assert run_akdctl_inproc("sim", "speed", "--realtime").code == 0
    proc = popen("-y", "commission", str(recipe))
    wait_until(_moving, "the recipe's move to start", timeout=30)
    time.sleep(0.3)
    proc.send_signal(signal.SIGTERM)
    result = finish(proc)
    line = next(ln for ln in result.err.splitlines() if ln.startswith("akdctl: error:"))
    assert line.count("axis stopped") == 1, line
