"""One resolver of PNU names (issue 22/23: "PNU names a recipe accepts are refused by pnu get").

A recipe accepted ``pnu = "Operating mode"`` while ``akdctl pnu get "Operating mode"`` said "cannot parse PNU
address". Both now go through ``drive/params.parse_pnu_spec``: every catalogue name resolves there, and the
command line and a recipe read the same PNU by it.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from akdctl.catalog.pnus import pnu_table
from akdctl.drive.params import parse_pnu_spec


def test_every_catalogue_name_resolves_to_its_pnu() -> None:
    for number, info in pnu_table().items():
        for spelling in (info.name, info.name.upper(), f"  {info.name.lower()} "):
            spec = parse_pnu_spec(spelling)
            assert spec.pnu == number and spec.subindex == 0, spelling
            assert spec.count == (info.length if info.is_array else 1), spelling


@pytest.mark.slow  # runs the real CLI in subprocesses
def test_pnu_get_and_a_recipe_accept_the_same_names(tmp_path: Path) -> None:
    from tests.harness import run_akdctl

    got = run_akdctl("--json", "pnu", "get", "Operating mode", "Jog v1", "Number list of defined parameters (1)")
    assert got.code == 0, got.err
    assert [p["pnu"] for p in json.loads(got.out)["parameters"]] == [930, 1004, 980]
    mode = json.loads(got.out)["parameters"][0]["values"][0]

    recipe = tmp_path / "r.toml"
    recipe.write_text(f'[[step]]\naction = "expect"\npnu = "Operating mode"\nvalue = {mode}\n'
                      '[[step]]\naction = "set"\npnu = "Jog v1"\nvalue = 200\n')
    assert run_akdctl("--yes", "commission", str(recipe)).code == 0
    assert json.loads(run_akdctl("--json", "pnu", "get", "Jog v1").out)["parameters"][0]["values"] == [200]
    assert run_akdctl("--yes", "pnu", "set", "Jog v1=300").code == 0
