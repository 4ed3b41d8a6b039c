"""Parameter-object rules of the AKD manual [M-25], [M-26] (reference/ethernetip.md 1.9): type and length read
before every write, floats x1000, 64-bit parameters take a 32-bit value, commands are a 1-byte write, names only
from the cited table."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from akdctl.catalog import eip_parameters
from akdctl.drive import eip_params
from akdctl.errors import UsageError


class FakeChannel:
    """Records Get/Set_Attribute_Single on class 0x0F; instances: {n: (type code, length, value bytes)}."""

    def __init__(self, instances: dict[int, tuple[int, int, bytes]]) -> None:
        self.instances = instances
        self.calls: list[tuple[str, int, int, bytes]] = []

    def get(self, class_id: int, instance: int, attribute: int) -> bytes:
        assert class_id == 0x0F
        self.calls.append(("get", instance, attribute, b""))
        code, size, value = self.instances[instance]
        return {1: value, 5: bytes([code]), 6: bytes([size])}[attribute]

    def set(self, class_id: int, instance: int, attribute: int, data: bytes) -> None:
        self.calls.append(("set", instance, attribute, data))


def test_every_table_row_names_a_source_and_is_unique() -> None:
    names = [p.name for p in eip_parameters.PARAMETERS]
    instances = [p.instance for p in eip_parameters.PARAMETERS]
    assert len(set(names)) == len(names) and len(set(instances)) == len(instances)
    assert all(p.source.startswith("http") for p in eip_parameters.PARAMETERS)
    assert eip_parameters.by_name("eip.posunit").instance == 796 and eip_parameters.by_name("HOME.MOVE").instance == 205


def test_unknown_names_are_refused_locally_and_numbers_pass() -> None:
    with pytest.raises(UsageError, match="unknown AKD parameter 'DRV.OPMODE'"):
        eip_params.resolve("DRV.OPMODE")
    assert eip_params.resolve("0x31C").name == "EIP.POSUNIT"
    assert eip_params.resolve("4242").kind == "?"
    with pytest.raises(UsageError):
        eip_params.resolve("0")


def test_write_reads_type_and_length_first_and_scales_floats() -> None:
    channel = FakeChannel({1: (0xC8, 4, bytes(4))})                      # AIN.CUTOFF, 4 B float [RSL-74]
    result = eip_params.write(channel, eip_params.resolve("AIN.CUTOFF"), "1.001")
    assert channel.calls[:2] == [("get", 1, 5, b""), ("get", 1, 6, b"")]
    assert channel.calls[2] == ("set", 1, 1, (1001).to_bytes(4, "little")) and result["written"] == "e9030000"
    channel.instances[1] = (0xC8, 4, (2500).to_bytes(4, "little"))
    assert eip_params.read(channel, eip_params.resolve("AIN.CUTOFF"))["value"] == 2.5


def test_64_bit_parameters_take_a_32_bit_value_and_lengths_are_exact() -> None:
    channel = FakeChannel({5: (0xC5, 8, bytes(8)), 11: (0xC3, 2, bytes(2))})
    eip_params.write(channel, eip_params.resolve("AIN.PSCALE"), "-5")
    assert channel.calls[-1] == ("set", 5, 1, (-5).to_bytes(4, "little", signed=True))
    eip_params.write(channel, eip_params.resolve("AIN.PSCALE"), str(1 << 40))
    assert channel.calls[-1][3] == (1 << 40).to_bytes(8, "little")
    eip_params.write(channel, eip_params.resolve("AOUT.MODE"), "3")
    assert channel.calls[-1] == ("set", 11, 1, b"\x03\x00")
    with pytest.raises(UsageError, match="does not fit"):
        eip_params.write(channel, eip_params.resolve("AOUT.MODE"), "70000")


def test_commands_are_a_one_byte_write_and_not_a_value() -> None:
    channel = FakeChannel({9: (0xC6, 1, b"\x00")})
    with pytest.raises(UsageError, match="is a command"):
        eip_params.write(channel, eip_params.resolve("AIN.ZERO"), "1")
    conn = SimpleNamespace(cip=lambda: channel, target=SimpleNamespace(display="fake"))
    plan = eip_params.plan_command(conn, eip_params.resolve("AIN.ZERO"))
    assert channel.calls == [] and plan.operation == "eip param run" and not plan.needing_consent
    eip_params.execute(conn, plan)
    assert channel.calls == [("set", 9, 1, b"\x01")]
    assert eip_params.plan_command(conn, eip_params.resolve("HOME.MOVE")).needing_consent  # starts homing
    with pytest.raises(UsageError, match="not a command parameter"):
        eip_params.plan_command(conn, eip_params.resolve("AOUT.MODE"))
