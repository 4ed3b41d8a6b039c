"""The processes a benchmark talks to: the bare UDP echo, canned-reply yardsticks and the simulator.

Why separate processes: a server in the client's process would share its interpreter lock and its CPU clock, so
neither the client's CPU per request nor the server's could be told apart. Every server here runs in its own
process; the client side runs in the benchmark's process, where ``time.thread_time`` is the client's CPU alone.

* :func:`udp_echo` - the baseline: a bare Python UDP request/response loop, what one round trip costs at all;
* :func:`canned` - the client's yardstick: a server that answers from replies it learnt from the real simulator
  (forwarding each new kind of request once), patching only the fields the client checks (ETG.8200: the mailbox
  counter; PNIO: activity, sequence numbers and the PROFIdrive request reference). It costs about what the echo
  costs, so the client's share of a round trip shows without the simulator's;
* :func:`sim_server` - ``akdctl sim serve`` through the measured tree's ``tests.harness.SimServer`` (deadlines,
  ready lines, port 0, clean stop in one place), with :class:`~benchlib.ProcessCpu` on its process.
"""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
from collections.abc import Iterator

from benchlib import ProcessCpu, akdctl_env, measured_tree_importable

UDP_ECHO = r"""
import socket
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1], flush=True)
while True:
    data, peer = s.recvfrom(65535)
    s.sendto(data, peer)
"""

# argv: mode (ecat|pnio) upstream-host upstream-port. Answers b"STATS" with "canned forwarded".
CANNED = r"""
import socket, struct, sys
mode, host, port = sys.argv[1], sys.argv[2], int(sys.argv[3])
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 0))
up = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
up.connect((host, port))
up.settimeout(5)
print(s.getsockname()[1], flush=True)
cache, stats, last_write = {}, [0, 0], [b""]

def ecat_key(d):
    return None if len(d) < 8 else d[:7] + bytes([d[7] & 0x8F]) + d[8:]

def ecat_patch(r, d):
    r = bytearray(r)
    r[7] = (r[7] & 0x8F) | (d[7] & 0x70)
    return r

def pn_opnum(d):
    return struct.unpack_from("<H" if d[4] >> 4 else ">H", d, 68)[0] if len(d) >= 80 else None

def pn_key(d):
    op = pn_opnum(d)
    if op == 3 and len(d) > 164:
        last_write[0] = d
        return (3, len(d))
    if op == 2 and len(d) >= 136:
        return (2, d[134:136], len(last_write[0]))
    return None

def pn_patch(r, d):
    r = bytearray(r)
    r[40:56], r[64:68], r[106:108] = d[40:56], d[64:68], d[106:108]
    if pn_opnum(d) == 2 and len(r) > 164 and last_write[0]:
        r[164] = last_write[0][164]
    return r

def pn_learnable(key, r, d):
    if len(r) < 108 or r[4] != d[4]:
        return False
    return key[0] != 2 or (len(r) > 164 and bool(last_write[0]) and r[164] == last_write[0][164])

key_of, patch = (ecat_key, ecat_patch) if mode == "ecat" else (pn_key, pn_patch)
learnable = (lambda k, r, d: True) if mode == "ecat" else pn_learnable
while True:
    data, peer = s.recvfrom(65535)
    if data == b"STATS":
        s.sendto(f"{stats[0]} {stats[1]}".encode(), peer)
        continue
    key = key_of(data)
    reply = cache.get(key) if key is not None else None
    if reply is not None:
        s.sendto(patch(reply, data), peer)
        stats[0] += 1
        continue
    up.send(data)
    try:
        reply = up.recv(65535)
    except socket.timeout:
        continue
    stats[1] += 1
    if key is not None and learnable(key, reply, data):
        cache[key] = reply
    s.sendto(reply, peer)
"""


class Proc:
    """A helper process that prints its UDP port first; ``cpu`` reads its CPU time."""

    def __init__(self, argv: list[str]) -> None:
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True,
                                     env=akdctl_env())
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()  # these scripts print their port at once or die (EOF)
        if not line.strip().isdigit():
            self.stop()
            raise RuntimeError(f"helper {argv[-1][:40]!r} did not start")
        self.port = int(line)
        self.cpu = ProcessCpu(self.proc.pid)

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


@contextlib.contextmanager
def udp_echo() -> Iterator[Proc]:
    proc = Proc([sys.executable, "-c", UDP_ECHO])
    try:
        yield proc
    finally:
        proc.stop()


@contextlib.contextmanager
def canned(mode: str, host: str, port: int) -> Iterator[Proc]:
    """A canned-reply server in front of ``host:port`` (``mode`` ``ecat`` or ``pnio``)."""
    proc = Proc([sys.executable, "-c", CANNED, mode, host, str(port)])
    try:
        yield proc
    finally:
        proc.stop()


def canned_stats(proc: Proc) -> tuple[int, int]:
    """(answered from the cache, forwarded to the simulator) so far."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.settimeout(2)
        s.sendto(b"STATS", ("127.0.0.1", proc.port))
        canned_n, forwarded = s.recv(100).split()
    return int(canned_n), int(forwarded)


class EchoClient:
    """The bare round trip: send ``size`` bytes, receive the echo."""

    def __init__(self, port: int, size: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.connect(("127.0.0.1", port))
        self.sock.settimeout(2)
        self.payload = bytes(size)

    def __call__(self) -> None:
        self.sock.send(self.payload)
        self.sock.recv(65535)

    def close(self) -> None:
        self.sock.close()


def _harness():  # noqa: ANN202 - the measured tree's tests.harness module
    measured_tree_importable()
    from tests import harness

    return harness


@contextlib.contextmanager
def sim_server(*face_args: str, faces: int = 1, env: dict[str, str] | None = None,
               netns: str | None = None, duration: float = 900) -> Iterator[object]:
    """``akdctl sim serve FACE-ARGS`` (ready, ports parsed); ``server.cpu`` is its :class:`ProcessCpu`."""
    harness = _harness()
    server = harness.SimServer(*face_args, faces=faces, env=env, netns=netns, duration=duration)
    server.start()
    try:
        server.cpu = ProcessCpu(server.pid)
        yield server
    finally:
        server.stop()
