"""The AKD's motion task table: read, write and describe stored tasks (``akdctl task list|show|set``).

Why: program mode (PROFINET manual 5.10.1) starts a task "configured by MT parameters"; a user needs to see
and set those tasks before ``task start`` runs one. The PROFINET manuals document no parameter for the table
(their PNUs are the signals and the PROFIdrive parameters), so the table is reached the way the AKD maps it onto
CoE objects (``profiles/motion_tasks``): MT.NUM selects a task, MT.LOAD copies it into the working parameters
MT.P/MT.V/MT.ACC/MT.DEC/MT.CNTL, MT.SET stores them back (docs/fidelity.md F11). Reading a task therefore writes
MT.NUM and MT.LOAD, which replace the working set points: a read saves them first and writes them back, is refused
while the axis moves, and never asks for motion consent (a read is never a motion). ``task set`` is a writing
operation (:func:`plan_set` / :func:`execute_set`) whose values pass the planner's rules for the move the task
will be (:func:`check_values`), the same rules ``task start`` applies again; ``task start`` is a motion and goes
through the one planner (drive/motion_plan.py, kind ``task``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from akdctl.errors import UsageError
from akdctl.profiles import motion_tasks as mt
from akdctl.profiles import units
from akdctl.profiles.units import CIA_COUNTS_PER_REV

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


def objects_of(conn: Any) -> Any:
    """The object channel the table lives behind; UsageError saying why on a parameter-only link."""
    if not conn.has_objects:
        raise UsageError(f"{conn.target.display}: {NO_TABLE}")
    return conn.objects()


#: The working parameters MT.LOAD overwrites, saved before a read and written back after it.
_WORKING = (mt.MT_P, mt.MT_V, mt.MT_ACC, mt.MT_DEC, mt.MT_CNTL)
#: What a read of the table says about its scratch writes (``task list|show``, the ``task start`` plan).
RESTORED_NOTE = ("the table is read through MT.LOAD, which overwrites the working parameters MT.P/MT.V/MT.ACC/"
                 "MT.DEC/MT.CNTL and MT.NUM; akdctl saved them first and wrote them back")


def refuse_if_moving(conn: Any) -> None:
    """Reading the table loads a task into the working set points: never while the axis moves (a read is never a
    motion). A standstill axis, enabled or not, is read and its working parameters restored."""
    from akdctl.errors import SafetyRefusal

    status = conn.axis().read_status()
    if not status.standstill:
        raise SafetyRefusal("refusing: reading a motion task loads it (MT.LOAD) into the working set points, and "
                            "the axis is moving; read the table at standstill")


def read_tasks(objects: Any, numbers: list[int]) -> list[Task]:
    """Tasks by MT.NUM = n, MT.LOAD, then the working parameters; the working parameters and MT.NUM as they were
    before are written back afterwards, also when a read fails (:data:`RESTORED_NOTE`)."""
    from akdctl.drive.values import read_object, write_object

    for number in numbers:
        check_number(number)
    saved = [(index, read_object(objects, index, 0)) for index in (*_WORKING, mt.MT_NUM)]
    try:
        return [_load(objects, number) for number in numbers]
    finally:
        for index, value in saved:
            write_object(objects, index, 0, value)


def read_task(objects: Any, number: int) -> Task:
    """One task (:func:`read_tasks`)."""
    return read_tasks(objects, [number])[0]


def _load(objects: Any, number: int) -> Task:
    from akdctl.drive.values import read_object, write_object

    write_object(objects, mt.MT_NUM, 0, number)
    write_object(objects, mt.MT_LOAD, 0, number)
    raw = {"position": read_object(objects, mt.MT_P, 0), "velocity": read_object(objects, mt.MT_V, 0),
           "acc": read_object(objects, mt.MT_ACC, 0), "dec": read_object(objects, mt.MT_DEC, 0),
           "cntl": read_object(objects, mt.MT_CNTL, 0)}
    return Task(number, raw["position"] / CIA_COUNTS_PER_REV, units.cia_rpm(raw["velocity"]),
                units.cia_rpm(raw["acc"]), units.cia_rpm(raw["dec"]), bool(raw["cntl"] & mt.CNTL_RELATIVE), raw)


# ====================================================================== task set: plan -> consent -> execute
@dataclass(frozen=True)
class TaskRequest:
    """``task set N --position P --velocity V --accel A [--decel D] [--relative]`` (rev, rpm, rpm/s)."""

    number: int
    position_rev: float
    velocity_rpm: float
    acc_rpm_s: float
    dec_rpm_s: float | None = None
    relative: bool = False


def check_values(conn: Any, number: int, position_rev: float, velocity_rpm: float, acc_rpm_s: float,
                 dec_rpm_s: float, relative: bool, start_rev: float | None = None) -> None:
    """The planner's rules for a stored task, at ``task set`` and again at ``task start`` (the task runs like a
    ``move`` with these values): finite and > 0, the velocity within the axis profile's set-point range (the
    range a ``move`` has, in the planner's words), the config profile's max_velocity / max_acceleration, and
    the travel window for an absolute target or, once the start position is known, a relative one.

    The accelerations are not held to the MDI grid a ``move`` uses: a task runs from the table's own MT.ACC /
    MT.DEC, not from MDI_ACC/MDI_DEC."""
    from akdctl.drive import motion_plan
    from akdctl.drive.axis.choice import axis_class
    from akdctl.errors import SafetyRefusal

    executed_by = f"motion task {number}"
    try:
        motion_plan.finite(position_rev, "position")
        for value, what in ((velocity_rpm, "velocity"), (acc_rpm_s, "acceleration"), (dec_rpm_s, "deceleration")):
            if not motion_plan.finite(value, what) > 0:
                raise UsageError(f"{what} must be greater than 0, got {value:g}")
        scales = axis_class(conn).motion_scales("position")
        motion_plan.quantise(scales.velocity, velocity_rpm, "velocity", explicit=False)
        if not relative:
            end: float | None = position_rev
        else:  # a relative task's end is known once the start position is (task start)
            end = None if start_rev is None else start_rev + position_rev
        motion_plan.check_executed_limits(conn, rpm=velocity_rpm, acc_rpm_s=max(acc_rpm_s, dec_rpm_s), end_rev=end,
                                          executed_by=executed_by)
    except (UsageError, SafetyRefusal) as exc:
        exc.message = exc.message.replace("refusing: ", f"refusing: {executed_by}: ", 1) \
            if exc.message.startswith("refusing: ") else f"{executed_by}: {exc.message}"
        raise


def plan_set(conn: Any, request: TaskRequest) -> Any:
    """What ``task set`` writes, checked like the move the task will be (:func:`check_values`); reads only."""
    from akdctl.drive import gate
    from akdctl.drive.operation import PlannedWrite, WritePlan

    r = request
    check_number(r.number)
    dec = r.acc_rpm_s if r.dec_rpm_s is None else r.dec_rpm_s
    check_values(conn, r.number, r.position_rev, r.velocity_rpm, r.acc_rpm_s, dec, r.relative)
    counts = units.rev_to_counts(r.position_rev)
    if not -(1 << 31) <= counts < 1 << 31:
        raise UsageError(f"task {r.number}: position {r.position_rev:g} rev is outside MT.P's 32-bit counts")
    values = [(mt.MT_NUM, "MT.NUM", r.number, str(r.number)),
              (mt.MT_P, "MT.P", counts, f"{r.position_rev:g} rev"),
              (mt.MT_V, "MT.V", units.cia_per_s(r.velocity_rpm), f"{r.velocity_rpm:g} rpm"),
              (mt.MT_ACC, "MT.ACC", units.cia_per_s(r.acc_rpm_s), f"{r.acc_rpm_s:g} rpm/s"),
              (mt.MT_DEC, "MT.DEC", units.cia_per_s(dec), f"{dec:g} rpm/s"),
              (mt.MT_CNTL, "MT.CNTL", mt.CNTL_RELATIVE if r.relative else 0,
               "relative" if r.relative else "absolute"),
              (mt.MT_SET, "MT.SET", r.number, f"store as task {r.number}")]
    writes = [PlannedWrite(f"0x{index:04X}:0 ({name})", raw, shown, gate.classify_object(index, 0, name))
              for index, name, raw, shown in values]
    objects_of(conn)  # a parameter-only link cannot reach the table: say why before any question
    enabled = gate.drive_enabled(conn) if any(w.gated is not None and w.gated.when_enabled for w in writes) else None
    return WritePlan("task set", conn.target.display, writes, enabled=enabled, verify=True,
                     notes=["nothing moves: the values are stored as the task (MT.SET); 'task start' runs it",
                            RESTORED_NOTE.replace("the table is read", "the stored task is read back")],
                     data={"number": r.number, "objects": [(index, name) for index, name, _, _ in values]})


def execute_set(conn: Any, accepted: Any) -> Task:
    """Write the plan, then read the stored task back (MT.LOAD, working parameters restored) and compare."""
    from akdctl.drive.operation import check_readback
    from akdctl.drive.values import write_object

    objects = objects_of(conn)
    for write, (index, _) in zip(accepted.writes, accepted.data["objects"]):
        write_object(objects, index, 0, write.raw)
    stored = read_task(objects, accepted.data["number"])
    wrote = {name: w.raw for w, (_, name) in zip(accepted.writes, accepted.data["objects"])}
    check_readback([("MT.P", wrote["MT.P"], stored.raw["position"]), ("MT.V", wrote["MT.V"], stored.raw["velocity"]),
                    ("MT.ACC", wrote["MT.ACC"], stored.raw["acc"]), ("MT.DEC", wrote["MT.DEC"], stored.raw["dec"]),
                    ("MT.CNTL", wrote["MT.CNTL"], stored.raw["cntl"] & mt.CNTL_RELATIVE)])
    return stored
