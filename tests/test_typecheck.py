"""The type checker runs over the package (issue 22): the wiring and the drive layer first.

Which files are checked is ``[tool.mypy] files`` in pyproject.toml (drive/, channels/, links.py, connection.py,
the vocabulary, the transport contract and registry); imports outside them are followed for their types but not
reported on until they join the list. Parameters are typed with the ABCs (``ObjectChannel``,
``ParameterChannel``, ``CipAttributes``, ``Connection``, ``Axis``) under ``TYPE_CHECKING`` where start-up cost
matters, so the checker sees what ``Any`` hid.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

mypy = pytest.importorskip("mypy", reason="mypy is in the 'test' extra")


def _cache_dir() -> Path:
    """mypy's incremental cache, shared by this run's two checks (tests/conftest.run_cache, removed at the run's end).

    Why: from an empty cache the check takes ~10 s of CPU, nearly all of it analysing modules the other check
    analysed already; mypy keys each cached module on its source's hash and the options, so a changed module (and
    what depends on it) is analysed anew."""
    from tests.conftest import run_cache

    return run_cache() / "mypy"


@pytest.mark.slow
def test_the_checked_packages_type_check_clean() -> None:
    proc = subprocess.run([sys.executable, "-m", "mypy", "--cache-dir", str(_cache_dir())], cwd=ROOT,
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    assert "Success" in proc.stdout


@pytest.mark.slow
def test_the_check_can_fail(tmp_path: Path) -> None:
    """The same configuration reports a wrong type: a channel where a Connection belongs."""
    bad = tmp_path / "bad.py"
    bad.write_text("from akdctl.channels.base import ObjectChannel\nfrom akdctl.drive.gate import drive_enabled\n\n\n"
                   "def f(channel: ObjectChannel) -> None:\n    drive_enabled(channel)\n", encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "mypy", "--cache-dir", str(_cache_dir()), str(bad)], cwd=ROOT,
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 1 and "drive_enabled" in proc.stdout, proc.stdout
