"""``--inventory FILE [--select TAG|NAME] [--parallel N]``: run one command on a line of drives.

Why each drive in its own akdctl process: every command already knows how to talk to one drive safely -- its
owner lock, its deadline (``--timeout``), its stop-on-error, its exit code. A process per drive keeps that
unchanged and isolates the drives from each other: a drive that hangs up, faults or kills its link fails that
drive only, and the others finish. The parent only reads the inventory (:mod:`akdctl.drive.inventory`), asks the
one consent for the whole line, runs at most ``--parallel`` drives at once, and gathers: output grouped per
drive, one ``--json`` document with a list per drive, one aggregated report for ``commission``, a comparison
for ``param diff``, a summary line, and the worst drive's exit code.

Which commands: those that make sense on many drives and cannot surprise anyone -- the read-only ones (``info``,
``status``, ``fault dump|list``, ``param get|dump|diff``, ``params backup``, ``pnu get``, ``sdo read``,
``support bundle``) and
``commission`` (one recipe, per-drive values by substitution, one consent). Every other command refuses
``--inventory`` (exit 2): moving a line of axes by hand is no job for a loop.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from akdctl.errors import EXIT_COMM, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, SafetyRefusal, UsageError

#: The options this module takes out of the command line (the rest goes to every drive's process).
LINE_OPTIONS = {"--inventory": True, "--select": True, "--parallel": True, "--stop-on-error": False}
#: Commands that run on a line: (group, subcommand) or (command,).
LINE_COMMANDS = {("info",), ("status",), ("fault", "dump"), ("fault", "list"), ("param", "get"), ("param", "dump"),
                 ("param", "diff"), ("params", "backup"), ("params", "diff"), ("pnu", "get"), ("sdo", "read"),
                 ("commission",), ("support", "bundle")}
GROUPS = {"fault", "param", "params", "support", "pnu", "sdo"}
DEFAULT_PARALLEL = 4
MAX_PARALLEL = 64
#: How long a drive's process may run on after Ctrl-C before it is killed (it is stopping its axis meanwhile).
STOP_GRACE_S = 10.0
#: How many lines of a drive's stderr the human report shows (the JSON document keeps them all).
SHOWN_STDERR_LINES = 6


class LineArgs:
    """The command line split: the line's own options, the command path, and what goes to each drive."""

    def __init__(self) -> None:
        self.inventory = ""
        self.select: list[str] = []
        self.parallel = DEFAULT_PARALLEL
        self.stop_on_error = False
        self.command: tuple[str, ...] = ()
        self.rest: list[str] = []  # everything else, in order (root options and the command's own)
        self.json = False
        self.yes = False


def wanted(args: Sequence[str]) -> bool:
    """Whether the command line asks for a line run (``--inventory`` before ``--``, and not ``--help``)."""
    head = list(args[: list(args).index("--")] if "--" in args else args)
    if "--help" in head or "-h" in head:
        return False
    return any(a == "--inventory" or a.startswith("--inventory=") for a in head)


def _value_options() -> set[str]:
    """The root options that take a value (their value is no command name)."""
    from akdctl.cli.main import cli

    taking = set()
    for param in cli.params:
        if getattr(param, "is_flag", False) or getattr(param, "count", False):
            continue
        taking.update(param.opts)
    return taking


def split_args(args: Sequence[str]) -> LineArgs:
    """Take the line's options out of ``args`` and find the command path; UsageError on anything a line
    cannot run."""
    out = LineArgs()
    taking = _value_options()
    tokens = list(args)
    i = 0
    positional: list[str] = []
    while i < len(tokens):
        token = tokens[i]
        name, eq, inline = token.partition("=")
        if token == "--":
            out.rest += tokens[i:]
            break
        if name in LINE_OPTIONS:
            if LINE_OPTIONS[name]:
                if eq:
                    value = inline
                else:
                    if i + 1 >= len(tokens):
                        raise UsageError(f"{name} needs a value")
                    i += 1
                    value = tokens[i]
                _take(out, name, value)
            else:
                if eq:
                    raise UsageError(f"{name} takes no value")
                out.stop_on_error = True
            i += 1
            continue
        if name in ("-T", "--target") or (token.startswith("-T") and len(token) > 2 and not token.startswith("--")):
            raise UsageError("--inventory chooses the targets: drop -T/--target (or run without --inventory)")
        out.rest.append(token)
        if token == "--json":
            out.json = True
        elif token in ("-y", "--yes"):
            out.yes = True
        elif token.startswith("-"):
            if not eq and name in taking and i + 1 < len(tokens):
                i += 1
                out.rest.append(tokens[i])
        else:
            positional.append(token)
        i += 1
    if not out.inventory:
        raise UsageError("--inventory needs a file")
    if not positional:
        raise UsageError("--inventory needs a command, e.g. akdctl --inventory line.toml status")
    command = tuple(positional[:2]) if positional[0] in GROUPS and len(positional) > 1 else (positional[0],)
    if command not in LINE_COMMANDS:
        shown = ", ".join(" ".join(c) for c in sorted(LINE_COMMANDS))
        raise UsageError(f"'{' '.join(command)}' does not run on a line of drives; --inventory works with: {shown}")
    out.command = command
    return out


def _take(out: LineArgs, name: str, value: str) -> None:
    if name == "--inventory":
        if out.inventory:
            raise UsageError("--inventory given twice")
        out.inventory = value
    elif name == "--select":
        out.select += [part.strip() for part in value.split(",") if part.strip()]
    elif name == "--parallel":
        try:
            number = int(value)
        except ValueError:
            number = 0
        if not 1 <= number <= MAX_PARALLEL:
            raise UsageError(f"--parallel {value!r}: a whole number of drives at once, 1..{MAX_PARALLEL}")
        out.parallel = number


class DriveRun:
    """One drive's process and what it left: exit code, stdout, stderr, its files."""

    def __init__(self, drive: Any, argv: list[str]) -> None:
        self.drive = drive
        self.argv = argv
        self.exit_code: int | None = None
        self.stdout = ""
        self.stderr = ""
        self.seconds = 0.0
        self.cpu_s = 0.0
        self.skipped = ""  # why it never ran (stop on error, interrupted)
        self.process: subprocess.Popen[bytes] | None = None
        self.files: dict[str, str] = {}

    @property
    def state(self) -> str:
        if self.skipped:
            return "skipped"
        if self.exit_code == EXIT_OK:
            return "passed"
        if self.exit_code == EXIT_COMM:
            return "unreachable"
        return "failed"

    def result_json(self) -> Any:
        import json

        text = self.stdout.strip()
        if not text:
            return None
        try:
            return json.loads(text)
        except ValueError:
            return {"text": self.stdout}

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {**self.drive.to_json(), "state": self.state, "exit_code": self.exit_code,
                                "seconds": round(self.seconds, 3)}
        if self.skipped:
            data["skipped"] = self.skipped
        else:
            data["result"] = self.result_json()
            errors = [line for line in self.stderr.splitlines() if line.strip()]
            if errors:
                data["stderr"] = errors
        return data


def _child_env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("AKDCTL_TARGET", None)  # the inventory names the target
    return env


def run_all(runs: list[DriveRun], parallel: int, *, stop_on_error: bool = False,
            on_done: Callable[[DriveRun], None] | None = None) -> bool:
    """Run every drive's process, at most ``parallel`` at once; returns False when interrupted.

    Ctrl-C (SIGINT) and SIGTERM reach the drives' processes, which stop their axes; the parent starts no new
    drive and waits for the running ones (killing one only after :data:`STOP_GRACE_S`).
    """
    import signal

    pending = list(runs)
    running: list[DriveRun] = []
    stopping = threading.Event()
    previous: dict[int, Any] = {}

    def on_signal(signum: int, frame: Any) -> None:
        stopping.set()
        for run in running:
            if run.process is not None and run.process.poll() is None:
                try:
                    run.process.send_signal(signal.SIGINT)
                except OSError:
                    pass

    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, on_signal)
    failed = False
    try:
        while pending or running:
            while pending and len(running) < parallel and not stopping.is_set() and not (stop_on_error and failed):
                run = pending.pop(0)
                _start(run)
                running.append(run)
            for run in list(running):
                if _reap(run, block=False):
                    running.remove(run)
                    failed = failed or run.exit_code != EXIT_OK
                    if on_done is not None:
                        on_done(run)
            if (stopping.is_set() or (stop_on_error and failed)) and pending:
                why = "interrupted" if stopping.is_set() else "not run: --stop-on-error after a failed drive"
                for run in pending:
                    run.skipped = why
                pending.clear()
            if running:
                time.sleep(0.005 if len(running) < parallel else 0.01)
                if stopping.is_set():
                    _grace(running)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return not stopping.is_set()


def _start(run: DriveRun) -> None:
    run.seconds = time.monotonic()
    run.process = subprocess.Popen(run.argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, env=_child_env())
    # one reader thread per pipe: a chatty drive can never block on a full pipe
    run._readers = [_reader(run.process.stdout, run, "stdout"), _reader(run.process.stderr, run, "stderr")]  # type: ignore[attr-defined]


def _reader(stream: Any, run: DriveRun, field: str) -> threading.Thread:
    def pump() -> None:
        data = stream.read()
        stream.close()
        setattr(run, field, data.decode("utf-8", "replace"))

    thread = threading.Thread(target=pump, daemon=True)
    thread.start()
    return thread


def _reap(run: DriveRun, *, block: bool) -> bool:
    assert run.process is not None
    code = run.process.wait() if block else run.process.poll()
    if code is None:
        return False
    for thread in run._readers:  # type: ignore[attr-defined]
        thread.join(5.0)
    run.exit_code = code if code >= 0 else EXIT_INTERRUPTED
    run.seconds = time.monotonic() - run.seconds
    return True


def _grace(running: list[DriveRun]) -> None:
    deadline = time.monotonic() + STOP_GRACE_S
    for run in running:
        if run.process is None:
            continue
        try:
            run.process.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            run.process.kill()


def child_argv(target: str, rest: list[str], *, json_output: bool) -> list[str]:
    argv = [sys.executable, "-m", "akdctl", "-T", target, *rest]
    if json_output and "--json" not in rest:
        argv.insert(5, "--json")
    return argv


# ----------------------------------------------------------------------------- the entry point
def run(args: Sequence[str]) -> int:
    """Run a line command (``main`` calls this when :func:`wanted`); returns the exit code."""
    from akdctl.drive import inventory

    line = split_args(args)
    inv = inventory.load(line.inventory)
    drives = inv.select(line.select)
    if line.command == ("commission",):
        from akdctl.cli.line_commission import run_commission

        return run_commission(line, inv, drives)
    if line.command in (("param", "diff"), ("params", "diff")):
        from akdctl.cli.line_compare import run_param_diff

        return run_param_diff(line, inv, drives)
    with tempfile.TemporaryDirectory(prefix="akdctl-line-") as scratch:
        runs = [DriveRun(d, child_argv(d.target, per_drive_args(line, d, Path(scratch)), json_output=line.json))
                for d in drives]
        completed = run_all(runs, line.parallel, stop_on_error=line.stop_on_error,
                            on_done=None if line.json else _progress)
        return finish(line, inv, runs, completed)


def per_drive_args(line: LineArgs, drive: Any, scratch: Path) -> list[str]:
    """The command line of one drive: files the command writes get the drive's name (``bundle.zip`` ->
    ``bundle-axis1.zip``) so drives never overwrite each other's."""
    rest = list(line.rest)
    outputs = {("params", "backup"): ("-o", "--output"), ("support", "bundle"): ("-o", "--output")}
    flags = outputs.get(line.command)
    if flags:
        for i, token in enumerate(rest):
            name, eq, value = token.partition("=")
            if name in flags:
                if eq:
                    rest[i] = f"{name}={named_file(value, drive.name)}"
                elif i + 1 < len(rest):
                    rest[i + 1] = named_file(rest[i + 1], drive.name)
    if line.command == ("param", "dump"):
        index = _positional_after(rest, "dump")
        if index is not None:
            rest[index] = named_file(rest[index], drive.name)
    return rest


def _positional_after(rest: list[str], word: str) -> int | None:
    try:
        start = rest.index(word)
    except ValueError:
        return None
    for i in range(start + 1, len(rest)):
        if not rest[i].startswith("-"):
            return i
    return None


def named_file(path: str, name: str) -> str:
    p = Path(path)
    suffixes = "".join(p.suffixes)
    stem = p.name[: len(p.name) - len(suffixes)] if suffixes else p.name
    return str(p.with_name(f"{stem}-{name}{suffixes}"))


def _progress(run: DriveRun) -> None:
    from akdctl.cli.output import message

    message(f"akdctl: {run.drive.name} ({run.drive.target}): {run.state} (exit {run.exit_code}, "
            f"{run.seconds:.2f} s)")


def worst(runs: Sequence[DriveRun]) -> int:
    """The line's exit code: the worst drive's (interrupted above all, then the highest code)."""
    codes = [r.exit_code for r in runs if r.exit_code is not None]
    if any(r.skipped == "interrupted" for r in runs) or EXIT_INTERRUPTED in codes:
        return EXIT_INTERRUPTED
    failing = [c for c in codes if c != EXIT_OK]
    if failing:
        return max(failing)
    if any(r.skipped for r in runs):
        return max(EXIT_USAGE, 1)
    return EXIT_OK


def summary(runs: Sequence[DriveRun]) -> dict[str, int]:
    counts = {"drives": len(runs), "passed": 0, "failed": 0, "unreachable": 0, "skipped": 0}
    for run in runs:
        counts[run.state] += 1
    return counts


def summary_line(command: str, counts: dict[str, int]) -> str:
    return (f"akdctl: {command} on {counts['drives']} drive(s): {counts['passed']} passed, {counts['failed']} "
            f"failed, {counts['unreachable']} unreachable, {counts['skipped']} skipped")


def finish(line: LineArgs, inv: Any, runs: Sequence[DriveRun], completed: bool,
           extra: dict[str, Any] | None = None) -> int:
    """Print the grouped result and the summary; the worst exit code."""
    from akdctl.cli.output import emit_json, inert, message

    counts = summary(runs)
    command = " ".join(line.command)
    if line.json:
        document = {"inventory": inv.path, "command": command, "select": line.select,
                    "drives": [r.to_json() for r in runs], "summary": counts, **(extra or {})}
        emit_json(document)
    else:
        for run in runs:
            header = f"== {run.drive.name} ({run.drive.target}): {run.state}"
            if run.exit_code not in (None, EXIT_OK):
                header += f" (exit {run.exit_code})"
            if run.skipped:
                header += f": {run.skipped}"
            sys.stdout.write(inert(header) + "\n")
            if run.stdout.strip():
                sys.stdout.write(run.stdout if run.stdout.endswith("\n") else run.stdout + "\n")
            shown = [line_ for line_ in run.stderr.splitlines() if line_.strip()]
            for text in shown[-SHOWN_STDERR_LINES:]:
                sys.stdout.write("   " + inert(text) + "\n")
        sys.stdout.flush()
    message(summary_line(command, counts) + ("" if completed else " (interrupted)"))
    return worst(runs)


def confirm_line(text: str, yes: bool) -> None:
    """The one consent for a whole line: ``--yes``, else a prompt on a terminal, else exit 4."""
    import click

    from akdctl.cli.output import inert

    if yes:
        return
    if not sys.stdin.isatty():
        raise SafetyRefusal(f"refusing to {text}: no terminal to ask for consent and --yes was not given; "
                            "nothing was written")
    if not click.confirm(inert(f"About to {text}. Proceed?"), default=False, err=True):
        raise SafetyRefusal(f"not confirmed: {text}; nothing was written")


__all__ = ["LINE_COMMANDS", "DriveRun", "LineArgs", "confirm_line", "finish", "run", "run_all", "split_args",
           "wanted", "worst"]
