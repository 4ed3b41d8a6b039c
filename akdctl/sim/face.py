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
    """Base of a network face: started and stopped by ``sim serve``, described by its ready line."""

    def start(self) -> None:
        raise NotImplementedError

    def stop(self) -> None:
        raise NotImplementedError

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
