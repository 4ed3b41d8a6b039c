"""Shared test fixtures: every test gets its own simulator state dir and no user config.

``akd`` runs the real CLI in a subprocess (``python -m akdctl``) and returns
``(exit_code, stdout, stderr)``; ``akd_inproc`` runs the same entry point in
this process (faster, for the many bad-input cases).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "root: needs root/CAP_NET_RAW/network namespaces")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Root-only tests skip visibly when not root and not in CI; in CI (CI=true) they always run."""
    if os.geteuid() == 0:
        return
    if os.environ.get("CI") == "true":
        return  # in CI they run regardless, and fail loudly if root is missing
    for item in items:
        if "root" in item.keywords:
            item.add_marker(pytest.mark.skip(reason="needs root (CAP_NET_RAW, network namespaces); runs in CI"))


@pytest.fixture(autouse=True)
def isolated_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    state = tmp_path / "akd-state"
    monkeypatch.setenv("AKDCTL_STATE_DIR", str(state))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg-config"))
    for var in ("AKDCTL_TARGET", "AKDCTL_PROFILE", "AKDCTL_CONFIG", "AKDCTL_DEBUG"):
        monkeypatch.delenv(var, raising=False)
    return state


def run_akdctl(*args: str, input: str | None = None, env: dict[str, str] | None = None,
               timeout: float = 60) -> tuple[int, str, str]:
    """The real CLI in a subprocess; the environment of the test (state dir …) is inherited."""
    full_env = dict(os.environ)
    full_env.setdefault("PYTHONPATH", str(ROOT))
    if env:
        full_env.update(env)
    proc = subprocess.run([sys.executable, "-m", "akdctl", *args], input=input, capture_output=True, text=True,
                          env=full_env, timeout=timeout, cwd=ROOT)
    return proc.returncode, proc.stdout, proc.stderr


@pytest.fixture
def akd():
    return run_akdctl


@pytest.fixture
def akd_inproc(capsys: pytest.CaptureFixture[str]):
    """Run ``akdctl.cli.main.main(argv)`` in-process; returns (exit_code, stdout, stderr)."""
    from akdctl.cli.main import main

    def run(*args: str) -> tuple[int, str, str]:
        capsys.readouterr()
        try:
            main(list(args))
            code = 0
        except SystemExit as exc:
            code = int(exc.code or 0)
        out, err = capsys.readouterr()
        return code, out, err

    return run
