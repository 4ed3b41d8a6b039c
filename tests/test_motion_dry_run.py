"""``--dry-run`` of the motion commands: the one planner's plan in words, nothing asked, owned, written or moved.

The dry run is the plan the real command then asks consent for and executes (README "Safety model"): run from the
same state, its JSON plan equals the plan the real command reports, and a refusal is the same refusal.
"""

from __future__ import annotations

import json

import pytest

from akdctl.sim.drive import SimDrive

CIA402 = "sim?drive=cia402"


def _ok(akd_inproc, *args: str) -> dict:
    code, out, err = akd_inproc("--json", *args)
    assert code == 0, (args, code, err)
    return json.loads(out)


def _drive() -> dict:
    """The simulated drive's state as written to it: its write counter, PNUs, objects and names (not its clock)."""
    snapshot = SimDrive("default").snapshot()
    return {key: snapshot[key] for key in ("writes", "pnus", "objects", "named")}


@pytest.mark.parametrize("argv", [
    ("move", "1.5"),
    ("move", "-90", "--relative", "--units", "deg"),
    ("jog", "100", "--for", "1s"),
    ("jog", "-50", "--distance", "0.25"),
    ("home", "--mode", "0"),
    ("enable",),
], ids=" ".join)
def test_the_dry_run_is_the_plan_the_command_runs(akd_inproc, argv: tuple[str, ...]) -> None:
    _ok(akd_inproc, "sim", "speed", "100000")
    _ok(akd_inproc, "--yes", "home", "--mode", "0")
    before = _drive()
    dry = _ok(akd_inproc, *argv, "--dry-run")
    assert dry["dry_run"] is True and dry["target"] == "sim"
    assert _drive() == before                                # nothing written: not a mode, not an enable
    code, out, err = akd_inproc(*argv, "--dry-run")          # the words, and no consent asked (no --yes, no tty)
    assert code == 0 and "(dry run, nothing written)" in out and f"{argv[0]} on sim:" in out, err
    ran = _ok(akd_inproc, "--yes", *argv)
    assert ran["plan"] == dry["plan"]


def test_a_refusal_is_the_same_refusal(akd_inproc) -> None:
    """A fault present refuses in the planner (README "Refusals in words"): the dry run refuses in the same words;
    a homed state visible only in the motion's mode is read after consent, and the dry run says so."""
    _ok(akd_inproc, "sim", "fault", "F501")
    dry = akd_inproc("-T", CIA402, "move", "0.5", "--relative", "--dry-run")
    ran = akd_inproc("-T", CIA402, "--yes", "move", "0.5", "--relative")
    assert dry[0] == ran[0] == 4 and "F501" in dry[2] and dry[2] == ran[2]
    _ok(akd_inproc, "--yes", "fault", "ack")
    code, out, err = akd_inproc("-T", CIA402, "move", "1", "--dry-run")
    assert code == 0 and "homed: read after consent, in the motion's mode" in out, err


def test_task_start_dry_run_names_the_stored_task_and_moves_nothing(akd_inproc) -> None:
    """The stored task is read (through MT.LOAD, the working parameters saved and written back: its note says so)
    and shown as it will run; the axis does not move and the drive stays in its mode."""
    _ok(akd_inproc, "sim", "speed", "100000")
    _ok(akd_inproc, "--yes", "home", "--mode", "0")
    status = _ok(akd_inproc, "status")["status"]
    dry = _ok(akd_inproc, "task", "start", "4", "--dry-run")["plan"]
    assert "motion task 4" in dry["what"] and "to 5 rev" in dry["what"] and any("MT.LOAD" in n for n in dry["notes"])
    after = _ok(akd_inproc, "status")["status"]
    assert (after["position_rev"], after["mode"], after["enabled"]) == \
        (status["position_rev"], status["mode"], status["enabled"])
