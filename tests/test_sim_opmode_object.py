"""DRV.OPMODE is one operating mode on the simulated AKD, whichever address reads or writes it.

The AKD gives DRV.OPMODE the CoE object 35B4h and PNU 930, HOME.MODE 50CBh and PNU 1001 [V reference/akd-parameter-names.md]. The simulator kept a
stored copy of 35B4h beside the live mode PNU 930 reads, so a factory drive answered ``param get DRV.OPMODE`` with 0
(torque) while ``pnu get 930`` and ``status`` said 1 (velocity). Both now go through one rule
(``MotionComponent.set_opmode``).
"""

from __future__ import annotations

import json
import struct

import pytest

from akdctl.sim.component import ABORT_DEVICE_STATE, ABORT_VALUE_RANGE
from akdctl.sim.errors import PnuAccessError, SdoAccessError
from akdctl.sim.model import DriveModel
from tests.harness import run_akdctl


def _opmode_object(model: DriveModel) -> int:
    return int(struct.unpack("<I", model.object_read(0x35B4, 0))[0])


def test_a_factory_drive_reads_one_mode_by_object_and_by_pnu() -> None:
    model = DriveModel()
    assert _opmode_object(model) == model.pnu_read_raw(930, 0, 1)[1][0] == 1
    assert model.object_read(0x6060, 0) == b"\x03"  # profile velocity


@pytest.mark.parametrize("value, cia_mode", [(0, 4), (1, 3), (2, 1)])
def test_a_write_of_the_object_is_the_mode_everywhere(value: int, cia_mode: int) -> None:
    model = DriveModel()
    model.object_write(0x35B4, 0, struct.pack("<I", value))
    assert _opmode_object(model) == value
    assert model.pnu_read_raw(930, 0, 1)[1][0] == value
    assert struct.unpack("<b", model.object_read(0x6060, 0))[0] == cia_mode


def test_a_pnu_write_shows_in_the_object() -> None:
    model = DriveModel()
    model.pnu_write_raw(930, 0, 0x42, [2])  # U16
    assert _opmode_object(model) == 2


def test_an_operating_mode_outside_0_to_2_is_refused_and_changes_nothing() -> None:
    model = DriveModel()
    with pytest.raises(SdoAccessError) as refused:
        model.object_write(0x35B4, 0, struct.pack("<I", 3))
    assert refused.value.code == ABORT_VALUE_RANGE
    assert _opmode_object(model) == 1


def _running_in_velocity_mode() -> DriveModel:
    model = DriveModel()
    for word in (0x06, 0x07, 0x0F):  # shutdown, switch on, enable operation (profile velocity, the factory mode)
        model.object_write(0x6040, 0, struct.pack("<H", word))
        model.advance(0.05)
    model.object_write(0x60FF, 0, struct.pack("<i", 100_000))
    model.advance(0.1)
    assert struct.unpack("<i", model.object_read(0x606C, 0))[0] != 0, "the axis should be moving"
    return model


def test_a_mode_change_while_the_axis_moves_is_refused_by_object_and_by_pnu_alike() -> None:
    model = _running_in_velocity_mode()
    with pytest.raises(SdoAccessError) as refused:
        model.object_write(0x35B4, 0, struct.pack("<I", 2))
    assert refused.value.code == ABORT_DEVICE_STATE
    with pytest.raises(PnuAccessError):
        model.pnu_write_raw(930, 0, 0x42, [2])  # U16
    assert _opmode_object(model) == model.pnu_read_raw(930, 0, 1)[1][0] == 1


@pytest.mark.slow  # the real CLI in subprocesses
def test_the_cli_reads_the_same_mode_by_name_and_by_pnu() -> None:
    by_name = run_akdctl("--json", "param", "get", "DRV.OPMODE")
    by_pnu = run_akdctl("--json", "pnu", "get", "930")
    assert by_name.code == 0 and by_pnu.code == 0, by_name.stderr + by_pnu.stderr
    named = json.loads(by_name.stdout)["parameters"][0]
    assert named["name"] == "DRV.OPMODE"
    assert named["value"] == json.loads(by_pnu.stdout)["parameters"][0]["values"][0] == 1


# HOME.MODE: 50CBh is "available also via PNU 1001" [V reference/akd-parameter-names.md, section 3]


def _home_mode_object(model: DriveModel) -> int:
    return int(struct.unpack("<I", model.object_read(0x50CB, 0))[0])


def test_home_mode_by_pnu_shows_in_its_object_and_back() -> None:
    model = DriveModel()
    assert _home_mode_object(model) == model.pnu_read_raw(1001, 0, 1)[1][0] == 0
    model.pnu_write_raw(1001, 0, 0x42, [3])  # U16, as the commissioning example's step sets it
    assert _home_mode_object(model) == 3
    model.object_write(0x50CB, 0, struct.pack("<I", 1))
    assert model.pnu_read_raw(1001, 0, 1)[1][0] == 1


def test_home_mode_outside_the_pnu_range_is_refused_by_object() -> None:
    model = DriveModel()
    with pytest.raises(SdoAccessError) as refused:
        model.object_write(0x50CB, 0, struct.pack("<I", 21))
    assert refused.value.code == ABORT_VALUE_RANGE
    assert model.pnu_read_raw(1001, 0, 1)[1][0] == 0


@pytest.mark.slow  # the real CLI in subprocesses
def test_the_cli_names_the_refusal_of_an_operating_mode_outside_0_to_2() -> None:
    refused = run_akdctl("sdo", "write", "0x35B4", "7")
    assert refused.code == 1, refused
    assert "0x06090030" in refused.stderr and "Value range of parameter exceeded" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
    mode = run_akdctl("--json", "param", "get", "DRV.OPMODE")
    assert json.loads(mode.stdout)["parameters"][0]["value"] == 1  # nothing changed
