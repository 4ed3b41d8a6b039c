"""A client talking to a real drive imports nothing of the simulator (issue 22, item 9).

Before, a consent on a real-drive target (``-T pn://… --yes enable``) loaded 14 ``akdctl.sim`` modules in the
client process, only to learn where the owner locks live. The modules a run imports are read from Python's own
import profile (``PYTHONPROFILEIMPORTTIME``, the ``-X importtime`` of tests/test_import_budget.py) of the real CLI.
"""

from __future__ import annotations

import pytest

from tests.harness import SimServer, closed_udp_port, run_akdctl


def _sim_modules(err: str) -> list[str]:
    names = [line.rsplit("|", 1)[1].strip() for line in err.splitlines()
             if line.startswith("import time:") and "|" in line and "imported package" not in line]
    assert names, "no import profile in stderr"
    return sorted(n for n in names if n == "akdctl.sim" or n.startswith("akdctl.sim."))


def _messages(err: str) -> str:
    return "\n".join(line for line in err.splitlines() if not line.startswith("import time:"))


@pytest.mark.slow
def test_enable_on_a_profinet_face_imports_no_simulator_module() -> None:
    with SimServer("--profinet", "127.0.0.1:0") as server:
        target = f"pn://{server.host}:{server.port}"
        result = run_akdctl("-T", target, "--yes", "enable", env={"PYTHONPROFILEIMPORTTIME": "1"}, timeout=90)
        assert result.code == 0, _messages(result.err)
        assert _sim_modules(result.err) == []
        status = run_akdctl("-T", target, "status", "--json", env={"PYTHONPROFILEIMPORTTIME": "1"}, timeout=90)
        assert status.code == 0, _messages(status.err)
        assert _sim_modules(status.err) == []


@pytest.mark.slow
def test_a_dead_address_imports_no_simulator_module() -> None:
    with closed_udp_port() as port:
        result = run_akdctl("-T", f"pn://127.0.0.1:{port}", "--timeout", "0.3", "--yes", "enable",
                            env={"PYTHONPROFILEIMPORTTIME": "1"}, timeout=60)
    assert result.code == 3, _messages(result.err)
    assert _sim_modules(result.err) == []


@pytest.mark.slow
def test_the_check_sees_a_simulator_import() -> None:
    """The check can fail: a command on the simulated drive does import it."""
    result = run_akdctl("status", env={"PYTHONPROFILEIMPORTTIME": "1"}, timeout=60)
    assert result.code == 0, _messages(result.err)
    assert "akdctl.sim.drive" in _sim_modules(result.err)
