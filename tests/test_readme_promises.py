"""Issue 14, README items: every link in README.md and docs/*.md resolves, the set-up commands leave no file in the
repository root, the prerequisites and the `can` extra are stated, and `964:0..4` works where zsh would glob
`964[0..4]`."""

from __future__ import annotations

import json
import re
import shlex
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.drive.params import parse_assignment, parse_pnu_spec
from tests.harness import ROOT

DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
_LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return {_slug(m.group(1)) for m in re.finditer(r"^#{1,6}\s+(.+?)\s*#*$", text, re.M)}


def _links(path: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return _LINK.findall(text)


def test_the_link_check_sees_links_and_anchors() -> None:
    assert "docs/motion.md" in _links(ROOT / "README.md")
    assert "safety-model" in _anchors(ROOT / "README.md") and "ethernetip" in _anchors(ROOT / "README.md")


@pytest.mark.parametrize("doc", DOCS, ids=[p.name for p in DOCS])
def test_every_link_resolves(doc: Path) -> None:
    broken = []
    for link in _links(doc):
        if re.match(r"^[a-z][a-z0-9+.-]*:", link):  # http:, https:, mailto: — not checked offline
            continue
        target, _, anchor = link.partition("#")
        path = (doc.parent / target).resolve() if target else doc
        if not path.exists():
            broken.append(f"{link}: no such file")
        elif anchor and path.suffix == ".md" and anchor not in _anchors(path):
            broken.append(f"{link}: no heading #{anchor} in {path.name}")
    assert broken == [], f"{doc.name}: {broken}"


def test_no_document_cites_a_file_the_repository_lacks() -> None:
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        assert "SPEC-NOTES.md" not in text, doc  # the rulings are docs/spec-notes.md
        for cited in re.findall(r"`(docs/[\w.-]+\.md)`", text):
            assert (ROOT / cited).exists(), (doc, cited)


def _setup_commands() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    setup = text.split("## Set up", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.+?)\n```", setup)


def test_prerequisites_are_stated() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    setup = text.split("## Set up", 1)[1].split("\n## ", 1)[0]
    assert "Python 3.11" in setup and "venv" in setup


def _ignored_dirs() -> set[str]:
    return {line.strip().rstrip("/") for line in (ROOT / ".gitignore").read_text().splitlines()
            if line.strip().endswith("/") and not line.startswith("#")}


def test_setup_writes_only_below_ignored_directories() -> None:
    first = _setup_commands()[0]
    akdctl = shlex.split(first.split("&&")[-1])
    written = [akdctl[i + 1] for i, word in enumerate(akdctl) if word in ("--report", "--output-dir")]
    assert "--output-dir" in akdctl and written
    for path in written:
        assert Path(path).parts[0] in _ignored_dirs(), path


@pytest.mark.slow
def test_the_first_setup_command_leaves_the_root_clean(tmp_path: Path) -> None:
    """The commission part of the first command, run in a copy of the repository's layout: only .venv/ changes."""
    repo = tmp_path / "repo"  # the test's own state directory also lives in tmp_path
    repo.mkdir()
    (repo / "examples").symlink_to(ROOT / "examples")
    (repo / ".venv").mkdir()
    args = shlex.split(_setup_commands()[0].split("&&")[-1])[1:]  # drop ".venv/bin/akdctl"
    before = sorted(p.name for p in repo.iterdir())
    code, _, err = _run_in(repo, args)
    assert code == 0, err
    assert sorted(p.name for p in repo.iterdir()) == before
    assert json.loads((repo / ".venv" / "report.json").read_text())["result"] == "passed"
    assert list((repo / ".venv").glob("*backup*.toml"))


def _run_in(directory: Path, args: list[str]) -> tuple[int, str, str]:
    from tests.harness import run_akdctl

    code, out, err = run_akdctl(*args, cwd=directory, timeout=120)
    return code, out, err


def test_can_extra_brings_msgpack_and_readme_says_so() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert any(dep.startswith("msgpack") for dep in project["optional-dependencies"]["can"])
    assert "akdctl[can]" in (ROOT / "README.md").read_text(encoding="utf-8")


# ---------------------------------------------------------------- 964:0..4
@given(pnu=st.sampled_from([964, 947, 915]), first=st.integers(0, 2), width=st.integers(0, 2))
def test_colon_form_is_the_bracket_form(pnu: int, first: int, width: int) -> None:
    last = first + width  # within every one of these arrays (964 has elements 0..4)
    assert parse_pnu_spec(f"{pnu}:{first}..{last}") == parse_pnu_spec(f"{pnu}[{first}..{last}]")
    assert parse_pnu_spec(f"{pnu}:{first}") == parse_pnu_spec(f"{pnu}[{first}]")


def test_colon_form_in_assignments() -> None:
    assert parse_assignment("915:0..1=1,5") == parse_assignment("915[0..1]=1,5")
    assert parse_assignment("915:1=5") == parse_assignment("915[1]=5")


def test_colon_form_through_the_cli(akd_inproc: Any) -> None:
    code, colon, err = akd_inproc("--json", "pnu", "get", "930", "964:0..4", "947:3")
    assert code == 0, err
    code, brackets, err = akd_inproc("--json", "pnu", "get", "930", "964[0..4]", "947[3]")
    assert code == 0 and json.loads(colon) == json.loads(brackets)
    code, _, err = akd_inproc("pnu", "get", "964::1")
    assert code == 2 and "PNU:FROM..TO" in err and "zsh" in err


def test_readme_examples_need_no_quoting_in_zsh() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    for block in re.findall(r"```sh\n(.*?)```", text, re.S):
        for line in block.splitlines():
            command = line.split("#", 1)[0]
            assert not re.search(r"(?<!['\"])\b\d+\[\d+(\.\.\d+)?\]", command), line
