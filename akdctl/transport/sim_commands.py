"""The simulated AKD's ASCII command channel, in process, for the REC.* recorder (``scope --source recorder``).

Why here: the scope's recorder client speaks to a CommandLink (``command(line) -> reply text``, an ``Error:``
reply raising a DriveError), the interface the ``akd://`` transport offers as ``conn.commands()``. A ``sim`` target
has no wire for the ASCII channel, so this adapter hands each line to the simulated recorder
(:func:`akdctl.sim.recorder.handle_rec`) as one transaction of the simulated drive: its virtual time advances
with the wall clock between commands, exactly as behind the network faces.
"""

from __future__ import annotations

from typing import Any

from akdctl.errors import DriveError


class SimCommandLink:
    """REC.* lines to the simulated recorder of ``drive`` (a :class:`akdctl.sim.drive.SimDrive`)."""

    def __init__(self, drive: Any) -> None:
        self.drive = drive

    def command(self, line: str) -> str:
        from akdctl.sim.recorder import RecorderError, handle_rec

        name, _, arg = line.strip().partition(" ")
        try:
            with self.drive.transaction() as model:
                return handle_rec(model, name, arg or None)
        except RecorderError as exc:
            raise DriveError(f"{line.strip()}: Error: {exc}") from None
