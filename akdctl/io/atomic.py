"""Crash-safe file writes: a temporary file in the same directory, fsync, then ``os.replace``.

Why here: the simulated drive's state file, parameter snapshots and support
bundles must never be left half-written (a reader sees the old file or the new
one, never a mix); one implementation keeps the fsync and the clean-up on
failure in one place.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from akdctl.errors import UsageError


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


def write_user_file(path: Path, data: bytes | str) -> None:
    """:func:`write_atomic` for a file the user named: an OS failure is a one-line :class:`UsageError`."""
    try:
        write_atomic(path, data)
    except OSError as exc:
        raise UsageError(f"cannot write {path}: {exc.strerror or exc}") from None
