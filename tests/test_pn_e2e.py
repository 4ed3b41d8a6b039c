"""End to end over real UDP: the akdctl CLI (pn://) against `akdctl sim serve --profinet` in another process.

Commands are a table (argv, expected exit code, text expected on stdout) so later commands are added with one
line; rows whose command group is not part of this version of akdctl are left out by name.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import re
import shutil
import socket
import subprocess
import time
from collections.abc import Iterator

import pytest

from tests.harness import CliResult, SimServer, run_akdctl

pytestmark = pytest.mark.slow


@pytest.fixture
def serve() -> Iterator:
    """Start PROFINET faces on ports they bind themselves; every one is stopped after the test."""
    with contextlib.ExitStack() as stack:
        yield lambda *extra: stack.enter_context(SimServer("--profinet", "127.0.0.1:0", *extra))


def target(server: SimServer) -> str:
    return f"pn://{server.host}:{server.port}"


def akdctl(target: str, *argv: str, timeout: float = 2.0) -> CliResult:
    return run_akdctl("-T", target, "--timeout", str(timeout), *argv, timeout=120)


def _group_exists(argv: tuple[str, ...]) -> bool:
    words = [a for a in argv if not a.startswith("-")]
    return bool(words) and importlib.util.find_spec(f"akdctl.cli.{words[0]}") is not None


# (argv, expected exit code, regex expected on stdout)
COMMANDS: list[tuple[tuple[str, ...], int, str]] = [
    (("pnu", "get", "930"), 0, r"930.*Operating mode"),
    (("pnu", "set", "930=2", "--verify"), 0, r"930"),
    (("--json", "pnu", "get", "930"), 0, r'"values": \[\s*2\s*\]'),
    (("pnu", "get", "964[0..4]", "965", "975"), 0, r"964"),
    (("pnu", "set", "930=1"), 0, r"930"),
    (("pnu", "describe", "930"), 0, r"930"),
    (("pnu", "set", "930=7"), 2, r""),                  # outside the catalogue's range: refused before sending
    (("info",), 0, r"AKD-P00606-NBCC-E000"),  # the one identity record (sim/identity.py, issue 23.8)
    (("--json", "info"), 0, r'"order_id"'),
    (("sdo", "read", "0x6060"), 2, r""),                # pn:// has no object channel
]
ACTIVE = [c for c in COMMANDS if _group_exists(c[0])]


def test_command_table_over_pn(serve) -> None:
    server = serve()
    failures = []
    for argv, code, pattern in ACTIVE:
        result = akdctl(target(server), *argv)
        if result.returncode != code or (pattern and not re.search(pattern, result.stdout)):
            failures.append(f"{argv}: exit {result.returncode} (want {code})\n{result.stdout}\n{result.stderr}")
        assert "Traceback" not in result.stderr
    assert not failures, "\n".join(failures)


def test_faults_injected_by_the_server(serve) -> None:
    server = serve("--pn-inject", "drop=3,dup=4,delay=5:0.3,rxdrop=7", "--pn-delay", "0.05")
    for value in (2, 0, 1, 2):
        result = akdctl(target(server), "pnu", "set", f"930={value}", "--verify", timeout=3)
        assert result.returncode == 0, result.stderr
    result = akdctl(target(server), "--json", "pnu", "get", "930", "964[0..4]", timeout=3)
    assert result.returncode == 0, result.stderr
    assert re.search(r'"values": \[\s*2\s*\]', result.stdout), result.stdout


def test_silent_device_exits_3_within_timeout() -> None:
    silent = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    silent.bind(("127.0.0.1", 0))
    try:
        start = time.monotonic()
        result = akdctl(f"pn://127.0.0.1:{silent.getsockname()[1]}", "pnu", "get", "930", timeout=0.5)
        elapsed = time.monotonic() - start
    finally:
        silent.close()
    assert result.returncode == 3, result.stderr
    assert "no answer" in result.stderr and "Traceback" not in result.stderr
    assert elapsed < 15        # bounded by --timeout (plus interpreter start), never a hang


def test_refused_ar_in_words(serve) -> None:
    server = serve("--pn-refuse-ar")
    result = akdctl(target(server), "pnu", "get", "930")
    assert result.returncode == 1
    assert "device refuses device-access AR" in result.stderr and "DB 81 01 04" in result.stderr


def _keep_duplicates(pairs: list[tuple[str, object]]) -> dict[str, object]:
    """tshark's JSON repeats keys inside one object (one per parameter); keep them all."""
    out: dict[str, object] = {}
    for key, value in pairs:
        if key in out:
            previous = out[key]
            out[key] = (previous if isinstance(previous, list) else [previous]) + [value]
        else:
            out[key] = value
    return out


def _values(tree: object, key: str) -> list[str]:
    found: list[str] = []
    if isinstance(tree, dict):
        for k, v in tree.items():
            if k == key:
                found.extend(v if isinstance(v, list) else [v])
            else:
                found.extend(_values(v, key))
    elif isinstance(tree, list):
        for item in tree:
            found.extend(_values(item, key))
    return found


def test_tshark_dissects_a_pcap_of_a_session(serve, tmp_path) -> None:
    tshark = shutil.which("tshark")
    if tshark is None:
        if os.environ.get("CI") == "true":
            pytest.fail("tshark is required in CI (.ci/run installs it)")
        pytest.skip("tshark is not installed (apt-get install tshark); CI runs this test")
    server = serve()
    capture = tmp_path / "session.pcap"
    result = akdctl(target(server), "--pcap", str(capture), "pnu", "set", "930=2")
    assert result.returncode == 0, result.stderr
    capture2 = tmp_path / "session2.pcap"
    result = akdctl(target(server), "--pcap", str(capture2), "pnu", "get", "930", "964[0..4]")
    assert result.returncode == 0, result.stderr
    docs = []
    for path in (capture, capture2):
        out = subprocess.run([tshark, "-r", str(path), "-T", "json"], capture_output=True, text=True, timeout=120,
                             env={**os.environ, "HOME": str(tmp_path)})
        assert out.returncode == 0, out.stderr
        docs.append(json.loads(out.stdout, object_pairs_hook=_keep_duplicates))
    assert {"0x0006"} == set(_values(docs, "pn_io.ar_type"))
    assert set(_values(docs, "pn_io.ar_properties.device_access")) == {"0x00000001"}
    assert set(_values(docs, "pn_io.index")) == {"0x002f"}
    numbers = _values(docs, "pn_io.profidrive.parameter.number")
    assert "930" in numbers and "964" in numbers
    words = _values(docs[0], "pn_io.profidrive.parameter.value_w")
    assert "0x0002" in words                                # the value written
    read_words = _values(docs[1], "pn_io.profidrive.parameter.value_w")
    assert "0x0002" in read_words and "0x0100" in read_words   # 930 read back, 964[0] vendor
    assert set(_values(docs, "pn_io.error_code")) == {"0x00"}
