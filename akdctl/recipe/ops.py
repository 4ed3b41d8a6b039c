"""What each recipe action does on the drive — always through the one implementation of that operation.

Why a thin layer: the recipe must behave exactly like the commands a technician
types (``pnu set --verify``, ``pdo map``, ``telegram set``, ``enable``, ``home``,
``move``, ``fault dump``, ``params backup``), so every action calls the same
drive-layer function those commands call and never re-implements it. A writing
step runs its operation's ``plan(conn, request)`` and ``execute(conn, plan)``
(:mod:`akdctl.drive.raw_write`, :mod:`akdctl.drive.telegram`, :mod:`akdctl.drive.pdo`,
:mod:`akdctl.drive.snapshot`; the request was built while validating) and reports
the plan it ran, so ``tests/test_write_parity.py`` can hold it to the command's.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akdctl.errors import CheckFailed, DriveFault, UsageError
from akdctl.recipe.schema import PlannedStep

if TYPE_CHECKING:
    from akdctl.connection import Connection

#: How often a recipe's ``check ... within`` reads its target again (a parameter, not the axis's status word:
#: drive/polling.py paces the axis waits).
CHECK_INTERVAL_S = 0.1


class Session:
    """The drive side of one recipe run: the Connection to the target, the axis once a step needs it."""

    def __init__(self, conn: "Connection", output_dir: Path, interrupted: Callable[[], bool]) -> None:
        self.conn = conn
        self.output_dir = output_dir
        self.interrupted = interrupted
        self._axis: Any = None
        self.files: list[str] = []

    def axis(self) -> Any:
        if self._axis is None:
            self._axis = self.conn.axis()
        return self._axis

    def output_file(self, relative: str, what: str) -> Path:
        """Where a file the recipe names is written: below the output directory, also once symbolic links are
        resolved (io/atomic.py ``confined``). The output directory itself is created if missing (the one
        directory akdctl makes for a file); directories below it are not."""
        from akdctl.io.atomic import confined

        try:
            self.output_dir.mkdir(exist_ok=True)
        except OSError as exc:
            raise UsageError(f"cannot create the output directory {self.output_dir}: {exc.strerror or exc}") from None
        return confined(self.output_dir, relative, what)

    @property
    def axis_opened(self) -> bool:
        return self._axis is not None

    def sleep(self, seconds: float) -> None:
        """Sleep so Ctrl-C is seen promptly (the runner then stops the axis)."""
        from akdctl.drive.polling import pause_unless_stopped

        if pause_unless_stopped(seconds, self.interrupted):
            raise KeyboardInterrupt


# ---------------------------------------------------------------------------- reading and comparing
def read_target(session: Session, target: dict[str, Any]) -> Any:
    from akdctl.drive.values import pnu_refused, read_pnus, read_snapshot_value

    if target["kind"] == "pnu":
        (reading,) = read_pnus(session.conn.parameters(), [target["spec"]])
        if not reading.ok:
            raise pnu_refused(reading, "read")
        values = reading.values or []
        return values if target["spec"].count > 1 else (values[0] if values else None)
    return read_snapshot_value(session.conn.objects(), target["entry"])


def matches(value: Any, comparison: dict[str, Any]) -> bool:
    if "value" in comparison:
        want = comparison["value"]
        if "mask" in comparison:
            return isinstance(value, int) and (value & comparison["mask"]) == (want & comparison["mask"])
        if "tolerance" in comparison and isinstance(value, (int, float)) and isinstance(want, (int, float)):
            return abs(value - want) <= comparison["tolerance"]
        if isinstance(value, list) and not isinstance(want, list):
            return len(value) == 1 and value[0] == want
        if isinstance(value, float) or isinstance(want, float):
            return isinstance(value, (int, float)) and math.isclose(float(value), float(want), rel_tol=1e-6)
        return value == want
    if not isinstance(value, (int, float)):
        return False
    return comparison.get("min", -math.inf) <= value <= comparison.get("max", math.inf)


# ---------------------------------------------------------------------------- actions
def do_set(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    """The raw-write operation ``pnu set``/``sdo write`` run (drive/raw_write.py): plan, execute, read back."""
    from akdctl.drive import raw_write

    plan = raw_write.plan(session.conn, params["request"])
    written = raw_write.execute(session.conn, plan)
    return {"written": {t["label"]: t["value"] for t in params["targets"]}, "writes": written,
            "plan": plan.to_json()}


def do_expect(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    target, comparison = params["target"], params["comparison"]
    got = read_target(session, target)
    if not matches(got, comparison):
        from akdctl.recipe.schema import _describe_comparison

        raise CheckFailed(f"expected {_describe_comparison(target['label'], comparison)}, read {got}",
                          details={"read": got})
    return {"read": got}


def do_wait(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    if "seconds" in params:
        if not session.axis_opened:
            session.sleep(params["seconds"])
            return {"waited_s": params["seconds"]}
        # With the axis in use, keep watching it: a fault during the wait ends the wait (and the run).
        axis = session.axis()
        end = time.monotonic() + params["seconds"]
        while (left := end - time.monotonic()) > 0:
            status = axis.read_status()
            if status.fault:
                raise DriveFault(f"drive fault while waiting: {status.fault_summary()}",
                                 details={"faults": status.faults})
            session.sleep(min(0.25, left))
        return {"waited_s": params["seconds"]}
    target, comparison = params["target"], params["comparison"]
    start = time.monotonic()
    deadline = start + params["timeout"]
    while True:
        got = read_target(session, target)
        if matches(got, comparison):
            return {"read": got, "waited_s": round(time.monotonic() - start, 3)}
        if time.monotonic() > deadline:
            from akdctl.recipe.schema import _describe_comparison

            raise CheckFailed(f"{_describe_comparison(target['label'], comparison)} did not hold within "
                              f"{params['timeout']:g} s (last read {got})", details={"read": got})
        session.sleep(CHECK_INTERVAL_S)


def do_map(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    if "telegram_map" in params:
        return _telegram(session, params)
    from akdctl.drive import pdo as dp

    plan = dp.plan(session.conn, params["request"])  # the one PDO operation 'pdo map' runs (PRE-OP included)
    result = dp.execute(session.conn, plan)
    return {"sdo_downloads": result["sdo_downloads"], "plan": plan.to_json()}


def _telegram(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    """``telegram set``/``telegram map``'s one operation (drive/telegram.py): plan, execute, read back."""
    from akdctl.drive import telegram as dt

    plan = dt.plan(session.conn, params["request"])
    return {**dt.execute(session.conn, plan).to_json(), "plan": plan.to_json()}


def do_telegram(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    return _telegram(session, params)


def _axis_with_timeout(session: Session, timeout: float | None) -> Any:
    axis = session.axis()
    if timeout is not None:
        axis.timeout = max(axis.timeout, timeout)
    return axis


def _motion(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    """enable/home/move: the one planner and execution the commands use (consent was given for the recipe)."""
    from akdctl.drive import motion_plan

    axis = _axis_with_timeout(session, params.get("timeout"))
    accepted = motion_plan.plan(session.conn, axis, params["request"])
    final = motion_plan.execute(axis, accepted, session.interrupted)
    return {**final.to_json(), "plan": accepted.to_json()}


def do_enable(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    return _motion(session, params)


def do_disable(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    return _axis_with_timeout(session, params.get("timeout")).disable().to_json()


def do_stop(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    return session.axis().stop(quick=params["quick"]).to_json()


def do_acknowledge(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    return session.axis().acknowledge_faults().to_json()


def do_home(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    return _motion(session, params)


def do_move(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    return _motion(session, params)


def do_check_faults(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    from akdctl.drive import faults

    data = faults.dump(session.conn)
    summary = faults.summary(data)
    if summary["fault_present"]:
        raise DriveFault(f"fault active: {', '.join(summary['faults']) or 'see fault dump'}",
                         details={"faults": summary["faults"]})
    if summary["warning_present"] and not params["allow_warnings"]:
        raise CheckFailed(f"warning active: {', '.join(summary['warnings']) or 'see fault dump'}")
    return summary


def do_save(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    from akdctl.drive.snapshot import save_nonvolatile

    save_nonvolatile(session.conn)
    return {"saved": True}


def do_backup(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    from akdctl.drive import snapshot

    conn = session.conn
    if params["only"]:
        items = snapshot.select_items([], only=params["only"])
        sources = sorted({"pnu" if i.kind == "pnu" else "objects" for i in items})
    else:
        sources = snapshot.choose_sources(conn, params["source"])
        items = snapshot.select_items(sources, params["groups"])
    snap = snapshot.take(conn, items, conn.target.display, sources)
    snapshot.write_file(snap, session.output_file(params["file"], "backup file"))
    session.files.append(str(params["file"]))
    return {"file": params["file"], "pnus": len(snap.pnus), "objects": len(snap.objects), "refused": snap.refused}


def do_restore(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    from akdctl.drive import snapshot

    plan = snapshot.plan(session.conn, snapshot.RestoreRequest(params["snapshot"], force=params["force"]))
    return {**snapshot.execute(session.conn, plan).to_json(), "plan": plan.to_json()}


def do_scope(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    """Record (through the one scope operation the command uses: drive/scope.py), write the files the step names
    below the output directory, then check the bounds (CheckFailed, exit 5). Consent for a recorded jog was given
    for the recipe."""
    from akdctl.drive import scope as op

    plan = op.plan(session.conn, params["request"])
    recording, failure = op.execute(session.conn, plan, stopped=session.interrupted)
    for key, relative in params["files"].items():
        from akdctl.io.atomic import atomic_open

        path = session.output_file(relative, f"scope {key} file")
        text = recording.to_csv() if key == "csv" else _svg(recording) if key == "svg" else \
            _json_text(recording.to_json())
        with atomic_open(path) as out:
            out.write(text)
        session.files.append(str(path))
    if failure is not None:
        raise failure
    measured = op.check_bounds(recording, params["bounds"]) if params["bounds"].any else {}
    return {"samples": len(recording), "rate_hz": recording.rate_achieved, "measured": measured,
            "summary": recording.summary()}


def _svg(recording: Any) -> str:
    from akdctl.drive.scope_svg import render_svg

    return render_svg(recording)


def _json_text(data: Any) -> str:
    import json

    return json.dumps(data, indent=1) + "\n"


ACTIONS: dict[str, Callable[[Session, dict[str, Any]], dict[str, Any]]] = {
    "set": do_set, "expect": do_expect, "wait": do_wait, "map": do_map, "telegram": do_telegram,
    "enable": do_enable, "disable": do_disable, "stop": do_stop, "acknowledge": do_acknowledge, "home": do_home,
    "move": do_move, "check_faults": do_check_faults, "save": do_save, "backup": do_backup, "restore": do_restore,
    "param": lambda session, params: do_param(session, params),
    "scope": do_scope,
}


def run_step(session: Session, step: PlannedStep) -> dict[str, Any]:
    return ACTIONS[step.action](session, step.params)


def do_param(session: Session, params: dict[str, Any]) -> dict[str, Any]:
    """AKD parameters by name: the plan and execute of ``param set`` (drive/names.py), one rule for both."""
    from akdctl.drive import names

    plan = names.plan(session.conn, params["assignments"], raw=params["raw"])
    return {"written": names.execute(session.conn, plan), "notes": plan.notes}
