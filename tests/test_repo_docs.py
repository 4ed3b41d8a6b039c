"""The repository's promises about itself: README commands, CI, exit-code table, generated files."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from akdctl.errors import EXIT_CODES

ROOT = Path(__file__).resolve().parent.parent


def _readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    setup = text.split("## Set up", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.+?)\n```", setup)


def test_readme_has_exactly_two_setup_commands() -> None:
    commands = _readme_commands()
    assert len(commands) == 2
    assert all("\n" not in c for c in commands)


def test_ci_runs_readme_test_command() -> None:
    test_command = _readme_commands()[1]
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert test_command in ci


def test_parallel_test_command_has_its_plugin_in_the_test_extra() -> None:
    """README's test command runs the suite on pytest-xdist workers (``-n``): a fresh ``pip install -e '.[test]'``
    must bring the plugin, or the command fails with "unrecognized arguments: -n"."""
    import tomllib

    test_command = _readme_commands()[1]
    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]["test"]
    assert " -n " in f"{test_command} "
    assert any(re.match(r"pytest-xdist\b", requirement) for requirement in extra), extra


def test_readme_exit_code_table_matches_the_code() -> None:
    text = (ROOT / "README.md").read_text()
    table = text.split("## Exit codes", 1)[1].split("\n## ", 1)[0]
    documented = {int(m) for m in re.findall(r"^\| (\d+) \|", table, re.M)}
    assert documented == set(EXIT_CODES) | {70}


@pytest.mark.slow
def test_completions_and_man_pages_are_generated_from_the_click_tree() -> None:
    proc = subprocess.run([sys.executable, str(ROOT / "tools" / "gen_docs.py"), "--check"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.slow
def test_help_imports_no_transport_rich_or_canopen() -> None:
    code = (
        "import sys; sys.argv = ['akdctl', '--help']\n"
        "from akdctl.cli.main import main\n"
        "try:\n    main()\nexcept SystemExit:\n    pass\n"
        "bad = [m for m in sys.modules if m.startswith(('rich', 'canopen', 'can.', 'scapy', 'akdctl.transport.',"
        " 'akdctl.protocol', 'akdctl.sim', 'akdctl.channels')) or m == 'can']\n"
        "allowed = {'akdctl.transport.target', 'akdctl.transport.registry'}\n"
        "bad = [m for m in bad if m not in allowed]\n"
        "sys.stderr.write('LOADED:' + ','.join(sorted(bad)) + '\\n')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    loaded = [line for line in proc.stderr.splitlines() if line.startswith("LOADED:")]
    assert loaded == ["LOADED:"], proc.stderr
