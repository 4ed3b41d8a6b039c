"""``--dry-run`` on every writing command prints the plan and writes nothing (issue 28 item 5).

Each command runs with ``--dry-run`` (and ``--yes``, so a missing consent cannot be what stops it) against the
simulated drive, whose write counter must not move; the plan (``--json``) names the writes the real run makes,
and the real run, for contrast, does move the counter.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from tests.harness import SimServer, run_akdctl

pytestmark = pytest.mark.slow  # runs the real CLI in subprocesses

PD, COE = "sim?drive=profidrive", "sim?drive=cia402"


def _writes() -> int:
    from akdctl.sim.drive import SimDrive

    return int(SimDrive("default").snapshot()["writes"])


def _check(target: str, args: list[str], expected_writes: int) -> None:
    before = _writes()
    dry = run_akdctl("-T", target, "--yes", "--json", *args, "--dry-run")
    assert dry.code == 0, (args, dry.err)
    document = json.loads(dry.out)
    plan = document.get("write_plan", document.get("plan"))
    assert len(plan["writes"]) == expected_writes, (args, plan)
    assert _writes() == before, f"{args} --dry-run wrote to the drive"
    plain = run_akdctl("-T", target, "--yes", *args, "--dry-run")
    assert plain.code == 0 and "dry run" in plain.out and "\\n" not in plain.out, plain.out
    assert _writes() == before
    real = run_akdctl("-T", target, "--yes", *args)
    assert real.code == 0, (args, real.err)
    assert _writes() > before, f"{args} without --dry-run wrote nothing: the counter cannot tell"


def test_dry_run_of_every_writing_command_on_the_simulator(tmp_path: Path) -> None:
    assert run_akdctl("sim", "reset").code == 0
    _check(PD, ["pnu", "set", "930=2", "1004=-500"], 2)
    _check(COE, ["sdo", "write", "0x6081:0", "1000"], 1)
    _check(PD, ["telegram", "set", "0"], 1)
    _check(PD, ["telegram", "map", "--setpoint", "1,5", "--actual", "2,6"], 2)
    _check(COE, ["pdo", "map", "--rx", "0x1701", "--tx", "0x1B20"], 6)
    backup = tmp_path / "b.toml"
    assert run_akdctl("-T", PD, "params", "backup", "-o", str(backup), "--only", "930,1001").code == 0
    assert run_akdctl("-T", PD, "--yes", "pnu", "set", "930=1", "1001=3").code == 0
    _check(PD, ["params", "restore", str(backup)], 2)
    assert run_akdctl("sim", "fault", "F501").code == 0
    _check(PD, ["fault", "ack"], 1)


def test_dry_run_of_the_cip_writes(tmp_path: Path) -> None:
    """The CIP faces keep no write counter; the attribute itself tells: unchanged by the dry run, changed by the
    real run."""
    with SimServer("--ethernetip", "127.0.0.1:0", "--eip-io-port", "0") as server:
        port = re.search(r"ethernetip [\d.]+:(\d+)", " ".join(server.ready))
        assert port, server.ready
        target = f"eip://127.0.0.1:{port.group(1)}"
        cases = ((["cip", "set", "0x25/1/3", "u8"], ["cip", "get", "0x25/1/3", "u8"]),
                 (["eip", "param", "set", "EIP.PROFUNIT"], ["eip", "param", "get", "EIP.PROFUNIT"]))
        for write, read in cases:
            def value() -> int:
                result = run_akdctl("-T", target, "--json", *read)
                assert result.code == 0, result.err
                return int(json.loads(result.out)["value"])

            before = value()
            new = str(before + 1 if before < 200 else 1)
            dry = run_akdctl("-T", target, "--yes", "--json", *write, new, "--dry-run")
            assert dry.code == 0, (write, dry.err)
            plan = json.loads(dry.out)["plan"]
            assert len(plan["writes"]) == 1 and plan["operation"] in ("cip set", "eip param set"), plan
            plain = run_akdctl("-T", target, "--yes", *write, new, "--dry-run")
            assert plain.code == 0 and "dry run" in plain.out, plain.err
            assert value() == before, f"{write} --dry-run wrote"
            real = run_akdctl("-T", target, "--yes", *write, new)
            assert real.code == 0, real.err
            assert value() == int(new), write
