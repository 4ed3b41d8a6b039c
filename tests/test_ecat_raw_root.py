"""EtherCAT on a raw interface: our simulated AKD slave on one end of a veth pair in a network namespace, and on the
other end (another namespace) (a) pysoem - an independent master (SOEM) - and (b) our own raw master through the
real CLI. tshark dissects our pcaps. Needs root (network namespaces, CAP_NET_RAW): skipped with a reason otherwise,
never skipped when CI=true.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.harness import ROOT, CliResult, SimServer, run_akdctl
from tests.netns import VethPair

IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
CI = os.environ.get("CI") == "true"

pytestmark = [
    pytest.mark.root,
    pytest.mark.slow,
    pytest.mark.skipif(not IS_ROOT and not CI, reason="needs root for network namespaces and raw sockets"),
]


def _run(*cmd: str, check: bool = True, timeout: float = 30) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, capture_output=True, text=True, check=check, timeout=timeout)


def _need_pysoem() -> None:
    """pysoem is the optional extra akdctl[soem]; in CI it must be installed (never skip there)."""
    if CI:
        import pysoem  # noqa: F401
    else:
        pytest.importorskip("pysoem", reason="optional extra akdctl[soem] not installed")


def slave_server(pair: VethPair, *extra: str) -> SimServer:
    """The simulated AKD slave on the ``b`` end of *pair* (start it with ``with``)."""
    return SimServer("--ethercat-raw", pair.if_b, *extra, netns=pair.b)


@pytest.fixture
def pair() -> Iterator[VethPair]:
    """Master side ``a``/``if_a``, slave side ``b``/``if_b``."""
    with VethPair() as p:
        yield p


@pytest.fixture
def slave(pair: VethPair) -> Iterator[SimServer]:
    with slave_server(pair) as server:
        assert server.ready[0].startswith("ethercat-raw"), server.ready
        yield server


def cli(pair: VethPair, *args: str, position: int = 0) -> CliResult:
    return run_akdctl("-T", f"ecat://{pair.if_a}/{position}", "--timeout", "1", *args, netns=pair.a)


def test_pysoem_master_against_sim_slave(pair: VethPair, slave: SimServer) -> None:
    _need_pysoem()
    script = textwrap.dedent(f"""
        import json, pysoem
        m = pysoem.Master()
        m.open({pair.if_a!r})
        try:
            n = m.config_init()
            s = m.slaves[0]
            out = dict(n=n, name_sii=s.name, man=s.man, id=s.id, rev=s.rev, vendor=s.sdo_read(0x1018, 1).hex(),
                       name=s.sdo_read(0x1008, 0).decode(), product=s.sdo_read(0x1018, 2).hex())
            s.sdo_write(0x6060, 0, bytes([3]))
            out["mode"] = s.sdo_read(0x6060, 0).hex()
            m.read_state()
            out["state"] = s.state
        finally:
            m.close()
        print(json.dumps(out))
    """)
    result = subprocess.run(["ip", "netns", "exec", pair.a, sys.executable, "-c", script], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout.strip().splitlines()[-1])
    assert out["n"] == 1 and out["name_sii"] == "AKD"  # SOEM names a slave by SII string 1
    assert out["man"] == 0x6A and out["id"] == 0x00414B44 and out["rev"] == 2
    assert out["vendor"] == "6a000000" and out["product"] == "444b4100" and out["name"] == "AKD"
    assert out["mode"] == "03" and out["state"] == 2  # PRE-OP


# argv, expected exit code, text expected on stdout
COMMANDS = [
    (["--json", "ecat", "scan"], 0, "\"akd\": true"),
    (["ecat", "state"], 0, "INIT"),
    (["sdo", "read", "0x1018:1"], 0, "106"),
    (["sdo", "read", "0x1008:0"], 0, "AKD"),
    (["sdo", "write", "0x6060:0", "3"], 0, None),
    (["sdo", "read", "0x6060:0"], 0, "3"),
    (["ecat", "state"], 0, "PREOP"),
    (["info"], 0, "106"),
    (["-y", "enable"], 0, "operation enabled"),
    (["status"], 0, "operation enabled"),
    (["-y", "disable"], 0, "drive disabled"),
    (["pdo", "show"], 0, "0x1701"),
    (["-y", "move", "1000"], 4, None),
    (["sdo", "read", "0x5FFF:0", "u8"], 1, None),
    (["--json", "ecat", "sii"], 0, "AKD-P00606-NBCC-E000"),
    (["ecat", "sii", "--raw"], 0, "0000: 09 00 00 08"),
    (["--json", "ecat", "state", "op", "--dry-run"], 0, "AL Control (0x0120)"),   # PRE-OP -> SAFE-OP -> OP
    (["ecat", "state"], 0, "PREOP"),                                             # ... and nothing requested
    (["ecat", "state", "op"], 0, "OP"),
    (["ecat", "state", "init"], 0, "INIT"),
    (["ecat", "state", "op", "--dry-run"], 0, "via INIT, SM0/SM1 from the SII"),
]


def test_our_master_through_the_cli(pair: VethPair, slave: SimServer) -> None:
    for argv, code, text in COMMANDS:
        result = cli(pair, *argv)
        assert result.returncode == code, (argv, result.stdout, result.stderr)
        if text is not None:
            assert text in result.stdout, (argv, result.stdout)
        if argv[:2] == ["--json", "ecat"] and "--dry-run" in argv:   # the stepping rule: one request per step up
            assert [w["value"] for w in json.loads(result.stdout)["plan"]["writes"]] == ["SAFEOP", "OP"]
    result = cli(pair, "sdo", "read", "0x1018:1", position=3)
    assert result.returncode == 2 and "no slave at position 3" in result.stderr


@pytest.mark.skipif(shutil.which("tshark") is None and not CI, reason="tshark not installed")
def test_tshark_dissects_raw_pcap(pair: VethPair, slave: SimServer, tmp_path: Path) -> None:
    pcap = tmp_path / "raw.pcap"
    result = cli(pair, "--pcap", str(pcap), "sdo", "read", "0x1018:1")
    assert result.returncode == 0, result.stderr
    fields = _run("tshark", "-r", str(pcap), "-T", "fields", "-e", "ecat.cmd", "-e", "ecat_mailbox.type", "-e",
                  "ecat_mailbox.coe.sdoidx", "-e", "ecat_mailbox.coe.sdosub", "-e", "ecat_mailbox.coe.sdodata",
                  timeout=60)
    rows = [line.split("\t") for line in fields.stdout.splitlines()]
    cmds = {c for r in rows for c in r[0].split(",")}
    assert {"0x07", "0x02", "0x04", "0x05"} <= cmds  # BRD, APWR, FPRD, FPWR
    mailbox = [r for r in rows if len(r) > 4 and r[2]]
    # request written with FPWR to SM0; reply read with FPRD from SM1 (in a frame that also polls the SM1 status)
    assert any(r[0] == "0x05" and r[1] == "3" and r[2] == "0x1018" and r[3] == "0x01" for r in mailbox)
    assert any("0x04" in r[0] and r[2] == "0x1018" and r[4] == "0x0000006a" for r in mailbox), mailbox


@pytest.mark.parametrize("inject, code, words", [
    ("drop=2", 0, None),  # every 2nd reply frame lost: recovered by the repeat request
    ("abort=1", 1, "general error"),
    ("mbxerr=1", (1, 3), "mailbox"),
])
def test_fault_injection(pair: VethPair, inject: str, code: object, words: str | None) -> None:
    with slave_server(pair, "--ecat-raw-inject", inject):
        for _ in range(3 if inject.startswith("drop") else 1):
            result = cli(pair, "sdo", "read", "0x1018:1")
            assert result.returncode in (code if isinstance(code, tuple) else (code,)), result.stderr
            if words:
                assert words in result.stderr.lower()
            assert "Traceback" not in result.stderr


def test_vanished_slave_exits_3(pair: VethPair) -> None:
    result = cli(pair, "sdo", "read", "0x1018:1")
    assert result.returncode == 3, result.stderr
    assert "no EtherCAT frame came back" in result.stderr or "no EtherCAT slave" in result.stderr


def test_missing_cap_net_raw_is_one_line(tmp_path: Path) -> None:
    if shutil.which("setpriv") is None:
        pytest.skip("setpriv not available to drop privileges")
    probe = _run("setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", sys.executable, "-c", "import click",
                 check=False)
    if probe.returncode != 0:
        pytest.skip("python is not usable by an unprivileged user here")
    # The unprivileged user cannot enter root's pytest tmp dirs: point every per-user path somewhere absent.
    env = dict(os.environ, AKDCTL_STATE_DIR="/nonexistent/akdctl-state", XDG_CONFIG_HOME="/nonexistent/akdctl-config",
               PYTHONPATH=str(ROOT), HOME="/nonexistent")
    result = run_akdctl("-T", "ecat://lo", "sdo", "read", "0x1018:1", env=env,
                        prefix=["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"])
    assert result.returncode == 2
    assert "needs CAP_NET_RAW" in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_soem_transport_through_the_cli(pair: VethPair, slave: SimServer) -> None:
    _need_pysoem()
    for argv, code, text in [(["sdo", "read", "0x1018:1"], 0, "106"), (["sdo", "read", "0x5FFF:0", "u8"], 1, None),
                             (["sdo", "write", "0x6060:0", "3"], 0, None)]:
        result = run_akdctl("-T", f"ecat+soem://{pair.if_a}/0", "--timeout", "1", *argv, netns=pair.a)
        assert result.returncode == code, (argv, result.stdout, result.stderr)
        if text:
            assert text in result.stdout
