"""Station alias, ESC registers and SII files through our raw master against the simulated slave (in-process, no
root): the four places of the alias and which wins, the SII word 4 + CRC write and its power-cycle rule, the
CoE path, the register guard, SII read/write with the CRC rule and Intel HEX, and the CRC-8 vectors of the
reference (foe-alias-recorder.md B, computed with SOEM's and IgH's algorithms)."""

from __future__ import annotations

import struct
from collections.abc import Iterator

import pytest

from akdctl.connection import Connection
from akdctl.drive import alias as alias_op
from akdctl.drive import ecat_registers as regs
from akdctl.errors import CheckFailed, SafetyRefusal, UsageError
from akdctl.protocol import ethercat as ec
from akdctl.protocol.errors import CodecError
from akdctl.protocol.sii import akd_sii_image, build_sii, crc8, decode_ihex, encode_ihex
from tests.test_ecat_raw_inprocess import Wire, drive, transport, wire  # noqa: F401 - drive, wire: fixtures

AKD_WORDS = [0x0009, 0x0800, 0x0000, 0x0000]  # SII words 0-3 of the real AKD (reference B)


@pytest.mark.parametrize("alias, crc", [(0, 0x10), (1, 0x39), (1001, 0x71), (0x1234, 0xE7), (0xFFFF, 0x86)])
def test_crc8_vectors_of_the_reference(alias: int, crc: int) -> None:
    assert crc8(struct.pack("<7H", *AKD_WORDS, alias, 0, 0)) == crc
    assert alias_op.crc_of([*AKD_WORDS, alias, 0, 0, 0]) == crc


@pytest.fixture
def conn(wire: Wire) -> Iterator[Connection]:
    c = Connection.over(transport(wire))
    try:
        yield c
    finally:
        c.close()


def test_alias_via_sii_reaches_param03_now_and_the_register_after_a_power_cycle(conn: Connection, wire: Wire) -> None:
    info = alias_op.read(conn)
    assert info["register_0x0012"] == 0 and info["sii_word4"] == 0 and info["sii_crc_ok"]
    plan = alias_op.plan(conn, 1001)
    assert plan.needing_consent and "DRV.NVSAVE" in plan.consent_text
    assert [w.raw for w in plan.writes] == [1001, 0x0071]
    result = alias_op.execute(conn, plan)
    after = result["after"]
    assert after["sii_word4"] == 1001 and after["sii_word7"] & 0xFF == 0x71 and after["sii_crc_ok"]
    assert after["fbus_param03"] == 1001  # the AKD keeps the alias as FBUS.PARAM03 (seed 001 5.14)
    assert after["register_0x0012"] == 0 and result["power_cycle_needed"]  # 0x0012 loads at power-on only
    wire.face.power_cycle()
    t = conn.transport()
    t.open_bus()  # type: ignore[attr-defined]
    assert struct.unpack("<H", t.master.fprd(t.slave.station, ec.REG_STATION_ALIAS, 2))[0] == 1001  # type: ignore[attr-defined]


def test_alias_via_coe_writes_param03(conn: Connection) -> None:
    result = alias_op.execute(conn, alias_op.plan(conn, 7, via="coe"))
    assert result["after"]["fbus_param03"] == 7 and result["after"]["sii_word4"] == 0
    assert "FBUS.PARAM03" in result["after"]["effective_source"] or "rotary" in result["after"]["effective_source"]


def test_alias_out_of_range_is_usage(conn: Connection) -> None:
    with pytest.raises(UsageError, match="out of range"):
        alias_op.plan(conn, 70000)


def test_effective_source_follows_param05_bit5() -> None:
    assert alias_op.effective(5, True).startswith("FBUS.PARAM03")
    assert alias_op.effective(0, True).startswith("the rotary switches")
    assert alias_op.effective(5, False).startswith("the rotary switches if they are not 0")


def test_a_wrong_crc_in_the_eeprom_leaves_the_alias_unloaded(wire: Wire) -> None:
    wire.face.esc.eeprom[8:10] = (5).to_bytes(2, "little")  # word 4 changed, CRC not
    wire.face.power_cycle()
    assert wire.face.esc.u16(ec.REG_STATION_ALIAS) == 0
    assert wire.face.esc.u16(ec.REG_EEP_CONTROL) & ec.EEP_ERROR_CHECKSUM


def test_register_read_and_guarded_write(conn: Connection) -> None:
    assert regs.read_registers(conn, ec.REG_AL_STATUS, 2) == struct.pack("<H", ec.AlState.PREOP)
    with pytest.raises(UsageError, match="outside the ESC"):
        regs.read_registers(conn, 0xFFFF, 4)
    with pytest.raises(SafetyRefusal, match="AL control"):
        regs.plan_register_write(conn, ec.REG_AL_CONTROL, b"\x01\x00")
    with pytest.raises(SafetyRefusal, match="watchdog"):
        regs.plan_register_write(conn, 0x0420, b"\x00\x00")
    plan = regs.plan_register_write(conn, 0x0F80, b"\x01\x02")
    assert plan.needing_consent
    result = regs.execute_register_write(conn, plan)
    assert result["same"] and result["read_back"] == "0102"


def test_sii_read_write_with_the_crc_rule(conn: Connection, wire: Wire) -> None:
    image = regs.read_sii(conn)
    assert image[:4] == bytes.fromhex("09000008")
    changed = bytearray(image)
    changed[8:10] = (42).to_bytes(2, "little")  # alias 42, CRC left wrong
    with pytest.raises(UsageError, match="CRC"):
        regs.plan_sii_write(conn, bytes(changed), "x.bin")
    plan = regs.plan_sii_write(conn, bytes(changed), "x.bin", fix_crc=True)
    assert [w.address for w in plan.writes] == ["SII word 0x0004", "SII word 0x0007"]
    assert regs.execute_sii_write(conn, plan)["verified"]
    assert wire.face.esc.eeprom[8:10] == (42).to_bytes(2, "little")
    foreign = bytearray(build_sii(akd_sii_image()))
    foreign[0x10] = 0x99  # another vendor
    foreign[14] = crc8(bytes(foreign[:14]))
    with pytest.raises(SafetyRefusal, match="vendor"):
        regs.plan_sii_write(conn, bytes(foreign), "other.bin")
    with pytest.raises(UsageError, match="even number"):
        regs.plan_sii_write(conn, b"\x00" * 11, "short.bin")


def test_sii_write_verify_catches_a_word_that_does_not_stick(conn: Connection, wire: Wire) -> None:
    image = bytearray(regs.read_sii(conn))
    image[0x7E] ^= 0x01  # version word
    plan = regs.plan_sii_write(conn, bytes(image), "x.bin")
    real = wire.face.esc._eeprom_command  # noqa: SLF001

    def forgetful() -> None:  # the EEPROM acknowledges but keeps the old word
        before = bytes(wire.face.esc.eeprom)
        real()
        wire.face.esc.eeprom[:] = before
    wire.face.esc._eeprom_command = forgetful  # type: ignore[method-assign]  # noqa: SLF001
    with pytest.raises(CheckFailed, match="SII word 0x003F"):
        regs.execute_sii_write(conn, plan)


def test_intel_hex_round_trip_and_defects() -> None:
    data = bytes(range(256)) + b"\x01\x02\x03"
    text = encode_ihex(data)
    assert decode_ihex(text) == data
    with pytest.raises(CodecError, match="checksum"):
        decode_ihex(text.replace(":10000000000102", ":10000000000103", 1))
    with pytest.raises(CodecError, match="no end record"):
        decode_ihex(text.rsplit(":00000001FF", 1)[0])


def test_a_second_slave_without_a_position_is_refused(wire: Wire, monkeypatch: pytest.MonkeyPatch) -> None:
    from akdctl.transport.ethercat_raw import EthercatRawTransport
    from akdctl.transport.registry import parse_target

    t = transport(wire)
    bare = EthercatRawTransport(parse_target("ecat://pair0"), t.options)  # no /POSITION
    bare.master = t.master
    conn = Connection.over(bare)
    conn.transport()
    monkeypatch.setattr(bare.master, "count_slaves", lambda: 2)
    with pytest.raises(UsageError, match="2 slaves answer .*name the one to change with its position"):
        alias_op.plan(conn, 5)
    conn.close()
