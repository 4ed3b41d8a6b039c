"""Row: our raw EtherCAT master (``ecat://``) against pysoem (SOEM), SDO uploads on the same simulated slave.

Set-up (root only): two veth pairs from the measured tree's ``tests.netns.VethPair``, each with ``akdctl sim serve
--ethercat-raw`` on its device end (the same simulated AKD slave: same code, factory state, its own drive name so
neither waits for the other's lock). Two wires instead of one, because two masters on one wire would each see the
other's frames and reconfigure the one slave.

The row is :data:`RUNS` runs. Each run starts one fresh worker process per master in its client namespace (a
master's set-up, its process placement and its caches are part of what varies between runs: the issue measured
0.98x median but 0.73x worst over 12 separate runs), and they upload 0x1018:01 in interleaved blocks (ours,
pysoem, ours, ...); the masters swap wires from run to run, so neither keeps the quieter server. A run's speed
ratio is the median over its rounds of pysoem's time per upload / ours; the row reports the median and the worst
of the runs' ratios and passes only when the median is >= 1.2, the worst >= 1.0 and our frames per upload are no
more than pysoem's in every run.

Frames per upload are the client interface's ``tx_packets`` over the block, counted in the worker's namespace.
A worker that dies (pysoem gives up an SDO on a slow reply with ``WkcError``; a bogus interface) makes the row
"peer crashed: <its last words>" (or "akdctl crashed: ..."), never a crash of the run.
"""

from __future__ import annotations

import statistics
import sys
from collections.abc import Callable

from benchlib import (
    BlockWorker,
    Interleaved,
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

#: Runs of interleaved blocks, each with fresh workers.
RUNS = 5

# argv: kind (ours|pysoem) ifname. Reads a block size per line, answers "wall cpu frames" per block.
WORKER = r"""
import sys, time
kind, ifname = sys.argv[1], sys.argv[2]
if kind == "ours":
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target
    conn = Connection(parse_target("ecat://" + ifname + "/0"), LinkOptions(timeout=1.0))
    objects = conn.objects()
    upload = lambda: objects.upload(0x1018, 1)
else:
    import pysoem
    master = pysoem.Master()
    master.open(ifname)
    if master.config_init() < 1:
        raise SystemExit("pysoem found no slave")
    slave = master.slaves[0]
    upload = lambda: slave.sdo_read(0x1018, 1)
def tx():
    with open(f"/sys/class/net/{ifname}/statistics/tx_packets") as fh:
        return int(fh.read())
upload()
print("ready", flush=True)
for line in sys.stdin:
    n = int(line)
    f0, c0, t0 = tx(), time.thread_time(), time.perf_counter()
    for _ in range(n):
        upload()
    wall, cpu, frames = time.perf_counter() - t0, time.thread_time() - c0, tx() - f0
    print(wall, cpu, frames, flush=True)
"""

#: What each worker kind is called in the row's value.
NAMES = {"ours": "akdctl", "pysoem": "peer"}


def start_worker(kind: str, ifname: str, netns: str | None = None) -> BlockWorker:
    """One master (``ours`` or ``pysoem``) in its own process, inside ``netns`` when given; WorkerDied if it
    does not come up (its last words say why)."""
    prefix = ["ip", "netns", "exec", netns] if netns else []
    # cwd: ``python -c`` puts the working directory first on sys.path; the measured checkout, not another one
    return BlockWorker(kind, [*prefix, sys.executable, "-c", WORKER, kind, ifname], env=akdctl_env(), fields=3,
                       cwd=str(akdctl_root()))


def block(worker: BlockWorker, n: int) -> Sample:
    wall, cpu, frames = worker.block(n)
    return Sample(n, wall, cpu, extra={"frames": frames / n})


def compare(start_ours: Callable[[int], BlockWorker], start_peer: Callable[[int], BlockWorker], runs: int,
            rounds: int, n: int) -> Result:
    """``runs`` runs of ``rounds`` interleaved blocks of ``n`` uploads, fresh workers per run (``start_*(run)``);
    a dead worker is the row's value, not an exception."""
    done: list[Interleaved] = []
    try:
        for k in range(runs):
            ours = start_ours(k)
            try:
                peer = start_peer(k)
                try:
                    done.append(_run(ours, peer, rounds, n))
                finally:
                    peer.stop()
            finally:
                ours.stop()
    except WorkerDied as exc:
        return Result(f"{NAMES.get(exc.kind, exc.kind)} crashed: {exc.last_words}", False,
                      [f"{exc.kind} worker died in run {len(done) + 1} of {runs}: {exc.last_words}"],
                      {"runs_done": float(len(done))})
    return _verdict(done)


def _run(ours: BlockWorker, peer: BlockWorker, rounds: int, n: int) -> Interleaved:
    return interleave(lambda: block(ours, n), lambda: block(peer, n), rounds=rounds)


def _verdict(done: list[Interleaved]) -> Result:
    speeds = [run.ratio(1, 0) for run in done]  # pysoem's time per upload / ours = our uploads/s / pysoem's
    frames_ours = [run.median(0, lambda x: x.extra["frames"]) or 0.0 for run in done]
    frames_soem = [run.median(1, lambda x: x.extra["frames"]) or 0.0 for run in done]
    median, worst = statistics.median(speeds), min(speeds)
    frames_ok = all(a <= b for a, b in zip(frames_ours, frames_soem))
    ok = median >= 1.2 and worst >= 1.0 and frames_ok
    every = Interleaved(2)
    for run in done:
        every.runs[0] += run.runs[0]
        every.runs[1] += run.runs[1]
    fo, fs = statistics.median(frames_ours), statistics.median(frames_soem)
    return Result(f"{fmt_ratio(median)}× median, {fmt_ratio(worst)}× worst of {len(done)}, frames {fo:.2g} vs {fs:.2g}",
                  ok, [
                      (f"per upload: ours {fmt_us(every.median(0))} wall, "
                       f"{fmt_us(every.median(0, lambda x: x.cpu_us))} CPU; pysoem {fmt_us(every.median(1))} wall, "
                       f"{fmt_us(every.median(1, lambda x: x.cpu_us))} CPU (client side, medians of every block)"),
                      ("speed ratio per run: " + ", ".join(fmt_ratio(x) for x in speeds)
                       + "; frames per run (ours/pysoem): "
                       + ", ".join(f"{a:.2g}/{b:.2g}" for a, b in zip(frames_ours, frames_soem))),
                  ],
                  {"speed_ratio": median, "speed_worst": worst, "frames_ours": fo, "frames_pysoem": fs})


def raw_vs_pysoem(s: Settings) -> Result:
    skipped = cannot_run("pysoem", root_for="network namespaces and raw sockets",
                         install="the optional extra akdctl[soem]")
    if skipped is not None:
        return skipped
    from servers import sim_server

    from tests.netns import VethPair

    env = {"AKDCTL_STATE_DIR": str(s.tmp / "raw")}
    # RUNS runs in about the time one run of s.rounds took: fewer rounds of shorter blocks per run.
    rounds, n = max(3, s.rounds // 2), max(50, s.block * 3 // 4)
    # every process of the comparison on one CPU: benchlib.comparison_cpu says why
    with VethPair() as wire_a, VethPair() as wire_b, started_on_comparison_cpu(
            sim_server("--name", "rawA", "--ethercat-raw", wire_a.if_b, env=env, netns=wire_a.b)), \
            started_on_comparison_cpu(
                sim_server("--name", "rawB", "--ethercat-raw", wire_b.if_b, env=env, netns=wire_b.b)):
        wires = (wire_a, wire_b)

        def ours(k: int) -> BlockWorker:
            wire = wires[k % 2]
            with comparison_cpu():
                return start_worker("ours", wire.if_a, wire.a)

        def peer(k: int) -> BlockWorker:
            wire = wires[(k + 1) % 2]
            with comparison_cpu():
                return start_worker("pysoem", wire.if_a, wire.a)

        return compare(ours, peer, RUNS, rounds, n)
