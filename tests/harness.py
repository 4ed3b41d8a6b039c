"""The one place tests start akdctl processes: the CLI runner, the simulator server and loopback namespaces.

Why one place: every end-to-end test needs the same four guarantees, and hand-rolled copies kept losing one of them:

* **no hang** - every wait has a deadline: the server's ready line is read by a reader thread and waited for with a
  timeout (never a bare ``readline()``), CLI runs carry ``timeout=``, stopping a server waits and then kills;
* **no port race** - a UDP face binds port 0 itself and the harness parses the bound ``host:port`` from its
  ``listening:`` line, instead of probing a free port and hoping nobody takes it before the server binds it;
* **no packet off the machine** - anything that multicasts runs in a :class:`LoopbackNetns` (only ``lo`` up, a
  multicast route on ``lo``) that the test creates and removes, even when the test fails;
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
import ipaddress
import os
import re
import socket
import subprocess
import sys
import threading
import time
import uuid
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
               netns: str | None = None, prefix: Sequence[str] = ()) -> CliResult:
    """The real CLI (``python -m akdctl ARGS``) in a subprocess, to completion or *timeout* seconds.

    stdin is *input* or empty (never the terminal pytest runs in), so a prompt cannot wait forever; *netns* runs it
    inside that network namespace; *prefix* is a command that runs it (e.g. ``setpriv`` to drop privileges).
    """
    proc = subprocess.run(_argv(args, netns, prefix), input=input if input is not None else "", capture_output=True,
                          text=True, env=akdctl_env(env), timeout=timeout, cwd=ROOT)
    return CliResult(proc.returncode, proc.stdout, proc.stderr)


def start_akdctl(*args: str, env: dict[str, str] | None = None, netns: str | None = None) -> subprocess.Popen[str]:
    """The real CLI started in the background (a move to interrupt, a lock to take meanwhile); end it with
    :func:`finish`."""
    return subprocess.Popen(_argv(args, netns), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, text=True, env=akdctl_env(env), cwd=ROOT)


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


def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30, check=True)


class LoopbackNetns:
    """A network namespace with only ``lo`` (up, with a multicast route), so multicast never reaches a real NIC.

    Needs root (tests using it carry ``@pytest.mark.root``).  Removed on exit even when the test failed; a name is
    unique per instance so parallel runs do not collide.  ``created`` lists every namespace made in this process,
    so a test can check that a fixture really made one.
    """

    created: list[str] = []

    def __init__(self, prefix: str = "akdt") -> None:
        self.name = f"{prefix}{uuid.uuid4().hex[:8]}"

    def __enter__(self) -> LoopbackNetns:
        _ip("netns", "add", self.name)
        try:
            _ip("-n", self.name, "link", "set", "lo", "up")
            _ip("-n", self.name, "route", "add", "224.0.0.0/4", "dev", "lo")
        except BaseException:
            self.delete()
            raise
        LoopbackNetns.created.append(self.name)
        return self

    def __exit__(self, *exc: object) -> None:
        self.delete()

    def delete(self) -> None:
        subprocess.run(["ip", "netns", "delete", self.name], capture_output=True, timeout=30)

    @property
    def path(self) -> Path:
        return Path("/run/netns") / self.name

    def links(self) -> list[str]:
        """Names of the network interfaces inside the namespace."""
        out = _ip("-n", self.name, "-o", "link", "show").stdout
        return [line.split(":")[1].strip() for line in out.splitlines()]

    def holds(self, pid: int) -> bool:
        """Whether process *pid* runs in this namespace (same inode as the namespace's bind mount)."""
        ns = os.stat(f"/proc/{pid}/ns/net")
        mine = os.stat(self.path)
        return (ns.st_dev, ns.st_ino) == (mine.st_dev, mine.st_ino)


def _is_address(host: str) -> bool:
    try:
        ipaddress.ip_address(host.split("%")[0])
    except ValueError:
        return False
    return True


def _local_host(host: str) -> bool:
    """Whether *host* stays on this machine: a loopback address or ``localhost``; any other name means DNS."""
    return host == "localhost" or (_is_address(host) and ipaddress.ip_address(host.split("%")[0]).is_loopback)


class Watch:
    """What tests do behind their backs, seen through PEP 578 audit events: subprocesses started, and in-process
    sockets aimed off the machine (a non-loopback connect or send, a name lookup, a bind to every interface).

    conftest installs the hook once per session (audit hooks cannot be removed) and checks the lists after every
    test.  Subprocesses are not seen inside; the harness gives them loopback targets or a namespace.
    """

    started: list[str] = []
    off_machine: list[str] = []
    installed = False
    _SOCKET_EVENTS = frozenset({"socket.connect", "socket.sendto", "socket.sendmsg", "socket.bind"})

    @staticmethod
    def classify(event: str, args: tuple) -> str | None:  # type: ignore[type-arg]
        """Why this audit event leaves the machine, or None when it stays on it (or is no network event)."""
        if event in Watch._SOCKET_EVENTS:
            sock, address = args[0], args[1]
            if getattr(sock, "family", None) not in (socket.AF_INET, socket.AF_INET6) or not isinstance(address, tuple):
                return None  # AF_UNIX paths, raw AF_PACKET/AF_CAN links: no IP route out
            host = str(address[0])
            if event == "socket.bind":
                return f"bind to every interface {address}" if host in ("", "0.0.0.0", "::") else None
            return None if _local_host(host) else f"{event} {address}"
        if event == "socket.getaddrinfo" and args[0] is not None:
            host = args[0].decode() if isinstance(args[0], bytes) else str(args[0])
            if not _is_address(host) and not _local_host(host):  # a literal address is parsed, not looked up
                return f"name lookup {host!r}"
        return None

    @classmethod
    def install(cls) -> None:
        if cls.installed:
            return
        cls.installed = True

        def hook(event: str, args: tuple) -> None:  # type: ignore[type-arg]
            if event == "subprocess.Popen":
                cls.started.append(str(args[0]))
            elif event.startswith("socket."):
                why = cls.classify(event, args)
                if why:
                    cls.off_machine.append(why)

        sys.addaudithook(hook)


class VethPair:
    """Two network namespaces joined by a veth pair - a private wire for raw Ethernet (EtherCAT, DCP) - with ``lo``
    up in both; ready once both ends carry frames.  Side ``a`` (``if_a``) is the client's, ``b`` (``if_b``) the
    device's; *address_a*/*address_b* give the ends IPv4 addresses (``10.77.0.2/24``).  Needs root; removed on exit
    even when the test failed (deleting a namespace deletes its end, and so the pair)."""

    def __init__(self, address_a: str | None = None, address_b: str | None = None) -> None:
        tag = uuid.uuid4().hex[:6]
        self.a, self.b = f"akdA{tag}", f"akdB{tag}"
        self.if_a, self.if_b = f"ea{tag}", f"eb{tag}"
        self.addresses = {self.a: address_a, self.b: address_b}

    def __enter__(self) -> VethPair:
        try:
            _ip("netns", "add", self.a)
            _ip("netns", "add", self.b)
            _ip("link", "add", self.if_a, "type", "veth", "peer", "name", self.if_b)
            for ns, ifname in ((self.a, self.if_a), (self.b, self.if_b)):
                _ip("link", "set", ifname, "netns", ns)
                if self.addresses[ns]:
                    _ip("-n", ns, "addr", "add", str(self.addresses[ns]), "dev", ifname)
                _ip("-n", ns, "link", "set", ifname, "up")
                _ip("-n", ns, "link", "set", "lo", "up")
            wait_until(self.is_up, "both veth ends to carry frames", timeout=10)
        except BaseException:
            self.delete()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.delete()

    def delete(self) -> None:
        for ns in (self.a, self.b):
            subprocess.run(["ip", "netns", "delete", ns], capture_output=True, timeout=30)
        subprocess.run(["ip", "link", "delete", self.if_a], capture_output=True, timeout=30)  # if never moved

    def is_up(self) -> bool:
        """Whether both ends report operstate UP (a frame sent earlier may be lost)."""
        return all("state UP" in _ip("-n", ns, "-o", "link", "show", "dev", ifname).stdout
                   for ns, ifname in ((self.a, self.if_a), (self.b, self.if_b)))
