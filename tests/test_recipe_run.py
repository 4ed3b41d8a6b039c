"""Recipes run end to end on the simulated AKD through the real CLI, with JSON and JUnit reports."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from akdctl.errors import EXIT_CHECK, EXIT_DRIVE, EXIT_OK
from tests.harness import ROOT, finish, start_akdctl, wait_until

EXAMPLE = ROOT / "examples" / "commission-sim.toml"


def sim_model_values() -> dict:
    from akdctl.sim.drive import SimDrive

    with SimDrive("default").transaction() as model:
        motion = model.component("motion")
        return {"writes": model.writes, "standstill": motion.standstill, "velocity": motion.velocity_rpm,
                "zsw1": model.pnu_read_raw(2, 0, 1)[1][0]}


def check_junit_structure(path: Path) -> ET.Element:
    """The structure JUnit consumers (Jenkins, GitLab, junitparser) require."""
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites"
    suites = root.findall("testsuite")
    assert len(suites) == 1
    suite = suites[0]
    for attr in ("name", "tests", "failures", "errors", "skipped", "time", "timestamp"):
        assert attr in suite.attrib
    cases = suite.findall("testcase")
    assert int(suite.get("tests")) == len(cases)
    for case in cases:
        assert case.get("name") and case.get("classname")
        float(case.get("time"))
        outcomes = [c.tag for c in case if c.tag in ("failure", "error", "skipped")]
        assert len(outcomes) <= 1
        for child in case:
            if child.tag in ("failure", "error"):
                assert child.get("message") and child.get("type")
    assert int(suite.get("failures")) == sum(1 for c in cases if c.find("failure") is not None)
    assert int(suite.get("errors")) == sum(1 for c in cases if c.find("error") is not None)
    assert int(suite.get("skipped")) == sum(1 for c in cases if c.find("skipped") is not None)
    return suite


def test_example_recipe_runs_green_with_json_and_junit_reports(akd, tmp_path: Path) -> None:
    junitparser = pytest.importorskip("junitparser")
    report_json, report_xml = tmp_path / "report.json", tmp_path / "junit.xml"
    out_dir = tmp_path / "out"
    code, out, err = akd("--yes", "commission", str(EXAMPLE), "--report", str(report_json), "--report",
                         str(report_xml), "--output-dir", str(out_dir))
    assert code == EXIT_OK, err
    data = json.loads(report_json.read_text())
    assert data["result"] == "passed" and data["exit_code"] == 0 and data["target"] == "sim"
    actions = [s["action"] for s in data["steps"]]
    for needed in ("set", "telegram", "map", "enable", "home", "move", "check_faults", "backup"):
        assert needed in actions
    assert all(s["status"] == "passed" and s["line"] for s in data["steps"])
    moves = [s for s in data["steps"] if s["action"] == "move"]
    assert moves[0]["details"]["position_rev"] == pytest.approx(2.0, abs=1e-3)
    assert (out_dir / "commission-sim-backup.toml").exists()

    suite = check_junit_structure(report_xml)
    assert int(suite.get("failures")) == 0 and int(suite.get("errors")) == 0
    xml = junitparser.JUnitXml.fromfile(str(report_xml))
    cases = [case for s in xml for case in s]
    assert len(cases) == len(data["steps"])
    assert all(case.is_passed for case in cases)


def test_failed_check_stops_the_run_reports_it_and_skips_the_rest(akd_inproc, tmp_path: Path) -> None:
    junitparser = pytest.importorskip("junitparser")
    recipe = tmp_path / "check.toml"
    recipe.write_text('[recipe]\nname = "check"\n\n'
                      '[[step]]\naction = "set"\npnu = "930"\nvalue = 2\n\n'
                      '[[step]]\naction = "expect"\nname = "telegram is 9"\npnu = "922"\nvalue = 9\n\n'
                      '[[step]]\naction = "set"\npnu = "1001"\nvalue = 3\n')  # not gated
    xml_path, json_path = tmp_path / "j.xml", tmp_path / "r.json"
    code, out, err = akd_inproc("commission", str(recipe), "--report", str(xml_path), "--report", str(json_path))
    assert code == EXIT_CHECK
    assert "step 2 (telegram is 9) failed at check.toml:9" in err and "expected PNU 922" in err
    data = json.loads(json_path.read_text())
    assert [s["status"] for s in data["steps"]] == ["passed", "failed", "skipped"]
    assert data["failed_step"]["step"] == 2
    suite = check_junit_structure(xml_path)
    assert suite.get("failures") == "1" and suite.get("skipped") == "1"
    cases = [case for s in junitparser.JUnitXml.fromfile(str(xml_path)) for case in s]
    assert cases[0].is_passed and not cases[1].is_passed and cases[2].is_skipped


@pytest.mark.slow
def test_injected_fault_mid_recipe_stops_it_makes_the_axis_safe_and_names_the_step(tmp_path: Path) -> None:
    recipe = tmp_path / "long.toml"
    recipe.write_text('[recipe]\nname = "long move"\n\n'
                      '[[step]]\naction = "set"\npnus = { "930" = 2, "1001" = 0 }\n\n'
                      '[[step]]\naction = "enable"\n\n'
                      '[[step]]\naction = "home"\n\n'
                      '[[step]]\naction = "move"\nname = "long move"\ntarget = 100\nvelocity = 60\n\n'
                      '[[step]]\naction = "backup"\nfile = "never.toml"\n')
    report = tmp_path / "r.json"
    proc = start_akdctl("--yes", "commission", str(recipe), "--report", str(report), "--output-dir", str(tmp_path))
    try:
        wait_until(lambda: proc.poll() is not None or abs(sim_model_values()["velocity"]) > 1.0,
                   "the long move to start", timeout=30)
        assert proc.poll() is None, proc.communicate()
        from akdctl.sim.drive import SimDrive

        with SimDrive("default").transaction() as model:
            model.component("faults").raise_fault("F501")
        code, out, err = finish(proc, timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert code == EXIT_DRIVE, err
    assert "step 4 (long move)" in err and "F501" in err
    data = json.loads(report.read_text())
    assert data["failed_step"]["step"] == 4 and data["failed_step"]["action"] == "move"
    assert [s["status"] for s in data["steps"]] == ["passed", "passed", "passed", "failed", "skipped"]
    assert "disabled" in data["safe_state"]
    state = sim_model_values()
    assert state["standstill"]
    assert not state["zsw1"] & 0x0004  # operation enabled is off
    assert not (tmp_path / "never.toml").exists()
