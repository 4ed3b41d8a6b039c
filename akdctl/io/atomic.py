"""Every file akdctl writes: crash-safe, into an existing directory, with one file-mode rule.

Why here: the simulated drive's state file, parameter backups, recipe reports,
support bundles and ``--export`` files must never be left half-written (a reader
sees the old file or the new one, never a mix), so they are written to a
temporary file in the same directory, fsynced and renamed over the target; one
implementation keeps the fsync and the clean-up on failure in one place.

The rules (README "Files akdctl writes"), each decided once here:

* **Mode**: a new file gets ``0666`` minus the umask (``0644`` under the usual
  ``022``), like ``cp`` or ``tar`` would create it; a file akdctl replaces keeps
  its permission bits. So ``umask 077`` makes every backup, report, bundle,
  export and capture private, and a backup someone made private stays so.
  (``mkstemp`` alone would create ``0600`` whatever the umask, while a plain
  ``open`` honours it: that difference was the bug.)
* **Directories**: akdctl writes a file the user names only into a directory
  that exists; it creates none (``params backup -o /nonexistent/x.toml`` is a
  one-line error, exit 2). The exceptions are its own state directory and the
  one directory ``commission --output-dir`` names.
* **Confinement**: a file a recipe names below an output directory must stay
  there once symbolic links are resolved (:func:`confined`).
"""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from akdctl.errors import UsageError


def current_umask() -> int:
    """The process's umask, read without changing it where the kernel tells (``/proc/self/status``)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # no /proc: the only portable way is to set it and put it back
    os.umask(mask)
    return mask


def file_mode(path: Path) -> int:
    """The mode a write to ``path`` gives the file (module docstring: the one rule)."""
    try:
        info = os.stat(path)
        if stat.S_ISREG(info.st_mode):
            return stat.S_IMODE(info.st_mode)
    except OSError:
        pass
    return 0o666 & ~current_umask()


@contextlib.contextmanager
def atomic_open(path: Path, mode: str = "w", *, prefix: str | None = None,
                encoding: str | None = None) -> Iterator[IO]:  # type: ignore[type-arg]
    """Open a temporary file beside ``path`` for writing; on a clean exit it replaces ``path``.

    On an exception the temporary file is removed and ``path`` is untouched.
    ``mode`` is ``"w"`` (text, ``encoding`` defaults to UTF-8) or ``"wb"``.
    """
    import tempfile  # here: a command that writes nothing never pays for importing it (and shutil, random)

    path = Path(path)
    directory = path.parent
    fd, tmp = tempfile.mkstemp(prefix=prefix if prefix is not None else f".{path.name}.", suffix=".tmp",
                               dir=directory)
    try:
        os.fchmod(fd, file_mode(path))
        if "b" in mode:
            fh = os.fdopen(fd, mode)
        else:
            fh = os.fdopen(fd, mode, encoding=encoding or "utf-8")
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_atomic(path: Path, data: bytes | str, *, prefix: str | None = None) -> None:
    """Write ``data`` (bytes or UTF-8 text) to ``path`` atomically."""
    with atomic_open(path, "wb" if isinstance(data, bytes) else "w", prefix=prefix) as fh:
        fh.write(data)


def require_directory(path: Path) -> None:
    """UsageError unless ``path``'s directory exists (akdctl creates no directory for a file it is told to write)."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise UsageError(f"cannot write {path}: directory {directory} does not exist (akdctl creates no directories)")


def write_user_file(path: Path, data: bytes | str) -> None:
    """:func:`write_atomic` for a file the user named: into an existing directory only; an OS failure
    is a one-line :class:`UsageError`."""
    path = Path(path)
    require_directory(path)
    try:
        write_atomic(path, data)
    except OSError as exc:
        raise UsageError(f"cannot write {path}: {exc.strerror or exc}") from None


def confined(directory: Path, relative: str | os.PathLike[str], what: str = "file") -> Path:
    """``directory / relative`` only if it stays inside ``directory`` after resolving symbolic links.

    Refused (UsageError): an absolute path, ``..``, a directory on the way that is a link leading
    elsewhere, and a final name that is itself a symbolic link. The result is built from the resolved
    directory, so the write lands where the check looked.
    """
    rel = Path(relative)
    if rel.is_absolute() or ".." in rel.parts or not rel.parts:
        raise UsageError(f"{what} {str(relative)!r}: must be a relative path below {directory}, without '..'")
    root = Path(directory).resolve()
    parent = (root / rel).parent.resolve()
    if parent != root and root not in parent.parents:
        raise UsageError(f"{what} {str(relative)!r}: leads outside {directory} through a symbolic link "
                         f"(to {parent}); refused")
    final = parent / rel.name
    if final.is_symlink():
        raise UsageError(f"{what} {str(relative)!r}: is a symbolic link; refused (write to a plain file name)")
    return final
