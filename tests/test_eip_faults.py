"""Issue 28 item 4: faults over eip:// through what an AKD offers to explicit messaging (drive/eip_faults.py).

``fault dump``, ``fault ack``, ``diagnose`` and ``support bundle`` against ``sim serve --ethernetip`` in its own
process: the general fault (0x24/1/5) and DRV.FAULT1 (0x0F/478) - both [I], and the dump says so - name the AKD
fault; what the target does not offer (history, warnings, homed, acknowledge) is named as not offered, and
acknowledging an active fault is refused in one line with the reason, never pointed at a channel eip:// lacks.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator

import pytest

from tests.harness import SimServer, run_akdctl

pytestmark = pytest.mark.slow


@pytest.fixture
def eip_target() -> Iterator[str]:
    with SimServer("--ethernetip", "127.0.0.1:0", "--eip-io-port", "0") as server:
        port = re.search(r"ethernetip [\d.]+:(\d+)", server.ready[0])
        assert port, server.ready
        yield f"eip://127.0.0.1:{port.group(1)}"


def _json(*args: str) -> dict:
    result = run_akdctl(*args, "--json")
    assert result.code == 0, result.stderr
    return json.loads(result.stdout)


def test_dump_and_ack_without_a_fault(eip_target: str) -> None:
    data = _json("-T", eip_target, "fault", "dump")
    eip = data["eip"]
    assert eip["fault_present"] is False and eip["active"] == [] and eip["errors"] == {}
    assert "[I:" in eip["sources"]["general_fault"] and "[I:" in eip["sources"]["fault1"]
    assert "acknowledge" in eip["not_offered"] and "homed, warnings" in eip["not_offered"]
    ack = _json("-T", eip_target, "fault", "ack")
    assert ack["fault_present"] is False and ack["acknowledged"] == []


def test_active_fault_is_named_and_ack_refused_in_one_line(eip_target: str) -> None:
    assert run_akdctl("sim", "fault", "F501").code == 0
    eip = _json("-T", eip_target, "fault", "dump")["eip"]
    assert eip["fault_present"] is True and eip["fault1"] == 501
    assert eip["active"] == [{"number": 501, "code": "F501", "name": "DC Bus link over-voltage", "kind": "fault"}]
    human = run_akdctl("-T", eip_target, "fault", "dump")
    assert human.code == 0 and "F501" in human.stdout and "not offered: acknowledge" in human.stdout
    markdown = run_akdctl("-T", eip_target, "fault", "dump", "--format", "markdown")
    assert markdown.code == 0 and "| F501 |" in markdown.stdout
    ack = run_akdctl("-T", eip_target, "fault", "ack")
    assert ack.code == 2 and ack.stderr.count("\n") == 1 and "F501 active" in ack.stderr
    assert "DRV.CLRFAULTS" in ack.stderr and "PNU" not in ack.stderr and "SDO" not in ack.stderr


def test_diagnose_and_bundle_name_the_fault(eip_target: str, tmp_path) -> None:
    assert run_akdctl("sim", "fault", "F501").code == 0
    result = _json("-T", eip_target, "diagnose")
    first = result["causes"][0]
    assert first["cause"] == "fault" and "F501" in first["text"] and "no CIP path" in first["remedy"]
    assert "homed, warnings" in result["not_read"]
    bundle = tmp_path / "b.json"
    assert run_akdctl("-T", eip_target, "support", "bundle", "-o", str(bundle)).code == 0
    shown = run_akdctl("support", "show", str(bundle), "--format", "markdown")
    assert shown.code == 0 and "| **!** | active | eip | F501 |" in shown.stdout
