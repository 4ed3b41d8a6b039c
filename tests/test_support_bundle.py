"""``akdctl support bundle`` / ``support show``: round trip without a drive, atomic writes, damaged files."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import pytest

from akdctl.drive import bundle as bm


def _bundle(akd: Any, path: Path, *extra: str) -> dict[str, Any]:
    code, out, err = akd("--json", *extra, "support", "bundle", "-o", str(path))
    assert code == 0, err
    summary = json.loads(out)
    assert summary["file"] == str(path) and summary["sections_with_errors"] == []
    return summary


def _load_json(path: Path) -> dict[str, Any]:
    if path.suffix == ".zip":
        with zipfile.ZipFile(path) as zf:
            return json.loads(zf.read(bm.ZIP_MEMBER))
    return json.loads(path.read_text())


@pytest.mark.parametrize("name", ["bundle.json", "bundle.zip"])
def test_bundle_then_show_on_a_machine_without_the_drive(akd: Any, tmp_path: Path, name: str) -> None:
    assert akd("sim", "fault", "F501", "n503")[0] == 0
    path = tmp_path / name
    _bundle(akd, path)
    data = _load_json(path)
    assert data["format"] == bm.FORMAT and data["format_version"] == bm.FORMAT_VERSION
    for key in ("created", "tool", "target", "identity", "faults", "status", "parameters", "mapping", "trace",
                "errors"):
        assert key in data, key
    assert data["tool"]["name"] == "akdctl" and data["target"]["display"] == "sim"
    assert data["identity"]["profidrive"]["profile"]["name"] == "PROFIdrive"
    assert data["identity"]["canopen"]["vendor_id"] == 0x6A
    assert [e["code"] for e in data["faults"]["profidrive"]["active"]] == ["F501"]
    assert [e["code"] for e in data["faults"]["canopen"]["warnings"]] == ["n503"]
    pnus = {p["pnu"]: p for p in data["parameters"]["pnus"]}
    assert pnus[947]["values"][0] == 501 and pnus[964]["values"][0] == 256
    assert any(o["object"] == "0x1018:1" and o["value"] == 0x6A for o in data["parameters"]["objects"])
    assert data["mapping"]["profidrive"]["telegram"] is not None
    assert data["trace"] and {"direction", "layer", "hex"} <= set(data["trace"][0])
    if name.endswith(".zip"):
        with zipfile.ZipFile(path) as zf:
            assert zf.read(bm.ZIP_TRACE).decode().count("\n") == len(data["trace"])
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp file left behind

    elsewhere = tmp_path / "no-drive-here"
    code, out, err = akd("support", "show", str(path), env={"AKDCTL_STATE_DIR": str(elsewhere)})
    assert code == 0, err
    assert not elsewhere.exists()  # showing never touched a (simulated) drive
    for text in ("support bundle (sim)", "F501", "DC Bus link over-voltage", "n503", "parameter snapshot",
                 "Fault message counter", "session trace", "PDO entries"):
        assert text in out, text
    code, out, _ = akd("--json", "support", "show", str(path), env={"AKDCTL_STATE_DIR": str(elsewhere)})
    assert code == 0 and json.loads(out) == data


def test_pnu_snapshot_is_one_batched_read(akd_inproc: Any, tmp_path: Path) -> None:
    from akdctl.catalog.pnus import pnu_table

    path = tmp_path / "b.json"
    _bundle(akd_inproc, path, "-T", "sim?drive=profidrive")
    data = json.loads(path.read_text())
    readable = [n for n, i in pnu_table().items() if "r" in i.access]
    assert len(data["parameters"]["pnus"]) == len(readable)
    # 39 parameters / 240 bytes per request: the whole catalogue needs only a handful of round trips
    assert 1 <= data["parameters"]["round_trips"]["pnus"] <= 8
    assert "objects" not in data["parameters"]


def test_cia402_bundle_has_the_object_view(akd_inproc: Any, tmp_path: Path) -> None:
    assert akd_inproc("sim", "fault", "F234")[0] == 0
    path = tmp_path / "b.json"
    _bundle(akd_inproc, path, "-T", "sim?drive=cia402")
    data = json.loads(path.read_text())
    assert "profidrive" not in data["faults"]
    assert [e["code"] for e in data["faults"]["canopen"]["faults"]] == ["F234"]
    assert "pnus" not in data["parameters"]
    assert data["mapping"]["canopen"]["rx"]["assign_object"] == "0x1C12"
    code, out, err = akd_inproc("support", "show", str(path))
    assert code == 0, err
    assert "F234" in out


def test_bundle_with_an_unknown_fault_number_shows_it_as_unknown(akd_inproc: Any, tmp_path: Path) -> None:
    path = tmp_path / "b.json"
    _bundle(akd_inproc, path)
    data = json.loads(path.read_text())
    data["faults"]["profidrive"]["active"] = [{"number": 777, "code": "F777?", "name": "unknown fault 777",
                                               "kind": "unknown"}]
    path.write_text(json.dumps(data))
    code, out, err = akd_inproc("support", "show", str(path))
    assert code == 0, err
    assert "F777?" in out and "unknown fault 777" in out


@pytest.mark.parametrize("content", [
    b"",
    b"not json at all",
    b'{"format": "something-else", "format_version": 1}',
    b'{"format": "akdctl-support-bundle", "format_version": 99}',
    b'{"format": "akdctl-support-bundle", "format_version": 1}',
    b'[1, 2, 3]',
    b"\xff\xfe\x00garbage",
])
def test_damaged_or_foreign_files_are_one_line_errors(akd_inproc: Any, tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "suspect.json"
    path.write_bytes(content)
    code, out, err = akd_inproc("support", "show", str(path))
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("akdctl: error:")


def test_truncated_zip_and_foreign_zip_are_rejected(akd_inproc: Any, tmp_path: Path) -> None:
    good = tmp_path / "b.zip"
    _bundle(akd_inproc, good)
    truncated = tmp_path / "t.zip"
    truncated.write_bytes(good.read_bytes()[: len(good.read_bytes()) // 2])
    foreign = tmp_path / "f.zip"
    with zipfile.ZipFile(foreign, "w") as zf:
        zf.writestr("other.txt", "hello")
    for path in (truncated, foreign, tmp_path / "missing.zip", tmp_path):
        code, _, err = akd_inproc("support", "show", str(path))
        assert code == 2 and len(err.strip().splitlines()) == 1, (path, err)


def test_damaged_sections_are_a_usage_error_not_a_crash(akd_inproc: Any, tmp_path: Path) -> None:
    path = tmp_path / "b.json"
    _bundle(akd_inproc, path)
    data = json.loads(path.read_text())
    data["faults"] = {"profidrive": {"active": "not a list"}}
    path.write_text(json.dumps(data))
    code, _, err = akd_inproc("support", "show", str(path))
    assert code == 2 and "damaged support bundle" in err


def test_write_is_atomic_when_interrupted(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import os

    path = tmp_path / "b.json"
    path.write_text("previous bundle")

    def broken_replace(src: str, dst: str) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", broken_replace)
    from akdctl.errors import UsageError

    with pytest.raises(UsageError):
        bm.write({"format": bm.FORMAT}, path)
    assert path.read_text() == "previous bundle"
    assert [p.name for p in tmp_path.iterdir()] == ["b.json"]


def test_missing_output_directory_is_a_usage_error(akd_inproc: Any, tmp_path: Path) -> None:
    code, _, err = akd_inproc("support", "bundle", "-o", str(tmp_path / "nope" / "b.json"))
    assert code == 2 and "does not exist" in err


def test_unreachable_drive_still_writes_a_bundle_and_exits_3(akd_inproc: Any, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    from akdctl.connection import Connection
    from akdctl.errors import NoAnswer

    def silent(self: Connection) -> Any:
        raise NoAnswer("no answer from the drive within 0.2 s")

    monkeypatch.setattr(Connection, "transport", silent)
    path = tmp_path / "b.json"
    code, _, err = akd_inproc("support", "bundle", "-o", str(path))
    assert code == 3 and "bundle written" in err
    data = json.loads(path.read_text())
    assert data["faults"] == {"error": "no answer from the drive within 0.2 s"}
    assert "transport" in data["errors"]
    code, out, err = akd_inproc("support", "show", str(path))
    assert code == 0, err
    assert "no answer" in out
