"""Who reads a python-can bus: canopen's receive thread, or the caller waiting for a reply.

Why: python-can's :class:`can.Notifier` reads every frame in its own thread and hands the answer a caller waits
for over to that caller's thread, so an SDO request and its answer cost three thread wake-ups (the receive thread
for the request's own echo on buses that loop frames back, again for the answer, then the caller). A caller that
reads the bus itself while it waits sleeps and wakes once. :class:`BusReader` is a ``can.Notifier`` whose reading
role moves between its thread and callers of :meth:`BusReader.wait`:

* whoever holds the **turn** (a lock) reads, and every frame it reads goes to the notifier's listeners exactly as
  the thread would hand it on (canopen's network, the tracer, akdctl's SDO reply queue), under the notifier's lock
  and before the turn is given up; a caller's answer reaches it through its listener like any other frame, so
  there is one path from the bus to every consumer;
* a caller that finds the thread reading asks it to stand aside and waits for the turn: the thread's read ends with
  the next frame (the answer, handed on before the turn is free) or after its cycle, and the caller goes on from
  there;
* the thread, standing aside, looks every :data:`HANDBACK_S` whether a caller is still at work: once none has been
  in a call for that long it reads again, so frames that come between calls (heartbeats, emergencies) wait at most
  that long in the bus's queue and are never lost; :meth:`BusReader.hand_back` gives the bus back at once (for
  waits that rely on the thread: canopen's own transfers, a heartbeat wait).

The notifier's other rules stay python-can's: a read error or a listener's exception goes to the listeners'
``on_error`` and, unhandled, stops the reading (``Network.check`` raises it on the next send, a caller waiting in
:meth:`BusReader.wait` gets it at once). One difference: the thread then ends quietly, where python-can's re-raises
and Python prints a traceback on stderr under akdctl's one-line error.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import TYPE_CHECKING, TypeVar

import can

if TYPE_CHECKING:
    from collections.abc import Iterable

    from can.notifier import MessageRecipient

T = TypeVar("T")

#: Seconds the receive thread stands aside after a caller's last read before it reads again itself.
HANDBACK_S = 0.005


class BusReader(can.Notifier):
    """A ``can.Notifier`` for one bus whose reading a waiting caller may take over (see the module docstring)."""

    def __init__(self, bus: can.BusABC, listeners: "Iterable[MessageRecipient]", timeout: float = 1.0) -> None:
        self._turn = threading.Lock()  # held by whoever calls bus.recv and hands the frame on
        self._aside = threading.Condition()  # the thread waits here while callers read
        self._wanted = False  # a caller asked the thread to stand aside
        self._last = 0.0  # monotonic time a caller's wait ended
        self._dead = False  # an unhandled read error stopped the reading
        super().__init__(bus, listeners, timeout)

    # -- the receive thread --------------------------------------------------------------------------------------
    def _rx_thread(self, bus: can.BusABC) -> None:
        turn, aside = self._turn, self._aside
        while not self._stopped and not self._dead:
            if self._wanted:
                with aside:
                    if self._wanted:
                        aside.wait(HANDBACK_S)
                self._resume_if_idle()
                continue
            try:
                with turn:
                    if self._wanted:
                        continue  # a caller read while this thread waited for the turn
                    msg = bus.recv(self.timeout)
                    if msg is not None:
                        with self._lock:
                            self._on_message_received(msg)
            except Exception as exc:  # noqa: BLE001 - python-can's Notifier rule, see _failed
                if not self._failed(exc):
                    return  # recorded for Network.check; no traceback from a thread (python-can's would print one)

    def _resume_if_idle(self) -> None:
        """Read again once no caller has waited for :data:`HANDBACK_S` (none is waiting now: the turn is free)."""
        if not self._wanted or not self._turn.acquire(blocking=False):
            return
        try:
            if time.monotonic() - self._last >= HANDBACK_S:
                self._wanted = False
        finally:
            self._turn.release()

    def _failed(self, exc: Exception) -> bool:
        """python-can's rule for a failed read or listener: recorded for ``Network.check``, handed to the listeners'
        ``on_error``; True if one handled it (reading goes on)."""
        self.exception = exc
        if self._on_error(exc):
            return True
        self._dead = True
        return False

    # -- callers -------------------------------------------------------------------------------------------------
    def wait(self, replies: "queue.SimpleQueue[T]", timeout: float) -> T:
        """The next item of ``replies`` (filled by a listener), reading the bus in this thread while it waits;
        :class:`queue.Empty` after ``timeout`` seconds. A read error is raised (after python-can's handling, see
        :meth:`_failed`)."""
        if not replies.empty():
            return replies.get_nowait()
        self._wanted = True  # before taking the turn: the thread stands aside after its current read
        turn = self._turn
        deadline = time.monotonic() + timeout
        left = timeout
        if not turn.acquire(blocking=False):
            if not turn.acquire(timeout=timeout if timeout > 0.0 else 0.0):
                raise queue.Empty
            left = deadline - time.monotonic()  # waited for the thread's read, which may have brought the answer
        try:
            recv, lock, deliver = self._bus_list[0].recv, self._lock, self._on_message_received
            while True:
                if not replies.empty():
                    return replies.get_nowait()
                if self._dead and self.exception is not None:
                    raise self.exception  # the reading stopped on this error (the caller words it)
                if left <= 0.0:
                    raise queue.Empty
                try:
                    msg = recv(left)
                    if msg is not None:
                        with lock:
                            deliver(msg)
                except Exception as exc:
                    self._failed(exc)
                    raise
                if not replies.empty():
                    return replies.get_nowait()
                left = deadline - time.monotonic()
        finally:
            self._last = time.monotonic()
            turn.release()

    def hand_back(self) -> None:
        """Let the receive thread read again now (before a wait that relies on it)."""
        if self._wanted:
            self._wanted = False
            with self._aside:
                self._aside.notify_all()

    def stop(self, timeout: float = 5.0) -> None:
        self._stopped = True
        self.hand_back()
        super().stop(timeout)
