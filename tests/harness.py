"""The one place tests start akdctl processes: the CLI runner and the simulator server.

Why one place: every end-to-end test needs the same four guarantees, and hand-rolled copies kept losing one of them:

* **no hang** - every wait has a deadline: the server's ready line is read by a reader thread and waited for with a
  timeout (never a bare ``readline()``), CLI runs carry ``timeout=``, stopping a server waits and then kills;
* **no port race** - a UDP face binds port 0 itself and the harness parses the bound ``host:port`` from its
  ``listening:`` line, instead of probing a free port and hoping nobody takes it before the server binds it;
* **no packet off the machine** - servers and CLI runs take ``netns=``: anything that multicasts runs in a
  :class:`tests.netns.LoopbackNetns` (only ``lo``, a multicast route on it) that the test creates and removes;
* **cleanup always** - servers are context managers; leaving the ``with`` stops and reaps the process.

Typical use::

    from tests.harness import SimServer, run_akdctl

    with SimServer("--profinet", "127.0.0.1:0") as server:
        result = run_akdctl("-T", f"pn://{server.host}:{server.port}", "pnu", "get", "930")
        assert result.code == 0, result.err

Both inherit the test's environment (the autouse ``isolated_env`` fixture gives every test its own
``AKDCTL_STATE_DIR``), so a CLI run and the server it talks to see the same simulated drive.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parent.parent
READY_TIMEOUT = 20.0  # seconds for `sim serve` to print its ready line(s); interpreter start-up dominates
STOP_TIMEOUT = 10.0  # seconds a stopped server gets before it is killed
READY_PREFIX = "listening: "
# "listening: profinet udp 127.0.0.1:34964", "listening: ethercat-udp udp 127.0.0.1:34980 stations ..."
_SOCKET_ADDRESS = re.compile(r"\b(?:udp|tcp) \[?(?P<host>[\w.:-]+?)\]?:(?P<port>\d+)\b")


def akdctl_env(env: dict[str, str] | None = None) -> dict[str, str]:
    """The test's environment plus *env*, with this checkout first on PYTHONPATH (subprocesses import it)."""
    full = dict(os.environ)
    paths = [p for p in full.get("PYTHONPATH", "").split(os.pathsep) if p]
    if str(ROOT) not in paths:
        full["PYTHONPATH"] = os.pathsep.join([str(ROOT), *paths])
    if env:
        full.update(env)
    return full


def _argv(args: Sequence[str], netns: str | None, prefix: Sequence[str] = ()) -> list[str]:
    inside = ["ip", "netns", "exec", netns] if netns else []
    return [*inside, *prefix, sys.executable, "-m", "akdctl", *args]


class CliResult(NamedTuple):
    """One finished CLI run; unpacks as ``code, out, err`` and also reads like a CompletedProcess."""

    code: int
    out: str
    err: str

    @property
    def returncode(self) -> int:
        return self.code

    @property
    def stdout(self) -> str:
        return self.out

    @property
    def stderr(self) -> str:
        return self.err


def run_akdctl(*args: str, input: str | None = None, env: dict[str, str] | None = None, timeout: float = 60,
               netns: str | None = None, prefix: Sequence[str] = (), cwd: Path | None = None) -> CliResult:
    """The real CLI (``python -m akdctl ARGS``) in a subprocess, to completion or *timeout* seconds.

    stdin is *input* or empty (never the terminal pytest runs in), so a prompt cannot wait forever; *netns* runs it
    inside that network namespace; *prefix* is a command that runs it (e.g. ``setpriv`` to drop privileges); *cwd*
    the directory it runs in (default: the checkout).
    """
    proc = subprocess.run(_argv(args, netns, prefix), input=input if input is not None else "", capture_output=True,
                          text=True, env=akdctl_env(env), timeout=timeout, cwd=cwd or ROOT)
    return CliResult(proc.returncode, proc.stdout, proc.stderr)


def start_akdctl(*args: str, env: dict[str, str] | None = None, netns: str | None = None,
                 ignore_sigint: bool = False) -> subprocess.Popen[str]:
    """The real CLI started in the background (a move to interrupt, a lock to take meanwhile); end it with
    :func:`finish`. ``ignore_sigint`` starts it as a shell's background job does (SIGINT inherited as ignored)."""
    def background_job() -> None:
        import signal

        signal.signal(signal.SIGINT, signal.SIG_IGN)

    return subprocess.Popen(_argv(args, netns), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, text=True, env=akdctl_env(env), cwd=ROOT,
                            preexec_fn=background_job if ignore_sigint else None)


def finish(proc: subprocess.Popen[str], timeout: float = 30.0) -> CliResult:
    """Wait for a background CLI run at most *timeout* seconds; kill and reap it if it overruns (then re-raise)."""
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise
    return CliResult(proc.returncode, out, err)


def wait_until(predicate: Callable[[], object], what: str, timeout: float = 20.0, poll: float = 0.05) -> None:
    """Poll observable state until *predicate* holds; fail naming *what* after *timeout* seconds."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(poll)


class _LineReader:
    """Drains one pipe on a daemon thread: lines are kept, and a full pipe can never block the server."""

    def __init__(self, stream) -> None:  # noqa: ANN001 - a text-mode pipe
        self.lines: list[str] = []
        self.closed = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._drain, args=(stream,), daemon=True)
        self._thread.start()

    def _drain(self, stream) -> None:  # noqa: ANN001
        try:
            for line in stream:
                with self._cond:
                    self.lines.append(line.rstrip("\n"))
                    self._cond.notify_all()
        except (OSError, ValueError):
            pass  # the stream was closed under us during stop()
        finally:
            with self._cond:
                self.closed = True
                self._cond.notify_all()

    def wait_for(self, predicate: Callable[[list[str]], bool], deadline: float) -> bool:
        with self._cond:
            while not predicate(self.lines):
                remaining = deadline - time.monotonic()
                if self.closed or remaining <= 0:
                    return predicate(self.lines)
                self._cond.wait(remaining)
            return True

    def join(self, timeout: float) -> None:
        self._thread.join(timeout)

    @property
    def text(self) -> str:
        with self._cond:
            return "\n".join(self.lines)


class SimServer:
    """``python -m akdctl sim serve FACE-ARGS`` in a subprocess, ready when every face printed its ready line.

    ``faces`` is how many ``listening:`` lines to wait for (one per face option given).  After start:
    ``ready`` is the list of those lines (without the ``listening: `` prefix), ``host``/``port`` the address the
    first UDP face bound (parsed from its line, so pass port 0), ``pid`` the server's process id.  Use it as a
    context manager, or call :meth:`stop` in a ``finally``.
    """

    def __init__(self, *face_args: str, duration: float = 120, faces: int = 1, env: dict[str, str] | None = None,
                 netns: str | None = None, ready_timeout: float = READY_TIMEOUT) -> None:
        self.args = ("sim", "serve", *face_args, "--duration", str(duration))
        self.faces = faces
        self.env = akdctl_env(env)
        self.netns = netns
        self.ready_timeout = ready_timeout
        self.ready: list[str] = []
        self.proc: subprocess.Popen[str] | None = None
        self._out: _LineReader | None = None
        self._err: _LineReader | None = None

    # -- lifecycle --------------------------------------------------------------------------------------------
    def start(self) -> SimServer:
        assert self.proc is None, "a SimServer starts once"
        self.proc = subprocess.Popen(_argv(self.args, self.netns), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     stdin=subprocess.DEVNULL, text=True, env=self.env, cwd=ROOT)
        self._out, self._err = _LineReader(self.proc.stdout), _LineReader(self.proc.stderr)
        deadline = time.monotonic() + self.ready_timeout
        if not self._out.wait_for(lambda lines: len(self._ready_lines(lines)) >= self.faces, deadline):
            exited = self.proc.poll()
            if exited is None and self._out.closed:  # stdout ended: the process is exiting, let it be reaped
                with contextlib.suppress(subprocess.TimeoutExpired):
                    exited = self.proc.wait(timeout=STOP_TIMEOUT)
            self.stop()
            why = (f"exited with {exited}" if exited is not None
                   else f"printed no ready line within {self.ready_timeout} s")
            raise AssertionError(f"sim serve {' '.join(self.args[2:])} {why}:\n{self.stdout}\n{self.stderr}")
        self.ready = self._ready_lines(self._out.lines)[:self.faces]
        return self

    def stop(self) -> int | None:
        """Terminate, wait (kill after STOP_TIMEOUT), reap; idempotent.  Returns the exit code."""
        proc = self.proc
        if proc is None:
            return None
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=STOP_TIMEOUT)
        for reader in (self._out, self._err):
            if reader is not None:
                reader.join(timeout=STOP_TIMEOUT)  # the pipes hit EOF once the process is gone
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()
        return proc.returncode

    def __enter__(self) -> SimServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- what the server told us ------------------------------------------------------------------------------
    @staticmethod
    def _ready_lines(lines: list[str]) -> list[str]:
        return [line[len(READY_PREFIX):] for line in lines if line.startswith(READY_PREFIX)]

    @property
    def pid(self) -> int:
        assert self.proc is not None, "server not started"
        return self.proc.pid

    def address_of(self, face: str = "") -> tuple[str, int]:
        """(host, port) the face bound, from the first ready line starting with *face* that names a ``udp``/``tcp``
        ``host:port`` - the real port when port 0 was asked for."""
        for line in self.ready:
            match = _SOCKET_ADDRESS.search(line) if line.startswith(face) else None
            if match:
                return match["host"], int(match["port"])
        raise AssertionError(f"no ready line {'of ' + face + ' ' if face else ''}names a host:port: {self.ready}")

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) of the first face that names one (see :meth:`address_of`)."""
        return self.address_of()

    @property
    def host(self) -> str:
        return self.address[0]

    @property
    def port(self) -> int:
        return self.address[1]

    @property
    def stdout(self) -> str:
        return self._out.text if self._out else ""

    @property
    def stderr(self) -> str:
        return self._err.text if self._err else ""


@contextlib.contextmanager
def closed_udp_port() -> Iterator[int]:
    """A UDP port on 127.0.0.1 that nothing listens on, and nothing can take while the block runs.

    The port is held by a socket bound to 127.0.0.2 (also loopback): a datagram to 127.0.0.1:PORT matches no socket
    and bounces (ICMP port unreachable), yet neither a port-0 bind nor a wildcard bind can be given the port
    meanwhile - unlike probing a free port and closing it, which races with every other process on the machine.
    """
    guard = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        guard.bind(("127.0.0.2", 0))
        yield guard.getsockname()[1]
    finally:
        guard.close()


class LossyUdpRelay:
    """A UDP relay on 127.0.0.1 that loses, duplicates and delays datagrams, for clients under a bad link.

    ``LossyUdpRelay(("127.0.0.1", server_port), loss=0.2, dup=0.2, delay=0.1, seed=1)`` as a context
    manager: clients send to ``relay.port``; each datagram (either way) is lost with probability ``loss``,
    else sent once more with probability ``dup`` and held back ``0..delay`` s (so a duplicate or a late
    datagram can arrive after the next request); ``dup_requests=False`` duplicates only replies (a client
    cannot stop a network from delivering its one request twice). Each client gets its own socket towards the server, so
    late replies go back to the client that asked, as a real gateway's would. One thread, seeded,
    loopback only; ``stats`` counts what it did.
    """

    def __init__(self, server: tuple[str, int], *, loss: float = 0.0, dup: float = 0.0, delay: float = 0.0,
                 seed: int = 0, dup_requests: bool = True) -> None:
        import random

        self.server = server
        self.loss, self.dup, self.delay = loss, dup, delay
        self.dup_requests = dup_requests
        self.rng = random.Random(seed)
        self.stats = {"forwarded": 0, "lost": 0, "duplicated": 0}
        self._front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._front.bind(("127.0.0.1", 0))
        self.port = self._front.getsockname()[1]
        self._backs: dict[tuple[str, int], socket.socket] = {}
        self._clients: dict[socket.socket, tuple[str, int]] = {}
        self._pending: list[tuple[float, socket.socket, bytes, tuple[str, int]]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lossy-relay", daemon=True)

    def __enter__(self) -> "LossyUdpRelay":
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self._front.close()
        for sock in self._backs.values():
            sock.close()

    def _back(self, client: tuple[str, int]) -> socket.socket:
        sock = self._backs.get(client)
        if sock is None:
            sock = self._backs[client] = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.bind(("127.0.0.1", 0))
            self._clients[sock] = client
        return sock

    def _schedule(self, sock: socket.socket, data: bytes, to: tuple[str, int], request: bool) -> None:
        if self.rng.random() < self.loss:
            self.stats["lost"] += 1
            return
        copies = 2 if self.rng.random() < self.dup and (self.dup_requests or not request) else 1
        self.stats["duplicated"] += copies - 1
        for _ in range(copies):
            self._pending.append((time.monotonic() + self.rng.uniform(0, self.delay), sock, data, to))

    def _run(self) -> None:
        import select

        while not self._stop.is_set():
            now = time.monotonic()
            due = [p for p in self._pending if p[0] <= now]
            self._pending = [p for p in self._pending if p[0] > now]
            for _at, sock, data, to in due:
                with contextlib.suppress(OSError):
                    sock.sendto(data, to)
                    self.stats["forwarded"] += 1
            wait = min([p[0] for p in self._pending], default=now + 0.05) - now
            ready, _, _ = select.select([self._front, *self._clients], [], [], max(0.0, min(wait, 0.05)))
            for sock in ready:
                try:
                    data, peer = sock.recvfrom(65535)
                except OSError:
                    continue
                if sock is self._front:
                    self._schedule(self._back(peer), data, self.server, True)
                else:
                    self._schedule(self._front, data, self._clients[sock], False)


def run_akdctl_tty(*args: str, env: dict[str, str] | None = None, timeout: float = 60, columns: int = 120,
                   stdin_tty: bool = True, interrupt_when: Callable[[str], bool] | None = None) -> CliResult:
    """The real CLI with stdout and stderr on a pseudo-terminal (``isatty()`` is true: rich, live views, prompts).

    Both streams share the terminal, as on a technician's screen: ``out`` is everything the terminal received
    (``\\r\\n`` line ends turned into ``\\n``), ``err`` is empty. stdin is the terminal too unless *stdin_tty* is
    false (then it is empty, so a prompt cannot wait). *interrupt_when* (the output so far -> bool) sends SIGINT
    once it holds, as Ctrl-C would (``status --watch``). The run ends within *timeout* seconds or is killed.
    """
    import pty
    import select
    import signal
    import struct
    import termios
    import fcntl

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, columns, 0, 0))
    full = akdctl_env({"TERM": "xterm-256color", "COLUMNS": str(columns), **(env or {})})
    full.pop("NO_COLOR", None)
    proc = subprocess.Popen(_argv(args, None), stdin=slave if stdin_tty else subprocess.DEVNULL, stdout=slave,
                            stderr=slave, env=full, cwd=ROOT, close_fds=True, start_new_session=True)
    os.close(slave)
    chunks: list[bytes] = []
    deadline = time.monotonic() + timeout
    try:
        while True:
            if time.monotonic() > deadline:
                proc.kill()
                raise subprocess.TimeoutExpired(proc.args, timeout)
            ready, _, _ = select.select([master], [], [], 0.1)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:  # EIO: the last writer closed the terminal
                    data = b""
                if not data:
                    break
                chunks.append(data)
                if interrupt_when is not None and interrupt_when(b"".join(chunks).decode("utf-8", "replace")):
                    interrupt_when = None
                    proc.send_signal(signal.SIGINT)
            elif proc.poll() is not None:
                # drain what is left without blocking, then stop
                while select.select([master], [], [], 0)[0]:
                    try:
                        data = os.read(master, 65536)
                    except OSError:
                        data = b""
                    if not data:
                        break
                    chunks.append(data)
                break
        code = proc.wait(timeout=max(0.1, deadline - time.monotonic()))
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    text = b"".join(chunks).decode("utf-8", "replace").replace("\r\n", "\n")
    return CliResult(code, text, "")


def live_descendants(pid: int | None = None) -> dict[int, str]:
    """Processes still running below *pid* (default: this one), as ``{pid: command line}``; zombies are left out
    (they have ended, their parent merely has not read the exit status yet).

    Why: a test that started a server or a CLI run must stop it; the session checks this once at its end
    (conftest ``nothing_left_behind``), so a leaked process fails the run instead of lingering on the machine."""
    parents: dict[int, list[int]] = {}
    states: dict[int, str] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue  # ended while we looked
        fields = stat[stat.rfind(")") + 2:].split()
        child = int(entry.name)
        states[child] = fields[0]
        parents.setdefault(int(fields[1]), []).append(child)
    found: dict[int, str] = {}
    todo = list(parents.get(os.getpid() if pid is None else pid, []))
    while todo:
        child = todo.pop()
        todo.extend(parents.get(child, []))
        if states.get(child) == "Z":
            continue
        try:
            cmdline = (Path("/proc") / str(child) / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        found[child] = cmdline.strip()
    return found


def run_akdctl_inproc(*args: str, input: str = "") -> CliResult:
    """The CLI's entry point (``akdctl.cli.main.main``) run in this process, with stdin *input* (not a terminal) and
    stdout/stderr captured, like :func:`run_akdctl` but without starting an interpreter.

    Why: a test's *preparation* (``sim reset``, ``sim speed``, ``enable``, ``home``) is not what it tests, and one
    subprocess costs a cold start (~0.3 s CPU); run it here and keep the subprocess for the runs under test.  Same
    environment (the test's ``AKDCTL_STATE_DIR``), so a later subprocess sees what this run left on the drive."""
    from click.testing import CliRunner

    from akdctl.cli.main import main

    with CliRunner().isolation(input=input) as (out, err, _):
        try:
            main(list(args))
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        sys.stdout.flush()
        sys.stderr.flush()
        out_text, err_text = out.getvalue().decode(errors="replace"), err.getvalue().decode(errors="replace")
    return CliResult(code, out_text, err_text)
