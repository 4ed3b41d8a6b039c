"""Issue 28 item 8: ``akdctl diagnose`` names every cause the drive exposes, most likely first, with its remedy.

Each branch is raised on the simulated drive on demand (``sim fault``, ``sim set``) and read back through the real
CLI in-process; the simulated drive honours an injected disable source (it does not enable), so the diagnosis is
checked against the behaviour it explains. Sources: DRV.DISSOURCES bits (reference/akd-ascii-channel.md, [G1] bits
0-5), SPEC-NOTES 23 (controlword mapped in OP), CiA 402 0x60FD limit switch bits.
"""

from __future__ import annotations

import json
from typing import Any

import pytest

CIA = "sim?drive=cia402"


def _diagnose(akd_inproc: Any, *args: str, target: str = CIA) -> dict[str, Any]:
    code, out, err = akd_inproc("-T", target, "--json", "diagnose", *args)
    assert code == 0, err
    return json.loads(out)


def _kinds(result: dict[str, Any], blocking: bool = True) -> list[str]:
    return [c["cause"] for c in result["causes"] if c["blocking"] == blocking]


def test_healthy_disabled_drive_has_nothing_blocking(akd_inproc: Any) -> None:
    result = _diagnose(akd_inproc)
    assert _kinds(result) == [] and result["enabled"] is False
    assert "only disabled" in result["verdict"]
    (note,) = [c for c in result["causes"] if c["cause"] == "disabled"]
    assert "DRV.DISSOURCES (0x3443) = 0x0001, bit 0" in note["evidence"]  # the drive's own words for it


def test_enabled_drive_is_fine(akd_inproc: Any) -> None:
    assert akd_inproc("-T", CIA, "-y", "enable")[0] == 0
    result = _diagnose(akd_inproc)
    assert result["enabled"] is True and _kinds(result) == [] and result["verdict"].startswith("enabled")


def test_hardware_enable_low_blocks_and_the_drive_really_stays_disabled(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "set", "hw-enable=low")[0] == 0
    assert akd_inproc("-T", CIA, "-y", "enable")[0] != 0  # the simulated drive honours its enable input
    result = _diagnose(akd_inproc)
    first = result["causes"][0]
    assert first["cause"] == "dissource" and "hardware enable" in first["text"] and "bit 2" in first["evidence"]
    assert "hardware enable" in result["verdict"]
    assert akd_inproc("sim", "set", "hw-enable=high")[0] == 0
    assert akd_inproc("-T", CIA, "-y", "enable")[0] == 0


@pytest.mark.parametrize(("bits", "words"), [(0x8, "in-rush"), (0x10, "initialising"), (0x20, "controlled stop"),
                                             (0x40, "fieldbus requested"), (0x800, None)])
def test_each_disable_source_has_words(akd_inproc: Any, bits: int, words: str | None) -> None:
    code, _, err = akd_inproc("sim", "set", f"dissources={bits}")
    if words is None:  # bit 11 does not exist: refused at the command line
        assert code == 2 and "0..0x7FF" in err
        return
    assert code == 0, err
    texts = [c["text"] for c in _diagnose(akd_inproc)["causes"] if c["blocking"]]
    assert len(texts) == 1 and words in texts[0]


def test_fault_ranks_first_with_its_remedy(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "set", "limit=negative")[0] == 0
    assert akd_inproc("sim", "fault", "F501")[0] == 0
    result = _diagnose(akd_inproc)
    assert _kinds(result)[:2] == ["fault", "limit"]
    assert "F501" in result["causes"][0]["text"] and "fault ack" in result["causes"][0]["remedy"]
    assert not any(c["cause"] == "dissource" for c in result["causes"])  # bit 1 is the fault already named
    assert "negative limit" in result["causes"][1]["text"]


def test_sto_warning_blocks_enabling(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "fault", "n602", "--persist")[0] == 0
    assert akd_inproc("-T", CIA, "-y", "enable")[0] != 0
    result = _diagnose(akd_inproc)
    assert result["causes"][0]["cause"] == "sto" and "STO" in result["causes"][0]["text"]


def test_controlword_mapped_in_op(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "set", "al-state=OP")[0] == 0
    result = _diagnose(akd_inproc)
    assert _kinds(result) == ["controlword-pdo"] and "SPEC-NOTES 23" in result["causes"][0]["text"]


def test_mode_against_mapping_and_against_the_request(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "set", "mode=8", "al-state=SAFEOP")[0] == 0
    result = _diagnose(akd_inproc)
    (cause,) = [c for c in result["causes"] if c["cause"] == "cycle"]
    assert "0x607A" in cause["text"] and "F706" in cause["text"]
    result = _diagnose(akd_inproc, "--mode", "velocity")
    assert "mode" in _kinds(result) and any("not velocity" in c["text"] for c in result["causes"])


def test_profidrive_reads_what_it_has(akd_inproc: Any) -> None:
    result = _diagnose(akd_inproc, target="sim?drive=profidrive")
    assert "STW1 and operating mode (PNU 1, 930)" in result["read"]
    assert any(c["cause"] == "mode" and "STW1 bit 10" in c["text"] and not c["blocking"] for c in result["causes"])


def test_human_output_and_bad_input(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "set", "hw-enable=low")[0] == 0
    code, out, _ = akd_inproc("-T", CIA, "diagnose")
    assert code == 0 and "blocks" in out and "hardware enable input is low" in out
    for args in (("sim", "set", "hw-enable=maybe"), ("sim", "set", "nonsense=1"), ("sim", "set", "limit"),
                 ("diagnose", "--mode", "fly")):
        code, _, err = akd_inproc(*args)
        assert code == 2 and err.startswith("akdctl: error:") and "Traceback" not in err, args


@pytest.mark.slow
def test_silent_drive_is_one_line_exit_3(akd: Any) -> None:
    from tests.harness import closed_udp_port

    with closed_udp_port() as port:
        code, _, err = akd("-T", f"pn://127.0.0.1:{port}", "--timeout", "0.3", "diagnose")
    assert code == 3 and err.count("\n") == 1 and "Traceback" not in err


def test_cycle_time_off_the_grid_and_below_the_minimum(akd_inproc: Any) -> None:
    for value, words in (("3,-4", "62.5"), ("1,-4", "minimum")):
        assert akd_inproc("sim", "set", f"cycle-time={value}", "al-state=SAFEOP")[0] == 0
        (cause,) = [c for c in _diagnose(akd_inproc)["causes"] if c["cause"] == "cycle"]
        assert words in cause["text"] and cause["blocking"]
    assert akd_inproc("sim", "set", "cycle-time=x")[0] == 2


def test_homed_note_in_position_mode(akd_inproc: Any) -> None:
    assert akd_inproc("-y", "pnu", "set", "930=2")[0] == 0
    result = _diagnose(akd_inproc, target="sim")
    (homed,) = [c for c in result["causes"] if c["cause"] == "homed"]
    assert not homed["blocking"] and homed["remedy"] == "akdctl home"


def test_quick_stop_active(akd_inproc: Any) -> None:
    assert akd_inproc("-T", CIA, "-y", "sdo", "write", "0x605A", "6")[0] == 0  # option 6: stay in quick stop
    assert akd_inproc("-T", CIA, "-y", "enable")[0] == 0
    assert akd_inproc("-T", CIA, "-y", "sdo", "write", "0x6040", "0x0002")[0] == 0
    result = _diagnose(akd_inproc)
    assert "quick-stop" in _kinds(result), result


@pytest.mark.slow
def test_over_the_ethercat_gateway_face(akd: Any) -> None:
    """The same cause read over ETG.8200 (CoE SDO on a real socket); the AL state it cannot see is listed."""
    from tests.harness import SimServer

    assert akd("sim", "set", "hw-enable=low")[0] == 0
    with SimServer("--ethercat-udp", "127.0.0.1:0") as server:
        code, out, err = akd("-T", f"ecat-udp://127.0.0.1:{server.port}/1001", "--json", "diagnose")
    assert code == 0, err
    result = json.loads(out)
    assert result["causes"][0]["text"] == "hardware enable input is low"
    assert "EtherCAT AL state" in result["not_read"]


def test_al_error_with_its_status_code_over_the_raw_master(tmp_path: Any) -> None:
    """Our raw master against our simulated slave over a socketpair (no root, as tests/test_ecat_raw_inprocess):
    a refused state change leaves PREOP+ERR and the AL status code, which diagnose names in words."""
    from test_ecat_raw_inprocess import Wire, transport

    from akdctl.connection import Connection
    from akdctl.drive.diagnose import diagnose
    from akdctl.errors import DriveError
    from akdctl.protocol import ethercat as ec
    from akdctl.sim.drive import SimDrive

    wire = Wire(SimDrive("default", tmp_path))
    t = transport(wire)
    conn = Connection.over(t)
    try:
        conn.transport()
        with pytest.raises(DriveError):
            t.master.request_state(t.slave.station, ec.AlState.OP)  # type: ignore[union-attr]  # PREOP -> OP: refused
        result = diagnose(conn)
    finally:
        conn.close()
        wire.close()
    (cause,) = [c for c in result["causes"] if c["cause"] == "al"]
    assert cause["blocking"] and "PREOP+ERR" in cause["text"] and "0x0011" in cause["text"]
    assert "0x0134 = 0x0011" in cause["evidence"]
