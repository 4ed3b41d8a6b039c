"""params backup / restore / diff through the real CLI on the simulated drive.

Exit codes per akdctl/errors.py: diff exits 5 (check failed) when it finds a
difference and 0 when there is none (documented in docs/commissioning.md).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from akdctl.errors import EXIT_CHECK, EXIT_OK, EXIT_SAFETY, EXIT_USAGE


def sim_state() -> dict:
    from akdctl.sim.drive import SimDrive

    return SimDrive("default").snapshot()


def writes() -> int:
    return int(sim_state().get("writes", 0))


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_backup_change_diff_restore_diff_empty(akd_inproc, tmp_path: Path, suffix: str) -> None:
    backup = tmp_path / f"golden{suffix}"
    code, out, err = akd_inproc("params", "backup", "-o", str(backup))
    assert code == EXIT_OK, err
    assert backup.exists()
    assert akd_inproc("params", "diff", str(backup))[0] == EXIT_OK

    assert akd_inproc("--yes", "pnu", "set", "930=2", "1004=-500", "922=7")[0] == EXIT_OK
    code, out, err = akd_inproc("--json", "params", "diff", str(backup))
    assert code == EXIT_CHECK, err
    changed = {d["key"]: (d["a"], d["b"]) for d in json.loads(out)["differences"]}
    assert changed["930"] == (1, 2)
    assert changed["1004"] == (163, -500)
    assert changed["922"] == (1, 7)

    code, out, err = akd_inproc("params", "restore", str(backup))
    assert code == EXIT_OK, err
    assert "930" in out and "2 → 1" in out
    code, out, err = akd_inproc("params", "diff", str(backup))
    assert code == EXIT_OK, err
    assert "no differences" in out


def test_backup_file_has_target_identity_firmware_time(akd_inproc, tmp_path: Path) -> None:
    import tomllib

    backup = tmp_path / "b.toml"
    assert akd_inproc("params", "backup", "-o", str(backup))[0] == EXIT_OK
    data = tomllib.loads(backup.read_text())
    head = data["akdctl_backup"]
    assert head["target"] == "sim" and head["format"] == 1 and head["firmware"] == "1.20"
    assert head["time"].endswith("Z")
    assert data["identity"]["manufacturer"] == 0x0100
    assert data["pnus"]["930"] == 1 and len(data["pnus"]["947"]) == 64
    assert not list(tmp_path.glob(".b.toml.*"))  # atomic write left no temporary file


def test_dry_run_prints_old_to_new_and_writes_nothing(akd_inproc, tmp_path: Path) -> None:
    backup = tmp_path / "b.json"
    assert akd_inproc("params", "backup", "-o", str(backup))[0] == EXIT_OK
    assert akd_inproc("--yes", "pnu", "set", "1006=1234")[0] == EXIT_OK
    before = writes()
    code, out, err = akd_inproc("params", "restore", "--dry-run", str(backup))
    assert code == EXIT_OK, err
    assert "1006" in out and "1234 → 1000" in out
    assert writes() == before
    assert akd_inproc("params", "diff", str(backup))[0] == EXIT_CHECK


def test_restore_writes_only_differences_and_never_stw1(akd_inproc, tmp_path: Path) -> None:
    backup = tmp_path / "b.toml"
    assert akd_inproc("params", "backup", "-o", str(backup))[0] == EXIT_OK
    text = backup.read_text().replace('"1" = 0', '"1" = 1151')  # STW1 in a file is never restored
    backup.write_text(text)
    assert akd_inproc("--yes", "pnu", "set", "1005=-100")[0] == EXIT_OK
    before = writes()
    code, out, err = akd_inproc("--json", "params", "restore", str(backup))
    assert code == EXIT_OK, err
    data = json.loads(out)
    assert [c["key"] for c in data["changes"]] == ["1005"]
    assert writes() == before + 1
    assert sim_state()["pnus"].get("1", [0]) == [0]


def test_restore_free_telegram_writes_telegram_before_its_mapping(akd_inproc, tmp_path: Path) -> None:
    assert akd_inproc("--yes", "pnu", "set", "922=0")[0] == EXIT_OK
    assert akd_inproc("--yes", "pnu", "set", "915=1,5", "916=2,6")[0] == EXIT_OK
    backup = tmp_path / "free.toml"
    assert akd_inproc("params", "backup", "-o", str(backup), "--group", "telegram")[0] == EXIT_OK
    assert akd_inproc("--yes", "pnu", "set", "922=1")[0] == EXIT_OK
    code, out, err = akd_inproc("--json", "params", "restore", str(backup))
    assert code == EXIT_OK, err
    keys = [c["key"] for c in json.loads(out)["changes"]]
    assert keys[0] == "922"
    assert akd_inproc("params", "diff", str(backup))[0] == EXIT_OK


def test_identity_mismatch_refused_unless_force(akd_inproc, tmp_path: Path) -> None:
    backup = tmp_path / "b.toml"
    assert akd_inproc("params", "backup", "-o", str(backup))[0] == EXIT_OK
    backup.write_text(backup.read_text().replace("drive_unit_type = 1", "drive_unit_type = 7"))
    assert akd_inproc("--yes", "pnu", "set", "1004=-300")[0] == EXIT_OK
    before = writes()
    code, _, err = akd_inproc("params", "restore", str(backup))
    assert code == EXIT_SAFETY
    assert "drive_unit_type" in err and "--force" in err
    assert writes() == before
    code, out, err = akd_inproc("params", "restore", "--force", str(backup))
    assert code == EXIT_OK, err
    assert "identity differs" in out


def test_save_writes_nvsave_signature(akd_inproc, tmp_path: Path) -> None:
    backup = tmp_path / "b.toml"
    assert akd_inproc("params", "backup", "-o", str(backup))[0] == EXIT_OK
    code, out, err = akd_inproc("params", "restore", "--save", str(backup))
    assert code == EXIT_OK, err
    assert sim_state()["objects"]["1010:01"] == (0x65766173).to_bytes(4, "little").hex()  # "save"


def test_objects_backup_restores_pdo_mapping_in_manual_sequence(akd_inproc, tmp_path: Path) -> None:
    backup = tmp_path / "pdo.json"
    assert akd_inproc("params", "backup", "-o", str(backup), "--source", "objects", "--group", "pdo")[0] == EXIT_OK
    data = json.loads(backup.read_text())
    assert "0x1600:1" in data["objects"] and "pnus" not in data
    for args in (("0x1600:0", "0"), ("0x1600:2", "0x60600008")):
        assert akd_inproc("--yes", "sdo", "write", *args)[0] == EXIT_OK
    assert akd_inproc("params", "diff", str(backup))[0] == EXIT_CHECK
    code, out, err = akd_inproc("--json", "params", "restore", str(backup))
    assert code == EXIT_OK, err
    written = [w["key"] for w in json.loads(out)["written"]]
    assert written[0] == "0x1600:0" and written[-1] == "0x1600:0"  # count 0, entries, count
    assert akd_inproc("params", "diff", str(backup))[0] == EXIT_OK


def test_diff_file_against_file(akd_inproc, tmp_path: Path) -> None:
    a, b = tmp_path / "a.toml", tmp_path / "b.json"
    assert akd_inproc("params", "backup", "-o", str(a))[0] == EXIT_OK
    assert akd_inproc("--yes", "pnu", "set", "1007=2000")[0] == EXIT_OK
    assert akd_inproc("params", "backup", "-o", str(b))[0] == EXIT_OK
    code, out, _ = akd_inproc("--json", "params", "diff", str(a), str(b))
    assert code == EXIT_CHECK
    assert [d["key"] for d in json.loads(out)["differences"]] == ["1007"]
    assert akd_inproc("params", "diff", str(a), str(a))[0] == EXIT_OK


def test_backup_uses_the_minimum_number_of_requests(akd_inproc, tmp_path: Path) -> None:
    """SPEC-NOTES 4: 39 parameters and 240 bytes per request; the backup packs to the minimum."""
    from akdctl.catalog.pnus import pnu_table

    code, out, err = akd_inproc("--json", "params", "backup", "-o", str(tmp_path / "b.json"))
    assert code == EXIT_OK, err
    used = json.loads(out)["round_trips"]["pnu requests"]
    table = pnu_table()
    # Lower bound: parameter count and the response bytes (4-byte header, 2-byte value header, padded data).
    data = sum(max(6, 2 + (i.length * (i.bits // 8) + 1) // 2 * 2) for i in table.values())
    bound = max(math.ceil(len(table) / 39), math.ceil(data / (240 - 4)))
    assert used == bound


@pytest.mark.parametrize("content, words", [
    ("not toml [", "not valid TOML"),
    ('[akdctl_backup]\nformat = 9\n', "format 9"),
    ('x = 1\n', "not an akdctl parameter backup"),
    ('[akdctl_backup]\nformat = 1\n[pnus]\n"9999" = 1\n', "9999"),
    ('[akdctl_backup]\nformat = 1\n[pnus]\n"930" = 7\n', "outside 0..2"),
    ('[akdctl_backup]\nformat = 1\n[pnus]\n"915" = 3\n', "list of"),
])
def test_bad_backup_files_are_usage_errors(akd_inproc, tmp_path: Path, content: str, words: str) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(content)
    before = writes()
    code, _, err = akd_inproc("params", "restore", str(bad))
    assert code == EXIT_USAGE
    assert words in err and "Traceback" not in err
    assert writes() == before


def test_backup_needs_a_known_suffix_and_existing_file_for_restore(akd_inproc, tmp_path: Path) -> None:
    assert akd_inproc("params", "backup", "-o", str(tmp_path / "b.txt"))[0] == EXIT_USAGE
    code, _, err = akd_inproc("params", "restore", str(tmp_path / "missing.toml"))
    assert code == EXIT_USAGE and "does not exist" in err


def test_backup_only_list(akd_inproc, tmp_path: Path) -> None:
    out_file = tmp_path / "few.json"
    code, _, err = akd_inproc("params", "backup", "-o", str(out_file), "--only", "930,922", "--only", "0x6060:0")
    assert code == EXIT_OK, err
    data = json.loads(out_file.read_text())
    assert set(data["pnus"]) == {"930", "922"} and set(data["objects"]) == {"0x6060:0"}


def test_restore_refuses_an_enabled_drive_and_writes_nothing(akd_inproc, tmp_path: Path) -> None:
    """The one "is the power stage on?" rule (drive/gate.py) guards a restore: exit 4 in words, no write."""
    backup = tmp_path / "b.toml"
    assert akd_inproc("params", "backup", "-o", str(backup))[0] == EXIT_OK
    assert akd_inproc("--yes", "pnu", "set", "1005=-100")[0] == EXIT_OK
    assert akd_inproc("--yes", "enable")[0] == EXIT_OK
    before = writes()
    code, _, err = akd_inproc("params", "restore", str(backup))
    assert code == 4, err
    assert "the drive is enabled (operation enabled); disable it before restoring parameters" in err
    assert writes() == before
    assert akd_inproc("--yes", "disable")[0] == EXIT_OK
    assert akd_inproc("params", "restore", str(backup))[0] == EXIT_OK
