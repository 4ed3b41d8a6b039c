"""``akdctl pdo`` through the real CLI against the simulated AKD (EtherCAT manual 5.5-5.7, SPEC-NOTES 16-19)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from akdctl.catalog import objects as oc

# EtherCAT manual 5.6.1, the startup-SDO list of the flexible-mapping example, entry for entry:
# (transition, index:sub, data, comment). Comments the manual truncates ("entr...", "i...") are prefixes.
MANUAL_5_6_1 = [
    ("<PS>", "0x1C12:00", "0x00 (0)", "clear sm pdos (0x1C12)"),
    ("<PS>", "0x1C13:00", "0x00 (0)", "clear sm pdos (0x1C13)"),
    ("<PS>", "0x1A00:00", "0x00 (0)", "clear pdo 0x1A00 entries"),
    ("<PS>", "0x1A00:01", "0x60410010 (1614872592)", "download pdo 0x1A00 entry"),
    ("<PS>", "0x1A00:02", "0x60630020 (1617100832)", "download pdo 0x1A00 entry"),
    ("<PS>", "0x1A00:00", "0x02 (2)", "download pdo 0x1A00 entr"),
    ("<PS>", "0x1A01:00", "0x00 (0)", "clear pdo 0x1A01 entries"),
    ("<PS>", "0x1A02:00", "0x00 (0)", "clear pdo 0x1A02 entries"),
    ("<PS>", "0x1A03:00", "0x00 (0)", "clear pdo 0x1A03 entries"),
    ("<PS>", "0x1600:00", "0x00 (0)", "clear pdo 0x1600 entries"),
    ("<PS>", "0x1600:01", "0x60400010 (1614807056)", "download pdo 0x1600 entry"),
    ("<PS>", "0x1600:02", "0x60C10120 (1623261472)", "download pdo 0x1600 entry"),
    ("<PS>", "0x1600:00", "0x02 (2)", "download pdo 0x1600 entr"),
    ("<PS>", "0x1601:00", "0x00 (0)", "clear pdo 0x1601 entries"),
    ("<PS>", "0x1602:00", "0x00 (0)", "clear pdo 0x1602 entries"),
    ("<PS>", "0x1603:00", "0x00 (0)", "clear pdo 0x1603 entries"),
    ("<PS>", "0x1C12:01", "0x1600 (5632)", "download pdo 0x1C12:01 i"),
    ("<PS>", "0x1C12:00", "0x01 (1)", "download pdo 0x1C12 count"),
    ("<PS>", "0x1C13:01", "0x1B01 (6913)", "download pdo 0x1C13:01 i"),
    ("<PS>", "0x1C13:00", "0x01 (1)", "download pdo 0x1C13 count"),
    ("PS", "0x6060:00", "0x07 (7)", "Opmode"),
    ("PS", "0x60C2:01", "0x02 (2)", "Cycle time"),
    ("PS", "0x60C2:02", "0xFD (253)", "Cycle exp"),
]
EXAMPLE_ARGS = ("--rx", "0x1600=0x6040:0/16,0x60C1:1/32", "--define", "0x1A00=0x6041:0/16,0x6063:0/32",
                "--tx", "0x1B01", "--opmode", "7", "--cycle-time", "2ms")

# Sizes from the manual's 5.5 list and the ESI notes (SPEC-NOTES 19).
FIXED_SIZES = {0x1701: 6, 0x1702: 6, 0x1720: 14, 0x1721: 8, 0x1722: 16, 0x1723: 16, 0x1724: 8, 0x1725: 16,
               0x1B01: 6, 0x1B20: 32, 0x1B21: 6, 0x1B22: 32, 0x1B23: 32, 0x1B24: 6, 0x1B25: 32, 0x1B26: 18}


def _writes(state_dir: Path) -> int:
    from akdctl.sim.drive import SimDrive

    with SimDrive("default", state_dir).transaction() as model:
        return model.writes


def _set_al_state(state_dir: Path, state: str) -> None:
    from akdctl.sim.drive import SimDrive

    with SimDrive("default", state_dir).transaction() as model:
        model.component("pdo").set_al_state(state)


def _check(rows: list[dict]) -> None:
    assert len(rows) == len(MANUAL_5_6_1)
    for row, (transition, address, data, comment) in zip(rows, MANUAL_5_6_1):
        assert row["transition"] == transition
        assert f"{row['index']}:{row['subindex']:02X}" == address
        assert row["data"] == data
        assert row["comment"].startswith(comment), (row, comment)
        assert row["protocol"] == "CoE"


def test_dry_run_reproduces_manual_5_6_1(akd_inproc, isolated_env: Path) -> None:
    code, out, err = akd_inproc("--json", "pdo", "map", *EXAMPLE_ARGS, "--dry-run")
    assert code == 0, err
    _check(json.loads(out)["startup"])
    assert _writes(isolated_env) == 0


def test_dry_run_table_form_and_export(akd, tmp_path: Path) -> None:
    export = tmp_path / "startup.json"
    code, out, err = akd("pdo", "map", *EXAMPLE_ARGS, "--dry-run", "--export", str(export))
    assert code == 0, err
    lines = out.splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("Transition"))
    assert lines[header].split() == ["Transition", "Protocol", "Index", "Data", "Comment"]
    body = lines[header + 1:]
    assert len(body) == len(MANUAL_5_6_1)
    for line, (transition, address, data, comment) in zip(body, MANUAL_5_6_1):
        assert line.startswith(transition) and f" {address} " in line and data in line and comment in line
    _check(json.loads(export.read_text())["startup"])


def test_applying_the_manual_example_then_show(akd_inproc, isolated_env: Path) -> None:
    code, out, err = akd_inproc("--json", "pdo", "map", *EXAMPLE_ARGS)
    assert code == 0, err
    result = json.loads(out)
    assert result["verified"] is True and result["written"] == len(MANUAL_5_6_1)
    code, out, err = akd_inproc("--json", "pdo", "show")
    shown = json.loads(out)
    assert shown["rx"]["assigned"] == ["0x1600"] and shown["tx"]["assigned"] == ["0x1B01"]
    rx = shown["rx"]["pdos"][0]
    assert [(e["address"], e["bits"], e["bit_offset"]) for e in rx["entries"]] == [
        ("0x6040:00", 16, 0), ("0x60C1:01", 32, 16)]
    assert shown["rx"]["bytes"] == 6 and shown["tx"]["bytes"] == 6
    # the defined-but-unassigned 0x1A00 holds the example's entries
    code, out, _ = akd_inproc("--json", "sdo", "read", "0x1A00:02")
    assert json.loads(out)["value"] == 0x60630020
    code, out, _ = akd_inproc("--json", "sdo", "read", "0x60C2:02")
    assert json.loads(out)["value"] == -3


def test_flexible_map_show_read_back(akd_inproc) -> None:
    code, out, err = akd_inproc("--json", "pdo", "map", "--rx", "0x1600=0x6040:0/16,0x60C1:1/32",
                                "--rx", "0x1601=0x6060:0/8,0x0002:0/8",
                                "--tx", "0x1A00=0x6041:0/16,0x6063:0/32", "--tx", "0x1A01=0x6061:0/8,0x2002:1/8")
    assert code == 0, err
    assert json.loads(out)["verified"] is True
    code, out, _ = akd_inproc("--json", "pdo", "show")
    shown = json.loads(out)
    assert shown["rx"]["assigned"] == ["0x1600", "0x1601"] and shown["rx"]["bytes"] == 8
    assert shown["tx"]["assigned"] == ["0x1A00", "0x1A01"] and shown["tx"]["bytes"] == 8
    offsets = [e["bit_offset"] for p in shown["rx"]["pdos"] for e in p["entries"]]
    assert offsets == [0, 16, 48, 56]
    code, out, _ = akd_inproc("pdo", "show")
    assert "0x1601 (flexible, 2 bytes)" in out and "Dummy" in out


@pytest.mark.parametrize("pdo", sorted(FIXED_SIZES))
def test_every_fixed_pdo_decodes_with_its_size(akd_inproc, pdo: int) -> None:
    direction = "--rx" if pdo in oc.FIXED_RX_PDOS else "--tx"
    code, out, err = akd_inproc("--json", "pdo", "map", direction, f"0x{pdo:04X}")
    assert code == 0, err
    code, out, _ = akd_inproc("--json", "pdo", "show")
    side = json.loads(out)["rx" if direction == "--rx" else "tx"]
    assert side["assigned"] == [f"0x{pdo:04X}"]
    assert side["bytes"] == FIXED_SIZES[pdo] == side["pdos"][0]["bytes"]
    assert side["pdos"][0]["fixed"] is True
    assert len(side["pdos"][0]["entries"]) == len(oc.fixed_pdo(pdo))


def test_presets_lists_every_fixed_pdo_with_size(akd_inproc) -> None:
    code, out, _ = akd_inproc("--json", "pdo", "presets")
    assert code == 0
    sizes = {int(p["name"], 16): p["bytes"] for p in json.loads(out)["pdos"]}
    assert sizes == FIXED_SIZES
    code, out, _ = akd_inproc("pdo", "presets", "0x1B20")
    assert "0x1B20 (TxPDO, 32 bytes)" in out and "0x20A0:00" in out
    code, _, err = akd_inproc("pdo", "presets", "0x1704")
    assert code == 2 and "not a fixed PDO" in err


# Each rule: the arguments, a fragment of akdctl's own refusal, the drive's abort code under --force.
VIOLATIONS = [
    pytest.param(("--rx", "0x1600=0x6041:0/16"), "cannot be mapped", 0x06040041, id="wrong-direction"),
    pytest.param(("--rx", "0x1600=0x1000:0/32"), "not PDO-mappable", 0x06040041, id="not-mappable"),
    pytest.param(("--rx", "0x1600=0x6040:0/32"), "has 16 bits", 0x06040041, id="wrong-length"),
    pytest.param(("--rx", "0x1600=0x607A:0/32,0x60FF:0/32,0x6040:0/16"), "at most 8", 0x06040042, id="pdo-9-bytes"),
    pytest.param(("--rx", "0x1600=0x6040:0/16,0x6060:0/8"), "odd length", 0x06040042, id="odd-length"),
    pytest.param(("--rx", "0x1600=0x607A:0/32,0x60FF:0/32", "--rx", "0x1601=0x60B1:0/32,0x6081:0/32",
                  "--rx", "0x1602=0x6083:0/32,0x6084:0/32"), "24 bytes", 0x06040042, id="rx-total-24"),
    pytest.param(("--rx", "0x1704"), "SPEC-NOTES 16", 0x06090030, id="unknown-pdo-1704"),
    pytest.param(("--tx", "0x1701"), "not a TxPDO", 0x06090030, id="rx-pdo-as-tx"),
    pytest.param(("--rx", "0x1701", "--rx", "0x1600=0x6040:0/16"), "excludes", 0x06040043, id="fixed-plus-flexible"),
]


@pytest.mark.parametrize("args,fragment,abort", VIOLATIONS)
def test_violation_refused_before_any_write(akd_inproc, isolated_env: Path, args, fragment: str, abort: int) -> None:
    before = _writes(isolated_env)
    code, out, err = akd_inproc("pdo", "map", *args)
    assert code == 2, err
    assert fragment in err and "nothing was written" in err
    assert _writes(isolated_env) == before


@pytest.mark.parametrize("args,fragment,abort", VIOLATIONS)
def test_violation_forced_is_refused_by_the_drive(akd_inproc, args, fragment: str, abort: int) -> None:
    code, out, err = akd_inproc("pdo", "map", "--force", *args)
    assert code == 1, err
    assert f"0x{abort:08X}" in err
    assert "--force" in err  # akdctl's own finding is still shown as a warning


def test_mapping_outside_preop(akd_inproc, isolated_env: Path) -> None:
    _set_al_state(isolated_env, "OP")
    before = _writes(isolated_env)
    code, _, err = akd_inproc("pdo", "map", "--rx", "0x1702")
    assert code == 2 and "PRE-OP" in err and "nothing was written" in err
    assert _writes(isolated_env) == before
    code, _, err = akd_inproc("pdo", "map", "--force", "--rx", "0x1702")
    assert code == 1 and "0x08000022" in err  # SPEC-NOTES 18
    assert _writes(isolated_env) == before
    code, out, _ = akd_inproc("--json", "pdo", "show")
    assert json.loads(out)["al_state"] == "OP" and json.loads(out)["rx"]["assigned"] == ["0x1701"]


def test_subindex_while_count_set_aborts(akd_inproc) -> None:
    # SPEC-NOTES 17 through plain SDO access: 0x1C12:00 is 1 by default
    code, _, err = akd_inproc("sdo", "write", "0x1C12:1", "0x1600")
    assert code == 1 and "0x06010003" in err


def test_map_from_file(akd_inproc, tmp_path: Path) -> None:
    plan = tmp_path / "mapping.toml"
    plan.write_text('rx = ["0x1702"]\ntx = ["0x1A00=0x6041:0/16,0x606C:0/32"]\n')
    code, out, err = akd_inproc("--json", "pdo", "map", "--file", str(plan))
    assert code == 0, err
    assert json.loads(out)["mapping"]["tx"]["assigned"] == ["0x1A00"]
    code, _, err = akd_inproc("pdo", "map", "--file", str(plan), "--rx", "0x1701")
    assert code == 2


def test_bad_input_is_a_usage_error(akd_inproc) -> None:
    for args in (("pdo", "map"), ("pdo", "map", "--rx", "0x1600=bogus"), ("pdo", "map", "--rx", "zz"),
                 ("pdo", "map", "--rx", "0x1701", "--cycle-time", "soon")):
        code, _, err = akd_inproc(*args)
        assert code == 2, (args, err)
        assert "Traceback" not in err


def test_read_back_difference_is_check_failed(akd_inproc, monkeypatch: pytest.MonkeyPatch) -> None:
    """If the drive holds something else after the sequence, exit 5 (CheckFailed)."""
    from akdctl.drive import pdo as dp

    real = dp.read_pdo

    def lying_read(channel, pdo):
        entries = real(channel, pdo)
        return entries[:-1] if pdo == 0x1600 else entries

    monkeypatch.setattr(dp, "read_pdo", lying_read)
    code, _, err = akd_inproc("pdo", "map", "--rx", "0x1600=0x6040:0/16,0x60C1:1/32")
    assert code == 5 and "differs" in err
