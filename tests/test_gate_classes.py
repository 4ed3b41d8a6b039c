"""Issue 23 item 1: the write gate classifies by the catalogue's classes, so every address of one AKD parameter
(CoE object, PNU, CIP Parameter instance, AKD name) gets one verdict, and manufacturer objects that select a mode
or carry a set point (DRV.OPMODE 0x35B4, target current 0x2071) are gated like the CiA 402 ones.

The unit tests walk the whole catalogue; the CLI tests run `pnu set`, `sdo write`, `cip set`, `eip param run` and
recipe `set` steps on an enabled simulated drive without a terminal: a gated write is exit 4 and the drive's write
counter does not move.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from akdctl.catalog import objects, pnus
from akdctl.drive import gate
from akdctl.protocol import cip
from akdctl.sim.drive import SimDrive
from tests.harness import run_akdctl as run
from tests.harness import (
    run_akdctl_inproc as prepare,  # set-up runs in-process: no cold start
)


def test_every_address_of_one_akd_name_has_one_class() -> None:
    """An AKD name reached as CoE objects and PNUs is classified alike everywhere (the class is the name's)."""
    by_name: dict[str, set[str | None]] = {}
    for entry in objects.entries().values():
        if entry.param and entry.writable and not objects.is_pdo_communication(entry.index):
            g = gate.classify_object(entry.index, entry.subindex)
            by_name.setdefault(entry.param.upper(), set()).add(g.write_class if g else None)
    for info in pnus.pnu_table().values():
        if info.akd_parameter and info.access == "rw":
            g = gate.classify_pnu(info.pnu)
            by_name.setdefault(info.akd_parameter.upper(), set()).add(g.write_class if g else None)
    for name, classes in by_name.items():
        g = gate.classify_name(name)
        assert classes == {g.write_class if g else None}, name


@pytest.mark.parametrize("address, cls, when_enabled", [
    ((0x35B4, 0), "mode", True),        # DRV.OPMODE: the first hole
    ((0x6060, 0), "mode", True),
    ((0x2071, 0), "setpoint", False),   # target current, named only by its description
    ((0x6040, 0), "control", False),
    ((0x345A, 1), "power", False),      # brake control command: a released brake lets a vertical axis fall
    ((0x3450, 0), "power", False),      # MOTOR.BRAKERLS
    ((0x5128, 0), "source", True),      # PL.FBSOURCE
    ((0x1C12, 0), "mapping", True),
    ((0x1600, 1), "mapping", True),
    ((0x3432, 0), "task_load", True),
])
def test_objects_by_class(address: tuple[int, int], cls: str, when_enabled: bool) -> None:
    g = gate.classify_object(*address)
    assert g is not None and g.write_class == cls and g.when_enabled is when_enabled


@pytest.mark.parametrize("address", [(0x34AA, 1), (0x34BA, 8), (0x3548, 0), (0x2030, 1), (0x2031, 0), (0x6065, 0)])
def test_what_neither_moves_nor_selects_is_not_gated(address: tuple[int, int]) -> None:
    """Position-compare "CMP0.SETPOINT n" is no motion set point; gains, user variables, the name are free."""
    assert gate.classify_object(*address) is None


def test_writes_by_name_for_the_names_engineer() -> None:
    assert gate.classify_name("DRV.CMDSOURCE").write_class == "source"  # not in the ESI's table, known by name
    assert gate.classify_name("drv.opmode").when_enabled
    assert gate.classify_name("DRV.EN").write_class == "power"
    assert gate.classify_name("MT.MOVE").write_class == "motion"
    assert gate.classify_name("VL.CMD").write_class == "setpoint"
    assert gate.classify_name("DRV.DIS") is None and gate.classify_name("VL.KP") is None
    assert gate.classify_name("Target current") is None  # a description is not an AKD name


def test_cip_parameter_instances_by_their_akd_name() -> None:
    assert gate.classify_cip(cip.PARAMETER, 205, 1).write_class == "motion"    # HOME.MOVE
    assert gate.classify_cip(cip.PARAMETER, 1, 1) is None                       # AIN.CUTOFF
    assert gate.classify_cip(cip.POSITION_CONTROLLER, 1, 17).write_class == "power"
    assert gate.classify_cip(cip.POSITION_CONTROLLER, 1, 3).when_enabled


# ------------------------------------------------------------------ through the real CLI (parity)

def _writes() -> int:
    return int(SimDrive("default").snapshot()["writes"])


def _recipe(tmp_path: Path, target: str) -> str:
    path = tmp_path / "r.toml"
    path.write_text(f'[recipe]\nname = "gate"\n\n[[step]]\naction = "set"\n{target}\n')
    return str(path)


@pytest.mark.slow
@pytest.mark.parametrize("argv, words", [
    (["sdo", "write", "0x35B4:0", "1"], "operating mode of an enabled drive"),
    (["sdo", "write", "0x2071:0", "100"], "0x2071:0"),
    (["pnu", "set", "930=1"], "operating mode of an enabled drive"),
    (["sdo", "write", "0x6060:0", "3"], "operating mode of an enabled drive"),
])
def test_mode_and_set_point_writes_on_an_enabled_drive_need_consent(argv: list[str], words: str) -> None:
    assert prepare("sim", "speed", "100000")[0] == 0
    assert prepare("--yes", "enable")[0] == 0
    before = _writes()
    code, _, err = run(*argv)
    assert code == 4 and words in err and "nothing was written" in err, err
    assert _writes() == before


@pytest.mark.slow
@pytest.mark.parametrize("step", ['object = "0x35B4:0"\nvalue = 1', 'pnu = "930"\nvalue = 1',
                                  'objects = { "0x2071:0" = 100 }'])
def test_recipe_set_steps_are_gated_like_the_commands(tmp_path: Path, step: str) -> None:
    assert prepare("sim", "speed", "100000")[0] == 0
    assert prepare("--yes", "enable")[0] == 0
    before = _writes()
    code, _, err = run("commission", _recipe(tmp_path, step))
    assert code == 4, err
    assert _writes() == before
