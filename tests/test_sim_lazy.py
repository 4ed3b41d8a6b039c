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


# ---------------------------------------------------------------- the motion component's parts (issue 29, 2nd pass)
from akdctl.sim.motion import PARTS, TASK_TABLE_OBJECTS  # noqa: E402


@pytest.mark.parametrize("name", list(PARTS))
def test_the_part_table_names_each_parts_class_and_fields(name: str) -> None:
    model = DriveModel()
    part = getattr(model.motion, name)
    module, cls, fields = PARTS[name]
    assert (type(part).__module__, type(part).__name__) == (module, cls)
    assert fields == type(part).FIELDS


def test_the_task_table_objects_are_what_the_table_binds() -> None:
    model = DriveModel()
    before = set(model._object_bindings)
    model.motion.tasks
    assert set(model._object_bindings) - before == set(TASK_TABLE_OBJECTS)


def test_reading_the_mode_builds_no_part_of_the_axis() -> None:
    model = DriveModel()
    model.advance(0.1)
    assert model.pnu_read_raw(930, 0, 1) == (0x42, [1])  # profile velocity (0x6060 = 3) is PNU 930 = 1
    assert model.motion._parts == {}
    model.object_read(0x6041, 0)  # the status word asks the axis and the CiA 402 machine
    assert set(model.motion._parts) == {"axis", "cia"}


def _moving_state() -> dict:  # type: ignore[type-arg]
    """A drive jogging at 100 rpm through PNU 1/5 (STW1 enable sequence), saved and reloaded as JSON."""
    model = DriveModel()
    model.pnu_write_raw(1, 0, 0x42, [0x047E])
    model.pnu_write_raw(1, 0, 0x42, [0x047F])
    model.pnu_write_raw(5, 0, 0x42, [0x0555])  # a set point
    model.advance(0.05)
    return json.loads(json.dumps(model.to_state()))


def test_an_axis_never_built_writes_back_its_loaded_state_and_the_revision_stays() -> None:
    state = _moving_state()
    loaded = DriveModel.from_state(state)
    revision = loaded.revision
    assert json.loads(json.dumps(loaded.to_state())) == state  # no part built: the loaded fields, unread
    assert loaded.motion._parts == {}
    loaded.motion.axis, loaded.motion.pd, loaded.motion.cia, loaded.motion.tasks  # noqa: B018 - building is no change
    assert loaded.revision == revision
    assert json.loads(json.dumps(loaded.to_state())) == state


def test_a_moving_axis_loaded_from_its_state_moves_as_the_one_that_saved_it() -> None:
    state = _moving_state()
    assert state["components"]["motion"]["vel"]  # it moves
    eager = DriveModel.from_state(state)
    for name in PARTS:  # every part built at once, as before issue 29
        getattr(eager.motion, name)
    lazy = DriveModel.from_state(state)
    eager.advance(0.2)
    lazy.advance(0.2)  # the tick builds the axis: it has something to integrate
    assert "axis" in lazy.motion._parts
    assert lazy.to_state() == eager.to_state()
    assert lazy.pnu_read_raw(2, 0, 1) == eager.pnu_read_raw(2, 0, 1)


def test_a_resting_axis_is_not_built_by_the_clock() -> None:
    model = DriveModel.from_state(json.loads(json.dumps(DriveModel().to_state())))
    model.advance(1.0)
    assert "axis" not in model.motion._parts
