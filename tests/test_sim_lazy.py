"""The simulated drive builds its rarely used components on first use (issue 29, cold start): the index that finds a
lazy component's owner of a PNU or object must match what the component binds, a read that builds one never
rewrites the state file, and a component never built writes back the state it was loaded with."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from akdctl.sim import model as model_module
from akdctl.sim.drive import SimDrive, SimStateError
from akdctl.sim.model import LAZY, LAZY_OBJECTS, LAZY_PNUS, DriveModel


@pytest.mark.parametrize("name", list(LAZY))
def test_the_owner_index_matches_what_each_lazy_component_binds(name: str) -> None:
    model = DriveModel()
    pnus, objects = set(model._pnu_bindings), set(model._object_bindings)
    model.component(name)
    bound_pnus = set(model._pnu_bindings) - pnus
    bound_objects = set(model._object_bindings) - objects
    assert bound_pnus == {p for p, owner in LAZY_PNUS.items() if owner == name}
    assert bound_objects == {i for i, owner in LAZY_OBJECTS.items() if owner == name}


def test_the_eager_components_bind_nothing_the_index_gives_to_a_lazy_one() -> None:
    model = DriveModel()
    assert not set(model._pnu_bindings) & set(LAZY_PNUS)
    assert not set(model._object_bindings) & set(LAZY_OBJECTS)


def test_an_axis_read_builds_neither_the_pdo_mapping_nor_the_files() -> None:
    model = DriveModel()
    model.advance(0.1)
    model.pnu_read_raw(930, 0, 1)
    model.object_read(0x6041, 0)
    assert set(model._built) <= {"motion", "faults"}  # the axis' tick and status word look at the faults
    model.pnu_read_raw(922, 0, 1)  # the telegram: the PDO component's
    assert "pdo" in model._built and "foe" not in model._built


@pytest.mark.parametrize("access", [
    lambda m: m.pnu_read_raw(944, 0, 1),
    lambda m: m.object_read(0x1C12, 0),
    lambda m: m.object_read(0x1A00, 1),
    lambda m: m.object_read(0x1001, 0),
    lambda m: m.faults.fault_present,
    lambda m: m.foe.files,
])
def test_building_a_component_from_its_loaded_state_is_no_change(access) -> None:  # type: ignore[no-untyped-def]
    model = DriveModel()
    model.pnu_write_raw(922, 0, 0x42, [7])  # telegram 7: the PDO state differs from the factory's
    state = json.loads(json.dumps(model.to_state()))
    loaded = DriveModel.from_state(state)
    revision = loaded.revision
    access(loaded)
    assert loaded.revision == revision
    assert json.loads(json.dumps(loaded.to_state())) == state


def test_a_component_never_built_writes_back_what_it_was_loaded_with() -> None:
    model = DriveModel()
    model.pnu_write_raw(922, 0, 0x42, [7])
    state = json.loads(json.dumps(model.to_state()))
    state["components"]["foe"] = {"files": {"a.bin": "AAEC"}}
    loaded = DriveModel.from_state(state)
    loaded.pnu_read_raw(930, 0, 1)
    assert "pdo" not in loaded._built and "foe" not in loaded._built
    assert loaded.to_state()["components"]["pdo"] == state["components"]["pdo"]
    assert loaded.to_state()["components"]["foe"] == {"files": {"a.bin": "AAEC"}}
    assert loaded.foe.read("a.bin") == b"\x00\x01\x02"


def test_a_damaged_lazy_component_is_reported_corrupt_when_first_used(isolated_env: Path) -> None:
    drive = SimDrive("default")
    drive.reset()
    state = json.loads(drive.path.read_text())
    state["components"]["pdo"]["telegram"] = "seven"
    state["components"]["pdo"]["assign"] = 5
    drive.path.write_text(json.dumps(state))
    fresh = SimDrive("default")
    try:
        with fresh.transaction() as model:  # the axis alone still works
            model.pnu_read_raw(930, 0, 1)
        with pytest.raises(SimStateError, match="corrupt.*pdo"), fresh.transaction() as model:
            model.pnu_read_raw(922, 0, 1)
        with pytest.raises(SimStateError, match="corrupt.*pdo"):  # also where a server turns it into a refusal
            fresh.handle_bmp(bytes.fromhex("01 01 00 01 10 01 03 9A 00 00"))
    finally:
        fresh.close()


@pytest.mark.slow
def test_the_model_module_imports_no_lazy_component() -> None:
    import subprocess
    import sys

    code = ("import sys, akdctl.sim.model as m; m.DriveModel().pnu_read_raw(930, 0, 1); "
            "print(sorted(k for k in sys.modules if k in ('akdctl.sim.pdo', 'akdctl.sim.foe', 'dataclasses')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True)
    assert out.stdout.strip() == "[]", out.stdout
    assert model_module.LAZY  # the table is the module's
