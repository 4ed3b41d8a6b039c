"""Refused requests on a face's stderr: one line per cause, then counts instead of copies.

Why its own module: the PROFINET face (refused Connects) and every TCP face (clients over the cap,
``sim/tcp_clients.py``) report refusals by the same rule (issue 23.16).
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any


class RefusalReport:
    """Refused requests on a face's stderr: one line per cause, then counts instead of copies.

    Why: a client that retries a refused Connect in a loop made the face write a long warning per datagram. The
    first refusal of a cause is printed in full; later ones of the same cause are counted and summarised in one
    line at most every ``interval`` seconds, and once more when the face stops, so nothing is hidden and the
    log stays readable.
    """

    def __init__(self, face: str, interval: float = 10.0, write: Any = None, what: str = "Connect(s)") -> None:
        self.face = face
        self.what = what  # what was refused, in the summary line
        self.interval = interval
        self._write = write or self._stderr
        self._lock = threading.Lock()
        self._printed: dict[str, float] = {}
        self._pending: dict[str, int] = {}

    @staticmethod
    def _stderr(line: str) -> None:
        sys.stderr.write(line + "\n")
        sys.stderr.flush()

    def refused(self, cause: str, text: str) -> bool:
        """Report one refusal; True when this one was printed in full (the first of its cause, or the first
        after ``interval`` seconds, carrying the count of those in between)."""
        now = time.monotonic()
        with self._lock:
            last = self._printed.get(cause)
            if last is not None and now - last < self.interval:
                self._pending[cause] = self._pending.get(cause, 0) + 1
                return False
            self._printed[cause] = now
            more = self._pending.pop(cause, 0)
        suffix = f" [{more} more refused for this cause since the last report]" if more else ""
        self._write(f"akdctl: warning: {self.face}: {text}{suffix}")
        return True

    def flush(self) -> None:
        """Print the counts not reported yet (when the face stops)."""
        with self._lock:
            pending, self._pending = self._pending, {}
        for cause, count in pending.items():
            self._write(f"akdctl: warning: {self.face}: {count} more {self.what} refused ({cause}) "
                        "since the last report")
