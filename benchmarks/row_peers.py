"""Rows: akdctl against independent clients doing the same work on the same simulated drive, in the same run.

* ``canopen``: SDO uploads of 0x1018:01 over ``can://`` against python-canopen's own ``node.sdo.upload`` on the
  same bus (python-can's ``udp_multicast`` inside a network namespace the row creates: root only);
* ``cip``: CIP Get_Attribute_Single (Identity 1/1/1) over ``eip://`` against pycomm3's ``generic_message``, both
  to one ``sim serve --ethernetip`` face on loopback.

Each client runs in its own process (a worker), told block by block over its stdin to do N operations; blocks
alternate (ours, peer, ours, ...). A worker answers with the block's wall time and its **process** CPU time, so
receive threads (python-can's notifier, pycomm3 has none) count. A worker that dies makes its row an error row with
the worker's last words; the run goes on.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from benchlib import (
    BlockWorker,
    Result,
    Sample,
    Settings,
    WorkerDied,
    akdctl_env,
    akdctl_root,
    cannot_run,
    comparison_cpu,
    fmt_ratio,
    fmt_us,
    interleave,
    started_on_comparison_cpu,
)

GROUP = "239.74.163.9"
NODE = 3

# argv: kind target-or-address. Reads a block size per line, answers "wall cpu" per block.
WORKER = r"""
import sys, time
kind, where = sys.argv[1], sys.argv[2]
if kind == "akdctl-can":
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target
    conn = Connection(parse_target(where), LinkOptions(timeout=1.0))
    objects = conn.objects()
    op = lambda: objects.upload(0x1018, 1)
elif kind == "python-canopen":
    import canopen
    group, node = where.split("/")
    network = canopen.Network()
    network.connect(interface="udp_multicast", channel=group)
    remote = canopen.RemoteNode(int(node), canopen.ObjectDictionary())
    network.add_node(remote)
    op = lambda: remote.sdo.upload(0x1018, 1)
elif kind == "akdctl-cip":
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target
    conn = Connection(parse_target(where), LinkOptions(timeout=1.0))
    cip = conn.cip()
    op = lambda: cip.get(1, 1, 1)
elif kind == "pycomm3":
    from pycomm3 import CIPDriver, Services
    driver = CIPDriver(where)
    driver.open()
    def op():
        tag = driver.generic_message(service=Services.get_attribute_single, class_code=1, instance=1,
                                     attribute=1, connected=False)
        if tag.error:
            raise SystemExit(f"pycomm3: {tag.error}")
else:
    raise SystemExit(f"unknown worker {kind}")
op()
print("ready", flush=True)
for line in sys.stdin:
    n = int(line)
    c0, t0 = time.process_time(), time.perf_counter()
    for _ in range(n):
        op()
    print(time.perf_counter() - t0, time.process_time() - c0, flush=True)
"""


class Worker(BlockWorker):
    """One client in its own process (inside ``netns`` if given), driven block by block over its stdin
    (:class:`benchlib.BlockWorker`: every wait bounded, a dead worker a :class:`benchlib.WorkerDied`)."""

    def __init__(self, kind: str, where: str, netns: str | None = None, script: str = WORKER) -> None:
        prefix: Sequence[str] = ("ip", "netns", "exec", netns) if netns else ()
        # cwd: ``python -c`` puts the working directory first on sys.path, so a worker started from another
        # checkout would import that checkout's akdctl instead of the measured one
        super().__init__(kind, [*prefix, sys.executable, "-c", script, kind, where], env=akdctl_env(),
                         cwd=str(akdctl_root()))

    def sample(self, n: int) -> Sample:
        wall, cpu = self.block(n)
        return Sample(n, wall, cpu)


def _compare(ours: Worker, peer: Worker, s: Settings, n: int, speed_goal: float, peer_name: str) -> Result:
    try:
        run = interleave(lambda: ours.sample(n), lambda: peer.sample(n), rounds=s.rounds)
    except WorkerDied as exc:  # a crashed client is the row's value, not a crash of the run
        return Result(str(exc), False, [f"{exc.kind} ended mid-run; its last words: {exc.last_words}"])
    finally:
        peer.stop()
        ours.stop()
    speed = run.ratio(1, 0)  # the peer's time per op / ours = our ops/s / the peer's
    cpu = run.ratio(0, 1, key=lambda x: x.cpu_us)
    ok = speed >= speed_goal and cpu <= 1.0
    return Result(f"{fmt_ratio(speed)}× ops/s, client CPU {fmt_ratio(cpu)}× the peer's", ok, [
        f"per op: akdctl {fmt_us(run.median(0))} wall, {fmt_us(run.median(0, lambda x: x.cpu_us))} CPU; "
        f"{peer_name} {fmt_us(run.median(1))} wall, {fmt_us(run.median(1, lambda x: x.cpu_us))} CPU "
        "(process CPU, receive threads included)"], {"speed_ratio": speed, "cpu_ratio": cpu})


def canopen_vs_python_canopen(s: Settings) -> Result:
    skipped = cannot_run("canopen", "msgpack", root_for="a network namespace keeps the multicast bus on this host")
    if skipped is not None:
        return skipped
    from servers import sim_server

    from tests.netns import LoopbackNetns

    env = {"AKDCTL_STATE_DIR": str(s.tmp / "can")}
    with LoopbackNetns("akdb") as netns, started_on_comparison_cpu(
            sim_server("--name", "canpeer", "--can", f"udp_multicast:{GROUP}:{NODE}", env=env, netns=netns.name)):
        with comparison_cpu():  # every process of the comparison on one CPU (benchlib.comparison_cpu says why)
            ours = Worker("akdctl-can", f"can://udp_multicast/{GROUP}/{NODE}", netns.name)
            try:
                peer = Worker("python-canopen", f"{GROUP}/{NODE}", netns.name)
            except BaseException:
                ours.stop()
                raise
        return _compare(ours, peer, s, max(20, s.block // 4), 1.1, "python-canopen")


def cip_vs_pycomm3(s: Settings) -> Result:
    try:
        import pycomm3  # noqa: F401
    except ImportError:
        return Result("skipped", None, ["pycomm3 is not installed (pip install 'akdctl[test]')"])
    import re

    from servers import sim_server

    env = {"AKDCTL_STATE_DIR": str(s.tmp / "cip")}
    with started_on_comparison_cpu(
            sim_server("--name", "cippeer", "--ethernetip", "127.0.0.1:0", "--eip-io-port", "0", env=env)) as server:
        match = re.match(r"ethernetip ([\d.]+):(\d+) ", server.ready[0])
        if match is None:
            raise RuntimeError(f"unexpected ready line {server.ready[0]!r}")
        host, port = match.groups()
        with comparison_cpu():
            ours = Worker("akdctl-cip", f"eip://{host}:{port}")
            try:
                peer = Worker("pycomm3", f"{host}:{port}")
            except BaseException:
                ours.stop()
                raise
        return _compare(ours, peer, s, max(50, s.block // 2), 1.2, "pycomm3")
