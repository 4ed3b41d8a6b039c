"""protocol/record.py: the value records that replaced dataclasses and named tuples on the cold path (issue 15.4)."""

from __future__ import annotations

import pytest

from akdctl.protocol import coe
from akdctl.protocol.bmp import ParameterAddress, ParameterValue
from akdctl.protocol.record import Record


class _Point(Record):
    __slots__ = ("x", "y")

    def __init__(self, x: int, y: int = 0) -> None:
        self.x = x
        self.y = y


class _Pair(Record):
    __slots__ = ("x", "y")

    def __init__(self, x: int, y: int = 0) -> None:
        self.x = x
        self.y = y


class _Bag(Record):
    __slots__ = ("items",)
    __hash__ = None  # type: ignore[assignment]

    def __init__(self, items: list[int]) -> None:
        self.items = items


def test_equal_by_value_within_one_class_only() -> None:
    assert _Point(1, 2) == _Point(1, 2) and _Point(1, 2) != _Point(1, 3)
    assert _Point(1, 2) != _Pair(1, 2) and _Point(1, 2) != (1, 2)  # not a tuple, not another record of that shape
    # the mirrored SDO messages of client and server have the same fields, and are still different messages
    assert coe.SdoUploadSegment(1) != coe.SdoDownloadSegmentResponse(1)
    assert coe.SdoUploadSegment(1) == coe.SdoUploadSegment(1)


def test_hash_repr_replace() -> None:
    assert hash(_Point(1, 2)) == hash(_Point(1, 2)) and len({_Point(1, 2), _Point(1, 2), _Point(2, 1)}) == 2
    assert repr(_Point(1, 2)) == "_Point(x=1, y=2)"
    assert repr(ParameterAddress(930)) == "ParameterAddress(pnu=930, subindex=0, count=1, attribute=16)"
    moved = _Point(1, 2).replace(y=5)
    assert moved == _Point(1, 5) and type(moved) is _Point
    with pytest.raises(TypeError):
        _Point(1).replace(z=1)
    with pytest.raises(TypeError):
        hash(_Bag([1]))
    assert _Bag([1]) == _Bag([1])


def test_records_have_no_instance_dict() -> None:
    with pytest.raises(AttributeError):
        _Point(1).z = 3  # type: ignore[attr-defined]
    assert ParameterValue(0x42, [1, 2]).values == (1, 2)  # a list given is kept as the tuple the codec expects
