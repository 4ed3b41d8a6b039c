"""How far a motion has come, while it runs: a rich progress bar on a terminal, plain lines otherwise.

Why: ``move``/``jog``/``home`` used to print position and velocity only, so a technician could not tell how much
of a 30 s move was left (issue 14). The planner already knows where the motion starts and ends
(:class:`~akdctl.drive.motion_plan.MotionPlan` ``start_rev``/``end_rev``/``duration_s``); each status the motion
loop reads is measured against it here: target, distance to go, percent and a time estimate. Homing has no known
end, so it shows position, velocity and the time left until its deadline.

On a terminal (stderr) the bar redraws in place and disappears when the motion ends (the final status follows on
stdout). Piped, a plain line goes to stderr at most once a second (the first at once); with ``--json`` nothing is
printed while the motion runs.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from typing import Any

PLAIN_EVERY_S = 1.0  # at most one plain progress line per second when stderr is not a terminal


@dataclass
class Measure:
    """One status against the plan: ``done`` of ``total`` (None when the end is unknown) and the words around it."""

    done: float | None
    total: float | None
    target: str
    to_go: str
    eta_s: float | None

    @property
    def fraction(self) -> float | None:
        if self.done is None or not self.total:
            return None
        return min(max(self.done / self.total, 0.0), 1.0)


def measure(plan: Any, status: Any, elapsed: float) -> Measure:
    """Where the motion stands: by position for moves and distance jogs, by time for timed jogs, open for homing."""
    r = plan.request
    speed = abs(status.velocity_rpm or 0.0) / 60.0  # rev/s
    if r.kind == "jog" and plan.duration_s:
        left = max(plan.duration_s - elapsed, 0.0)
        return Measure(min(elapsed, plan.duration_s), plan.duration_s, f"for {plan.duration_s:g} s", "", left)
    if plan.end_rev is not None and plan.start_rev is not None:
        target = f"to {plan.end_rev:.4f} rev"
        total = abs(plan.end_rev - plan.start_rev)
        if status.position_rev is None:
            return Measure(None, total, target, "position not readable", None)
        to_go = abs(plan.end_rev - status.position_rev)
        return Measure(max(total - to_go, 0.0), total, target, f"{to_go:.4f} rev to go", _eta(plan, to_go, speed))
    where = f"at {status.position_rev:.4f} rev" if status.position_rev is not None else "searching"
    phase, finished = None, False
    if r.kind == "home":
        from akdctl.drive.axis.base import HOMING_COMPLETED, AxisStatus  # loaded with the axis that gave the status

        phase = status.homing_phase() if isinstance(status, AxisStatus) else None
        finished = phase == HOMING_COMPLETED
    if phase:  # what the drive reports of the homing's progress (issue 28 item 7)
        where = f"{phase}, {where}"
    if status.velocity_rpm is not None:
        where += f", {status.velocity_rpm:.1f} rpm"
    if plan.deadline_s and not finished:  # a finished homing has nothing left to give up on
        where += f" (gives up in {max(plan.deadline_s - elapsed, 0.0):.0f} s)"
    return Measure(None, None, "", where, None)


def _eta(plan: Any, to_go: float, speed: float) -> float | None:
    """Seconds left of a trapezoid: what is left at the planned velocity, plus the ramps still to run."""
    if to_go <= 0.0:
        return 0.0
    cruise = abs(plan.velocity.executed) / 60.0 if plan.velocity is not None else 0.0  # rev/s
    acc = abs(plan.accel.executed) / 60.0 if plan.accel is not None else 0.0  # rev/s²
    dec = abs(plan.decel.executed) / 60.0 if plan.decel is not None else acc
    if cruise <= 0.0 or acc <= 0.0 or dec <= 0.0:
        return to_go / speed if speed > 1e-9 else None
    return to_go / cruise + max(cruise - speed, 0.0) ** 2 / (2 * acc * cruise) + cruise / (2 * dec)


class MotionProgress:
    """A context manager whose :meth:`update` is the motion loop's progress callback."""

    def __init__(self, plan: Any, *, quiet: bool = False, stream: Any = None) -> None:
        self.plan = plan
        self.stream = stream or sys.stderr
        self.quiet = quiet
        self.terminal = not quiet and self.stream.isatty()
        self.started = time.monotonic()
        self.last_line = 0.0
        self.last: Measure | None = None
        self._bar: Any = None
        self._task: Any = None

    def __enter__(self) -> "MotionProgress":
        if self.terminal:
            from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn

            from akdctl.cli.output import console

            self._bar = Progress(TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                                 TextColumn("{task.fields[to_go]}"), TextColumn("{task.fields[eta]}"),
                                 TimeElapsedColumn(), console=console(stderr=True), transient=True,
                                 auto_refresh=False)
            self._bar.start()
            self._task = self._bar.add_task(self.plan.request.kind, total=None, to_go="", eta="")
        return self

    def update(self, status: Any) -> None:
        m = measure(self.plan, status, time.monotonic() - self.started)
        self.last = m
        if self.quiet:
            return
        eta = f"~{m.eta_s:.1f} s left" if m.eta_s is not None else ""
        if self._bar is not None:
            self._bar.update(self._task, description=f"{self.plan.request.kind} {m.target}".strip(), total=m.total,
                             completed=m.done or 0.0, to_go=m.to_go, eta=eta)
            self._bar.refresh()
            return
        now = time.monotonic()
        if now - self.last_line >= PLAIN_EVERY_S:
            self.last_line = now
            self._line(m, eta)

    def _line(self, m: Measure, eta: str) -> None:
        percent = f" {m.fraction * 100:.0f} %," if m.fraction is not None else ""
        words = ", ".join(w for w in (m.to_go, eta) if w)
        what = f"{self.plan.request.kind} {m.target}".strip()
        self.stream.write(f"akdctl: {what}:{percent} {words}\n")
        self.stream.flush()

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()
