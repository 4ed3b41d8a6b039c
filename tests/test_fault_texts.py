"""Issue 14: ``fault list`` classifies F139 and "Emergency error free" correctly; ``fault explain`` gives a remedy
where a public source states one and says where to look otherwise (akdctl/catalog/data/faults.csv, catalog/faults.py).
"""

from __future__ import annotations

import json
from typing import Any

from akdctl.catalog import faults


def test_every_kind_follows_the_akd_prefix() -> None:
    for f in faults.faults():
        if f.code:
            assert f.kind == ("fault" if f.code.startswith("F") else "warning"), f
    assert faults.by_code("F139").kind == "fault"  # type: ignore[union-attr]
    free = faults.by_emcy(0)
    assert [f.kind for f in free] == ["none"] and "not a fault" in free[0].remedy.lower()


def test_fault_list_classifies_f139_and_error_free(akd_inproc: Any) -> None:
    code, out, err = akd_inproc("--json", "fault", "list", "F139")
    assert code == 0, err
    assert [(f["code"], f["kind"]) for f in json.loads(out)["faults"]] == [("F139", "fault")]
    code, out, err = akd_inproc("--json", "fault", "list", "error free")
    assert code == 0, err
    assert [(f["code"], f["kind"]) for f in json.loads(out)["faults"]] == [(None, "none")]
    code, out, _ = akd_inproc("--json", "fault", "list", "--kind", "warning")
    assert all(f["code"] is None or f["code"].startswith("n") for f in json.loads(out)["faults"])


def test_explain_gives_the_cited_remedy(akd_inproc: Any) -> None:
    code, out, err = akd_inproc("--json", "fault", "explain", "F125")
    assert code == 0, err
    (item,) = json.loads(out)["faults"]
    assert "FBUS.PARAM04" in item["remedy"] and "EtherCAT manual" in item["source"] and "where_to_look" not in item
    code, out, err = akd_inproc("fault", "explain", "F125")
    assert code == 0 and "seven EtherCAT frames" in " ".join(out.split()), out


def test_explain_says_where_to_look_without_a_source(akd_inproc: Any) -> None:
    code, out, err = akd_inproc("--json", "fault", "explain", "F139")
    assert code == 0, err
    (item,) = json.loads(out)["faults"]
    assert item["remedy"] is None and "AKD Fault Card" in item["where_to_look"] and "DRV.FAULTS" in item["where_to_look"]
    code, out, err = akd_inproc("fault", "explain", "F139")
    assert code == 0 and "AKD Fault Card" in " ".join(out.split()), out
