"""The simulated AKD's fault component: situations, counter, acknowledge, CiA objects, EMCY, armed faults.

Relies on SPEC-NOTES 14 (PNU 947: 8 situations x 8 numbers, situation 0 active, acknowledge shifts by 8,
PNU 944 counts situations) and SPEC-NOTES 21 (0x1001/0x1003/0x2000/0x2001/0x2012/0x2013, EMCY codes).
"""

from __future__ import annotations

import json
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.sim.faults import FaultComponent, error_register_bits
from akdctl.sim.model import DriveModel
from akdctl.sim.sdo_server import SdoAccessError


def _model() -> tuple[DriveModel, FaultComponent]:
    model = DriveModel()
    comp = model.component("faults")
    assert isinstance(comp, FaultComponent)
    return model, comp


def _buffer(model: DriveModel) -> list[int]:
    return model.signed_pnu(947)


def _u32(model: DriveModel, index: int, sub: int) -> int:
    return int.from_bytes(model.object_read(index, sub), "little")


def test_single_fault_fills_situation_zero_and_counts_one_situation() -> None:
    model, comp = _model()
    comp.raise_fault("F501")
    assert _buffer(model)[:8] == [501, 0, 0, 0, 0, 0, 0, 0]
    assert model.signed_pnu(944) == [1]
    assert comp.fault_present and not comp.warning_present
    assert comp.active() == ["F501"]


def test_faults_raised_before_acknowledge_share_one_situation_of_at_most_eight() -> None:
    model, comp = _model()
    codes = ["F501", "F502", "F503", "F523", "F247", "F519", "F234", "F235", "F236"]  # nine faults
    for code in codes:
        comp.raise_fault(code)
    comp.raise_fault("F501")  # already active: not repeated
    assert _buffer(model)[:8] == [501, 502, 503, 523, 247, 519, 234, 235]
    assert _buffer(model)[8:] == [0] * 56
    assert model.signed_pnu(944) == [1]  # one situation


def test_acknowledge_shifts_by_eight_and_the_oldest_situation_drops_after_eight() -> None:
    model, comp = _model()
    assert comp.acknowledge() is False  # nothing active: nothing shifts
    numbers = [501, 502, 503, 523, 247, 519, 234, 235, 236, 237]  # ten situations
    for number in numbers:
        comp.raise_fault(f"F{number}")
        assert comp.acknowledge() is True
    buf = _buffer(model)
    assert buf[:8] == [0] * 8  # nothing active
    situations = [buf[i] for i in range(8, 64, 8)]
    assert situations == [237, 236, 235, 234, 519, 247, 523]  # newest first; 501, 502, 503 dropped
    assert model.signed_pnu(944) == [10]
    assert not comp.fault_present


def test_warning_sets_warning_present_but_never_enters_pnu_947() -> None:
    model, comp = _model()
    comp.raise_fault("n503")
    assert comp.warning_present and not comp.fault_present
    assert _buffer(model) == [0] * 64
    assert model.signed_pnu(944) == [0]
    assert _u32(model, 0x2000, 1) == 503
    assert comp.active() == ["n503"]
    assert comp.clear_causes() == ["n503"]
    assert not comp.warning_present


def test_unknown_code_is_a_value_error() -> None:
    _, comp = _model()
    for bad in ("F9999", "X1", "", "0x3210"):
        with pytest.raises(ValueError):
            comp.raise_fault(bad)


def test_cia_objects_follow_the_faults() -> None:
    model, comp = _model()
    comp.raise_fault("F501")  # EMCY 0x3210 (voltage)
    comp.raise_fault("F234")  # EMCY 0x4210 (temperature)
    assert model.object_read(0x1001, 0) == bytes([0x01 | 0x04 | 0x08])
    assert model.object_read(0x1003, 0) == bytes([2])
    assert _u32(model, 0x1003, 1) == 0x4210 | (234 << 16)  # newest at sub 1
    assert _u32(model, 0x1003, 2) == 0x3210 | (501 << 16)
    assert struct.unpack("<H", model.object_read(0x2001, 1))[0] == 501
    assert struct.unpack("<H", model.object_read(0x2001, 2))[0] == 234
    assert _u32(model, 0x2012, 1) == 234 and _u32(model, 0x2012, 2) == 501
    assert model.object_read(0x2012, 0) == bytes([20])
    comp.acknowledge()
    assert model.object_read(0x1001, 0) == b"\x00"
    assert struct.unpack("<H", model.object_read(0x2001, 1))[0] == 0
    assert _u32(model, 0x2012, 1) == 234  # history survives the acknowledge


def test_history_time_stamps_use_the_virtual_clock() -> None:
    model, comp = _model()
    model.advance(12.5)
    comp.raise_fault("F501")
    comp.acknowledge()
    model.advance(30)
    comp.raise_fault("F502")
    assert _u32(model, 0x2013, 1) == 42 and _u32(model, 0x2013, 2) == 12


def test_error_field_clears_only_with_zero_written_to_sub0() -> None:
    model, comp = _model()
    comp.raise_fault("F501")
    with pytest.raises(SdoAccessError) as exc:
        model.object_write(0x1003, 0, b"\x01")
    assert exc.value.code == 0x06090030
    with pytest.raises(SdoAccessError):
        model.object_write(0x1003, 1, b"\x00\x00\x00\x00")  # entries are read-only
    model.object_write(0x1003, 0, b"\x00")
    assert model.object_read(0x1003, 0) == b"\x00"
    assert _u32(model, 0x2012, 1) == 501  # the AKD history is separate


def test_emergencies_carry_the_table_code_and_reset_after_acknowledge() -> None:
    _, comp = _model()
    comp.raise_fault("F501")
    comp.raise_fault("n503")
    emcys = comp.take_emergencies()
    assert [(e.error_code, e.error_register) for e in emcys] == [(0x3210, 0x05), (0x3180, 0x05)]
    assert emcys[0].data == struct.pack("<H", 501) + bytes(3)
    assert comp.take_emergencies() == []
    comp.acknowledge()
    (reset,) = comp.take_emergencies()
    assert reset.is_reset and reset.error_register == 0


def test_error_register_bits_by_class() -> None:
    assert error_register_bits(0x2310) == 0x03
    assert error_register_bits(0x3210) == 0x05
    assert error_register_bits(0x4310) == 0x09
    assert error_register_bits(0x8130) == 0x11
    assert error_register_bits(0xFF00) == 0x81
    assert error_register_bits(0x5530) == 0x01


def test_armed_fault_rises_between_two_reads() -> None:
    model, comp = _model()
    comp.arm("F501", 1)
    assert model.signed_pnu(944) == [0]  # answered before the fault rose
    assert model.signed_pnu(944) == [1]
    assert comp.armed == []
    with pytest.raises(ValueError):
        comp.arm("F501", 0)


def test_persisting_cause_returns_after_acknowledge_until_cleared() -> None:
    model, comp = _model()
    comp.raise_fault("F501", persist=True)
    assert comp.acknowledge() is True
    assert comp.active() == ["F501"] and model.signed_pnu(944) == [2]
    assert comp.clear_causes() == ["F501"]
    assert comp.acknowledge() is True
    assert not comp.fault_present


def test_state_round_trips_through_json() -> None:
    model, comp = _model()
    comp.raise_fault("F501")
    comp.acknowledge()
    comp.raise_fault("F502")
    comp.raise_fault("n503")
    comp.arm("F234", 3)
    state = json.loads(json.dumps(model.to_state()))
    again = DriveModel.from_state(state)
    other = again.component("faults")
    assert other.to_state() == comp.to_state()
    assert again.signed_pnu(947) == model.signed_pnu(947)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(st.sampled_from(["F501", "F502", "F503", "F234", "F235", "n503"]), st.just("ack")),
                max_size=40))
def test_buffer_matches_a_reference_model(ops: list[str]) -> None:
    """Random raise/acknowledge sequences: PNU 947/944 equal a straightforward reference of SPEC-NOTES 14."""
    model, comp = _model()
    situations: list[list[int]] = [[] for _ in range(8)]
    counter = 0
    for op in ops:
        if op == "ack":
            if situations[0]:
                situations = [[]] + situations[:7]
            comp.acknowledge()
            continue
        comp.raise_fault(op)
        if op.startswith("n"):
            continue
        number = int(op[1:])
        if not situations[0]:
            counter += 1
        if number not in situations[0]:
            situations[0].append(number)
    flat = [n for s in situations for n in s + [0] * (8 - len(s))]
    assert model.signed_pnu(947) == flat
    assert model.signed_pnu(944) == [counter]
    assert comp.fault_present == bool(situations[0])
