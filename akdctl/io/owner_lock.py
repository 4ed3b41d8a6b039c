"""An exclusive, self-describing owner lock: one holder at a time, and who it is.

Why ``flock`` on a file: the kernel drops the lock when its holder dies (kill -9,
a crash, a closed terminal), so a dead owner can never block anyone; and it binds
to the open file description, so two commands in one process exclude each other
as two processes do. The holder writes one JSON line (pid, command, since) into
the file, so a refused caller can name the owner instead of saying "busy".

The file stays in place after release (removing it would race with a new holder
that opened the old inode); it is tiny and rewritten by every holder. Nothing
here knows what is being owned: :func:`akdctl.cli.consent.own_axis` uses it for
the axis of one target.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import time
from pathlib import Path
from typing import Any

#: What of the owner's record is shown: one line, printable, bounded (the file may have been edited).
_MAX_RECORD = 4096


class OwnerBusy(Exception):
    """The lock is held by someone else; ``owner`` is their record (may be empty while they start)."""

    def __init__(self, path: Path, owner: dict[str, Any]) -> None:
        super().__init__(f"{path} is held by {owner or 'another process'}")
        self.path = path
        self.owner = owner


class OwnerLock:
    """``acquire(command)`` takes the lock or raises :class:`OwnerBusy`; ``release()`` (idempotent) frees it."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._fd: int | None = None
        self._also: list[OwnerLock] = []

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self, command: str) -> None:
        """Take the lock without waiting; write our record. OSError when the directory is unusable."""
        if self._fd is not None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)  # the umask applies (io/atomic.py)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise OwnerBusy(self.path, _owner_soon(self.path)) from None
            raise
        record = json.dumps({"pid": os.getpid(), "command": command[:300], "since": time.time()})
        os.ftruncate(fd, 0)
        os.pwrite(fd, record.encode() + b"\n", 0)
        self._fd = fd

    def also(self, other: "OwnerLock", command: str) -> None:
        """Take ``other`` too (raises :class:`OwnerBusy` as :meth:`acquire` does) and free it with this one.

        Why: one axis can have two names (its address and the serial it reports); the holder of either keeps
        out a second command that came by the other."""
        other.acquire(command)
        self._also.append(other)

    def release(self) -> None:
        also, self._also = self._also, []
        for other in also:
            other.release()
        fd, self._fd = self._fd, None
        if fd is not None:
            try:
                os.ftruncate(fd, 0)  # a reader racing the next holder sees "starting", never our stale record
            except OSError:
                pass
            os.close(fd)  # closing releases the flock

    def __enter__(self) -> "OwnerLock":
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __del__(self) -> None:  # a holder dropped without release (a test's half-built context)
        self.release()


def _owner_soon(path: Path, patience: float = 0.2) -> dict[str, Any]:
    """The holder's record, waiting a moment for a holder that has the lock but has not written it yet
    (or has emptied it while it lets go); {} if it stays empty."""
    deadline = time.monotonic() + patience
    while True:
        owner = read_owner(path)
        if owner or time.monotonic() >= deadline:
            return owner
        time.sleep(0.01)


def read_owner(path: Path) -> dict[str, Any]:
    """The holder's record: ``pid`` (int), ``command`` (printable text), ``since`` (epoch s); {} if unknown."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(_MAX_RECORD)
        data = json.loads(raw.decode("utf-8", "replace") or "{}")
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict):
        return {}
    owner: dict[str, Any] = {}
    if isinstance(data.get("pid"), int) and not isinstance(data.get("pid"), bool):
        owner["pid"] = data["pid"]
    if isinstance(data.get("command"), str):
        owner["command"] = "".join(c if c.isprintable() else "?" for c in data["command"])[:300]
    if isinstance(data.get("since"), (int, float)) and not isinstance(data.get("since"), bool):
        owner["since"] = float(data["since"])
    return owner
