"""``akdctl fault ...`` and ``akdctl sim fault|clear`` through the real CLI (state dir = tmp_path).

SPEC-NOTES 14 (PNU 944/947 semantics) and 21 (CoE fault objects) underlie the expectations.
"""

from __future__ import annotations

import json
import os
from typing import Any

import pytest


def _json(out: str) -> Any:
    return json.loads(out)


def test_single_fault_dump_in_every_format(akd: Any, akd_inproc: Any, isolated_env: Any) -> None:
    code, out, err = akd("sim", "fault", "F501")
    assert code == 0, err
    assert os.environ["AKDCTL_STATE_DIR"] == str(isolated_env) and any(isolated_env.iterdir())

    code, out, err = akd("--json", "fault", "dump")
    assert code == 0, err
    data = _json(out)
    pd, co = data["profidrive"], data["canopen"]
    assert pd["fault_message_counter"] == 1 and pd["consistent"] and pd["fault_present"]
    assert [e["code"] for e in pd["active"]] == ["F501"]
    assert pd["active"][0]["name"] == "DC Bus link over-voltage"
    assert [e["code"] for e in co["faults"]] == ["F501"] and co["error_register"] == 0x05

    code, out2, _ = akd_inproc("fault", "dump", "--format", "json")
    assert code == 0 and _json(out2)["profidrive"]["active"] == pd["active"]

    code, out, _ = akd_inproc("fault", "dump")
    assert code == 0
    assert "F501" in out and "DC Bus link over-voltage" in out and "fault dump (sim)" in out
    assert "bit 3 fault SET" in out

    code, out, _ = akd_inproc("fault", "dump", "--format", "markdown")
    assert code == 0
    assert out.startswith("## AKD fault dump — sim")
    assert "| 1 | F501 | fault | DC Bus link over-voltage |" in out
    assert "### active fault situation (PNU 947[0..7])" in out


def test_multiple_faults_then_ack_moves_them_to_acknowledged(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "fault", "F501", "F502", "n503")[0] == 0
    code, out, err = akd_inproc("--json", "fault", "ack")
    assert code == 0, err
    assert _json(out)["acknowledged"] == ["F501", "F502"]
    code, out, _ = akd_inproc("--json", "-T", "sim?drive=profidrive", "fault", "dump")
    data = _json(out)
    assert "canopen" not in data
    pd = data["profidrive"]
    assert pd["active"] == [] and not pd["fault_present"] and pd["warning_present"]
    assert pd["acknowledged"][0]["situation"] == 1
    assert [e["code"] for e in pd["acknowledged"][0]["faults"]] == ["F501", "F502"]
    assert pd["buffer"][8:10] == [501, 502]
    code, out, _ = akd_inproc("--json", "fault", "ack")
    assert code == 0 and _json(out)["acknowledged"] == []


def test_history_after_more_than_eight_situations_drops_the_oldest(akd_inproc: Any) -> None:
    numbers = [501, 502, 503, 523, 247, 519, 234, 235, 236, 237]
    for number in numbers:
        assert akd_inproc("sim", "fault", f"F{number}")[0] == 0
        assert akd_inproc("fault", "ack")[0] == 0
    code, out, _ = akd_inproc("--json", "-T", "sim?drive=profidrive", "fault", "dump")
    pd = _json(out)["profidrive"]
    assert pd["fault_message_counter"] == 10
    assert [s["situation"] for s in pd["acknowledged"]] == [1, 2, 3, 4, 5, 6, 7]
    assert [s["faults"][0]["number"] for s in pd["acknowledged"]] == [237, 236, 235, 234, 519, 247, 523]
    code, out, _ = akd_inproc("-T", "sim?drive=profidrive", "fault", "dump")
    assert "F501" not in out and "F237" in out


def test_counter_moving_during_the_dump_is_retried(akd: Any) -> None:
    assert akd("sim", "fault", "F501", "--after-reads", "1")[0] == 0
    code, out, err = akd("--json", "-T", "sim?drive=profidrive", "fault", "dump")
    assert code == 0, err
    pd = _json(out)["profidrive"]
    assert pd["attempts"] == 2 and pd["consistent"] and pd["fault_message_counter"] == 1
    assert [e["code"] for e in pd["active"]] == ["F501"]


def test_coe_path_on_the_sim_with_emergencies_and_clear_history(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "fault", "F234", "n503")[0] == 0
    code, out, err = akd_inproc("--json", "-T", "sim?drive=cia402", "fault", "dump")
    assert code == 0, err
    data = _json(out)
    assert "profidrive" not in data
    co = data["canopen"]
    assert [e["code"] for e in co["faults"]] == ["F234"]
    assert [e["code"] for e in co["warnings"]] == ["n503"]
    assert [e["faults"] for e in co["error_history"]] == [["n503"], ["F234"]]
    assert {e["emcy"] for e in co["emergencies"]} >= {"0x4210", "0x3180"}
    assert co["error_register"] == 0x09 and "temperature" in co["error_register_text"]

    code, out, err = akd_inproc("--json", "-T", "sim?drive=cia402", "fault", "ack")
    assert code == 0, err
    code, out, err = akd_inproc("--json", "-T", "sim?drive=cia402", "fault", "clear-history", "--dry-run")
    assert code == 0 and _json(out)["plan"]["writes"][0]["address"].startswith("0x1003:0"), err
    assert len(_json(akd_inproc("--json", "-T", "sim?drive=cia402", "fault", "dump")[1])["canopen"]["error_history"]) == 2
    code, out, err = akd_inproc("--json", "-T", "sim?drive=cia402", "fault", "clear-history")
    assert code == 0, err
    assert _json(out)["entries_left"] == 0 and "only 0x1003 is written" in err
    co = _json(akd_inproc("--json", "-T", "sim?drive=cia402", "fault", "dump")[1])["canopen"]
    assert co["error_history"] == [] and [e["code"] for e in co["fault_history"]] == ["F234"]


def test_clear_history_is_refused_on_profidrive(akd_inproc: Any) -> None:
    code, out, err = akd_inproc("-T", "sim?drive=profidrive", "fault", "clear-history")
    assert code == 2 and "PNU 947" in err and "cannot be cleared" in err
    assert len(err.strip().splitlines()) == 1


def test_persisting_cause_makes_ack_fail_until_sim_clear(akd_inproc: Any) -> None:
    assert akd_inproc("sim", "fault", "F501", "--persist")[0] == 0
    code, _, err = akd_inproc("fault", "ack")
    assert code == 1 and "F501" in err
    code, out, _ = akd_inproc("--json", "sim", "clear")
    assert code == 0 and _json(out)["removed_causes"] == ["F501"]
    assert akd_inproc("fault", "ack")[0] == 0
    assert _json(akd_inproc("--json", "fault", "dump")[1])["profidrive"]["active"] == []


def test_unknown_fault_numbers_in_the_buffer_are_shown_as_unknown(akd_inproc: Any) -> None:
    from akdctl.sim.drive import SimDrive

    with SimDrive("default").transaction() as model:
        comp = model.component("faults")
        comp.situations[0] = [9999, 501]
        comp.history = [(4242, 7)]
    code, out, err = akd_inproc("--json", "fault", "dump")
    assert code == 0, err
    data = _json(out)
    active = data["profidrive"]["active"]
    assert active[0] == {"number": 9999, "code": "F9999?", "name": "unknown fault 9999 (not in the AKD table)",
                         "kind": "unknown"}
    assert data["canopen"]["fault_history"][0]["kind"] == "unknown"
    code, out, _ = akd_inproc("fault", "dump", "--format", "markdown")
    assert code == 0 and "F9999?" in out


def test_sim_fault_rejects_unknown_codes(akd_inproc: Any) -> None:
    code, _, err = akd_inproc("sim", "fault", "F9999")
    assert code == 2 and "F9999" in err
    code, _, err = akd_inproc("sim", "fault", "F501", "--after-reads", "0")
    assert code == 2


def test_list_filters_by_kind_and_text(akd_inproc: Any) -> None:
    code, out, _ = akd_inproc("--json", "fault", "list", "--kind", "warning")
    data = _json(out)
    assert data["count"] > 5 and all(f["kind"] == "warning" for f in data["faults"])
    code, out, _ = akd_inproc("--json", "fault", "list", "over-voltage")
    codes = [f["code"] for f in _json(out)["faults"]]
    assert "F501" in codes and "n501" in codes
    code, out, _ = akd_inproc("fault", "list", "0x3210")
    assert code == 0 and "F501" in out


@pytest.mark.parametrize("query", ["F417", "f417", "417"])
def test_explain_gives_reaction_and_remedy_where_known(akd_inproc: Any, query: str) -> None:
    code, out, _ = akd_inproc("--json", "fault", "explain", query)
    assert code == 0
    (item,) = _json(out)["faults"]
    assert item["code"] == "F417" and item["reaction"] == "dynamic braking" and item["remedy"]


def test_explain_by_emcy_code_and_unknown(akd_inproc: Any) -> None:
    code, out, _ = akd_inproc("fault", "explain", "F501")
    assert code == 0 and "not given by a public source" in out and "n501" in out
    code, out, _ = akd_inproc("--json", "fault", "explain", "0x3210")
    assert code == 0 and [f["code"] for f in _json(out)["faults"]] == ["F501"]
    code, _, err = akd_inproc("fault", "explain", "F9999")
    assert code == 2 and "unknown AKD fault" in err
    code, _, err = akd_inproc("fault", "explain", "0xZZ")
    assert code == 2


def test_dump_fails_only_when_every_view_is_refused(akd_inproc: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    from akdctl.drive import faults as df
    from akdctl.errors import ParameterRefused, SdoAborted

    def refuse_pnu(channel: Any, **_: Any) -> Any:
        raise ParameterRefused("drive refused to read PNU 944 (impermissible parameter number, error 0x00)")

    monkeypatch.setattr(df, "read_profidrive_faults", refuse_pnu)
    code, out, err = akd_inproc("--json", "fault", "dump")
    assert code == 0, err  # the CoE view still answered
    assert "error" in _json(out)["profidrive"] and "canopen" in _json(out)

    def refuse_sdo(channel: Any, **_: Any) -> Any:
        raise SdoAborted("SDO abort 0x06020000: object does not exist")

    monkeypatch.setattr(df, "read_canopen_faults", refuse_sdo)
    code, out, err = akd_inproc("fault", "dump")
    assert code == 1 and "refused the fault dump" in err and "not readable" in out
