"""Property tests for what users type: PNU addresses/assignments, object addresses, targets, config.

Whatever the input, a parser either returns a well-formed result or raises
akdctl's UsageError — never another exception (which would be a traceback).
"""

from __future__ import annotations

import string

from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.catalog.pnus import pnu_table
from akdctl.drive.objects import parse_address
from akdctl.drive.params import parse_assignment, parse_pnu_spec
from akdctl.errors import UsageError
from akdctl.transport.registry import parse_target

TEXT = st.text(alphabet=string.printable + "äµ€", max_size=40)


@given(TEXT)
def test_pnu_spec_parser_never_crashes(text: str) -> None:
    try:
        spec = parse_pnu_spec(text)
    except UsageError:
        return
    assert 1 <= spec.pnu <= 0xFFFF and 1 <= spec.count <= 234 and 0 <= spec.subindex <= 0xFFFE


@given(TEXT)
def test_assignment_parser_never_crashes(text: str) -> None:
    try:
        spec, values = parse_assignment(text)
    except UsageError:
        return
    assert spec.info is not None and spec.info.writable
    assert len(values) == spec.count
    lo, hi = spec.info.limits()
    assert all(lo <= v <= hi for v in values)


@given(st.sampled_from(sorted(pnu_table())), st.data())
def test_pnu_ranges_round_trip(pnu: int, data: st.DataObject) -> None:
    info = pnu_table()[pnu]
    if info.is_array and info.length > 0:
        first = data.draw(st.integers(0, info.length - 1))
        last = data.draw(st.integers(first, min(info.length - 1, first + 233)))
        spec = parse_pnu_spec(f"{pnu}[{first}..{last}]")
        assert (spec.subindex, spec.count) == (first, last - first + 1)
        assert parse_pnu_spec(spec.label) == spec
    else:
        spec = parse_pnu_spec(str(pnu))
        assert (spec.subindex, spec.count) == (0, 1)


@given(st.sampled_from([i for i in pnu_table().values() if i.writable]), st.data())
def test_valid_assignments_parse_to_their_values(info, data: st.DataObject) -> None:  # type: ignore[no-untyped-def]
    lo, hi = info.limits()
    value = data.draw(st.integers(lo, hi))
    text = f"{info.pnu}={value:#x}" if value >= 0 and data.draw(st.booleans()) else f"{info.pnu}={value}"
    spec, values = parse_assignment(text)
    assert values[0] == value and spec.pnu == info.pnu


@given(TEXT)
def test_object_address_parser_never_crashes(text: str) -> None:
    try:
        address = parse_address(text)
    except UsageError:
        return
    assert 0 <= address.index <= 0xFFFF and 0 <= address.subindex <= 0xFF


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFF))
def test_object_address_round_trip(index: int, sub: int) -> None:
    assert parse_address(f"0x{index:04X}:{sub}") == parse_address(f"{index:04X}h.{sub}")
    assert (parse_address(f"0x{index:x}:{sub:#x}").index, parse_address(f"0x{index:x}:{sub:#x}").subindex) == (index, sub)


@settings(max_examples=300)
@given(TEXT)
def test_target_parser_never_crashes(text: str) -> None:
    try:
        target = parse_target(text)
    except UsageError as exc:
        assert exc.message
        return
    assert target.scheme


@given(st.sampled_from(["pn", "ecat-udp", "ecat", "can"]), TEXT)
def test_scheme_prefixed_garbage_is_usage_error(scheme: str, rest: str) -> None:
    try:
        parse_target(f"{scheme}://{rest}")
    except UsageError:
        pass


@settings(suppress_health_check=[__import__('hypothesis').HealthCheck.function_scoped_fixture])
@given(st.text(max_size=200))
def test_config_loader_never_crashes(tmp_path_factory, text: str) -> None:  # type: ignore[no-untyped-def]
    from akdctl.config import load_config, select_profile

    path = tmp_path_factory.mktemp("cfg") / "c.toml"
    path.write_bytes(text.encode("utf-8", "replace"))
    try:
        config = load_config(path)
        select_profile(config, None)
    except UsageError:
        pass
