"""The simulated AKD's motion task table, visible and settable the way the AKD maps it onto CoE objects.

Why a module of its own: program mode (PROFINET manual 5.10.1: "The motion tasks, which are configured by MT
parameters in AKD, can be accessed") starts a stored task; the table used to be a fixed, invisible dict. The
AKD's ESI maps the table's commands onto CoE objects, and the simulator follows them (docs/fidelity.md F11):

* MT.NUM — the task number MT.SET and MT.LOAD act on;
* MT.LOAD (write-only) — copy task MT.NUM into the working parameters;
* MT.SET (write-only) — store the working parameters as task MT.NUM;
* the working parameters MT.P, MT.V, MT.ACC, MT.DEC, MT.CNTL.

The object numbers (and what is inferred about them) are ``profiles/motion_tasks``, shared with ``akdctl task``.

The table keeps positions in revolutions and speeds in rpm / rpm/s (the kinematics' units); the objects are CiA
402 counts (65536 per revolution), converted by ``profiles/units``. Any value written to MT.SET / MT.LOAD runs
the command [I].
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING, Any

from akdctl.profiles import units
from akdctl.profiles.motion_tasks import (
    CNTL_RELATIVE,
    MAX_TASK,
    MT_ACC,
    MT_CNTL,
    MT_DEC,
    MT_LOAD,
    MT_NUM,
    MT_P,
    MT_SET,
    MT_V,
)
from akdctl.profiles.units import CIA_COUNTS_PER_REV
from akdctl.sim.component import ABORT_VALUE_RANGE, FieldState
from akdctl.sim.errors import SdoAccessError

if TYPE_CHECKING:
    from akdctl.sim.motion import MotionComponent

#: The table a new simulated drive starts with (program mode, SATZANW 1..4): AKD MT.* parameters.
DEFAULT_TASKS = {
    "1": {"position": 1.0, "rpm": 600.0, "acc": 10000.0, "dec": 10000.0, "absolute": False},
    "2": {"position": -1.0, "rpm": 600.0, "acc": 10000.0, "dec": 10000.0, "absolute": False},
    "3": {"position": 0.0, "rpm": 600.0, "acc": 10000.0, "dec": 10000.0, "absolute": True},
    "4": {"position": 5.0, "rpm": 1200.0, "acc": 10000.0, "dec": 10000.0, "absolute": True},
}


class TaskTable(FieldState):
    """Tasks by number (as strings: the state is JSON) and MT.NUM."""

    FIELDS = ("tasks", "mt_num")

    def __init__(self, drive: "MotionComponent") -> None:
        super().__init__(drive)
        self.drive = drive
        self.tasks: dict[str, dict[str, Any]] = {k: dict(v) for k, v in DEFAULT_TASKS.items()}
        self.mt_num = 0

    def get(self, number: int) -> dict[str, Any] | None:
        """A configured task (velocity and ramps above 0), or None."""
        entry = self.tasks.get(str(number))
        if entry is None or entry["rpm"] <= 0 or entry["acc"] <= 0 or entry["dec"] <= 0:
            return None
        return entry

    def bind(self) -> None:
        m = self.drive.model
        m.bind_object(MT_NUM, read=self._read_num, write=self._write_num)
        m.bind_object(MT_LOAD, write=self._load)
        m.bind_object(MT_SET, write=self._set)

    # ------------------------------------------------------------------ objects
    def _read_num(self, sub: int) -> bytes:
        self.drive.model.object_entry(MT_NUM, sub)
        return struct.pack("<I", self.mt_num)

    def _write_num(self, sub: int, data: bytes) -> None:
        value = struct.unpack("<I", data)[0]
        if value > MAX_TASK:
            raise SdoAccessError(ABORT_VALUE_RANGE, f"MT.NUM {value}: motion tasks are 0..{MAX_TASK}")
        self.mt_num = value

    def _load(self, sub: int, data: bytes) -> None:
        """MT.LOAD: task MT.NUM into the working parameters (an unset task loads zeros)."""
        entry = self.tasks.get(str(self.mt_num)) or {"position": 0.0, "rpm": 0.0, "acc": 0.0, "dec": 0.0,
                                                      "absolute": True}
        m = self.drive.model
        m.set_stored_object(MT_P, 0, struct.pack("<i", round(entry["position"] * CIA_COUNTS_PER_REV)))
        m.set_stored_object(MT_V, 0, struct.pack("<I", units.cia_per_s(entry["rpm"])))
        m.set_stored_object(MT_ACC, 0, struct.pack("<I", units.cia_per_s(entry["acc"])))
        m.set_stored_object(MT_DEC, 0, struct.pack("<I", units.cia_per_s(entry["dec"])))
        m.set_stored_object(MT_CNTL, 0, struct.pack("<I", 0 if entry["absolute"] else CNTL_RELATIVE))

    def _set(self, sub: int, data: bytes) -> None:
        """MT.SET: the working parameters become task MT.NUM."""
        m = self.drive.model
        self.changed()
        self.tasks[str(self.mt_num)] = {
            "position": m.object_value(MT_P, 0) / CIA_COUNTS_PER_REV,
            "rpm": units.cia_rpm(m.object_value(MT_V, 0)),
            "acc": units.cia_rpm(m.object_value(MT_ACC, 0)),
            "dec": units.cia_rpm(m.object_value(MT_DEC, 0)),
            "absolute": not m.object_value(MT_CNTL, 0) & CNTL_RELATIVE,
        }
