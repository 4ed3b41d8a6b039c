"""The simulated AKD enforces the PDO mapping rules itself, on every SDO write (SPEC-NOTES 16-18, 23)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.catalog import objects as oc
from akdctl.sim.model import DriveModel
from akdctl.sim.pdo import PdoComponent, normalise_al_state
from akdctl.sim.sdo_server import SdoAccessError


def _write(model: DriveModel, index: int, sub: int, value: int) -> None:
    size = oc.lookup(index, sub).nbytes
    model.object_write(index, sub, (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little"))


def _abort(model: DriveModel, index: int, sub: int, value: int) -> int:
    before = model.writes
    with pytest.raises(SdoAccessError) as info:
        _write(model, index, sub, value)
    assert model.writes == before, "a refused write must not count"
    return info.value.code


def _read(model: DriveModel, index: int, sub: int) -> int:
    return int.from_bytes(model.object_read(index, sub), "little")


@pytest.fixture
def model() -> DriveModel:
    return DriveModel()


def _pdo(model: DriveModel) -> PdoComponent:
    comp = model.component("pdo")
    assert isinstance(comp, PdoComponent)
    return comp


def test_defaults_are_the_esi_assignment(model: DriveModel) -> None:
    assert _read(model, 0x1C12, 0) == 1 and _read(model, 0x1C12, 1) == oc.DEFAULT_RX_PDO
    assert _read(model, 0x1C13, 0) == 1 and _read(model, 0x1C13, 1) == oc.DEFAULT_TX_PDO
    assert _pdo(model).al_state == "PREOP"
    assert _read(model, 0x1600, 0) == 1 and _read(model, 0x1600, 1) == 0x60400010


@pytest.mark.parametrize("pdo", sorted({**oc.FIXED_RX_PDOS, **oc.FIXED_TX_PDOS}))
def test_fixed_pdos_read_back_their_catalogue_contents(model: DriveModel, pdo: int) -> None:
    entries = oc.fixed_pdo(pdo)
    assert _read(model, pdo, 0) == len(entries)
    got = [oc.PdoEntry.from_mapping_value(_read(model, pdo, s)) for s in range(1, len(entries) + 1)]
    assert tuple(got) == entries
    assert _abort(model, pdo, 1, 0x60400010) == 0x06010002  # fixed PDOs are read-only


def test_subindex_written_while_count_not_zero(model: DriveModel) -> None:
    # SPEC-NOTES 17: 0x1C12/0x1C13 sub >= 1 only while sub 0 = 0; the same holds for mapping objects
    assert _abort(model, 0x1C12, 1, 0x1600) == 0x06010003
    assert _abort(model, 0x1C13, 1, 0x1A00) == 0x06010003
    assert _abort(model, 0x1600, 1, 0x60400010) == 0x06010003


def test_unknown_or_wrong_direction_pdo_number(model: DriveModel) -> None:
    _write(model, 0x1C12, 0, 0)
    assert _abort(model, 0x1C12, 1, 0x1704) == 0x06090030  # SPEC-NOTES 16: the manual's 0x1704
    assert _abort(model, 0x1C12, 1, 0x1B01) == 0x06090030
    _write(model, 0x1C13, 0, 0)
    assert _abort(model, 0x1C13, 1, 0x1701) == 0x06090030


def test_entry_not_mappable(model: DriveModel) -> None:
    _write(model, 0x1600, 0, 0)
    assert _abort(model, 0x1600, 1, 0x60410010) == 0x06040041  # statusword is a Tx object
    assert _abort(model, 0x1600, 1, 0x10000020) == 0x06040041  # device type: not mappable
    assert _abort(model, 0x1600, 1, 0x60400020) == 0x06040041  # wrong bit length
    assert _abort(model, 0x1600, 1, 0x12340010) == 0x06040041  # no such object
    _write(model, 0x1A00, 0, 0)
    assert _abort(model, 0x1A00, 1, 0x60400010) == 0x06040041  # controlword is an Rx object


def test_pdo_length_and_odd_length(model: DriveModel) -> None:
    _write(model, 0x1600, 0, 0)
    for sub, value in enumerate((0x607A0020, 0x60FF0020, 0x60400010), start=1):
        _write(model, 0x1600, sub, value)
    assert _abort(model, 0x1600, 0, 3) == 0x06040042  # 10 bytes > 8
    _write(model, 0x1600, 0, 2)  # 8 bytes is fine
    _write(model, 0x1601, 0, 0)
    _write(model, 0x1601, 1, 0x60400010)
    _write(model, 0x1601, 2, 0x60600008)
    assert _abort(model, 0x1601, 0, 2) == 0x06040042  # 3 bytes: odd (SPEC-NOTES 18)
    _write(model, 0x1601, 3, oc.RX_DUMMY.mapping_value)
    _write(model, 0x1601, 0, 3)  # padded with the dummy object: 4 bytes
    _write(model, 0x1A01, 0, 0)
    _write(model, 0x1A01, 1, 0x60610008)
    assert _abort(model, 0x1A01, 0, 1) == 0x06040042
    _write(model, 0x1A01, 2, oc.TX_PADDING[0].mapping_value)
    _write(model, 0x1A01, 0, 2)


def test_rx_total_limit(model: DriveModel) -> None:
    for pdo in (0x1600, 0x1601, 0x1602):
        _write(model, pdo, 0, 0)
        _write(model, pdo, 1, 0x607A0020)
        _write(model, pdo, 2, 0x60FF0020)
        _write(model, pdo, 0, 2)
    _write(model, 0x1C12, 0, 0)
    for sub, pdo in enumerate((0x1600, 0x1601, 0x1602), start=1):
        _write(model, 0x1C12, sub, pdo)
    assert _abort(model, 0x1C12, 0, 3) == 0x06040042  # 24 bytes > 22
    _write(model, 0x1C12, 0, 2)
    assert _pdo(model).assigned("rx") == [0x1600, 0x1601]


def test_fixed_pdo_excludes_others(model: DriveModel) -> None:
    _write(model, 0x1C12, 0, 0)
    _write(model, 0x1C12, 1, 0x1701)
    _write(model, 0x1C12, 2, 0x1600)
    assert _abort(model, 0x1C12, 0, 2) == 0x06040043
    assert _abort(model, 0x1C12, 0, 5) == 0x06090031


def test_changes_only_in_preop(model: DriveModel) -> None:
    comp = _pdo(model)
    for state in ("SAFEOP", "OP", "INIT"):
        comp.set_al_state(state)
        assert _abort(model, 0x1C12, 0, 0) == 0x08000022  # SPEC-NOTES 18
        assert _abort(model, 0x1600, 0, 0) == 0x08000022
    comp.set_al_state("PREOP")
    _write(model, 0x1C12, 0, 0)


def test_controlword_in_active_rxpdo(model: DriveModel) -> None:
    comp = _pdo(model)
    assert not comp.controlword_in_active_rxpdo()  # PRE-OP
    comp.set_al_state("OP")
    assert comp.controlword_in_active_rxpdo()  # 0x1701 carries 0x6040 (SPEC-NOTES 23)
    comp.set_al_state("PREOP")
    _write(model, 0x1C12, 0, 0)
    _write(model, 0x1600, 0, 0)
    _write(model, 0x1600, 1, 0x60FF0020)
    _write(model, 0x1600, 0, 1)
    _write(model, 0x1C12, 1, 0x1600)
    _write(model, 0x1C12, 0, 1)
    comp.set_al_state(0x08)
    assert not comp.controlword_in_active_rxpdo()


def test_state_round_trip(model: DriveModel) -> None:
    _write(model, 0x1C13, 0, 0)
    _write(model, 0x1C13, 1, 0x1B20)
    _write(model, 0x1C13, 0, 1)
    _pdo(model).set_al_state("SAFEOP")
    again = DriveModel.from_state(model.to_state())
    assert _pdo(again).assigned("tx") == [0x1B20]
    assert _pdo(again).al_state == "SAFEOP"


@pytest.mark.parametrize("text,expected", [("pre-op", "PREOP"), ("op", "OP"), (2, "PREOP"), (0x14, "SAFEOP")])
def test_al_state_names(text: object, expected: str) -> None:
    assert normalise_al_state(text) == expected


def test_al_state_unknown() -> None:
    with pytest.raises(ValueError):
        normalise_al_state("running")


_INDICES = st.sampled_from([0x1C12, 0x1C13, 0x1600, 0x1601, 0x1602, 0x1A00, 0x1A01])
_ENTRY_VALUES = st.sampled_from([0, 0x60400010, 0x60C10120, 0x607A0020, 0x60FF0020, 0x60600008, 0x00020008,
                                 0x60410010, 0x60630020, 0x60610008, 0x20020108, 0x10000020])
_PDO_VALUES = st.sampled_from([0, 0x1600, 0x1601, 0x1602, 0x1701, 0x1704, 0x1A00, 0x1A01, 0x1B01, 0x1B20])


@st.composite
def _writes(draw: st.DrawFn) -> list[tuple[int, int, int]]:
    out = []
    for _ in range(draw(st.integers(0, 40))):
        index = draw(_INDICES)
        sub = draw(st.integers(0, 4))
        if sub == 0:
            value = draw(st.integers(0, 9))
        elif index in (0x1C12, 0x1C13):
            value = draw(_PDO_VALUES)
        else:
            value = draw(_ENTRY_VALUES)
        out.append((index, sub, value))
    return out


@settings(max_examples=150, deadline=None)
@given(_writes())
def test_no_write_sequence_breaks_the_rules(writes: list[tuple[int, int, int]]) -> None:
    """Whatever a client writes, the active process data stays within SPEC-NOTES 16-18."""
    model = DriveModel()
    comp = _pdo(model)
    for index, sub, value in writes:
        try:
            _write(model, index, sub, value)
        except SdoAccessError as exc:
            assert exc.code in {0x06010003, 0x06040041, 0x06040042, 0x06040043, 0x06090030, 0x06090031}
    for direction, limit, fixed in (("rx", oc.RX_TOTAL_MAX_BYTES, oc.FIXED_RX_PDOS),
                                     ("tx", oc.TX_TOTAL_MAX_BYTES, oc.FIXED_TX_PDOS)):
        assigned = comp.assigned(direction)
        assert all((oc.is_rx_pdo(p) if direction == "rx" else oc.is_tx_pdo(p)) for p in assigned)
        assert len(assigned) <= 1 or not any(p in fixed for p in assigned)
        assert oc.pdo_bytes(comp.active_entries(direction)) <= limit
        for pdo in assigned:
            entries = comp.pdo_entries(pdo)
            assert sum(e.bits for e in entries) % 16 == 0 and oc.pdo_bytes(entries) <= oc.PDO_MAX_BYTES or pdo in fixed
