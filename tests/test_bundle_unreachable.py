"""Issue 14: ``support bundle`` against a drive that cannot be reached exits 3 after one timeout, not one per section.

akdctl/drive/bundle.py ``_guard``: the first communication failure ends the reading; the later sections say they
were not read; the bundle is still written; the command exits 3. A drive *refusal* in one section still lets the
others run (tests/test_support_bundle.py).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from akdctl.drive import bundle as bm
from tests.harness import closed_udp_port, run_akdctl


def test_a_silent_drive_is_asked_once(akd_inproc: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from akdctl.drive import identity
    from akdctl.errors import NoAnswer

    calls: list[str] = []

    def silent(conn: Any, *a: Any, **k: Any) -> Any:
        calls.append("identity")
        raise NoAnswer("no answer from the drive within 0.2 s")

    monkeypatch.setattr(identity, "read_identity", silent)
    path = tmp_path / "b.json"
    code, out, err = akd_inproc("support", "bundle", "-o", str(path))
    assert code == 3 and "bundle written" in err and "the sections after it were not read" in err, err
    assert calls == ["identity"]
    data = json.loads(path.read_text())
    assert data["identity"]["kind"] == "timeout"
    for section in ("faults", "status", "mapping"):
        assert data[section]["kind"] == "skipped" and data[section]["error"].startswith(bm.SKIPPED)
    assert data["errors"][bm.LINK_ERROR].startswith("identity: no answer")
    assert len([ln for ln in err.splitlines() if "warning" in ln]) == 1  # one warning, not one per section
    code, out, err = akd_inproc("support", "show", str(path))
    assert code == 0, err


def test_a_drive_refusal_is_not_a_lost_link(akd_inproc: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from akdctl.drive import identity
    from akdctl.errors import DriveError

    def refuse(conn: Any, *a: Any, **k: Any) -> Any:
        raise DriveError("identity refused")

    monkeypatch.setattr(identity, "read_identity", refuse)
    path = tmp_path / "b.json"
    code, _, err = akd_inproc("support", "bundle", "-o", str(path))
    assert code == 0, err
    data = json.loads(path.read_text())
    assert "error" in data["identity"] and "error" not in data["status"] and bm.LINK_ERROR not in data["errors"]


@pytest.mark.slow
def test_unreachable_gateway_exits_3_after_one_timeout(tmp_path: Path) -> None:
    path = tmp_path / "b.json"
    with closed_udp_port() as port:
        code, _, err = run_akdctl("--timeout", "0.3", "-T", f"ecat-udp://127.0.0.1:{port}/1", "support", "bundle",
                                  "-o", str(path))
    assert code == 3 and "bundle written" in err, err
    data = json.loads(path.read_text())
    asked = [bytes.fromhex(r["hex"]) for r in data["trace"] if r["direction"] == "tx"]
    # One request and its retries (which differ only in the mailbox counter, byte 7), not one per section.
    assert asked and len({frame[:7] + frame[8:] for frame in asked}) == 1, asked
