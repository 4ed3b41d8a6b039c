"""What a network face of ``akdctl sim serve`` is: its options as data, its life cycle.

Why: ``sim serve`` accepts the union of its faces' options, and ``cli/sim.py``
turns these declarations into click options in one place, so the simulator
does not depend on the CLI toolkit and a face's options are written once, next
to the code that reads them. Every face prints one ready line,
``listening: <describe()>``, naming the address and port it actually bound (a
test can bind port 0 and read the port from it).
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class FaceOption:
    """One ``sim serve`` option a face reads (``from_options`` gets it as keyword ``dest``)."""

    flag: str  # "--ethercat-udp"
    dest: str  # keyword name in from_options(**kwargs)
    help: str
    metavar: str | None = None
    default: Any = None
    type: type | None = None  # int, float or str (None: str)
    range: tuple[int, int] | None = None  # inclusive bounds of an int
    flag_value: str | None = None  # the value of the bare flag ("--profinet" alone): an optional value
    is_flag: bool = False  # a switch without value
    show_default: bool = False


class Face:
    """Base of a network face: started and stopped by ``sim serve``, described by its ready line.

    The life cycle is written once here (it was copied into every face): :meth:`start` runs the face's
    :meth:`open` (bind sockets, open the bus; it starts its loops with :meth:`spawn`), and stops again if that
    fails; :meth:`stop` sets ``_stop`` (every loop runs ``while not self._stop.is_set()``), runs :meth:`interrupt`
    (wake loops that block), joins every thread, then :meth:`close` (release what ``open`` took). A thread that
    dies of an exception leaves it in :attr:`error` and says so on stderr instead of vanishing. ``ready`` is true
    from a successful start to the stop. ``stop`` is safe twice and after a failed start.
    """

    #: Seconds ``stop`` waits for each thread (every loop wakes at least every 0.2 s).
    JOIN_TIMEOUT = 5.0

    def __init__(self) -> None:
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._ready = threading.Event()
        #: The first exception that ended one of the face's threads, or None.
        self.error: BaseException | None = None

    # -- the life cycle (not overridden) -----------------------------------------------------------------------
    def start(self) -> None:
        self._stop.clear()
        self.error = None
        try:
            self.open()
        except BaseException:
            self.stop()
            raise
        self._ready.set()

    def stop(self) -> None:
        self._ready.clear()
        self._stop.set()
        try:
            self.interrupt()
        finally:
            self.join(self.JOIN_TIMEOUT)
            self._threads = [t for t in self._threads if t.is_alive()]
            self.close()

    def spawn(self, target: Callable[..., object], name: str, *args: object) -> threading.Thread:
        """Run ``target(*args)`` on a daemon thread of this face, joined by :meth:`stop`."""
        thread = threading.Thread(target=self._guarded, args=(target, name, args), name=name, daemon=True)
        self._threads = [t for t in self._threads if t.is_alive()] + [thread]
        thread.start()
        return thread

    def join(self, timeout: float | None = None) -> None:
        """Wait for the face's threads to end (each up to ``timeout`` seconds)."""
        for thread in list(self._threads):
            if thread is not threading.current_thread():
                thread.join(timeout)

    @property
    def ready(self) -> bool:
        """Whether the face is serving: started, not stopped."""
        return self._ready.is_set()

    def _guarded(self, target: Callable[..., object], name: str, args: tuple[object, ...]) -> None:
        try:
            target(*args)
        except BaseException as exc:  # noqa: BLE001 - a face thread must not die unseen
            if self.error is None:
                self.error = exc
            if not self._stop.is_set():
                sys.stderr.write(f"akdctl: warning: {name} stopped: {type(exc).__name__}: {exc}\n")
                sys.stderr.flush()

    # -- what a face implements ----------------------------------------------------------------------------------
    def open(self) -> None:
        """Take the face's resources (sockets, bus) and :meth:`spawn` its loops."""
        raise NotImplementedError

    def interrupt(self) -> None:
        """Wake loops that block without a timeout (close a listening socket, write a wake pipe)."""

    def close(self) -> None:
        """Release what :meth:`open` took; the threads have ended (or were given up on)."""

    def describe(self) -> str:
        """What the ready line says after ``listening: `` (the bound address and port, interface or tty)."""
        raise NotImplementedError

    def warnings(self) -> list[str]:
        """Things the user must know once the face runs (printed on stderr by ``sim serve``)."""
        return []


_reported: dict[str, str] = {}
_report_lock = threading.Lock()


def request_failed(where: str, exc: BaseException) -> None:
    """A request made the drive raise (state file locked or unwritable, a model error): the face answers it with
    its protocol's error and keeps serving. Say why on stderr, once per face and distinct message, so the cause is
    visible without a flood when every request fails the same way."""
    from akdctl.errors import AkdError

    text = str(exc) if isinstance(exc, AkdError) else f"{type(exc).__name__}: {exc}"  # ours say it in words
    with _report_lock:
        if _reported.get(where) == text:
            return
        _reported[where] = text
    sys.stderr.write(f"akdctl: warning: {where}: a request failed, answered with an error: {text}\n")
    sys.stderr.flush()
