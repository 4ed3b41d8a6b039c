"""drive/values.py: catalogue-typed objects and PNUs, encoded and decoded in one place.

Property tests round-trip every scalar type the catalogue uses (objects) and every catalogue PNU
through encode → decode; the range checks must name the allowed range; and the typed reads and
the one identity reader run against the simulated drive.
"""

from __future__ import annotations

import math
import struct
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.catalog.objects import entries
from akdctl.catalog.pnus import pnu_table
from akdctl.drive import values
from akdctl.errors import MalformedReply, ParameterRefused, UsageError
from akdctl.protocol.datatypes import TYPES
from akdctl.protocol.bmp import ParameterFailure, ParameterValue

CATALOGUE_TYPES = sorted({e.short_type for e in entries().values()} & set(TYPES))


def _value_of(type_name: str) -> st.SearchStrategy[Any]:
    t = TYPES[type_name]
    if t.kind == "bool":
        return st.booleans()
    if t.kind in ("int", "uint"):
        return st.integers(t.minimum, t.maximum)
    if t.kind == "float":
        return st.floats(allow_nan=False, width=32 if t.size == 4 else 64)
    if t.kind == "str":
        return st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=40)
    return st.binary(max_size=40)


def test_the_catalogue_uses_the_scalar_types() -> None:
    assert {"u8", "u16", "u32", "i8", "i16", "i32", "vs"} <= set(CATALOGUE_TYPES)


@pytest.mark.parametrize("type_name", sorted(TYPES))
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_object_values_round_trip_per_type(type_name: str, data: st.DataObject) -> None:
    value = data.draw(_value_of(type_name))
    raw = values.encode_value(type_name, value)
    assert TYPES[type_name].size in (None, len(raw))
    assert values.decode(type_name, raw) == value


@pytest.mark.parametrize("type_name", [t for t in sorted(TYPES) if TYPES[t].kind in ("int", "uint")])
def test_out_of_range_names_the_allowed_range(type_name: str) -> None:
    t = TYPES[type_name]
    with pytest.raises(UsageError, match=rf"\({t.minimum}\.\.{t.maximum}\)"):
        values.encode_value(type_name, t.maximum + 1, "object 0x6060:0")
    with pytest.raises(UsageError, match=rf"\({t.minimum}\.\.{t.maximum}\)"):
        values.encode_value(type_name, t.minimum - 1)


@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_snapshot_values_round_trip_for_catalogue_objects(data: st.DataObject) -> None:
    entry = data.draw(st.sampled_from(sorted(entries().values(), key=lambda e: (e.index, e.subindex))))
    kind = entry.short_type
    value = data.draw(_value_of(kind))
    if kind == "os":
        value = "0x" + value.hex()
    elif kind == "bool":
        value = int(value)
    raw = values.encode_object(entry, value)
    back = values.snapshot_value(entry, raw)
    if isinstance(value, float):
        assert back == value or (math.isnan(back) and math.isnan(value))
    else:
        assert back == value


def test_decode_drops_expedited_zero_padding_and_refuses_short_data() -> None:
    # CiA 301: an expedited upload without size indication carries four bytes
    assert values.decode("u8", b"\x07\x00\x00\x00") == 7
    assert values.decode("i16", b"\xff\xff\x00\x00") == -1
    with pytest.raises(MalformedReply, match="u16 needs 2 bytes"):
        values.decode("u16", b"\x01")
    with pytest.raises(MalformedReply):
        values.decode("u8", b"\x01\x02")          # not padding: a wider value than the type


def test_snapshot_value_keeps_what_does_not_decode_as_hex() -> None:
    entry = next(e for e in entries().values() if e.short_type == "u16")
    assert values.snapshot_value(entry, b"\x01") == "0x01"


class FakeObjects:
    """An object channel over a dict of raw bytes, recording downloads."""

    def __init__(self, data: dict[tuple[int, int], bytes]) -> None:
        self.data = dict(data)

    def upload(self, index: int, subindex: int) -> bytes:
        return self.data[(index, subindex)]

    def download(self, index: int, subindex: int, data: bytes) -> None:
        self.data[(index, subindex)] = data


def test_objects_are_read_and_written_by_the_catalogue_type() -> None:
    channel = FakeObjects({(0x6061, 0): b"\xfe", (0x6064, 0): struct.pack("<i", -1234)})
    assert values.read_object(channel, 0x6061, 0) == -2          # i8 in the catalogue
    assert values.read_object(channel, 0x6064, 0) == -1234       # i32
    values.write_object(channel, 0x6083, 0, 100_000)             # u32
    assert channel.data[(0x6083, 0)] == struct.pack("<I", 100_000)
    with pytest.raises(UsageError, match=r"object 0x6060:0.*-128\.\.127"):
        values.write_object(channel, 0x6060, 0, 200)
    assert (0x6060, 0) not in channel.data
    with pytest.raises(UsageError, match="not in the AKD catalogue"):
        values.read_object(channel, 0x5FFF, 0)


def test_array_elements_beyond_the_catalogue_share_its_type() -> None:
    channel = FakeObjects({(0x1003, 40): struct.pack("<I", 0x12345678)})
    assert values.object_type(0x1003, 40) == "u32"
    assert values.read_object(channel, 0x1003, 40) == 0x12345678


# --- PNUs ----------------------------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_pnu_values_round_trip_for_catalogue_pnus(data: st.DataObject) -> None:
    info = data.draw(st.sampled_from([i for _, i in sorted(pnu_table().items())]))
    lo, hi = info.limits()
    chosen = data.draw(st.lists(st.integers(lo, hi), min_size=1, max_size=info.length))
    values.check_pnu_values(info, chosen)
    wire = values.pnu_to_wire(info, chosen)
    assert wire.format == info.wire_format
    assert all(0 <= v < 1 << info.bits for v in wire.values)        # two's complement bits on the wire
    assert values.pnu_from_wire(info, list(wire.values)) == chosen


def test_pnu_limits_are_named() -> None:
    info = next(i for i in pnu_table().values() if i.writable and i.signed)
    lo, hi = info.limits()
    with pytest.raises(UsageError, match=rf"outside {lo}\.\.{hi}"):
        values.check_pnu_values(info, [hi + 1])
    with pytest.raises(UsageError, match="expected an integer"):
        values.check_pnu_values(info, [True])


class FakeParameters:
    """A parameter channel over a dict of wire values (unsigned), answering refusals for unknown PNUs."""

    def __init__(self, data: dict[int, list[int]]) -> None:
        self.data = data
        self.requests = 0

    def read(self, addresses: Any) -> list[Any]:
        self.requests += 1
        return [ParameterValue(0x42, tuple(self.data[a.pnu][a.subindex:a.subindex + a.count]))
                if a.pnu in self.data else ParameterFailure(0) for a in addresses]

    def write(self, items: Any) -> list[Any]:
        self.requests += 1
        for address, value in items:
            self.data.setdefault(address.pnu, [0])[address.subindex:address.subindex + address.count] = value.values
        return [None for _ in items]


def test_pnu_map_reads_signed_and_writes_in_one_request_each() -> None:
    signed = next(i for i in pnu_table().values() if i.signed and not i.is_array and i.writable)
    channel = FakeParameters({2: [0x0237], signed.pnu: [(1 << signed.bits) - 5]})
    assert values.read_pnu_map(channel, [2, signed.pnu]) == {2: [0x0237], signed.pnu: [-5]}
    values.write_pnu_map(channel, [(signed.pnu, -7), (2, 1)])
    assert channel.data[signed.pnu] == [(1 << signed.bits) - 7] and channel.requests == 2
    with pytest.raises(ParameterRefused, match="PNU 999"):
        values.read_pnu_map(channel, [999])


def test_pnu_spec_is_built_from_the_catalogue() -> None:
    assert values.pnu_spec(947).count == pnu_table()[947].length
    assert values.pnu_spec(947, 3, 1).label == "947[3]"
    assert values.pnu_spec(930).label == "930"


# --- the one identity reader, against the simulated drive ------------------------------------------------------


def _sim() -> Any:
    """A Connection to the simulated drive (identity and snapshot read through a Connection)."""
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target
    from akdctl.transport.sim import SimTransport

    return Connection.over(SimTransport(parse_target("sim", "test"), LinkOptions(timeout=2.0)))


def test_identity_is_read_once_and_flattened_for_backups() -> None:
    from akdctl.drive import identity, snapshot

    conn = _sim()
    try:
        full = identity.read_identity(conn)
        assert full["profidrive"]["drive_unit"]["software_version"] == "1.20"
        assert set(full["canopen"]) == {k for k, _, _ in identity.IDENTITY_OBJECTS}
        flat = identity.backup_identity(full)
        assert flat["firmware"] == "1.20" and flat["manufacturer"] == full["profidrive"]["drive_unit"]["manufacturer"]
        assert flat["vendor_id"] == full["canopen"]["vendor_id"]
        # the backup's reader is the same reading, flattened
        assert snapshot.read_identity(conn, True, True) == flat
        # a PNU backup already holds 964: its identity matches without another round trip
        values_964 = {"964": full["profidrive"]["drive_unit"]["raw"]}
        assert snapshot.identity_from_pnus(values_964).items() <= flat.items()
    finally:
        conn.close()
