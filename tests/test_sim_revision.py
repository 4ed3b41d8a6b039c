"""The revision rule (``akdctl/sim/component.py`` ``Tracked``): whatever changes the persisted state bumps a revision.

The store (``sim/drive.py``) saves only when the model's revision moved, so a change that does not bump it would be
lost at the next reload. These tests run every kind of request - scripted (enable, move, home, faults, armed faults,
emergencies, PDO mapping, telegrams, the task table, FoE, the watchdog) and a seeded random walk over every
catalogued PNU and object - and after each one compare ``to_state()`` before and after with the revisions: the
model's and the changed component's. The last test checks the same end to end: after every transaction the state
file holds exactly the model a fresh process would load.
"""

from __future__ import annotations

import json
import os
import random
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from akdctl.sim.component import FieldState, Tracked
from akdctl.sim.drive import SimDrive
from akdctl.sim.model import DriveModel

STEPS = int(os.environ.get("AKDCTL_REVISION_STEPS", "600"))


def _observed(model: DriveModel) -> dict[str, Any]:
    """The persisted state as the file holds it (JSON types), without the virtual clock (never part of the mark)."""
    state = json.loads(json.dumps(model.to_state()))
    state.pop("clock")
    return state


def _checked(model: DriveModel, what: str, action: Callable[[], object]) -> None:
    before, revision = _observed(model), model.revision
    parts = {c.name: c.revision for c in model.components}
    try:
        action()
    except Exception as exc:  # noqa: BLE001 - refused requests are part of the walk; they must follow the rule too
        if type(exc).__name__ not in ("PnuAccessError", "SdoAccessError", "ValueError", "FoeRefused"):
            raise
    after = _observed(model)
    if after == before:
        return
    changed = sorted(k for k in after if after[k] != before.get(k))
    assert model.revision != revision, f"{what} changed {changed} but not the model's revision"
    for comp in model.components:
        if after["components"][comp.name] != before["components"][comp.name]:
            assert comp.revision != parts[comp.name], f"{what} changed component {comp.name!r} without its revision"


def _obj(model: DriveModel, index: int, sub: int, fmt: str, value: int) -> Callable[[], object]:
    return lambda: model.object_write(index, sub, struct.pack(fmt, value))


def _pnu(model: DriveModel, pnu: int, value: int, sub: int = 0) -> Callable[[], object]:
    info = model.pnu_info(pnu)
    return lambda: model.pnu_write_raw(pnu, sub, info.wire_format, [value & ((1 << info.bits) - 1)])


def _script(model: DriveModel) -> list[tuple[str, Callable[[], object]]]:
    """Every kind of state change the simulator knows, in an order that makes each of them happen."""
    faults, pdo, motion = model.faults, model.pdo, model.motion
    tick = lambda dt: (lambda: model.advance(dt))  # noqa: E731
    steps: list[tuple[str, Callable[[], object]]] = [
        ("read statusword", lambda: model.object_read(0x6041, 0)),
        ("read ZSW1", lambda: model.pnu_read_raw(2, 0, 1)),
        ("read a never-written PNU", lambda: model.pnu_read_raw(1005, 0, 1)),
        ("tick at rest", tick(0.5)),
        # CiA 402: enable, profile velocity, profile position, homing
        ("cw shutdown", _obj(model, 0x6040, 0, "<H", 0x06)),
        ("cw switch on", _obj(model, 0x6040, 0, "<H", 0x07)),
        ("cw enable", _obj(model, 0x6040, 0, "<H", 0x0F)),
        ("target velocity", _obj(model, 0x60FF, 0, "<i", 65536)),
        ("tick velocity", tick(0.2)),
        ("read position", lambda: model.object_read(0x6064, 0)),
        ("target velocity 0", _obj(model, 0x60FF, 0, "<i", 0)),
        ("tick to standstill", tick(5.0)),
        ("mode pp", _obj(model, 0x6060, 0, "<b", 1)),
        ("target position", _obj(model, 0x607A, 0, "<i", 3 * 65536)),
        ("cw new set point", _obj(model, 0x6040, 0, "<H", 0x1F)),
        ("tick move", tick(0.05)),
        ("cw halt", _obj(model, 0x6040, 0, "<H", 0x10F)),
        ("tick halt", tick(0.05)),
        ("cw resume", _obj(model, 0x6040, 0, "<H", 0x0F)),
        ("tick to the end", tick(30.0)),
        ("mode homing", _obj(model, 0x6060, 0, "<b", 6)),
        ("homing method", _obj(model, 0x6098, 0, "<b", 19)),
        ("cw start homing", _obj(model, 0x6040, 0, "<H", 0x1F)),
        *[step for i in range(40) for step in ((f"tick homing {i}", tick(0.2)), ("read statusword (feeds the watchdog)",
                                                                                lambda: model.object_read(0x6041, 0)))],
        ("cw disable", _obj(model, 0x6040, 0, "<H", 0x06)),
        ("tick stop", tick(5.0)),
        ("quick stop code", _obj(model, 0x605A, 0, "<h", 6)),
        # PROFIdrive: opmode, STW1 enable, jog, traversing task, watchdog
        ("opmode position", _pnu(model, 930, 2)),
        ("stw1 off", _pnu(model, 1, 0x047E)),
        ("stw1 on", _pnu(model, 1, 0x047F)),
        ("stw1 jog", _pnu(model, 1, 0x057F)),
        ("tick jog", tick(0.2)),
        ("tick past the watchdog", tick(5.0)),
        ("stw1 task", _pnu(model, 1, 0x047F | 0x40)),
        ("tick task", tick(0.1)),
        ("stw1 reject", _pnu(model, 1, 0x046F)),
        ("tick reject", tick(10.0)),
        ("opmode velocity", _pnu(model, 930, 1)),
        ("nsoll", _pnu(model, 5, 0x1000)),
        ("tick velocity", tick(0.2)),
        ("stw1 off again", _pnu(model, 1, 0x047E)),
        ("tick off", tick(10.0)),
        ("watchdog setting", lambda: setattr(motion, "watchdog_s", 2.0)),
        # faults, warnings, armed faults, emergencies, the error field
        ("raise F501", lambda: faults.raise_fault("F501")),
        ("raise n503", lambda: faults.raise_fault("n503")),
        ("raise persisting F502", lambda: faults.raise_fault("F502", persist=True)),
        ("arm F503", lambda: faults.arm("F503", 2)),
        ("read 947", lambda: model.pnu_read_raw(947, 0, 8)),
        ("read 944", lambda: model.pnu_read_raw(944, 0, 1)),
        ("read 947 again", lambda: model.pnu_read_raw(947, 0, 8)),
        ("take emergencies", lambda: faults.take_emergencies()),
        ("take no emergencies", lambda: faults.take_emergencies()),
        ("acknowledge by STW1", _pnu(model, 1, 0x04FE)),
        ("acknowledge by controlword", _obj(model, 0x6040, 0, "<H", 0x80)),
        ("clear causes", lambda: faults.clear_causes()),
        ("clear the error field", _obj(model, 0x1003, 0, "<B", 0)),
        ("clear a warning", lambda: faults.clear_warning("n503")),
        # PDO mapping and assignment (PRE-OP), AL state, telegrams
        ("rx assign 0", _obj(model, 0x1C12, 0, "<B", 0)),
        ("mapping 0", _obj(model, 0x1600, 0, "<B", 0)),
        ("mapping entry", _obj(model, 0x1600, 1, "<I", 0x60400010)),
        ("mapping entry 2", _obj(model, 0x1600, 2, "<I", 0x607A0020)),
        ("mapping count", _obj(model, 0x1600, 0, "<B", 2)),
        ("rx assign entry", _obj(model, 0x1C12, 1, "<H", 0x1600)),
        ("rx assign count", _obj(model, 0x1C12, 0, "<B", 1)),
        ("AL OP", lambda: pdo.set_al_state("OP")),
        ("AL PREOP", lambda: pdo.set_al_state("PREOP")),
        ("telegram free", _pnu(model, 922, 0)),
        ("free words", _pnu(model, 915, 1, 0)),
        ("telegram 7", _pnu(model, 922, 7)),
        ("cycle time", _obj(model, 0x60C2, 1, "<B", 4)),
        # the motion task table (MT.NUM, MT.SET, MT.LOAD)
        ("MT.NUM", _obj(model, 0x365B, 0, "<I", 5)),
        ("MT.P", _obj(model, 0x607A, 0, "<i", 65536)),
        ("MT.V", _obj(model, 0x6081, 0, "<I", 1000000)),
        ("MT.SET", _obj(model, 0x3431, 0, "<H", 1)),
        ("MT.NUM 1", _obj(model, 0x365B, 0, "<I", 1)),
        ("MT.LOAD", _obj(model, 0x3432, 0, "<H", 1)),
        # files, stored values
        ("FoE write", lambda: model.foe_write("notes.txt", 0, b"hello")),
        ("FoE overwrite", lambda: model.foe_write("notes.txt", 0, b"hello again")),
        ("stored PNU", lambda: model.set_stored_pnu(1005, [7])),
        ("stored object", lambda: model.set_stored_object(0x2032, 0, b"abc")),
        ("string object", lambda: model.object_write(0x2032, 0, b"x" * 100)),
    ]
    return steps


def test_every_scripted_change_bumps_a_revision() -> None:
    model = DriveModel()
    for what, action in _script(model):
        _checked(model, what, action)


def _random_steps(model: DriveModel, rng: random.Random, count: int) -> list[tuple[str, Callable[[], object]]]:
    """Writes of random values to every writable PNU and object, reads of everything, ticks of random length."""
    from akdctl.catalog import objects as object_catalog
    from akdctl.catalog import pnus as pnu_catalog

    writable = [e for e in object_catalog.entries().values() if e.access in ("rw", "wo")]
    readable = [e for e in object_catalog.entries().values() if e.access in ("rw", "ro")]
    pnus = list(pnu_catalog.pnu_table().values())
    favourites = [(0x6040, 0, 2, [0x06, 0x07, 0x0F, 0x1F, 0x80, 0x0B]), (0x6060, 0, 1, [1, 3, 4, 6, 7, 8])]
    steps: list[tuple[str, Callable[[], object]]] = []
    for _ in range(count):
        kind = rng.random()
        if kind < 0.3:
            entry = rng.choice(writable)
            size = entry.bits // 8 if entry.bits % 8 == 0 and entry.bits else rng.randint(0, 12)
            data = rng.randbytes(size)
            steps.append((f"write 0x{entry.index:04X}:{entry.subindex} = {data.hex()}",
                          lambda e=entry, d=data: model.object_write(e.index, e.subindex, d)))
        elif kind < 0.45:
            index, sub, size, values = rng.choice(favourites)
            value = rng.choice(values)
            steps.append((f"write 0x{index:04X} = {value}",
                          lambda i=index, s=sub, n=size, v=value: model.object_write(i, s, v.to_bytes(n, "little"))))
        elif kind < 0.65:
            info = rng.choice(pnus)
            sub = rng.randrange(info.length)
            value = rng.getrandbits(info.bits)
            steps.append((f"write PNU {info.pnu}[{sub}] = {value}",
                          lambda i=info, s=sub, v=value: model.pnu_write_raw(i.pnu, s, i.wire_format, [v])))
        elif kind < 0.75:
            entry = rng.choice(readable)
            steps.append((f"read 0x{entry.index:04X}:{entry.subindex}",
                          lambda e=entry: model.object_read(e.index, e.subindex)))
        elif kind < 0.85:
            info = rng.choice(pnus)
            steps.append((f"read PNU {info.pnu}", lambda i=info: model.pnu_read_raw(i.pnu, 0, i.length)))
        elif kind < 0.9:
            code = rng.choice(["F501", "F502", "n503", "F401"])
            steps.append((f"raise {code}", lambda c=code: model.faults.raise_fault(c, persist=rng.random() < 0.3)))
        else:
            dt = rng.choice([0.001, 0.05, 0.5, 3.0, 60.0])
            steps.append((f"tick {dt}", lambda t=dt: model.advance(t)))
    return steps


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_random_walk_over_every_pnu_and_object_bumps_a_revision_for_each_change(seed: int) -> None:
    model = DriveModel()
    rng = random.Random(seed)
    for what, action in _random_steps(model, rng, STEPS):
        _checked(model, what, action)


def test_an_in_place_change_without_changed_is_caught() -> None:
    """The check is not vacuous: a component that edits a list in place and forgets ``changed()`` is named."""
    model = DriveModel()
    with pytest.raises(AssertionError, match="'faults' without its revision|not the model's revision"):
        _checked(model, "a forgetful change", lambda: model.faults.warnings.append(503))
    before, own = model.revision, model.faults.revision
    model.faults.warnings = [503, 504]  # an assignment to a persisted attribute counts by itself
    assert model.revision == before + 1 and model.faults.revision == own + 1


def test_fields_count_real_changes_only() -> None:
    class Part(FieldState):
        FIELDS = ("a", "b")

    class Owner(Tracked):
        def _model_of(self) -> None:
            return None

    owner = Owner()
    part = Part(owner)
    part.a, part.b = 0.0, None
    first = owner.revision
    part.a = 0.0  # the same value again (a tick at rest)
    part.b = None
    part.other = 5  # not persisted
    assert owner.revision == first
    part.a = 1.5
    assert part.revision == 3 and owner.revision == first + 1


def test_every_transaction_leaves_the_file_as_the_model_is(tmp_path: Path) -> None:
    """End to end through the store: after each transaction a fresh process loads exactly the held model."""
    drive = SimDrive("rev", tmp_path)
    rng = random.Random(7)
    with drive.transaction() as model:
        steps = _script(model) + _random_steps(model, rng, STEPS // 3)
    for what, action in steps:
        with drive.transaction(advance=False) as model:
            # the steps were built over the first model; a held model is the same object unless reloaded
            try:
                action()
            except Exception as exc:  # noqa: BLE001 - refused requests are part of the walk
                if type(exc).__name__ not in ("PnuAccessError", "SdoAccessError", "ValueError", "FoeRefused"):
                    raise
            held = _observed(model)
        fresh = SimDrive("rev", tmp_path)
        with fresh.transaction(advance=False) as loaded:
            assert _observed(loaded) == held, f"{what}: the state file misses a change"
        fresh.close()
    drive.close()
