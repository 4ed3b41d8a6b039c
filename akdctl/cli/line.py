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

from akdctl.errors import EXIT_COMM, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, UsageError

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
        self.skipped = ""  # why it never ran (stop on error, interrupted)
        self.files: dict[str, str] = {}
        self.pid = 0
        self._process: subprocess.Popen[bytes] | None = None  # spawned (not forked) drives
        self._fds: dict[int, bytearray] = {}  # open pipe -> what came through it
        self._out_fd = self._err_fd = -1
        self._status: int | None = None  # raw wait status once reaped

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


def fork_mode() -> bool:
    """Drives run in forked copies of this process (no interpreter start, no imports per drive: the line's CPU
    is the drives' work) where the platform forks; ``AKDCTL_LINE_SPAWN=1`` starts a fresh interpreter per drive
    instead (the same command line, the same result)."""
    return hasattr(os, "fork") and os.environ.get("AKDCTL_LINE_SPAWN") != "1"


def warm_up(command: Sequence[str]) -> None:
    """Import, once in the parent, what every forked drive would otherwise import itself: the command's module
    and the modules a drive command needs whatever the target (connection, axis, values, catalogue)."""
    import importlib

    from akdctl.cli.main import COMMANDS

    entry = COMMANDS.get(command[0])
    names = [entry[0]] if entry else []
    names += ["akdctl.connection", "akdctl.config", "akdctl.cli.output", "akdctl.drive.values",
              "akdctl.transport.registry", "akdctl.transport.trace"]
    if command == ("commission",):
        names += ["akdctl.recipe", "akdctl.recipe.schema", "akdctl.recipe.runner", "akdctl.recipe.ops",
                  "akdctl.recipe.report", "akdctl.drive.gate"]
    for name in names:
        try:
            importlib.import_module(name)
        except ImportError:
            continue


def run_all(runs: list[DriveRun], parallel: int, *, stop_on_error: bool = False,
            on_done: Callable[[DriveRun], None] | None = None) -> bool:
    """Run every drive's process, at most ``parallel`` at once; returns False when interrupted.

    One thread: the drives' pipes are read by one selector loop (a chatty drive never blocks on a full pipe,
    and a fork is never taken while another thread holds a lock). Ctrl-C (SIGINT) and SIGTERM reach the
    drives' processes, which stop their axes; the parent starts no new drive and waits for the running ones
    (killing one only after :data:`STOP_GRACE_S`).
    """
    import selectors
    import signal

    forking = fork_mode()
    pending = list(runs)
    running: list[DriveRun] = []
    stopping: list[float] = []  # when the stop began
    by_fd: dict[int, DriveRun] = {}
    selector = selectors.DefaultSelector()
    previous: dict[int, Any] = {}

    def on_signal(signum: int, frame: Any) -> None:
        if not stopping:
            stopping.append(time.monotonic())
        for run in running:
            _signal(run, signal.SIGINT)

    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, on_signal)
    failed = False
    try:
        while pending or running:
            while pending and len(running) < parallel and not stopping and not (stop_on_error and failed):
                run = pending.pop(0)
                _start(run, forking)
                for fd in run._fds:
                    selector.register(fd, selectors.EVENT_READ)
                    by_fd[fd] = run
                running.append(run)
            if (stopping or (stop_on_error and failed)) and pending:
                why = "interrupted" if stopping else "not run: --stop-on-error after a failed drive"
                for run in pending:
                    run.skipped = why
                pending.clear()
            for key, _ in selector.select(timeout=0.05):
                fd = int(key.fd)
                run = by_fd[fd]
                try:
                    chunk = os.read(fd, 65536)
                except (BlockingIOError, InterruptedError):
                    continue
                if chunk:
                    run._fds[fd] += chunk
                else:
                    selector.unregister(fd)
                    os.close(fd)
                    del by_fd[fd]
                    run._fds[fd] = run._fds[fd]  # kept: the text is read from it at the end
                    _closed(run, fd)
            for run in list(running):
                if _open_fds(run) or not _reap(run):
                    continue
                running.remove(run)
                failed = failed or run.exit_code != EXIT_OK
                if on_done is not None:
                    on_done(run)
            if stopping and running and time.monotonic() - stopping[0] > STOP_GRACE_S:
                for run in running:
                    _signal(run, signal.SIGKILL)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        selector.close()
    return not stopping


def _signal(run: DriveRun, signum: int) -> None:
    if run.pid and run._status is None:
        try:
            os.kill(run.pid, signum)
        except OSError:
            pass


def _open_fds(run: DriveRun) -> bool:
    return run._out_fd != -1 or run._err_fd != -1


def _closed(run: DriveRun, fd: int) -> None:
    if fd == run._out_fd:
        run.stdout = run._fds[fd].decode("utf-8", "replace")
        run._out_fd = -1
    elif fd == run._err_fd:
        run.stderr = run._fds[fd].decode("utf-8", "replace")
        run._err_fd = -1


def _start(run: DriveRun, forking: bool) -> None:
    run.seconds = time.monotonic()
    if not forking:
        run._process = subprocess.Popen(run.argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, env=_child_env())
        run.pid = run._process.pid
        assert run._process.stdout is not None and run._process.stderr is not None
        run._out_fd = os.dup(run._process.stdout.fileno())
        run._err_fd = os.dup(run._process.stderr.fileno())
        run._process.stdout.close()
        run._process.stderr.close()
    else:
        out_r, out_w = os.pipe()
        err_r, err_w = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:  # the drive: this process, forked, runs the one command and never returns
            _drive_process(run.argv, out_r, out_w, err_r, err_w)
        os.close(out_w)
        os.close(err_w)
        run.pid, run._out_fd, run._err_fd = pid, out_r, err_r
    for fd in (run._out_fd, run._err_fd):
        os.set_blocking(fd, False)
        run._fds[fd] = bytearray()


def _drive_process(argv: list[str], out_r: int, out_w: int, err_r: int, err_w: int) -> None:
    """In the forked child: stdin from /dev/null, stdout/stderr into the parent's pipes, default signal
    handling, then the ordinary entry point with the drive's command line; exits with its code."""
    import signal

    code = 70
    try:
        os.close(out_r)
        os.close(err_r)
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.dup2(out_w, 1)
        os.dup2(err_w, 2)
        for fd in (null, out_w, err_w):
            os.close(fd)
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, signal.SIG_DFL if signum == signal.SIGTERM else signal.default_int_handler)
        os.environ.pop("AKDCTL_TARGET", None)
        from akdctl.cli.main import main

        try:
            main(argv[3:])  # argv is [python, -m, akdctl, ...]: the same command line a spawned drive gets
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def _reap(run: DriveRun) -> bool:
    if run._process is not None:
        code = run._process.poll()
        if code is None:
            return False
        run._status = code
    else:
        pid, status = os.waitpid(run.pid, os.WNOHANG)
        if pid == 0:
            return False
        run._status = status
        code = os.waitstatus_to_exitcode(status)
    run.exit_code = code if code >= 0 else EXIT_INTERRUPTED
    run.seconds = time.monotonic() - run.seconds
    return True


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
        if fork_mode():
            warm_up(line.command)
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
    """The one consent for a whole line: the CLI's one question (:func:`akdctl.cli.consent.ask`); each drive's
    process then runs with ``--yes`` and takes its own axis's owner lock."""
    from akdctl.cli.consent import ask

    ask(text, yes)


__all__ = ["LINE_COMMANDS", "DriveRun", "LineArgs", "confirm_line", "finish", "run", "run_all", "split_args",
           "wanted", "worst"]
