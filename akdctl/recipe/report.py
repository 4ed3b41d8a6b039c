"""Commissioning reports: the run as JSON (every step, its data) and as JUnit XML (one test case per step).

Why JUnit: every CI system (Jenkins, GitLab, GitHub Actions, Azure) renders it
without plugins, so a commissioning run shows up as a test suite whose cases are
the recipe's steps. A failed check (read-back or expected value) is a
``<failure>``; a drive refusal, fault or lost link is an ``<error>``; steps not
run after the first failure are ``<skipped>``. Both files are written atomically.
"""

from __future__ import annotations

import json
import socket
import xml.etree.ElementTree as ET
from pathlib import Path

from akdctl.errors import UsageError
from akdctl.io.atomic import require_directory, write_user_file
from akdctl.recipe.runner import FAILED, PLANNED, SKIPPED, RunResult

KINDS = {".json": "json", ".xml": "junit"}


def kind_of(path: str) -> str:
    suffix = Path(path).suffix.lower()
    if suffix not in KINDS:
        raise UsageError(f"report {path}: the suffix chooses the kind: .json (JSON report) or .xml (JUnit XML)")
    require_directory(Path(path))  # checked before the run, so a run is never lost for want of a directory
    return KINDS[suffix]


def write(result: RunResult, path: str) -> None:
    text = to_json_text(result) if kind_of(path) == "json" else to_junit(result)
    write_user_file(Path(path), text)


def to_json_text(result: RunResult) -> str:
    return json.dumps(result.to_json(), indent=2, default=str) + "\n"


def _is_failure(kind: str) -> bool:
    return kind == "check-failed"


def to_junit(result: RunResult) -> str:
    failures = sum(1 for r in result.results if r.status == FAILED and _is_failure(r.kind))
    errors = sum(1 for r in result.results if r.status == FAILED and not _is_failure(r.kind))
    skipped = sum(1 for r in result.results if r.status in (SKIPPED, PLANNED))
    counts = {"tests": str(len(result.results)), "failures": str(failures), "errors": str(errors),
              "skipped": str(skipped), "time": f"{result.duration:.3f}"}
    suites = ET.Element("testsuites", {"name": "akdctl commission", **counts})
    suite = ET.SubElement(suites, "testsuite", {"name": result.recipe, **counts, "timestamp": result.started,
                                                "hostname": socket.gethostname() or "localhost"})
    props = ET.SubElement(suite, "properties")
    for name, value in (("target", result.target), ("recipe_file", result.file), ("exit_code", str(result.exit_code)),
                        ("dry_run", str(result.dry_run).lower()), ("safe_state", result.safe_state)):
        if value:
            ET.SubElement(props, "property", {"name": name, "value": value})
    classname = f"commission.{Path(result.file).stem}"
    for r in result.results:
        attrs = {"name": f"step {r.step.number:02d}: {r.step.name}", "classname": classname,
                 "time": f"{r.duration:.3f}", "file": r.step.file}
        if r.step.line is not None:
            attrs["line"] = str(r.step.line)
        case = ET.SubElement(suite, "testcase", attrs)
        if r.status == FAILED:
            tag = "failure" if _is_failure(r.kind) else "error"
            element = ET.SubElement(case, tag, {"message": r.message, "type": r.kind or "error"})
            element.text = r.message + (f"\nexit code {r.exit_code}" if r.exit_code else "") + \
                (f"\naxis: {result.safe_state}" if result.safe_state else "")
        elif r.status == SKIPPED:
            ET.SubElement(case, "skipped", {"message": r.message or "not run"})
        elif r.status == PLANNED:
            ET.SubElement(case, "skipped", {"message": f"dry run: {r.step.plan}"})
        out = ET.SubElement(case, "system-out")
        out.text = f"{r.step.action}: {r.step.plan}"
    ET.indent(suites)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(suites, encoding="unicode") + "\n"
