"""The Modbus and ASCII-channel peer rows of benchmarks/run_all.py (issue 29) run end to end and a worker that
crashes is a reported row. Nothing here judges a figure: the rows' marks are timings, which tests never assert."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "benchmarks"


@pytest.mark.slow
def test_modbus_and_ascii_rows_run_end_to_end(tmp_path: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT), AKDCTL_STATE_DIR=str(tmp_path))
    proc = subprocess.run([sys.executable, str(BENCH / "run_all.py"), "--quick", "--only", "modbus,ascii",
                           "--markdown"], env=env, capture_output=True, text=True, timeout=120, cwd=tmp_path, check=False)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    for row in ("modbus", "ascii"):
        line = re.search(rf"^\| {row} \|(.*)\|$", out, re.MULTILINE)
        assert line is not None, out
        cells = [c.strip() for c in line.group(1).split("|")]
        assert re.fullmatch(r"[\d.]+× ops/s, client CPU [\d.]+× the peer's", cells[1]), cells
        assert cells[2] == "≥ 1.0×" and cells[3] in ("pass", "SHORT"), cells
    assert "crashed" not in out and "error:" not in out, out
    assert "pyModbusTCP" in out   # the second yardstick ran beside pymodbus


SCRIPT = r"""
import sys, time
kind, where = sys.argv[1], sys.argv[2]
if kind == "akdctl":
    op = lambda: None
elif kind == "dies":
    calls = [0]
    def op():
        calls[0] += 1
        if calls[0] > 30:
            raise SystemExit("the peer fell over")
elif kind == "never":
    raise SystemExit("no such library")
"""


@pytest.mark.slow
@pytest.mark.parametrize("peer,words", [("dies", "the peer fell over"), ("never", "no such library")])
def test_a_crashed_peer_is_a_reported_row(tmp_path: Path, peer: str, words: str) -> None:
    sys.path.insert(0, str(BENCH))
    try:
        from benchlib import Settings
        from row_tcp_peers import compare
    finally:
        sys.path.remove(str(BENCH))
    settings = Settings(quick=True, tmp=tmp_path, rounds=3, block=20, process_rounds=1)
    result = compare(SCRIPT, {"akdctl": "-", peer: "-"}, settings, 10, peer=peer)
    assert result.value == f"{peer} crashed" and result.ok is False
    assert any(words in note for note in result.notes), result.notes
