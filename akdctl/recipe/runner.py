"""Running a validated recipe: steps in order, stop at the first failure with the axis made safe.

Why the runner owns safety: a CI job that fails half-way must not leave a live
axis behind. On any failure (and on Ctrl-C) the runner stops the axis and
disables the power stage through the Axis (the one implementation of both),
records what that did, marks the remaining steps skipped, and hands back a
result from which the JSON and JUnit reports are written — reports exist
whether the run passed or not.
"""

from __future__ import annotations

import datetime as _dt
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from akdctl.errors import EXIT_INTERRUPTED, EXIT_OK, AkdError, CommError, Interrupted
from akdctl.recipe.ops import Session, run_step
from akdctl.recipe.schema import PlannedStep

PASSED, FAILED, SKIPPED, PLANNED = "passed", "failed", "skipped", "planned"


@dataclass
class StepResult:
    step: PlannedStep
    status: str
    duration: float = 0.0
    message: str = ""
    kind: str = ""  # error kind (check-failed, drive-fault, ...) of a failure
    exit_code: int = EXIT_OK
    details: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        data = {**self.step.to_json(), "status": self.status, "duration_s": round(self.duration, 3)}
        if self.message:
            data["message"] = self.message
        if self.kind:
            data["error_kind"] = self.kind
            data["exit_code"] = self.exit_code
        if self.details:
            data["details"] = self.details
        return data


@dataclass
class RunResult:
    recipe: str
    description: str
    file: str
    target: str
    started: str
    duration: float
    dry_run: bool
    results: list[StepResult]
    exit_code: int = EXIT_OK
    error: AkdError | None = None
    safe_state: str = ""
    files: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return self.exit_code == EXIT_OK

    @property
    def interrupted(self) -> bool:
        """Stopped by a signal (SIGINT, SIGTERM, SIGHUP): the report says so."""
        return isinstance(self.error, Interrupted)

    @property
    def failed_step(self) -> StepResult | None:
        return next((r for r in self.results if r.status == FAILED), None)

    def to_json(self) -> dict[str, Any]:
        failed = self.failed_step
        data: dict[str, Any] = {
            "recipe": self.recipe, "description": self.description, "file": self.file, "target": self.target,
            "started": self.started, "duration_s": round(self.duration, 3), "dry_run": self.dry_run,
            "result": "planned" if self.dry_run else ("passed" if self.passed else
                                                       "interrupted" if self.interrupted else "failed"),
            "exit_code": self.exit_code,
            "counts": {status: sum(1 for r in self.results if r.status == status)
                       for status in (PASSED, FAILED, SKIPPED, PLANNED)},
            "steps": [r.to_json() for r in self.results],
        }
        if failed is not None:
            data["failed_step"] = {"step": failed.step.number, "name": failed.step.name, "action": failed.step.action,
                                   "where": failed.step.where, "message": failed.message}
        if self.safe_state:
            data["safe_state"] = self.safe_state
        if self.files:
            data["files"] = self.files
        return data


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def plan_only(steps: list[PlannedStep], **meta: Any) -> RunResult:
    return RunResult(started=now_iso(), duration=0.0, dry_run=True,
                     results=[StepResult(s, PLANNED) for s in steps], **meta)


def make_safe(session: Session, has_motion: bool) -> str:
    """Stop, then disable, through the Axis; never raises; says what happened."""
    if not (session.axis_opened or has_motion):
        return ""
    try:
        axis = session.axis()
    except AkdError as exc:
        return f"could not open the axis to make it safe: {exc.message}"
    _, stopped = axis.safe_stop()
    try:
        axis.disable()
        return f"{stopped}; power stage disabled"
    except CommError as exc:
        return f"{stopped}; could not disable, the drive does not answer ({exc.message})"
    except AkdError as exc:
        return f"{stopped}; disable failed: {exc.message}"


def run(steps: list[PlannedStep], session: Session, progress: Callable[[str], None] | None = None,
        **meta: Any) -> RunResult:
    """Execute the steps; the first failure stops the run (axis made safe, the rest skipped)."""
    started, t0 = now_iso(), time.monotonic()
    results: list[StepResult] = []
    error: AkdError | None = None
    exit_code = EXIT_OK
    has_motion = any(s.motion for s in steps)
    total = len(steps)
    for position, step in enumerate(steps):
        if progress:
            progress(f"[{step.number}/{total}] {step.name} …")
        begin = time.monotonic()
        try:
            if session.interrupted():
                raise KeyboardInterrupt
            details = run_step(session, step)
        except KeyboardInterrupt:
            error = Interrupted(f"interrupted during step {step.number} ({step.name})")
            exit_code = EXIT_INTERRUPTED
        except AkdError as exc:
            error = exc
            exit_code = exc.exit_code
        else:
            results.append(StepResult(step, PASSED, time.monotonic() - begin, details=_jsonable(details)))
            if progress:
                progress(f"[{step.number}/{total}] {step.name}: ok ({time.monotonic() - begin:.2f} s)")
            continue
        results.append(StepResult(step, FAILED, time.monotonic() - begin, f"{step.where}: {error.message}",
                                  error.kind, exit_code, _jsonable(error.details)))
        if progress:
            progress(f"[{step.number}/{total}] {step.name}: FAILED: {error.message}")
        for rest in steps[position + 1:]:
            results.append(StepResult(rest, SKIPPED, message=f"not run: step {step.number} failed"))
        break
    safe_state = ""
    if error is not None:
        if progress and (session.axis_opened or has_motion):
            progress("making the axis safe (stop, disable) …")
        safe_state = make_safe(session, has_motion)
    return RunResult(started=started, duration=time.monotonic() - t0, dry_run=False, results=results,
                     exit_code=exit_code, error=error, safe_state=safe_state, files=session.files, **meta)


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).hex()
    if value is None or isinstance(value, (int, float, str, bool)):
        return value
    if hasattr(value, "to_json"):
        return _jsonable(value.to_json())
    return str(value)


def output_dir_for(path: str | None) -> Path:
    return Path(path) if path else Path.cwd()
