"""Parity: every writing operation plans the same from the command line and from a recipe step (issue 22).

For each case the same request runs as ``akdctl <command> --dry-run --json`` (the plan, nothing written) and as
a one-step recipe on a fresh simulated drive in the same starting state, whose report carries the plan its step
executed. The writes (address, value, raw bytes, the gate's verdict), the preconditions, the read-back flag and
what needs consent must be equal; and without ``--yes`` both refuse (exit 4) exactly when the plan needs consent.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from tests.harness import run_akdctl, run_akdctl_inproc

pytestmark = pytest.mark.slow  # runs the real CLI in subprocesses

ENABLE = ("enable",)
PROFIDRIVE, CIA402 = "sim?drive=profidrive", "sim?drive=cia402"


def _toml(value: object) -> str:
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {_toml(v)}" for k, v in value.items()) + " }"
    return "true" if value is True else "false" if value is False else json.dumps(value)


def _prepare(target: str, steps: tuple[tuple[str, ...], ...]) -> None:
    """The starting state, set in this process: only the runs compared are the CLI under test (subprocesses)."""
    assert run_akdctl_inproc("sim", "reset").code == 0
    for step in steps:
        result = run_akdctl_inproc("-T", target, "--yes", *step)
        assert result.code == 0, (step, result.err)


def _essence(plan: dict[str, Any]) -> dict[str, Any]:
    return {key: plan[key] for key in ("operation", "writes", "preconditions", "verify", "needs_consent")}


# (name, target, preparation, CLI args, recipe step)
CASES: list[tuple[str, str, tuple[tuple[str, ...], ...], list[str], dict[str, Any]]] = [
    ("pnu set plain", PROFIDRIVE, (), ["pnu", "set", "1002=16", "--verify"],
     {"action": "set", "pnu": 1002, "value": 16}),
    ("pnu set by name", PROFIDRIVE, (), ["pnu", "set", "Homing mode=0", "--verify"],
     {"action": "set", "pnu": "Homing mode", "value": 0}),
    ("pnu set gated set point", PROFIDRIVE, (), ["pnu", "set", "1004=-500", "1005=500", "--verify"],
     {"action": "set", "pnus": {"1004": -500, "1005": 500}}),
    ("pnu set mode while enabled", PROFIDRIVE, (ENABLE,), ["pnu", "set", "930=1", "--verify"],
     {"action": "set", "pnu": 930, "value": 1}),
    ("pnu set mode while disabled", PROFIDRIVE, (), ["pnu", "set", "930=1", "--verify"],
     {"action": "set", "pnu": 930, "value": 1}),
    ("sdo write plain", CIA402, (), ["sdo", "write", "0x2031:0", "vs", "axis-1", "--verify"],
     {"action": "set", "object": "0x2031:0", "value": "axis-1"}),
    ("sdo write set point", CIA402, (), ["sdo", "write", "0x6081:0", "1000", "--verify"],
     {"action": "set", "object": "0x6081:0", "value": 1000}),
    ("sdo write mode while enabled", CIA402, (ENABLE,), ["sdo", "write", "0x6060:0", "3", "--verify"],
     {"action": "set", "object": "0x6060:0", "value": 3}),
    ("telegram set", PROFIDRIVE, (), ["telegram", "set", "9"], {"action": "telegram", "telegram": 9}),
    ("telegram set while enabled", PROFIDRIVE, (ENABLE,), ["telegram", "set", "1"],
     {"action": "telegram", "telegram": 1}),
    ("telegram map", PROFIDRIVE, (("telegram", "set", "0"),), ["telegram", "map", "--setpoint", "1,5",
                                                              "--actual", "2,6,52"],
     {"action": "map", "setpoint": ["STW1", "NSOLL_A"], "actual": ["2", "6", "52"]}),
    ("pdo map fixed", CIA402, (), ["pdo", "map", "--rx", "0x1701", "--tx", "0x1B20"],
     {"action": "map", "rx": ["0x1701"], "tx": ["0x1B20"]}),
    ("pdo map flexible with mode", CIA402, (), ["pdo", "map", "--rx", "0x1600=0x6040:0/16,0x60C1:1/32",
                                                "--tx", "0x1A00=0x6041:0/16,0x6063:0/32", "--opmode", "csp"],
     {"action": "map", "rx": ["0x1600=0x6040:0/16,0x60C1:1/32"], "tx": ["0x1A00=0x6041:0/16,0x6063:0/32"],
      "opmode": "csp"}),
    ("pdo map while enabled", CIA402, (ENABLE,), ["pdo", "map", "--rx", "0x1701", "--tx", "0x1B20"],
     {"action": "map", "rx": ["0x1701"], "tx": ["0x1B20"]}),
]


def _recipe_plan(tmp_path: Path, target: str, step: dict[str, Any], *, yes: bool) -> tuple[int, dict[str, Any], str]:
    recipe = tmp_path / "step.toml"
    recipe.write_text("[[step]]\n" + "".join(f"{k} = {_toml(v)}\n" for k, v in step.items()))
    result = run_akdctl("-T", target, *(["--yes"] if yes else []), "--json", "commission", str(recipe))
    if result.code != 0 or not yes:
        return result.code, {}, result.err
    report = json.loads(result.out)
    return result.code, report["steps"][0]["details"]["plan"], result.err


@pytest.mark.parametrize("name, target, prep, cli, step", CASES, ids=[c[0] for c in CASES])
def test_cli_and_recipe_plan_the_same_writes(tmp_path: Path, name: str, target: str,
                                             prep: tuple[tuple[str, ...], ...], cli: list[str],
                                             step: dict[str, Any]) -> None:
    _prepare(target, prep)
    dry = run_akdctl("-T", target, "--json", *cli, "--dry-run")
    assert dry.code == 0, dry.err
    document = json.loads(dry.out)
    cli_plan = document.get("write_plan", document["plan"])  # pdo map keeps "plan" for its mapping
    _prepare(target, prep)
    code, recipe_plan, err = _recipe_plan(tmp_path, target, step, yes=True)
    assert code == 0, err
    assert _essence(cli_plan) == _essence(recipe_plan), name

    # The consent the plan names is the one both ask for: without --yes (no terminal) both refuse, or both run.
    _prepare(target, prep)
    cli_run = run_akdctl("-T", target, *cli)
    _prepare(target, prep)
    rec_code, _, rec_err = _recipe_plan(tmp_path, target, step, yes=False)
    expected = 4 if cli_plan["needs_consent"] else 0
    assert (cli_run.code, rec_code) == (expected, expected), (name, cli_run.err, rec_err)


def test_params_restore_plans_the_same_from_the_command_and_a_recipe(tmp_path: Path) -> None:
    backup = tmp_path / "axis.toml"
    assert run_akdctl("sim", "reset").code == 0
    made = run_akdctl("-T", PROFIDRIVE, "params", "backup", "-o", str(backup), "--only", "930,1004,1001")
    assert made.code == 0, made.err
    change = (("pnu", "set", "930=2", "1004=-500", "1001=3"),)

    _prepare(PROFIDRIVE, change)
    dry = run_akdctl("-T", PROFIDRIVE, "--json", "params", "restore", str(backup), "--dry-run")
    assert dry.code == 0, dry.err
    cli_plan = json.loads(dry.out)["plan"]
    assert sorted(w["address"].split()[0] for w in cli_plan["writes"]) == ["1001", "1004", "930"]

    _prepare(PROFIDRIVE, change)
    code, recipe_plan, err = _recipe_plan(tmp_path, PROFIDRIVE, {"action": "restore", "file": "axis.toml"}, yes=True)
    assert code == 0, err
    assert _essence(cli_plan) == _essence(recipe_plan)
