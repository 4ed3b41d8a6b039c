"""Parsing and validating PDO mapping plans (akdctl.drive.pdo) without a drive."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.catalog import objects as oc
from akdctl.drive import pdo as dp
from akdctl.errors import UsageError


def test_parse_entry_forms() -> None:
    assert dp.parse_entry("0x6040:0/16") == oc.PdoEntry(0x6040, 0, 16)
    assert dp.parse_entry("0x60C1:1") == oc.PdoEntry(0x60C1, 1, 32)  # bits from the catalogue
    assert dp.parse_entry("6063h:0/32") == oc.PdoEntry(0x6063, 0, 32)
    with pytest.raises(UsageError):
        dp.parse_entry("0x1234:0")  # unknown object needs /BITS
    with pytest.raises(UsageError):
        dp.parse_entry("nonsense")


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFF), st.integers(1, 0xFF))
def test_entry_text_round_trip(index: int, sub: int, bits: int) -> None:
    entry = oc.PdoEntry(index, sub, bits)
    # sub-indices are decimal unless written 0x.. (akdctl convention) ...
    assert dp.parse_entry(f"0x{index:04X}:{sub}/{bits}") == entry
    assert dp.parse_entry(f"0x{index:04X}:0x{sub:02X}/{bits}") == entry
    # ... and the manual's two-digit form (0x60C1:01) reads back for the sub-indices PDOs use (0..9)
    if sub < 10:
        assert dp.parse_entry(str(entry)) == entry


@given(st.text(max_size=30))
def test_parse_pdo_arg_raises_only_usage_errors(text: str) -> None:
    try:
        dp.parse_pdo_arg(text)
    except UsageError:
        pass


@pytest.mark.parametrize("text,expected", [
    ("2ms", (2, -3)), ("250us", (25, -5)), ("0.5ms", (5, -4)), ("2,-3", (2, -3)), ("0.004", (4, -3)), ("1s", (1, 0)),
])
def test_cycle_time(text: str, expected: tuple[int, int]) -> None:
    assert dp.parse_cycle_time(text) == expected


def test_cycle_time_bad() -> None:
    for text in ("fast", "-1ms", "0", "1.234567891ms"):
        with pytest.raises(UsageError):
            dp.parse_cycle_time(text)


def test_fixed_plan_is_valid_and_follows_5_5() -> None:
    plan = dp.build_plan(rx=["0x1701"])
    assert dp.validate(plan) == []
    steps = dp.startup_list(plan)
    # EtherCAT manual 5.5: 0x1C12:0 = 0, 0x1C12:1 = 0x1701, 0x1C12:0 = 1
    assert [(s.index, s.subindex, s.value) for s in steps] == [(0x1C12, 0, 0), (0x1C12, 1, 0x1701), (0x1C12, 0, 1)]


@pytest.mark.parametrize("args,fragment", [
    ({"rx": ["0x1600=0x6041:0/16"]}, "cannot be mapped into an RxPDO"),
    ({"rx": ["0x1600=0x6040:0/32"]}, "has 16 bits"),
    ({"rx": ["0x1600=0x607A:0/32,0x60FF:0/32,0x6040:0/16"]}, "at most 8"),
    ({"rx": ["0x1600=0x6040:0/16,0x6060:0/8"]}, "odd length"),
    ({"tx": ["0x1A00=0x6061:0/8"]}, "0x2002"),
    ({"rx": ["0x1704"]}, "SPEC-NOTES 16"),
    ({"rx": ["0x1B01"]}, "not an RxPDO"),
    ({"rx": ["0x1701", "0x1600=0x6040:0/16"]}, "excludes"),
    ({"rx": ["0x1601"]}, "entries are not given"),
    ({"rx": ["0x1600=0x607A:0/32,0x60FF:0/32", "0x1601=0x60B1:0/32,0x6081:0/32",
             "0x1602=0x6083:0/32,0x6084:0/32"]}, "24 bytes"),
    ({"define": ["0x1A00=0x6041:0/16"]}, "no --tx assignment"),
    ({"define": ["0x1701=0x6040:0/16"]}, "fixed PDO"),
    ({"rx": ["0x1701"], "cycle_time": "100us"}, "250 us"),
])
def test_validation_problems(args: dict, fragment: str) -> None:
    problems = dp.validate(dp.build_plan(**args))
    assert any(fragment in p for p in problems), problems


def test_padding_makes_odd_pdos_valid() -> None:
    plan = dp.build_plan(rx=["0x1600=0x6040:0/16,0x6060:0/8,0x0002:0/8"], tx=["0x1A00=0x6041:0/16,0x6061:0/8,0x2002:1/8"])
    assert dp.validate(plan) == []


def test_plan_file_toml_and_json(tmp_path) -> None:
    toml = tmp_path / "map.toml"
    toml.write_text('rx = ["0x1600=0x6040:0/16,0x60C1:1/32"]\ntx = [0x1B01]\n'
                    'define = ["0x1A00=0x6041:0/16,0x6063:0/32"]\nopmode = "ip"\ncycle_time = "2ms"\n')
    plan = dp.load_plan_file(str(toml))
    assert plan.assign == {"rx": [0x1600], "tx": [0x1B01]}
    assert plan.opmode == 7 and plan.cycle == (2, -3)
    js = tmp_path / "map.json"
    js.write_text('{"rx": ["0x1701"], "tx": ["0x1B20"]}')
    assert dp.load_plan_file(str(js)).assign == {"rx": [0x1701], "tx": [0x1B20]}
    bad = tmp_path / "bad.json"
    bad.write_text('{"rx": "0x1701", "color": 1}')
    with pytest.raises(UsageError):
        dp.load_plan_file(str(bad))
    broken = tmp_path / "broken.toml"
    broken.write_text("rx = [")
    with pytest.raises(UsageError):
        dp.load_plan_file(str(broken))
