"""The AKD's motion task table: read, write and describe stored tasks (``akdctl task list|show|set``).

Why: program mode (PROFINET manual 5.10.1) starts a task "configured by MT parameters"; a user needs to see
and set those tasks before ``task start`` runs one. The PROFINET manuals document no parameter for the table
(their PNUs are the signals and the PROFIdrive parameters), so the table is reached the way the AKD maps it onto
CoE objects (``profiles/motion_tasks``): MT.NUM selects a task, MT.LOAD copies it into the working parameters
MT.P/MT.V/MT.ACC/MT.DEC/MT.CNTL, MT.SET stores them back (docs/fidelity.md F11). Reading a task therefore writes
MT.NUM and MT.LOAD, which replaces the profile-position set points; the write gate (drive/gate.py) asks for
consent when the drive is enabled. ``task start`` is a motion and goes through the one planner
(drive/motion_plan.py, kind ``task``) instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from akdctl.errors import UsageError
from akdctl.profiles import motion_tasks as mt
from akdctl.profiles import units
from akdctl.profiles.units import CIA_COUNTS_PER_REV

if TYPE_CHECKING:
    from akdctl.connection import Connection
    from akdctl.channels.base import ObjectChannel

#: Why the table cannot be reached over a parameter channel alone (pn://): the manuals' PNU lists have no MT.*.
NO_TABLE = ("the AKD's PROFINET manuals document no parameter for the motion task table; it is reached through "
            "the CoE objects MT.NUM 0x365B / MT.LOAD 0x3432 / MT.SET 0x3431 (an EtherCAT or CANopen target, or sim)")


@dataclass(frozen=True)
class Task:
    """One stored motion task in the units a user thinks in (rev, rpm, rpm/s) and as the drive holds it (raw)."""

    number: int
    position_rev: float
    velocity_rpm: float
    acc_rpm_s: float
    dec_rpm_s: float
    relative: bool
    raw: dict[str, int]

    @property
    def configured(self) -> bool:
        """A task the drive can run: velocity and both ramps above 0 (an unset task loads zeros)."""
        return self.raw["velocity"] > 0 and self.raw["acc"] > 0 and self.raw["dec"] > 0

    def to_json(self) -> dict[str, Any]:
        return {"task": self.number, "configured": self.configured, "position_rev": round(self.position_rev, 6),
                "relative": self.relative, "velocity_rpm": round(self.velocity_rpm, 6),
                "acc_rpm_s": round(self.acc_rpm_s, 6), "dec_rpm_s": round(self.dec_rpm_s, 6), "raw": self.raw}


def check_number(number: int) -> int:
    if isinstance(number, bool) or not isinstance(number, int) or not 0 <= number <= mt.MAX_TASK:
        raise UsageError(f"motion task {number!r}: the AKD's tasks are 0..{mt.MAX_TASK}")
    return number


def objects_of(conn: "Connection") -> Any:
    """The object channel the table lives behind; UsageError saying why on a parameter-only link."""
    if not conn.has_objects:
        raise UsageError(f"{conn.target.display}: {NO_TABLE}")
    return conn.objects()


def gated_reads() -> list[Any]:
    """What reading tasks writes, for the write gate: MT.NUM and MT.LOAD (gated while the drive is enabled)."""
    from akdctl.drive import gate

    return [gate.classify_object(mt.MT_NUM, 0, "MT.NUM"), gate.classify_object(mt.MT_LOAD, 0, "MT.LOAD")]


def gated_writes() -> list[Any]:
    """What ``task set`` writes, for the write gate: the working parameters (set points) and MT.SET."""
    from akdctl.drive import gate

    names = {mt.MT_P: "MT.P", mt.MT_V: "MT.V", mt.MT_ACC: "MT.ACC", mt.MT_DEC: "MT.DEC", mt.MT_CNTL: "MT.CNTL",
             mt.MT_NUM: "MT.NUM", mt.MT_SET: "MT.SET"}
    return [gate.classify_object(index, 0, name) for index, name in names.items()]


def read_task(objects: "ObjectChannel", number: int) -> Task:
    """MT.NUM = n, MT.LOAD, then the working parameters."""
    from akdctl.drive.values import read_object, write_object

    check_number(number)
    write_object(objects, mt.MT_NUM, 0, number)
    write_object(objects, mt.MT_LOAD, 0, number)
    raw = {"position": read_object(objects, mt.MT_P, 0), "velocity": read_object(objects, mt.MT_V, 0),
           "acc": read_object(objects, mt.MT_ACC, 0), "dec": read_object(objects, mt.MT_DEC, 0),
           "cntl": read_object(objects, mt.MT_CNTL, 0)}
    return Task(number, raw["position"] / CIA_COUNTS_PER_REV, units.cia_rpm(raw["velocity"]),
                units.cia_rpm(raw["acc"]), units.cia_rpm(raw["dec"]), bool(raw["cntl"] & mt.CNTL_RELATIVE), raw)


def write_task(objects: "ObjectChannel", number: int, position_rev: float, velocity_rpm: float, acc_rpm_s: float,
               dec_rpm_s: float, relative: bool) -> Task:
    """Working parameters, then MT.NUM = n and MT.SET; returns the task as read back."""
    from akdctl.drive.values import write_object

    check_number(number)
    for what, value in (("velocity", velocity_rpm), ("acceleration", acc_rpm_s), ("deceleration", dec_rpm_s)):
        if not value > 0:
            raise UsageError(f"task {number}: {what} must be greater than 0, got {value:g}")
    counts = units.rev_to_counts(position_rev)
    if not -(1 << 31) <= counts < 1 << 31:
        raise UsageError(f"task {number}: position {position_rev:g} rev is outside MT.P's 32-bit counts")
    write_object(objects, mt.MT_NUM, 0, number)
    write_object(objects, mt.MT_P, 0, counts)
    write_object(objects, mt.MT_V, 0, units.cia_per_s(velocity_rpm))
    write_object(objects, mt.MT_ACC, 0, units.cia_per_s(acc_rpm_s))
    write_object(objects, mt.MT_DEC, 0, units.cia_per_s(dec_rpm_s))
    write_object(objects, mt.MT_CNTL, 0, mt.CNTL_RELATIVE if relative else 0)
    write_object(objects, mt.MT_SET, 0, number)
    return read_task(objects, number)
