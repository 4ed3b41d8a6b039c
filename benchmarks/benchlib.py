"""The measuring rules every benchmark row follows, written once.

Why one module: a benchmark flatters as soon as one row measures differently from the others (blocks instead of
pairs, a baseline from another run, PNU/s divided by round trips/s). So every row uses the same three tools:

* :func:`interleave` - two workloads A and B run in alternating blocks (A, B, A, B ...) and every figure is the
  median over the rounds, so a noisy neighbour on this shared machine slows both sides of a pair alike and a ratio
  is only ever taken between two blocks measured side by side;
* :class:`Sample` - one block's wall time and the client's CPU time (``time.thread_time``), per operation;
* :class:`ProcessCpu` - the CPU time another process (a server) spent, from ``/proc/PID/task/*/schedstat``
  (nanoseconds, every thread) with ``/proc/PID/stat`` (clock ticks) as the fallback.

Which akdctl is measured: the one ``import akdctl`` finds (``PYTHONPATH`` first), never this checkout by accident,
so another work package measures its own tree with this runner. Subprocesses get the same tree first on
``PYTHONPATH`` (:func:`akdctl_env`).
"""

from __future__ import annotations

import contextlib
import os
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")

HERE = Path(__file__).resolve().parent


def akdctl_root() -> Path:
    """The directory holding the ``akdctl`` package that is measured (PYTHONPATH first, else the installed one)."""
    try:
        import akdctl
    except ImportError:  # run from a bare checkout without PYTHONPATH: measure that checkout
        sys.path.insert(0, str(HERE.parent))
        import akdctl
    return Path(akdctl.__file__).resolve().parent.parent


def measured_tree_importable() -> None:
    """The measured tree first on ``sys.path``, so its ``tests`` helpers (netns, harness) are the ones a row uses."""
    root = str(akdctl_root())
    if root not in sys.path:
        sys.path.insert(0, root)


def cannot_run(*modules: str, root_for: str | None = None, install: str = "pip install 'akdctl[test]'") -> "Result | None":
    """Why a row cannot run here (a "skipped" Result), or None: then it can, with the measured tree importable.
    ``root_for`` says what root is needed for (None: root is not needed); ``modules`` must import."""
    if root_for is not None and os.geteuid() != 0:
        return Result("skipped", None, [f"needs root ({root_for}); run as root"])
    import importlib

    for name in modules:
        try:
            importlib.import_module(name)
        except ImportError:
            return Result("skipped", None, [f"{name} is not installed ({install})"])
    measured_tree_importable()
    return None


def akdctl_env(**extra: str) -> dict[str, str]:
    """This environment with the measured tree first on PYTHONPATH (and bytecode writing allowed: an installed
    package has its .pyc files, so a cold start must not include compiling)."""
    env = dict(os.environ)
    root = str(akdctl_root())
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and p != root]
    env["PYTHONPATH"] = os.pathsep.join([root, *paths])
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env.pop("AKDCTL_TARGET", None)
    env.pop("AKDCTL_PROFILE", None)
    env.update(extra)
    return env


@dataclass
class Sample:
    """One block of ``n`` operations: wall seconds, client CPU seconds, server CPU seconds (None if unknown)."""

    n: int
    wall: float
    cpu: float
    server_cpu: float | None = None
    extra: dict[str, float] = field(default_factory=dict)

    @property
    def wall_us(self) -> float:
        return self.wall / self.n * 1e6

    @property
    def cpu_us(self) -> float:
        return self.cpu / self.n * 1e6

    @property
    def server_us(self) -> float | None:
        return None if self.server_cpu is None else self.server_cpu / self.n * 1e6


def run_block(op: Callable[[], object], n: int, server: ProcessCpu | None = None) -> Sample:
    """``op`` ``n`` times in this thread; wall time, this thread's CPU time and the server's CPU time."""
    s0 = server.seconds() if server is not None else None
    c0, t0 = time.thread_time(), time.perf_counter()
    for _ in range(n):
        op()
    wall, cpu = time.perf_counter() - t0, time.thread_time() - c0
    s1 = server.seconds() if server is not None else None
    return Sample(n, wall, cpu, None if s0 is None or s1 is None else s1 - s0)


class Interleaved:
    """The samples of an interleaved run: ``runs[k][i]`` is workload k's block in round i (all side by side)."""

    def __init__(self, count: int) -> None:
        self.runs: list[list[Sample]] = [[] for _ in range(count)]

    def ratio(self, a: int, b: int, key: Callable[[Sample], float] = lambda s: s.wall_us) -> float:
        """Median over rounds of key(a)/key(b)."""
        return statistics.median(key(x) / key(y) for x, y in zip(self.runs[a], self.runs[b]))

    def diff(self, a: int, b: int, key: Callable[[Sample], float] = lambda s: s.wall_us) -> float:
        """Median over rounds of key(a) - key(b)."""
        return statistics.median(key(x) - key(y) for x, y in zip(self.runs[a], self.runs[b]))

    def median(self, k: int, key: Callable[[Sample], float | None] = lambda s: s.wall_us) -> float | None:
        values = [v for v in (key(s) for s in self.runs[k]) if v is not None]
        return statistics.median(values) if values else None


def interleave(*workloads: Callable[[], Sample], rounds: int, warmup: bool = True) -> Interleaved:
    """Blocks A, B, (C ...), A, B ... for ``rounds`` rounds, after one unmeasured block of each."""
    if warmup:
        for work in workloads:
            work()
    out = Interleaved(len(workloads))
    for _ in range(rounds):
        for k, work in enumerate(workloads):
            out.runs[k].append(work())
    return out


class ProcessCpu:
    """CPU seconds a process has used so far (all its threads), read from /proc."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.source = "schedstat" if self._schedstat() is not None else "stat"

    def _schedstat(self) -> float | None:
        total = 0
        try:
            tasks = os.listdir(f"/proc/{self.pid}/task")
            for task in tasks:
                try:
                    with open(f"/proc/{self.pid}/task/{task}/schedstat") as fh:
                        total += int(fh.read().split()[0])
                except FileNotFoundError:
                    continue  # a thread that ended meanwhile (its time is lost: threads are not used per request)
        except (OSError, ValueError, IndexError):
            return None
        return total / 1e9

    def user_system(self) -> tuple[float, float] | None:
        """User and kernel CPU seconds so far, from /proc/PID/stat (clock ticks: coarse, for splits over many
        blocks, never a row's judged figure)."""
        try:
            with open(f"/proc/{self.pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            tick = os.sysconf("SC_CLK_TCK")
            return int(fields[11]) / tick, int(fields[12]) / tick
        except (OSError, ValueError, IndexError):
            return None

    def seconds(self) -> float | None:
        if self.source == "schedstat":
            return self._schedstat()
        try:
            with open(f"/proc/{self.pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, ValueError, IndexError):
            return None


@dataclass
class Settings:
    """How long the rows measure: ``rounds`` interleaved rounds of ``block`` operations (``--quick`` shrinks both)."""

    quick: bool
    tmp: Path
    rounds: int
    block: int
    process_rounds: int  # interleaved pairs of process starts (cold start, raw master workers)


@dataclass
class Result:
    """One goal row's outcome: the measured figure as printed, pass (True), short (False) or skipped (None)."""

    value: str
    ok: bool | None
    notes: list[str] = field(default_factory=list)
    figures: dict[str, float | None] = field(default_factory=dict)


def fmt_us(value: float | None) -> str:
    return "-" if value is None else f"{value:.0f} µs" if value >= 10 else f"{value:.1f} µs"


def fmt_ratio(value: float | None) -> str:
    return "-" if value is None else f"{value:.3g}"


# ---------------------------------------------------------------------- measured clients in worker processes

class WorkerDied(RuntimeError):
    """A measured worker process ended, hung past its timeout, or answered something that is not a block's
    figures. ``last_words`` is the last line it wrote to stderr (its exception), for the row's value."""

    def __init__(self, kind: str, last_words: str) -> None:
        super().__init__(f"{kind} crashed: {last_words}")
        self.kind = kind
        self.last_words = last_words


class BlockWorker:
    """One measured client in its own process, driven block by block: it prints ``ready`` once set up, then reads
    a block size per stdin line and answers one line of numbers per block.

    Why not ``readline()`` on its pipe: a worker that dies answers an empty line (a row then died of a
    ``ValueError`` unpacking it) and a worker that hangs blocks the whole run. Here every read waits at most its
    timeout, and whatever goes wrong is a :class:`WorkerDied` carrying the worker's last words; its stderr goes to
    a file, so a chatty worker cannot fill a pipe and stall.
    """

    def __init__(self, kind: str, argv: list[str], env: dict[str, str] | None = None, fields: int = 2,
                 start_timeout: float = 60.0, block_timeout: float = 120.0, cwd: str | None = None) -> None:
        import subprocess
        import tempfile

        self.kind, self.fields, self.block_timeout = kind, fields, block_timeout
        self._err = tempfile.TemporaryFile(mode="w+b")  # noqa: SIM115 - closed when the worker is reported dead
        self._pending = b""
        self._silent = False  # the last read ran out of time (the worker hangs): it is killed, not waited for
        self.proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._err,
                                     bufsize=0, env=env, cwd=cwd)
        line = self._line(start_timeout)
        if line != "ready":
            raise self._died(f"said {line!r} instead of ready" if line else
                             f"not ready within {start_timeout:g} s" if self._silent else "ended before it was ready")

    def _line(self, timeout: float) -> str | None:
        """The worker's next stdout line, or None when it ended or stayed silent for ``timeout`` s."""
        import selectors

        assert self.proc.stdout is not None
        fd = self.proc.stdout.fileno()
        deadline = time.monotonic() + timeout
        self._silent = False
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while b"\n" not in self._pending:
                left = deadline - time.monotonic()
                if left <= 0 or not sel.select(left):
                    self._silent = True
                    return None
                chunk = os.read(fd, 4096)
                if not chunk:
                    return None
                self._pending += chunk
        line, self._pending = self._pending.split(b"\n", 1)
        return line.decode(errors="replace").strip()

    def _died(self, what: str) -> WorkerDied:
        if self._silent:
            self.proc.kill()
        self.stop()
        self._err.seek(0)
        lines = [x.strip() for x in self._err.read().decode(errors="replace").splitlines() if x.strip()]
        self._err.close()
        if self._silent:
            words = what + (f" (its last words: {lines[-1][-200:]})" if lines else "")
        else:
            words = lines[-1][-300:] if lines else f"{what}, exit status {self.proc.returncode}"
        return WorkerDied(self.kind, words)

    def block(self, n: int | str) -> list[float]:
        """Tell the worker to do ``n`` operations (or send it the words of a block, e.g. ``"poll 100"``); its
        answer's numbers (``fields`` of them)."""
        assert self.proc.stdin is not None
        try:
            self.proc.stdin.write(f"{n}\n".encode())
        except (BrokenPipeError, ValueError):
            raise self._died("ended") from None
        line = self._line(self.block_timeout)
        try:
            values = [float(x) for x in (line or "").split()]
        except ValueError:
            values = []
        if len(values) != self.fields:
            raise self._died(f"no answer within {self.block_timeout:g} s" if self._silent else
                             f"answered {line!r}" if line else "ended") from None
        return values

    def stop(self) -> None:
        """End the worker (closing its stdin ends its loop; killed if it does not end within 10 s)."""
        import subprocess

        if self.proc.stdin is not None and not self.proc.stdin.closed:
            try:
                self.proc.stdin.close()
            except BrokenPipeError:
                pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def cpu_speed() -> tuple[float, ...]:
    """Milliseconds of thread CPU time a fixed pure-Python loop takes on each CPU this process may run on, measured
    one CPU at a time (the affinity is restored after).

    Why: on this project's 2-vCPU machines each vCPU alternates, for seconds to tens of seconds, between a fast
    and a slow phase (the same loop takes ~15 ms or ~28 ms; the host's doing, not steal time). A row with an
    absolute goal (µs per request) measured in a slow phase reads ~1.8x worse. ``run_all`` prints this before and
    after each row so a reader can see the phase a figure was taken in; no row is judged by it."""
    def loop() -> float:
        start, x = time.thread_time(), 0
        for i in range(200_000):
            x += i * i
        return (time.thread_time() - start) * 1e3

    try:
        allowed = sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return (min(loop(), loop()),)
    figures = []
    try:
        for cpu in allowed:
            os.sched_setaffinity(0, {cpu})
            figures.append(min(loop(), loop()))
    finally:
        os.sched_setaffinity(0, set(allowed))
    return tuple(figures)


def allowed_cpus() -> list[int]:
    """The CPUs this process may run on, in order (one, unnamed, where affinity cannot be read)."""
    try:
        return sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return []


def comparison_cpu() -> OnCpu:
    """Where every process of a peer comparison starts (the clients and the server they share): one CPU, the last
    this process may use (no change where affinity cannot be read). Why one for all: an op is a ping-pong through
    one server, each CPU here has speed phases of its own, and the CPU the scheduler gave each client and each
    client's server thread was luck that held for a whole row (ascii, the same code: 1.62x in one run, 0.95x in
    another; canopen 1.09x and 1.28x). On one CPU, every process meets the same phase and a round trip costs the two
    sides' CPU: the same server work for both clients."""
    cpus = allowed_cpus()
    return OnCpu(cpus[-1] if cpus else None)


@contextlib.contextmanager
def started_on_comparison_cpu(server: contextlib.AbstractContextManager[T]) -> Iterator[T]:
    """``server`` (a row's ``sim_server(...)``) started inside :func:`comparison_cpu`; only the start is pinned
    (the server process keeps the mask, this process gets its own back at once)."""
    with contextlib.ExitStack() as stack:
        with comparison_cpu():
            entered = stack.enter_context(server)
        yield entered


class OnCpu:
    """``with OnCpu(cpu):`` -- processes started inside run on ``cpu`` only (``None``: no change).

    Why: each vCPU here has speed phases of its own (:func:`cpu_speed`), so two sides of a comparison that the
    scheduler puts on different CPUs can differ by ~1.8x for no reason of their own. Started on one CPU, both sides
    of a pair meet the same phase. How: the calling thread's affinity is set for the duration (a child inherits the
    mask of the thread that starts it) and restored after; the measuring process's other threads are not touched."""

    def __init__(self, cpu: int | None) -> None:
        self.cpu = cpu
        self._before: set[int] | None = None

    def __enter__(self) -> "OnCpu":
        if self.cpu is not None:
            self._before = set(os.sched_getaffinity(0))
            os.sched_setaffinity(0, {self.cpu})
        return self

    def __exit__(self, *exc: object) -> None:
        if self._before is not None:
            os.sched_setaffinity(0, self._before)
            self._before = None
