"""Reading and decoding fault dumps (akdctl.drive.faults): consistency loops, decoding, unknown numbers.

SPEC-NOTES 14: read 944, 947, 944 again and retry when the counter moved. SPEC-NOTES 21: the CoE view.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.drive import faults as df
from akdctl.errors import ParameterRefused
from akdctl.protocol.emcy import Emergency
from akdctl.protocol.bmp import ParameterAddress, ParameterFailure, ParameterValue


class ScriptedChannel:
    """A ParameterChannel whose PNU 944 answers follow a script (the counter moving mid-dump)."""

    def __init__(self, counters: list[int], buffer: list[int], zsw1: int = 0x0208) -> None:
        self.counters = list(counters)
        self.buffer = buffer
        self.zsw1 = zsw1
        self.requests = 0
        self.log: list[list[int]] = []

    def read(self, addresses: Sequence[ParameterAddress]) -> list[Any]:
        self.requests += 1
        self.log.append([a.pnu for a in addresses])
        out: list[Any] = []
        for a in addresses:
            if a.pnu == 944:
                value = self.counters.pop(0) if len(self.counters) > 1 else self.counters[0]
                out.append(ParameterValue(0x42, (value,)))
            elif a.pnu == 947:
                out.append(ParameterValue(0x42, tuple(self.buffer[a.subindex : a.subindex + a.count])))
            elif a.pnu == 2:
                out.append(ParameterValue(0x42, (self.zsw1,)))
            else:
                out.append(ParameterFailure(0x00))
        return out


def test_counter_moving_once_is_retried_and_consistent() -> None:
    buffer = [501, 502] + [0] * 6 + [234] + [0] * 55
    channel = ScriptedChannel([3, 4, 4, 4], buffer)
    result = df.read_profidrive_faults(channel)
    assert result.consistent and result.attempts == 2 and result.counter == 4
    assert [e.code for e in result.active] == ["F501", "F502"]
    assert result.acknowledged[0]["situation"] == 1 and result.acknowledged[0]["faults"][0].code == "F234"
    # each attempt: 944 (with ZSW1), then 947, then 944 -- three round trips
    assert channel.log[:3] == [[944, 2], [947], [944]]


def test_counter_that_never_settles_gives_up_and_says_so() -> None:
    channel = ScriptedChannel(list(range(100)), [0] * 64)
    result = df.read_profidrive_faults(channel, max_attempts=3)
    assert not result.consistent and result.attempts == 3
    assert result.to_json()["consistent"] is False


def test_refused_fault_pnu_raises_parameter_refused() -> None:
    class Refusing(ScriptedChannel):
        def read(self, addresses: Sequence[ParameterAddress]) -> list[Any]:
            return [ParameterFailure(0x00) for _ in addresses]

    with pytest.raises(ParameterRefused):
        df.read_profidrive_faults(Refusing([0], [0] * 64))


def test_unknown_numbers_are_shown_as_unknown() -> None:
    active, acked = df.split_buffer([501, 9999] + [0] * 6 + [0] * 8 + [12345] + [0] * 47)
    assert [e.kind for e in active] == ["fault", "unknown"]
    assert active[1].code == "F9999?" and "unknown" in active[1].name
    assert acked == [{"situation": 2, "faults": [df.decode_number(12345)]}]
    warning = df.decode_number(4444, warning=True)
    assert warning.kind == "unknown" and warning.code == "n4444?"
    entry = df.decode_error_field(0xABCD0000 | 0x1234)
    assert entry["known"] is False and "unknown" in entry["text"]
    emcy = df.decode_emergency(Emergency(0x1234, 0x01, b"\xff\xff\x00\x00\x00"))
    assert emcy["faults"] == [] and "0x1234" in emcy["text"]


def test_error_field_narrows_to_the_number_in_the_upper_half() -> None:
    assert df.decode_error_field(0x3210 | (501 << 16))["faults"] == ["F501"]
    shared = df.decode_error_field(0x3210)  # no number: every fault with that code
    assert "F501" in shared["faults"] and shared["known"]


@given(st.lists(st.integers(min_value=0, max_value=0xFFFF), min_size=0, max_size=64))
def test_split_buffer_never_raises_and_keeps_every_nonzero_number(values: list[int]) -> None:
    active, acked = df.split_buffer(values)
    kept = [e.number for e in active] + [e.number for s in acked for e in s["faults"]]
    assert kept == [v for v in values if v]


@given(st.integers(min_value=0, max_value=0xFFFFFFFF))
def test_error_field_decoding_never_raises(value: int) -> None:
    entry = df.decode_error_field(value)
    assert entry["raw"] == f"0x{value:08X}"


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFF), st.binary(max_size=5))
def test_emergency_decoding_never_raises(code: int, register: int, data: bytes) -> None:
    assert df.decode_emergency(Emergency(code, register, data))["emcy"] == f"0x{code:04X}"


# ---------------------------------------------------------------------------- against the simulator
def _sim_transport(tmp_path: Any, query: str = "") -> Any:
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target
    from akdctl.transport.sim import SimTransport

    return Connection.over(SimTransport(parse_target("sim" + query, "test"), LinkOptions(timeout=2.0)))


def _with_model(fn: Any) -> None:
    from akdctl.sim.drive import SimDrive

    with SimDrive("default").transaction() as model:
        fn(model.component("faults"))


def test_sim_pnu_dump_retries_when_a_fault_rises_between_reads(tmp_path: Any) -> None:
    transport = _sim_transport(tmp_path)
    _with_model(lambda c: c.arm("F501", 1))  # raised right after the first 944 read
    result = df.read_profidrive_faults(transport.parameters())
    assert result.attempts == 2 and result.consistent
    assert result.counter == 1 and [e.code for e in result.active] == ["F501"]
    assert result.zsw1 is not None and result.zsw1 & 0x08


def test_sim_coe_dump_retries_when_a_fault_rises_mid_read(tmp_path: Any) -> None:
    transport = _sim_transport(tmp_path, "?drive=cia402")
    _with_model(lambda c: c.arm("F502", 6))  # somewhere inside the object reads
    result = df.read_canopen_faults(transport.objects())
    assert result.attempts == 2 and result.consistent
    assert [e.code for e in result.faults] == ["F502"]
    assert [e.code for e in result.history] == ["F502"]
    assert result.error_field[0]["faults"] == ["F502"]
    assert result.error_register == 0x05
    assert [e["emcy"] for e in result.emergencies] == ["0x3220"]


def test_sim_coe_dump_decodes_warnings_and_history(tmp_path: Any) -> None:
    transport = _sim_transport(tmp_path, "?drive=cia402")

    def inject(comp: Any) -> None:
        comp.raise_fault("F501")
        comp.acknowledge()
        comp.raise_fault("F234")
        comp.raise_fault("n503")

    _with_model(inject)
    result = df.read_canopen_faults(transport.objects()).to_json()
    assert [f["code"] for f in result["faults"]] == ["F234"]
    assert [w["code"] for w in result["warnings"]] == ["n503"]
    assert [h["code"] for h in result["fault_history"]] == ["F234", "F501"]
    assert result["fault_present"] and result["warning_present"]
    assert result["errors"] == {}
