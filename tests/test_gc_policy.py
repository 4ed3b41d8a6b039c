"""The garbage-collector policy of akdctl's own process (cli/main.py, issue 29): what it sets, and where it stops.

``python -m akdctl ...`` (and the console script) raise the young-generation threshold and freeze what is left
before exit; ``main(argv)`` called inside another program (the tests, a line run's worker) leaves that program's
collector alone. The collector stays enabled (a long-running command still collects its cyclic garbage), and a
command's output and exit code do not depend on the policy. Counts and flags only: nothing here is timed.
"""

from __future__ import annotations

import gc
import subprocess
import sys

import pytest

from tests.harness import akdctl_env, run_akdctl

#: Runs ``python -m akdctl ARGS`` as python would and reports the collector's settings when the process exits.
_PROBE = """
import atexit, gc, runpy, sys
atexit.register(lambda: sys.stderr.write(
    f"--gc-- {gc.get_threshold()[0]} {gc.isenabled()} {gc.get_freeze_count()}\\n"))
sys.argv = ["akdctl", *sys.argv[1:]]
runpy.run_module("akdctl", run_name="__main__", alter_sys=True)
"""


def _run(args: list[str], env: dict[str, str], *, probe: bool) -> subprocess.CompletedProcess[str]:
    argv = [sys.executable, "-c", _PROBE, *args] if probe else [sys.executable, "-m", "akdctl", *args]
    return subprocess.run(argv, check=False, capture_output=True, text=True, env=env, timeout=120, stdin=subprocess.DEVNULL)


@pytest.fixture
def env() -> dict[str, str]:
    """This test's state and config directories (conftest's isolated_env), the state file in place."""
    env = akdctl_env()
    assert run_akdctl("sim", "reset", env=env).code == 0
    return env


@pytest.mark.slow
@pytest.mark.parametrize("args", [["pnu", "get", "930"], ["sdo", "read", "0x6041"], ["--help"],
                                  ["pnu", "get", "99999"]])
def test_the_cli_process_raises_the_threshold_and_freezes_before_exit(args: list[str], env: dict[str, str]) -> None:
    from akdctl.cli.main import GC_YOUNG_THRESHOLD

    proc = _run(args, env, probe=True)
    _, found, report = proc.stderr.rpartition("--gc-- ")
    assert found, proc.stderr[-2000:]
    threshold, enabled, frozen = report.split()
    assert int(threshold) == GC_YOUNG_THRESHOLD != 700
    assert enabled == "True"  # tuned, never switched off
    assert int(frozen) > 1000  # the modules, classes and functions the command imported


@pytest.mark.slow
@pytest.mark.parametrize("args", [["pnu", "get", "930"], ["sdo", "read", "0x6041"], ["pnu", "get", "99999"],
                                  ["pnu", "get"], ["--version"]])
def test_the_policy_changes_no_output_and_no_exit_code(args: list[str], env: dict[str, str], akd_inproc) -> None:
    """The process (policy on) and main(argv) in this process (policy off) print the same and exit alike."""
    proc = _run(args, env, probe=False)
    code, out, err = akd_inproc(*args)  # the same state directory (conftest's isolated_env)
    assert (proc.returncode, proc.stdout, proc.stderr) == (code, out, err)


def test_main_with_argv_leaves_its_hosts_collector_alone(akd_inproc) -> None:
    before = (gc.get_threshold(), gc.isenabled(), gc.get_freeze_count())
    assert akd_inproc("pnu", "get", "930")[0] == 0
    assert akd_inproc("pnu", "get", "99999")[0] != 0
    assert (gc.get_threshold(), gc.isenabled(), gc.get_freeze_count()) == before
