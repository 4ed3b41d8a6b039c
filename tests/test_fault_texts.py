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


#: Issue 23.23: the common power-stage and bus faults it names. F533 is not in the public EMCY table the catalogue
#: comes from (reference/akd_faults_emcy.csv): ``fault explain F533`` is an unknown code, exit 2.
ISSUE_23_FAULTS = ("F501", "F502", "F503", "F504", "F505", "F523", "F524", "F531", "F532", "F534", "F535",
                   "F702", "F703", "F125", "F129")


def test_the_common_faults_cite_a_source_or_say_honestly_that_none_is_at_hand(akd_inproc: Any) -> None:
    """Issue 23.23: a remedy only with its named source (F125: the EtherCAT manual; F703: the parameter reference's
    DRV.DIS); the others have no public source in the project's seeds or reference and say where to look."""
    cited = {}
    for code in ISSUE_23_FAULTS:
        rc, out, err = akd_inproc("--json", "fault", "explain", code)
        assert rc == 0, err
        (item,) = [f for f in json.loads(out)["faults"] if f["code"] == code]
        if item["remedy"]:
            assert "remedy:" in item["source"], item  # every remedy names where it comes from
            cited[code] = item["source"]
        else:
            assert "no public source we cite" in item["where_to_look"]
    assert set(cited) == {"F125", "F703"}
    assert akd_inproc("fault", "explain", "F533")[0] == 2
    assert "DRV.DIS" in cited["F703"] and "EtherCAT manual" in cited["F125"]
