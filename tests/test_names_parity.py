"""Parity: ``param set`` and a recipe ``param`` step plan through one rule (drive/names.py) and agree (issue 24).

The same request runs as ``akdctl param set`` and as a one-step recipe on the same simulated drive; the verdict
(written values, or the refusal and its exit code) must be the same.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest


def _recipe(tmp_path: Path, pairs: dict[str, object]) -> str:
    body = ", ".join(f'"{k}" = {json.dumps(v)}' for k, v in pairs.items())
    path = tmp_path / "r.toml"
    path.write_text(f'[recipe]\nname = "parity"\n[[step]]\naction = "param"\nset = {{ {body} }}\n')
    return str(path)


CASES = [
    ({"VL.KP": 0.875, "HOME.MODE": 6}, True, 0),
    ({"MT.P": 1000}, False, 4),              # a set point: needs consent in both
    ({"MT.P": 1000}, True, 0),
    ({"DRV.OPMODE": 9}, True, 2),            # outside the published range
    ({"VL.FB": 1}, True, 2),                 # read-only
    ({"NOT.ANAME": 1}, True, 2),             # unknown name
]


@pytest.mark.parametrize(("pairs", "yes", "code"), CASES)
def test_cli_and_recipe_agree(akd_inproc, tmp_path: Path, pairs: dict[str, object], yes: bool, code: int) -> None:
    consent = ["-y"] if yes else []
    args = [f"{k}={v}" for k, v in pairs.items()]
    cli_code, cli_out, cli_err = akd_inproc(*consent, "--json", "param", "set", *args)
    assert akd_inproc("sim", "reset")[0] == 0
    recipe_code, recipe_out, recipe_err = akd_inproc(*consent, "--json", "commission", _recipe(tmp_path, pairs))
    assert cli_code == code, cli_err
    assert recipe_code == code, recipe_err
    if code == 0:
        written = {w["name"]: w["value"] for w in json.loads(cli_out)["written"]}
        assert written == pairs
        got = json.loads(akd_inproc("--json", "param", "get", *pairs)[1])["parameters"]
        assert {p["name"]: p["value"] for p in got} == pairs   # the recipe wrote what the CLI wrote
    elif code == 2:
        words = cli_err.split("akdctl: error: ")[1].split(" [target")[0].strip()
        assert words.split(";")[0] in recipe_err
