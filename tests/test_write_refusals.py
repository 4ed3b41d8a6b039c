"""What a user reads when a writing command refuses (issue 23 item 17): every line break is a line break.

A refusal listing several reasons (``telegram map``, ``pdo map``) prints one reason per line under the
``akdctl: error:`` line, never a literal ``\\n``; a newline inside the user's own input stays escaped.
"""

from __future__ import annotations

import pytest

from tests.harness import run_akdctl

pytestmark = pytest.mark.slow  # runs the real CLI in subprocesses


def test_a_telegram_mapping_refusal_lists_each_reason_on_its_own_line() -> None:
    assert run_akdctl("--yes", "telegram", "set", "1").code == 0
    result = run_akdctl("telegram", "map", "--setpoint", "2")
    assert result.code == 2, result.err
    lines = result.err.splitlines()
    assert "\\n" not in result.err, result.err
    assert lines[0].startswith("akdctl: error: telegram mapping refused, nothing was written:")
    assert lines[1].startswith("  - telegram 1 is selected") and lines[2].startswith("  - signal 2 (ZSW1)"), lines


def test_a_pdo_mapping_refusal_lists_each_reason_on_its_own_line() -> None:
    result = run_akdctl("-T", "sim?drive=cia402", "pdo", "map", "--rx", "0x1600=0x6041:0/16", "--tx", "0x1B01",
                        "--tx", "0x1B01")
    assert result.code == 2, result.err
    assert "\\n" not in result.err, result.err
    lines = result.err.splitlines()
    assert lines[0].startswith("akdctl: error: mapping refused, nothing was written:"), lines
    assert len(lines) >= 3 and all(line.startswith("  ") for line in lines[1:]), lines


def test_a_newline_inside_the_users_input_stays_escaped() -> None:
    result = run_akdctl("params", "restore", "/nonexistent/a\nakdctl: error: forged.toml")
    assert result.code == 2
    assert len(result.err.splitlines()) == 1 and "a\\nakdctl" in result.err, result.err
