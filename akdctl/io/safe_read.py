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


def read_regular(path: str | os.PathLike[str], *, limit: int, what: str, name: str | None = None) -> bytes:
    """The bytes of ``path`` if it is a regular file of at most ``limit`` bytes; UsageError otherwise.

    ``what`` names the expected content in the errors ("a support bundle"); ``name`` is how the
    file is shown (default: the path as given).
    """
    shown = name if name is not None else str(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise UsageError(f"{shown}: no such file") from None
    except IsADirectoryError:
        raise UsageError(f"{shown}: is a directory, not {what}") from None
    except OSError as exc:
        raise UsageError(f"{shown}: cannot read: {exc.strerror or exc}") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise UsageError(f"{shown}: is a directory, not {what}")
        if not stat.S_ISREG(info.st_mode):
            kind = next((k for test, k in _KINDS if test(info.st_mode)), "not a regular file")
            raise UsageError(f"{shown}: is {kind}, not {what}; only regular files are read")
        if info.st_size > limit:
            raise UsageError(f"{shown}: {info.st_size} bytes, larger than the {limit} bytes {what} may have")
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
            raise UsageError(f"{shown}: grew beyond the {limit} bytes {what} may have while it was read")
        return b"".join(chunks)
    except OSError as exc:
        raise UsageError(f"{shown}: cannot read: {exc.strerror or exc}") from None
    finally:
        os.close(fd)


def read_regular_text(path: str | os.PathLike[str], *, limit: int, what: str, name: str | None = None) -> str:
    """:func:`read_regular` decoded as UTF-8; a binary file is a one-line UsageError."""
    shown = name if name is not None else str(path)
    try:
        return read_regular(path, limit=limit, what=what, name=name).decode("utf-8")
    except UnicodeDecodeError:
        raise UsageError(f"{shown}: not a text file (UTF-8 expected), not {what}") from None

