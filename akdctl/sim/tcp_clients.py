"""The clients of a simulated drive's TCP face: a cap, a refusal in the protocol's words, and EMFILE survived.

Why: the EtherNet/IP face held one thread per client without a limit (989 threads under a flood), and when the
process ran out of file descriptors ``accept()`` raised EMFILE, the accept thread ended without a word, and the
face went on saying "serving" while every later connect timed out (issue 23.10). Every TCP face (EtherNet/IP
now; the ASCII and Modbus faces to come) accepts through :class:`TcpClients`:

* **a cap**: at most ``limit`` clients are served at once (:data:`DEFAULT_LIMIT`, 32: the AKD's own number of
  TCP connections is not in the public sources we have, [I]); one more is accepted only to be refused in the
  protocol's words (the face's ``refuse`` callable answers its first request: EtherNet/IP's encapsulation status
  0x0002 "insufficient memory"), then closed. Refused connections waiting for their first request are bounded
  too (:data:`MAX_REFUSING`); beyond that they are closed at once;
* **EMFILE/ENFILE/ENOBUFS/ENOMEM** from ``accept()``: the loop backs off (50 ms doubling to 1 s) instead of
  ending or spinning, and says so once per episode on stderr; the pending connection stays in the listen
  backlog until a descriptor is free;
* repeated refusals are reported once per cause with counts (``sim/refusals.py``).
"""

from __future__ import annotations

import errno
import select
import socket
import sys
import threading
import time
from collections.abc import Callable

from akdctl.sim.refusals import RefusalReport

#: Clients a TCP face serves at once.
DEFAULT_LIMIT = 32
#: Refused connections kept open at once while they wait to hear the refusal.
MAX_REFUSING = 64
#: How long a refused connection may take to send its first request before it is just closed (seconds).
REFUSE_WAIT_S = 1.0
#: accept() errors that mean "no resources right now": back off, never end the loop.
RESOURCE_ERRORS = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM})
BACKOFF_S = (0.05, 1.0)


class TcpClients:
    """Accepting and counting one face's TCP clients (see the module doc).

    ``refuse(sock)`` is called when a refused connection has sent data: it reads the first request and answers
    it with the protocol's "no resources" reply (it must not block longer than the socket's short timeout).
    """

    def __init__(self, face: str, refuse: Callable[[socket.socket], None], limit: int | None = None,
                 write: Callable[[str], None] | None = None) -> None:
        self.face = face
        self.limit = DEFAULT_LIMIT if limit is None else limit
        self.refuse = refuse
        self.active = 0
        self.refused = 0
        self._lock = threading.Lock()
        self._refusing: dict[socket.socket, float] = {}
        self._backoff = 0.0
        self._write = write or _stderr
        self.report = RefusalReport(face, write=self._write, what="connection(s)")

    def accept(self, listener: socket.socket, wait: float = 0.2) -> tuple[socket.socket, tuple[str, int]] | None:
        """Wait up to ``wait`` s for a client; return it when it may be served (count it: :meth:`release` when it
        ends), else None (nothing came, a refused client was handled, or descriptors ran out and we backed off).
        OSError other than running out of resources (the listener was closed) is raised."""
        self._expire_refusing()
        ready, _, _ = select.select([listener, *self._refusing], [], [], wait)
        for sock in ready:
            if sock is not listener:
                self._answer_refused(sock)
        if listener not in ready:
            return None
        try:
            client, peer = listener.accept()
        except OSError as exc:
            if exc.errno not in RESOURCE_ERRORS:
                raise
            self._back_off(exc)
            return None
        if self._backoff:
            self._write(f"akdctl: warning: {self.face}: accepting clients again")
            self._backoff = 0.0
        with self._lock:
            if self.active < self.limit:
                self.active += 1
                return client, peer
            self.refused += 1
        self.report.refused("too many clients", f"connection from {peer[0]}:{peer[1]} refused: {self.limit} "
                                                 f"clients already served (the face's cap)")
        if len(self._refusing) >= MAX_REFUSING:
            _close(client)
        else:
            client.settimeout(0.05)
            self._refusing[client] = time.monotonic() + REFUSE_WAIT_S
        return None

    def release(self) -> None:
        """One served client ended."""
        with self._lock:
            self.active = max(0, self.active - 1)

    def close(self) -> None:
        """Close the refused connections still waiting and print the counts not reported yet."""
        for sock in list(self._refusing):
            _close(sock)
        self._refusing.clear()
        self.report.flush()

    def _answer_refused(self, sock: socket.socket) -> None:
        self._refusing.pop(sock, None)
        try:
            self.refuse(sock)
        except Exception:
            pass
        finally:
            _close(sock)

    def _expire_refusing(self) -> None:
        now = time.monotonic()
        for sock, until in list(self._refusing.items()):
            if until <= now:
                self._refusing.pop(sock, None)
                _close(sock)

    def _back_off(self, exc: OSError) -> None:
        if not self._backoff:
            self._write(f"akdctl: warning: {self.face}: cannot accept a client ({exc.strerror}); backing off "
                        "until a file descriptor is free (raise the open-file limit, ulimit -n, to serve more)")
            self._backoff = BACKOFF_S[0]
        else:
            self._backoff = min(BACKOFF_S[1], self._backoff * 2)
        time.sleep(self._backoff)


def _close(sock: socket.socket) -> None:
    try:
        sock.close()
    except OSError:
        pass


def _stderr(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
