"""Issue 17.10/17.12 and 14: files handed to akdctl, and files akdctl writes.

Reading (akdctl/io/safe_read.py): regular files only (a FIFO or a device is refused at once, never read), a size
cap on the file, on every zip member's uncompressed size and on their total, deep nesting and huge numbers as
one-line errors. Writing (akdctl/io/atomic.py): only into an existing directory, never outside a recipe's output
directory through a symbolic link, and one file-mode rule (0666 minus the umask; a replaced file keeps its mode).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import stat
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from akdctl.drive import bundle as bm
from akdctl.errors import UsageError
from akdctl.io import atomic
from akdctl.io.safe_read import read_regular


def _one_line_error(code: int, out: str, err: str, *words: str) -> None:
    assert code == 2 and out == "", (code, out, err)
    assert len(err.strip().splitlines()) == 1 and err.startswith("akdctl: error:"), err
    for word in words:
        assert word in err, err


@pytest.fixture
def fifo(tmp_path: Path) -> Iterator[Path]:
    path = tmp_path / "pipe.json"
    os.mkfifo(path)
    yield path


# ---------------------------------------------------------------- reading
def test_support_show_refuses_a_fifo_and_devices_at_once(akd_inproc: Any, fifo: Path) -> None:
    _one_line_error(*akd_inproc("support", "show", str(fifo)), "is a FIFO", "only regular files")
    _one_line_error(*akd_inproc("support", "show", "/dev/zero"), "is a character device")


def test_support_show_refuses_an_oversized_file_before_reading_it(akd_inproc: Any, tmp_path: Path) -> None:
    path = tmp_path / "big.json"
    with open(path, "wb") as fh:
        fh.truncate(bm.MAX_BUNDLE_BYTES + 1)  # sparse: costs no disk
    _one_line_error(*akd_inproc("support", "show", str(path)), "larger than")


def _zip_with(path: Path, members: dict[str, int]) -> None:
    """Deflated members of the given uncompressed sizes (spaces compress ~1000:1)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, size in members.items():
            with zf.open(name, "w", force_zip64=size > 0x7FFFFFFF) as fh:
                block = b" " * (1 << 20)
                for _ in range(size // len(block)):
                    fh.write(block)
                fh.write(b" " * (size % len(block)))


def test_support_show_refuses_a_member_that_unpacks_beyond_the_cap(akd_inproc: Any, tmp_path: Path) -> None:
    path = tmp_path / "bomb.zip"
    _zip_with(path, {bm.ZIP_MEMBER: bm.MAX_MEMBER_BYTES + 1})
    assert path.stat().st_size < bm.MAX_MEMBER_BYTES // 100
    _one_line_error(*akd_inproc("support", "show", str(path)), "unpacks to", "bundle.json")


def test_support_show_refuses_members_that_together_unpack_beyond_the_cap(akd_inproc: Any, tmp_path: Path) -> None:
    path = tmp_path / "many.zip"
    _zip_with(path, {f"m{i}": bm.MAX_MEMBER_BYTES for i in range(bm.MAX_UNPACKED_BYTES // bm.MAX_MEMBER_BYTES + 1)})
    _one_line_error(*akd_inproc("support", "show", str(path)), "unpacks to")


def test_support_show_refuses_a_zip_of_many_members(akd_inproc: Any, tmp_path: Path) -> None:
    path = tmp_path / "members.zip"
    with zipfile.ZipFile(path, "w") as zf:
        for i in range(bm.MAX_ZIP_MEMBERS + 1):
            zf.writestr(f"m{i}", b"")
    _one_line_error(*akd_inproc("support", "show", str(path)), "members")


def test_support_show_does_not_trust_a_member_s_declared_size(akd_inproc: Any, tmp_path: Path) -> None:
    """A member declaring 100 bytes that holds 10 MB: the read stops at the declared size (CRC error, exit 2)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(bm.ZIP_MEMBER, b" " * 10_000_000)
    raw = bytearray(buf.getvalue())
    size = (10_000_000).to_bytes(4, "little")
    for at in [i for i in range(len(raw)) if raw[i:i + 4] == size]:
        raw[at:at + 4] = (100).to_bytes(4, "little")  # local and central headers both lie
    path = tmp_path / "liar.zip"
    path.write_bytes(bytes(raw))
    _one_line_error(*akd_inproc("support", "show", str(path)))


@pytest.mark.parametrize("content", [b"[" * 100_000 + b"]" * 100_000, b'{"format": ' + b"9" * 10_000 + b"}"])
def test_support_show_deep_nesting_and_huge_numbers_are_one_line(akd_inproc: Any, tmp_path: Path,
                                                                 content: bytes) -> None:
    path = tmp_path / "deep.json"
    path.write_bytes(content)
    _one_line_error(*akd_inproc("support", "show", str(path)), "not an akdctl support bundle")


def test_recipe_and_backup_files_are_regular_files_only(akd_inproc: Any, tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "r.toml")
    code, out, err = akd_inproc("commission", "--dry-run", str(tmp_path / "r.toml"))
    assert code == 2 and "is a FIFO" in err, err
    os.mkfifo(tmp_path / "b.toml")
    code, out, err = akd_inproc("params", "diff", str(tmp_path / "b.toml"))
    assert code == 2 and "is a FIFO" in err, err


def test_deeply_nested_recipe_and_backup_are_one_line(akd_inproc: Any, tmp_path: Path) -> None:
    deep = "x = " + "[" * 50_000 + "]" * 50_000 + "\n"
    (tmp_path / "r.toml").write_text(deep)
    (tmp_path / "b.toml").write_text(deep)
    code, _, err = akd_inproc("commission", "--dry-run", str(tmp_path / "r.toml"))
    assert code == 2 and len(err.strip().splitlines()) <= 2 and "internal error" not in err, err
    code, _, err = akd_inproc("params", "diff", str(tmp_path / "b.toml"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "internal error" not in err, err


def test_read_regular_bounds_a_file_that_grows(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "f"
    path.write_bytes(b"x" * 10)
    real_fstat = os.fstat

    def small(fd: int) -> os.stat_result:  # the file was 10 bytes when looked at, then grew
        info = real_fstat(fd)
        return os.stat_result((info.st_mode, *info[1:6], 5, *info[7:]))

    monkeypatch.setattr(os, "fstat", small)
    with pytest.raises(UsageError, match="grew beyond"):
        read_regular(path, limit=5, what="x")


# ---------------------------------------------------------------- writing
def test_recipe_backup_through_a_symlinked_directory_is_refused(akd_inproc: Any, tmp_path: Path) -> None:
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "sub").symlink_to(elsewhere)
    (out / "link.toml").symlink_to(elsewhere / "x.toml")
    for name in ("sub/b.toml", "link.toml"):
        recipe = tmp_path / "r.toml"
        recipe.write_text(f'[[step]]\naction = "backup"\nfile = "{name}"\n')
        code, _, err = akd_inproc("--yes", "commission", str(recipe), "--output-dir", str(out))
        assert code == 2 and "refused" in err, err
    assert list(elsewhere.iterdir()) == []


def test_a_recipe_backup_lands_in_the_output_directory(akd_inproc: Any, tmp_path: Path) -> None:
    recipe = tmp_path / "r.toml"
    recipe.write_text('[[step]]\naction = "backup"\nfile = "b.toml"\n')
    code, _, err = akd_inproc("--yes", "commission", str(recipe), "--output-dir", str(tmp_path / "out"))
    assert code == 0, err
    assert (tmp_path / "out" / "b.toml").is_file()


@pytest.mark.parametrize("args", [["params", "backup", "-o", "{d}/x.toml"], ["support", "bundle", "-o", "{d}/b.json"],
                                  ["commission", "--dry-run", "EXAMPLE", "--report", "{d}/r.json"]])
def test_no_directory_is_created_for_a_file(akd_inproc: Any, tmp_path: Path, args: list[str]) -> None:
    from tests.harness import ROOT

    missing = tmp_path / "nonexistent"
    argv = [a.replace("{d}", str(missing)).replace("EXAMPLE", str(ROOT / "examples" / "commission-sim.toml"))
            for a in args]
    code, _, err = akd_inproc(*argv)
    assert code == 2 and "does not exist" in err and "creates no directories" in err, err
    assert not missing.exists()


@contextlib.contextmanager
def _umask(mask: int) -> Iterator[None]:
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


def _writers(tmp_path: Path) -> list[tuple[list[str], Path]]:
    from tests.harness import ROOT

    example = str(ROOT / "examples" / "commission-sim.toml")
    return [(["params", "backup", "-o", str(tmp_path / "b.toml")], tmp_path / "b.toml"),
            (["support", "bundle", "-o", str(tmp_path / "s.zip")], tmp_path / "s.zip"),
            (["commission", "--dry-run", example, "--report", str(tmp_path / "r.xml")], tmp_path / "r.xml"),
            (["pdo", "map", "--dry-run", "--rx", "0x1701", "--tx", "0x1B01", "--export", str(tmp_path / "e.json")],
             tmp_path / "e.json"),
            (["--pcap", str(tmp_path / "c.pcap"), "pnu", "get", "930"], tmp_path / "c.pcap")]


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_every_file_akdctl_writes_follows_the_umask(akd_inproc: Any, tmp_path: Path, mask: int, mode: int) -> None:
    for argv, path in _writers(tmp_path):
        with _umask(mask):
            code, _, err = akd_inproc(*argv)
        assert code == 0, (argv, err)
        assert stat.S_IMODE(path.stat().st_mode) == mode, (argv, oct(path.stat().st_mode))


def test_a_replaced_file_keeps_its_mode(akd_inproc: Any, tmp_path: Path) -> None:
    for argv, path in _writers(tmp_path):
        path.write_text("previous")
        path.chmod(0o640)
        with _umask(0o022):
            code, _, err = akd_inproc(*argv)
        assert code == 0, (argv, err)
        assert path.read_bytes() != b"previous" and stat.S_IMODE(path.stat().st_mode) == 0o640, argv


def test_confined_paths(tmp_path: Path) -> None:
    (tmp_path / "d").mkdir()
    assert atomic.confined(tmp_path, "d/x.toml") == tmp_path.resolve() / "d" / "x.toml"
    for bad in ("/etc/x", "../x", "", "d/../../x"):
        with pytest.raises(UsageError):
            atomic.confined(tmp_path, bad)


def test_json_bundle_written_is_valid(tmp_path: Path) -> None:
    path = tmp_path / "b.json"
    bm.write({"format": bm.FORMAT}, path)
    assert json.loads(path.read_text()) == {"format": bm.FORMAT}
