"""Catalogue data: object dictionary, fixed PDOs, faults, error texts."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.catalog import faults, objects, texts
from akdctl.catalog.objects import PdoEntry

REPO = Path(__file__).resolve().parent.parent


# --- fixed PDOs (SPEC-NOTES 16, 19) -----------------------------------------------------

FIXED_SIZES = {
    0x1701: 6, 0x1702: 6, 0x1720: 14, 0x1721: 8, 0x1722: 16, 0x1723: 16, 0x1724: 8, 0x1725: 16,
    0x1B01: 6, 0x1B20: 32, 0x1B21: 6, 0x1B22: 32, 0x1B23: 32, 0x1B24: 6, 0x1B25: 32, 0x1B26: 18,
}


@pytest.mark.parametrize("number,size", sorted(FIXED_SIZES.items()))
def test_fixed_pdo_sizes(number: int, size: int) -> None:
    entries = objects.fixed_pdo(number)
    assert entries is not None
    assert objects.pdo_bytes(entries) == size


def test_fixed_pdo_sets_are_exactly_the_esi_ones() -> None:
    # SPEC-NOTES 16: 0x1704 is not an AKD PDO.
    assert set(objects.FIXED_RX_PDOS) == {0x1701, 0x1702, *range(0x1720, 0x1726)}
    assert set(objects.FIXED_TX_PDOS) == {0x1B01, *range(0x1B20, 0x1B27)}
    assert objects.fixed_pdo(0x1704) is None
    assert objects.DEFAULT_RX_PDO in objects.FIXED_RX_PDOS and objects.DEFAULT_TX_PDO in objects.FIXED_TX_PDOS


@pytest.mark.parametrize("number", sorted(FIXED_SIZES))
def test_fixed_pdo_constants_match_the_table(number: int) -> None:
    """The hand-written constants equal the defaults generated from the ESI."""
    entries = objects.fixed_pdo(number)
    sub0 = objects.lookup(number, 0)
    assert sub0 is not None and sub0.default == len(entries) and sub0.access == "ro"
    for n, entry in enumerate(entries, start=1):
        row = objects.lookup(number, n)
        assert row is not None and row.default == entry.mapping_value


@pytest.mark.parametrize("number", sorted(FIXED_SIZES))
def test_fixed_pdo_entries_are_mappable_objects(number: int) -> None:
    rx = number in objects.FIXED_RX_PDOS
    for entry in objects.fixed_pdo(number):
        obj = objects.lookup(entry.index, entry.subindex)
        assert obj is not None, entry
        assert obj.bits == entry.bits
        assert (obj.rx_mappable if rx else obj.tx_mappable), entry


def test_manual_example_1702_mapping() -> None:
    # EtherCAT manual 5.5: 0x1702 sub 1 reads 0x60FF0020, sub 2 0x60400010.
    assert [e.mapping_value for e in objects.FIXED_RX_PDOS[0x1702]] == [0x60FF0020, 0x60400010]


def test_flexible_pdos_and_limits() -> None:
    # SPEC-NOTES 18.
    assert list(objects.FLEXIBLE_RX) == [0x1600, 0x1601, 0x1602, 0x1603]
    assert list(objects.FLEXIBLE_TX) == [0x1A00, 0x1A01, 0x1A02, 0x1A03]
    assert (objects.PDO_MAX_BYTES, objects.RX_TOTAL_MAX_BYTES, objects.TX_TOTAL_MAX_BYTES) == (8, 22, 32)
    assert objects.RX_DUMMY.mapping_value == 0x00020008
    assert [e.mapping_value for e in objects.TX_PADDING] == [0x20020108, 0x20020208, 0x20020308, 0x20020408]
    dummy = objects.lookup(0x0002, 0)
    assert dummy is not None and dummy.rx_mappable and dummy.bits == 8
    for pad in objects.TX_PADDING:
        obj = objects.lookup(pad.index, pad.subindex)
        assert obj is not None and obj.tx_mappable and obj.bits == 8
    for number in objects.FLEXIBLE_RX:
        assert objects.lookup(number, 8) is not None and objects.lookup(number, 8).writable
        assert objects.is_rx_pdo(number) and not objects.is_tx_pdo(number)
    assert objects.lookup(0x1600, 1).default == 0x60400010
    assert objects.lookup(0x1A00, 1).default == 0x60410010
    assert objects.pdo_bytes([]) == 0
    assert objects.pdo_bytes([PdoEntry(0x6040, 0, 16), objects.RX_DUMMY]) == 3


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFF), st.integers(0, 0xFF))
def test_mapping_value_round_trip(index: int, sub: int, bits: int) -> None:
    entry = PdoEntry(index, sub, bits)
    assert PdoEntry.from_mapping_value(entry.mapping_value) == entry


@given(st.integers(0, 0xFFFFFFFF))
def test_mapping_value_from_any_u32(value: int) -> None:
    assert PdoEntry.from_mapping_value(value).mapping_value == value


@given(st.one_of(st.integers(max_value=-1), st.integers(min_value=1 << 32)))
def test_mapping_value_out_of_range(value: int) -> None:
    with pytest.raises(ValueError):
        PdoEntry.from_mapping_value(value)


# --- object dictionary ------------------------------------------------------------------

# (type, access, pdo) per reference/cia402_and_canopen_reference.md (AKD ESI v2.50).
CIA402 = {
    0x1000: ("UDINT", "ro", ""), 0x1001: ("USINT", "ro", ""), 0x1002: ("UDINT", "ro", "T"),
    0x1014: ("UDINT", "rw", ""),
    0x6040: ("UINT", "rw", "R"), 0x6041: ("UINT", "ro", "T"), 0x605A: ("INT", "rw", ""),
    0x6060: ("SINT", "rw", "R"), 0x6061: ("SINT", "ro", "T"), 0x6063: ("DINT", "ro", "T"),
    0x6064: ("DINT", "ro", "T"), 0x6065: ("UDINT", "rw", ""), 0x606C: ("DINT", "ro", "T"),
    0x6071: ("INT", "rw", "R"), 0x6072: ("UINT", "rw", "R"), 0x6077: ("INT", "ro", "T"),
    0x607A: ("DINT", "rw", "R"), 0x607C: ("DINT", "rw", ""), 0x6081: ("UDINT", "rw", "R"),
    0x6083: ("UDINT", "rw", "R"), 0x6084: ("UDINT", "rw", "R"), 0x6087: ("UDINT", "rw", "R"),
    0x6098: ("SINT", "rw", ""), 0x609A: ("UDINT", "rw", ""), 0x60B1: ("DINT", "rw", "R"),
    0x60B2: ("INT", "rw", "R"), 0x60B8: ("UINT", "rw", "R"), 0x60B9: ("UINT", "rw", "T"),
    0x60C0: ("INT", "rw", ""), 0x60E0: ("UINT", "rw", "R"), 0x60E1: ("UINT", "rw", "R"),
    0x60F4: ("DINT", "ro", "T"), 0x60FC: ("DINT", "ro", "T"), 0x60FD: ("UDINT", "ro", "T"),
    0x60FF: ("DINT", "rw", "R"), 0x6502: ("UDINT", "ro", ""),
}
CIA402_SUBS = {
    (0x1003, 0): ("USINT", "rw"), (0x1003, 1): ("UDINT", "ro"), (0x1003, 10): ("UDINT", "ro"),
    (0x1018, 1): ("UDINT", "ro"), (0x1018, 4): ("UDINT", "ro"),
    (0x607D, 1): ("DINT", "rw"), (0x607D, 2): ("DINT", "rw"),
    (0x608F, 1): ("UDINT", "rw"), (0x6091, 2): ("UDINT", "rw"), (0x6092, 1): ("UDINT", "rw"),
    (0x6099, 1): ("UDINT", "rw"), (0x6099, 2): ("UDINT", "rw"),
    (0x60C1, 1): ("DINT", "rw"), (0x60C2, 1): ("USINT", "rw"), (0x60C2, 2): ("SINT", "rw"),
    (0x60FE, 1): ("UDINT", "rw"), (0x60FE, 2): ("UDINT", "rw"),
}


@pytest.mark.parametrize("index", sorted(CIA402))
def test_cia402_objects(index: int) -> None:
    entry = objects.lookup(index, 0)
    assert entry is not None
    assert (entry.type, entry.access, entry.pdo) == CIA402[index]
    assert objects.subentries(index) == [entry]


@pytest.mark.parametrize("key", sorted(CIA402_SUBS))
def test_cia402_record_members(key: tuple[int, int]) -> None:
    entry = objects.lookup(*key)
    assert entry is not None
    assert (entry.type, entry.access) == CIA402_SUBS[key]


def test_object_details() -> None:
    assert objects.lookup(0x603F, 0) is None and objects.object_name(0x603F) is None  # SPEC-NOTES 21
    cw = objects.lookup(0x6040, 0)
    assert cw.param == "controlword" and cw.short_type == "u16" and cw.readable and cw.writable
    assert objects.object_name(0x6040) == "Controlword"
    assert objects.object_name(0x60C2) == "Interpolation time period"
    assert objects.lookup(0x1000, 0).default == 0x00020192
    assert objects.lookup(0x1018, 1).default == 0x6A and objects.lookup(0x1018, 2).default == 0x00414B44
    assert objects.lookup(0x6060, 0).default == 7
    assert objects.lookup(0x60C2, 1).default == 2 and objects.lookup(0x60C2, 2).default == -3
    assert objects.lookup(0x60C2, 2).short_type == "i8"
    assert objects.lookup(0x3470, 4).param == "AIN.VALUE"
    assert objects.lookup(0x6081, 0).param == "MT.V"
    assert objects.lookup(0x5084, 0).param == "DRV.IPEAK"  # 0x5xxx names carry an 'M' suffix
    assert objects.lookup(0x2031, 0).short_type == "vs"
    assert objects.lookup(0x6041, 0).readable and not objects.lookup(0x6041, 0).writable
    assert [e.subindex for e in objects.subentries(0x1C12)] == [0, 1, 2, 3, 4]
    assert objects.lookup(0x1C12, 1).type == "UINT" and objects.lookup(0x1C12, 1).writable
    assert objects.lookup(0x1C13, 0).default == 4
    assert objects.subentries(0xDEAD) == []
    keys = list(objects.entries())
    assert keys == sorted(keys)


def test_fault_and_warning_objects() -> None:
    # SPEC-NOTES 21: 0x2000 warnings, 0x2001 faults, 0x2002 status bytes, 0x2012/0x2013 history.
    warn = objects.subentries(0x2000)
    assert [e.param for e in warn[1:]] == ["DRV.WARNING1", "DRV.WARNING2", "DRV.WARNING3"]
    assert all(e.type == "UDINT" for e in warn[1:])
    flt = objects.subentries(0x2001)
    assert len(flt) == 11 and all(e.type == "UINT" and e.access == "ro" for e in flt[1:])
    assert flt[10].param == "DRV.FAULT10"
    assert [e.type for e in objects.subentries(0x2002)[1:]] == ["USINT"] * 4
    for index in (0x2012, 0x2013):
        subs = objects.subentries(index)
        assert len(subs) == 21 and subs[0].default == 20
        assert all(e.type == "UDINT" for e in subs[1:])


def test_short_types_agree_with_datatypes() -> None:
    if importlib.util.find_spec("akdctl.protocol.datatypes") is None:
        pytest.skip("akdctl.protocol.datatypes not present")
    from akdctl.protocol import datatypes

    for entry in objects.entries().values():
        assert entry.short_type == datatypes.type_for_esi(entry.type), entry


def test_search_and_params() -> None:
    assert [e.key for e in objects.search("6040")] == [(0x6040, 0)]
    assert [e.key for e in objects.search("0x60c2:02")] == [(0x60C2, 2)]
    assert {e.index for e in objects.search("60C2")} == {0x60C2}
    assert 0x60F4 in {e.index for e in objects.search("following error")}
    assert {e.index for e in objects.search("drv.fault")} >= {0x2001}
    assert objects.search("") == [] and objects.search("no such thing at all") == []
    assert [e.key for e in objects.by_param("CONTROLWORD")] == [(0x6040, 0)]
    assert objects.by_param("nothing") == []
    assert objects.indices()[0] == 0x0002


@pytest.mark.slow
def test_import_is_cheap() -> None:
    code = (
        "import sys, akdctl.catalog.objects as o, akdctl.catalog.faults as f, akdctl.catalog.texts\n"
        "print('rich' in sys.modules, 'click' in sys.modules, o._lines.cache_info().currsize, "
        "f.faults.cache_info().currsize)"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "False", "0", "0"]


def test_generator_on_a_small_esi(tmp_path: Path) -> None:
    """tools/gen_objects.py: newest revision, record expansion, defaults, fixed PDO fill, params."""
    spec = importlib.util.spec_from_file_location("gen_objects", REPO / "tools" / "gen_objects.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    xml = textwrap.dedent("""\
        <EtherCATInfo><Descriptions><Devices>
        <Device><Type ProductCode="#x1" RevisionNo="#x1">old</Type><Profile><Dictionary>
          <DataTypes><DataType><Name>UINT</Name><BitSize>16</BitSize></DataType></DataTypes>
          <Objects><Object><Index>#x7000</Index><Name>Old</Name><Type>UINT</Type><BitSize>16</BitSize>
            <Flags><Access>ro</Access></Flags></Object></Objects>
        </Dictionary></Profile></Device>
        <Device><Type ProductCode="#x00414B44" RevisionNo="#x00260000">new</Type><Profile><Dictionary>
          <DataTypes>
            <DataType><Name>UINT</Name><BitSize>16</BitSize></DataType>
            <DataType><Name>SINT</Name><BitSize>8</BitSize></DataType>
            <DataType><Name>UDINT</Name><BitSize>32</BitSize></DataType>
            <DataType><Name>USINT</Name><BitSize>8</BitSize></DataType>
            <DataType><Name>DT1B99</Name><BitSize>48</BitSize>
              <SubItem><SubIdx>0</SubIdx><Name>Highest sub-index supported</Name><Type>USINT</Type>
                <BitSize>8</BitSize><Flags><Access>ro</Access></Flags></SubItem>
              <SubItem><SubIdx>1</SubIdx><Name>Mapping entry 1</Name><Type>UDINT</Type>
                <BitSize>32</BitSize><Flags><Access>ro</Access></Flags></SubItem></DataType>
            <DataType><Name>DTARR</Name><BaseType>USINT</BaseType><BitSize>16</BitSize>
              <ArrayInfo><LBound>1</LBound><Elements>2</Elements></ArrayInfo></DataType>
            <DataType><Name>DT1C00</Name><BitSize>32</BitSize>
              <SubItem><SubIdx>0</SubIdx><Name>Count</Name><Type>USINT</Type><BitSize>8</BitSize>
                <Flags><Access>ro</Access></Flags></SubItem>
              <SubItem><Name>Elements</Name><Type>DTARR</Type><BitSize>16</BitSize>
                <Flags><Access>ro</Access></Flags></SubItem></DataType>
          </DataTypes>
          <Objects>
            <Object><Index>#x6040</Index><Name>Controlword</Name><Type>UINT</Type><BitSize>16</BitSize>
              <Flags><Access>rw</Access><PdoMapping>R</PdoMapping></Flags></Object>
            <Object><Index>#x60C2</Index><Name>Index</Name><Type>SINT</Type><BitSize>8</BitSize>
              <Info><DefaultData>fd</DefaultData></Info><Flags><Access>rw</Access></Flags></Object>
            <Object><Index>#x5084</Index><Name>DRV.IPEAKM</Name><Type>UDINT</Type><BitSize>32</BitSize>
              <Info><DefaultData>10270000</DefaultData></Info><Flags><Access>ro</Access></Flags></Object>
            <Object><Index>#x1B99</Index><Name>TPDO</Name><Type>DT1B99</Type><BitSize>48</BitSize>
              <Info><SubItem><Name>Highest sub-index supported</Name><Info><DefaultData>01</DefaultData></Info>
              </SubItem><SubItem><Name>Mapping entry 1</Name><Info><DefaultData>00000000</DefaultData></Info>
              </SubItem></Info><Flags><Access>ro</Access></Flags></Object>
            <Object><Index>#x1C00</Index><Name>SM types</Name><Type>DT1C00</Type><BitSize>32</BitSize>
              <Info><SubItem><Name>Count</Name><Info><DefaultData>02</DefaultData></Info></SubItem>
              <SubItem><Name>SubIndex 001</Name><Info><DefaultData>01</DefaultData></Info></SubItem>
              <SubItem><Name>SubIndex 002</Name><Info><DefaultData>02</DefaultData></Info></SubItem></Info>
              <Flags><Access>ro</Access></Flags></Object>
          </Objects>
        </Dictionary></Profile>
        <TxPdo Fixed="1"><Index>#x1B99</Index><Name>In</Name>
          <Entry><Index>#x6040</Index><SubIndex>0</SubIndex><BitLen>16</BitLen><Name>Controlword</Name></Entry>
        </TxPdo></Device>
        </Devices></Descriptions></EtherCATInfo>
        """)
    path = tmp_path / "esi.xml"
    path.write_text(xml)
    out = tmp_path / "objects.tsv"
    assert gen.main([str(path), "-o", str(out)]) == 0
    rows = [line.split("\t") for line in out.read_text().splitlines() if not line.startswith("#")]
    header, body = rows[0], rows[1:]
    table = {(r[0], r[1]): dict(zip(header, r)) for r in body}
    assert ("0x7000", "0") not in table  # only the newest revision
    assert table[("0x6040", "0")]["param"] == "controlword" and table[("0x6040", "0")]["pdo"] == "R"
    assert table[("0x60C2", "0")]["default"] == "-3"
    assert table[("0x5084", "0")]["param"] == "DRV.IPEAK" and table[("0x5084", "0")]["default"] == "0x00002710"
    assert table[("0x1B99", "1")]["default"] == "0x60400010"  # filled from the PDO description
    assert [table[("0x1C00", s)]["name"] for s in ("1", "2")] == ["SubIndex 001", "SubIndex 002"]
    assert table[("0x1C00", "2")]["default"] == "2"
    assert ("0x0002", "0") in table  # the dummy object supplement


# --- faults -----------------------------------------------------------------------------

def test_fault_lookups() -> None:
    f501 = faults.by_code("F501")
    assert f501 is not None and f501.number == 501 and f501.kind == "fault" and f501.emcy == 0x3210
    for spelling in ("f501", " F501 ", "F0501", 501, "501"):
        assert faults.by_code(spelling) == f501
    n503 = faults.by_code("n503")
    assert n503 is not None and n503.is_warning and n503.emcy == 0x3180
    assert faults.by_code("N503") == n503
    assert faults.by_number(503, warning=True) == n503
    assert faults.by_number(503) == faults.by_code("F503")
    assert faults.by_number(702, warning=True) == faults.by_code("n702")
    for bad in ("F9999", "x501", "", "F", None, 1234, True, 3.5):
        assert faults.by_code(bad) is None  # type: ignore[arg-type]
    assert faults.by_emcy(0x3210) == [f501]
    assert faults.by_emcy(0x1234) == []


def test_fault_texts() -> None:
    assert faults.describe_number(501) == "F501 DC Bus link over-voltage"
    assert faults.describe_number(1234) == "unknown fault 1234"
    assert faults.describe_number("junk") == "unknown fault 'junk'"  # type: ignore[arg-type]
    assert faults.emcy_text(0) == "no error (emergency reset)"
    assert faults.emcy_text(0x3210) == "F501 DC Bus link over-voltage"
    assert faults.emcy_text(0xABCD) == "emergency 0xABCD"


def test_fault_table_integrity() -> None:
    table = faults.faults()
    assert len(table) > 200
    codes = [f.code for f in table if f.code]
    assert len(codes) == len(set(codes))
    for f in table:
        assert 0 <= f.emcy <= 0xFFFF
        assert f.kind in ("fault", "warning", "none")
        if f.code:
            assert f.code[0] in "Fn" and int(f.code[1:]) == f.number
            assert f.kind == {"F": "fault", "n": "warning"}[f.code[0]], f  # the AKD's prefix says it (F139)
        if f.remedy:
            assert "remedy" in f.source  # every remedy names where it came from
    f404 = faults.by_code("F404")
    assert f404.reaction == "dynamic braking" and f404.remedy


# --- texts ------------------------------------------------------------------------------

def test_sdo_abort_texts() -> None:
    assert texts.sdo_abort_text(0x06020000) == "Object does not exist in the object dictionary"
    assert texts.sdo_abort_text(0x06010003).startswith("Subindex cannot be written")
    assert texts.sdo_abort_text(0x12345678) == "unknown SDO abort code 0x12345678"
    assert "0x" not in texts.sdo_abort_text(0x08000022)


def test_abort_and_mailbox_codes_cover_the_protocol_layer() -> None:
    if importlib.util.find_spec("akdctl.protocol.coe") is None:
        pytest.skip("akdctl.protocol.coe not present")
    from akdctl.protocol import coe, mailbox

    assert set(getattr(coe, "ABORT_TEXTS", {})) <= set(texts.SDO_ABORT_TEXTS)
    assert set(getattr(mailbox, "MAILBOX_ERROR_TEXTS", {})) <= set(texts.MAILBOX_ERROR_TEXTS)


def test_profidrive_texts() -> None:
    assert texts.profidrive_error_text(0x00) == "Impermissible parameter number"
    assert texts.profidrive_error_text(0x16).startswith("Parameter address impermissible")
    assert texts.profidrive_error_text(0x70) == "manufacturer-specific PROFIdrive error 0x70"
    assert texts.profidrive_error_text(0x24) == "unknown PROFIdrive error 0x24"
    assert 0x03 in texts.PROFIDRIVE_SUBINDEX_INFO_ERRORS


def test_pnio_status_texts() -> None:
    assert texts.pnio_status_text(0, 0, 0, 0) == "OK [00 00 00 00]"
    busy = texts.pnio_status_text(0xDE, 0x80, 0xB5, 0x00)
    assert busy.startswith("read error: access: state conflict") and "try again" in busy
    assert busy.endswith("[DE 80 B5 00]")
    assert "invalid index" in texts.pnio_status_text(0xDF, 0x80, 0xB0, 0x00)
    refused = texts.pnio_status_text(0xDB, 0x81, 0x01, 0x04)
    assert "AR type not supported" in refused and refused.startswith("connect error")
    assert texts.pnio_status_text(0x12, 0x80, 0x99, 0x00) == "error 0x12: unknown record error 0x99 [12 80 99 00]"
    assert "user-specific" in texts.pnio_status_text(0xDE, 0x80, 0xAB, 0)
    assert "unknown error decode 0x07" in texts.pnio_status_text(0xDE, 0x07, 0, 0)
    assert set(range(0xB0, 0xBA)) <= set(texts.RECORD_ERROR_TEXTS)
    assert {0xDB, 0xDC, 0xDE, 0xDF} <= set(texts.PNIO_ERROR_CODE_TEXTS)


@given(st.integers(0, 255), st.integers(0, 255), st.integers(0, 255), st.integers(0, 255))
def test_pnio_status_text_never_fails(b0: int, b1: int, b2: int, b3: int) -> None:
    text = texts.pnio_status_text(b0, b1, b2, b3)
    assert text.endswith(f"[{b0:02X} {b1:02X} {b2:02X} {b3:02X}]")


def test_al_status_texts() -> None:
    # SPEC-NOTES 22: the AKD reports 0x0000, 0x0011 and 0x0017.
    for code in texts.AKD_AL_STATUS_CODES:
        assert code in texts.AL_STATUS_CODE_TEXTS
    assert texts.al_status_text(0x0011) == "Invalid requested state change"
    assert texts.al_status_text(0x0017) == "Invalid sync manager configuration"
    assert texts.al_status_text(0x0077) == "unknown AL status code 0x0077"
    assert texts.al_status_text(0x8001) == "vendor-specific AL status code 0x8001"


def test_error_register_and_mailbox_texts() -> None:
    assert texts.error_register_text(0) == "no error"
    assert texts.error_register_text(0x05) == "generic error, voltage"
    assert texts.error_register_text(0x80) == "manufacturer specific"
    assert texts.ERROR_REGISTER_BITS[3] == "temperature"
    assert texts.mailbox_error_text(2) == "Mailbox protocol not supported"
    assert texts.mailbox_error_text(0x99) == "unknown mailbox error 0x0099"


@given(st.integers(-(1 << 40), 1 << 40))
def test_text_lookups_never_raise(code: int) -> None:
    for fn in (texts.sdo_abort_text, texts.profidrive_error_text, texts.al_status_text,
               texts.mailbox_error_text, texts.error_register_text, faults.describe_number, faults.emcy_text):
        assert isinstance(fn(code), str)


def test_one_object_found_by_search_is_the_whole_table_split() -> None:
    """``_object_lines`` finds an object's rows by searching the text (the generator sorts the rows, so each object is
    one block): the same rows the full split groups, for every object, and nothing for an index the table lacks."""
    header, grouped = objects._lines()
    assert objects._header() == header
    for index, lines in grouped.items():
        assert objects._object_lines(index) == lines, hex(index)
    assert objects._object_lines(0x0001) is None and objects.lookup(0x10000, 0) is None
