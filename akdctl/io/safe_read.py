"""Reading a file a user hands us: a regular file only, bounded, never blocking.

Why one reader: bundles, backups and recipes arrive from other machines and
people. A FIFO blocks ``open()`` forever, ``/dev/zero`` never ends, a file may
grow while it is read, and ``stat().st_size`` checked before ``read_text()``
protects against none of these. So the file is opened without blocking
(``O_NONBLOCK``: a FIFO opens at once), ``fstat`` of that same descriptor
decides (regular file or a one-line refusal: no race between check and read),
and at most ``limit`` + 1 bytes are read. Every refusal is a one-line
:class:`~akdctl.errors.UsageError` (exit 2) naming the file.
"""

from __future__ import annotations

import os
import stat

from akdctl.errors import UsageError

_KINDS = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


class FileRefused(Exception):
    """Why :func:`read_bounded` did not return a file's bytes, for the caller to phrase: ``kind`` names what the
    path is when it is no regular file ("a FIFO"), ``size`` its size when it is larger than the limit, ``grew``
    when it grew beyond the limit while it was read."""

    def __init__(self, kind: str | None = None, size: int | None = None, grew: bool = False) -> None:
        super().__init__(kind or ("grew while read" if grew else f"{size} bytes"))
        self.kind, self.size, self.grew = kind, size, grew


def read_bounded(path: str | os.PathLike[str], limit: int) -> bytes:
    """The bytes of ``path`` if it is a regular file of at most ``limit`` bytes: opened without blocking,
    ``fstat`` of that descriptor decides, at most ``limit`` + 1 bytes read. :class:`FileRefused` otherwise;
    OSError (FileNotFoundError included) as the system raised it."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | getattr(os, "O_NOCTTY", 0))
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise FileRefused("a directory")
        if not stat.S_ISREG(info.st_mode):
            raise FileRefused(next((k for test, k in _KINDS if test(info.st_mode)), "not a regular file"))
        if info.st_size > limit:
            raise FileRefused(size=info.st_size)
        os.set_blocking(fd, True)
        chunks: list[bytes] = []
        left = limit + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        if left <= 0:
            raise FileRefused(grew=True)
        return b"".join(chunks)
    finally:
        os.close(fd)


def read_regular(path: str | os.PathLike[str], *, limit: int, what: str, name: str | None = None) -> bytes:
    """The bytes of ``path`` if it is a regular file of at most ``limit`` bytes; UsageError otherwise.

    ``what`` names the expected content in the errors ("a support bundle"); ``name`` is how the
    file is shown (default: the path as given).
    """
    shown = name if name is not None else str(path)
    try:
        return read_bounded(path, limit)
    except FileNotFoundError:
        raise UsageError(f"{shown}: no such file") from None
    except IsADirectoryError:
        raise UsageError(f"{shown}: is a directory, not {what}") from None
    except OSError as exc:
        raise UsageError(f"{shown}: cannot read: {exc.strerror or exc}") from None
    except FileRefused as refused:
        if refused.kind == "a directory":
            raise UsageError(f"{shown}: is a directory, not {what}") from None
        if refused.kind is not None:
            raise UsageError(f"{shown}: is {refused.kind}, not {what}; only regular files are read") from None
        if refused.grew:
            raise UsageError(f"{shown}: grew beyond the {limit} bytes {what} may have while it was read") from None
        raise UsageError(f"{shown}: {refused.size} bytes, larger than the {limit} bytes {what} may have") from None


def read_regular_text(path: str | os.PathLike[str], *, limit: int, what: str, name: str | None = None) -> str:
    """:func:`read_regular` decoded as UTF-8; a binary file is a one-line UsageError."""
    shown = name if name is not None else str(path)
    try:
        return read_regular(path, limit=limit, what=what, name=name).decode("utf-8")
    except UnicodeDecodeError:
        raise UsageError(f"{shown}: not a text file (UTF-8 expected), not {what}") from None

