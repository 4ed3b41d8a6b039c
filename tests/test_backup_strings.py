"""A backup of a string object always restores (issue 23 item 18).

``sdo write 0x2031 vs "Axé\\x7f"`` then ``params backup`` used to write TOML that ``params restore`` rejected
(a raw DEL is not allowed in a TOML string). Every text a string object can hold -- C0 controls, DEL, C1
controls, quotes, backslashes, non-Latin scripts, astral characters, bidirectional overrides -- must survive
backup -> restore --dry-run -> restore, in TOML and in JSON.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

from akdctl.drive.snapshot import toml_string

TARGET = "sim?drive=cia402"
#: The writable string objects of the catalogue (DRV.NAME, DRV.CUSTOMIDENTIFIER, MOTOR.NAME).
OBJECTS = ("0x2031:0", "0x2032:0", "0x3899:0")
STRINGS = (
    "Axé\x7f",
    "".join(chr(c) for c in range(1, 0x20)),
    "\"quoted\" \\ 'single' [x] = 1 # not a comment",
    "\x80\x9f\xa0\xff\u00e9",
    "€漢字🙂\U0010fffd",
    "\u202eevil\u2066x\u2069",
    "\t\r\n mixed \x1b[31m red",
)


def test_every_code_point_round_trips_through_the_backups_toml_string() -> None:
    for start in range(0, 0x110000, 4096):
        text = "".join(chr(c) for c in range(start, min(start + 4096, 0x110000)) if not 0xD800 <= c <= 0xDFFF)
        assert tomllib.loads("a = " + toml_string(text))["a"] == text, hex(start)


def _writes() -> int:
    from akdctl.sim.drive import SimDrive

    return int(SimDrive("default").snapshot()["writes"])


@pytest.mark.slow  # runs the real CLI in subprocesses
@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_backup_of_any_string_restores(tmp_path: Path, suffix: str) -> None:
    from tests.harness import run_akdctl, run_akdctl_inproc

    # The runs under test (the writes of each text, backup, restore) are subprocesses; the preparation and the
    # reading back run the CLI's entry point in this process (run_akdctl_inproc: same drive, no cold start).
    assert run_akdctl_inproc("sim", "reset").code == 0
    for round_number in range(0, len(STRINGS), len(OBJECTS)):
        chosen = dict(zip(OBJECTS, STRINGS[round_number:round_number + len(OBJECTS)]))
        for address, text in chosen.items():
            written = run_akdctl("-T", TARGET, "--yes", "sdo", "write", address, "vs", text, "--verify")
            assert written.code == 0, (text, written.err)
        backup = tmp_path / f"strings{round_number}{suffix}"
        made = run_akdctl("-T", TARGET, "params", "backup", "-o", str(backup), "--only", ",".join(chosen))
        assert made.code == 0, made.err
        for address in chosen:
            assert run_akdctl_inproc("-T", TARGET, "--yes", "sdo", "write", address, "vs", "other").code == 0

        before = _writes()
        dry = run_akdctl("-T", TARGET, "--json", "params", "restore", str(backup), "--dry-run")
        assert dry.code == 0, dry.err
        assert len(json.loads(dry.out)["changes"]) == len(chosen)
        assert _writes() == before  # the dry run wrote nothing

        restored = run_akdctl("-T", TARGET, "params", "restore", str(backup))
        assert restored.code == 0, restored.err
        for address, text in chosen.items():
            read = run_akdctl_inproc("-T", TARGET, "--json", "sdo", "read", address)
            assert json.loads(read.out)["value"] == text, (address, text)


@pytest.mark.slow  # runs the real CLI in subprocesses
@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_string_object_holding_bytes_that_are_not_utf8_restores_byte_for_byte(tmp_path: Path, suffix: str) -> None:
    """Decoding such bytes replaced them with U+FFFD, and the restore wrote EF BF BD and called it verified."""
    from tests.harness import run_akdctl, run_akdctl_inproc

    assert run_akdctl_inproc("sim", "reset").code == 0  # preparation and reading back in this process, as above
    raw = {"0x2031:0": "41ff42", "0x2032:0": "e9c3", "0x3899:0": "80"}
    for address, octets in raw.items():
        assert run_akdctl("-T", TARGET, "--yes", "sdo", "write", address, "os", octets).code == 0
    backup = tmp_path / f"bytes{suffix}"
    assert run_akdctl("-T", TARGET, "params", "backup", "-o", str(backup), "--only", ",".join(raw)).code == 0
    for address in raw:
        assert run_akdctl_inproc("-T", TARGET, "--yes", "sdo", "write", address, "vs", "other").code == 0
    dry = run_akdctl("-T", TARGET, "params", "restore", str(backup), "--dry-run")
    assert dry.code == 0 and "not UTF-8 text" in dry.out, dry.err
    restored = run_akdctl("-T", TARGET, "params", "restore", str(backup))
    assert restored.code == 0, restored.err
    for address, octets in raw.items():
        read = run_akdctl_inproc("-T", TARGET, "--json", "sdo", "read", address, "os")
        assert json.loads(read.out)["value"] == octets, address
    assert run_akdctl("-T", TARGET, "params", "diff", str(backup)).code == 0
