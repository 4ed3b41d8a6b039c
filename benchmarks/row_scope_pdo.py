"""Row: the scope's pdo source, client CPU per recorded bus cycle, against a polled sample of the same object on the
same slave (the baseline: what ``--source poll`` pays per sample over ``ecat://``) and against pysoem's cyclic
exchange (the peer: SOEM in C, send/receive_processdata).

Set-up (root only), as row_raw: two veth pairs from the measured tree's ``tests.netns.VethPair``, each with ``akdctl
sim serve --ethercat-raw`` on its device end. Our worker sits in its namespace and keeps the slave in SAFE-OP
(drive/scope_pdo_bus.BusInputs, entered once) and, per block, records N cycles with ``scope_pdo.record`` (the
TxPDO 0x1B01: 0x6063 and the status word) or polls N samples of 0x6063 with the poll source's Sampler; pysoem's
worker maps, goes to SAFE-OP and exchanges N cycles. No pacing: the cycle is 250 us, shorter than one exchange, so
every block runs as fast as the wire answers and the CPU per cycle is the figure (``time.thread_time``).
The blocks alternate: pdo, poll, pysoem, pdo, ...
"""

from __future__ import annotations

import sys

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
    fmt_ratio,
    fmt_us,
    interleave,
)

# argv: kind (ours|pysoem) ifname. Reads "pdo N" / "poll N" / "soem N" per line, answers "wall cpu" per block.
WORKER = r"""
import struct, sys, time
kind, ifname = sys.argv[1], sys.argv[2]
if kind == "ours":
    from akdctl.connection import Connection
    from akdctl.drive import scope as op
    from akdctl.drive import scope_pdo
    from akdctl.drive.scope_model import Recording
    from akdctl.drive.scope_pdo_bus import BusInputs
    from akdctl.drive.scope_signals import Sampler
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target
    conn = Connection(parse_target("ecat://" + ifname + "/0"), LinkOptions(timeout=1.0))
    plan = op.plan(conn, op.build_request(["0x6063", "STATUSWORD"], source="pdo", rate_hz=4000.0, samples=2))
    spec, trigger = plan.data["pdo"], plan.data["trigger"]
    polled = op.plan(conn, op.build_request(["0x6063"], source="poll", samples=2))
    sampler = polled.data["sampler"]
    bus = BusInputs(conn.process_data(spec.rx.bytes, spec.tx.bytes), spec.cycle_s)
    bus.__enter__()
    def work(what, n):
        if what == "pdo":
            spec.cycles = n
            recording = Recording("bench", "pdo", [c.channel for c in spec.columns[:spec.width]])
            scope_pdo.record(bus, spec, recording, trigger, stopped=lambda: False, timeout_s=1.0)
            assert len(recording) > 0
        else:
            for _ in range(n):
                sampler.read()
else:
    import pysoem
    master = pysoem.Master()
    master.open(ifname)
    if master.config_init() < 1:
        raise SystemExit("pysoem found no slave")
    master.config_map()
    master.state = pysoem.SAFEOP_STATE
    master.write_state()
    if master.state_check(pysoem.SAFEOP_STATE, 2_000_000) != pysoem.SAFEOP_STATE:
        raise SystemExit("pysoem: the slave did not reach SAFE-OP")
    slave = master.slaves[0]
    def work(what, n):
        for _ in range(n):
            master.send_processdata()
            master.receive_processdata(2000)
            struct.unpack_from("<iH", slave.input)
work("pdo" if kind == "ours" else "soem", 10)
print("ready", flush=True)
for line in sys.stdin:
    what, n = line.split()
    c0, t0 = time.thread_time(), time.perf_counter()
    work(what, int(n))
    print(time.perf_counter() - t0, time.thread_time() - c0, flush=True)
if kind == "ours":
    bus.__exit__(None, None, None)
    conn.close()
else:
    master.state = pysoem.PREOP_STATE
    master.write_state()
    master.close()
"""


class Worker(BlockWorker):
    """One master in its own process inside a namespace, driven block by block over its stdin
    (:class:`benchlib.BlockWorker`: every wait bounded, a dead master a :class:`benchlib.WorkerDied`)."""

    def __init__(self, kind: str, netns: str, ifname: str) -> None:
        super().__init__(kind, ["ip", "netns", "exec", netns, sys.executable, "-c", WORKER, kind, ifname],
                         env=akdctl_env(), cwd=str(akdctl_root()))

    def sample(self, what: str, n: int) -> Sample:
        wall, cpu = self.block(f"{what} {n}")
        return Sample(n, wall, cpu)


def scope_pdo_cpu(s: Settings) -> Result:
    skipped = cannot_run("pysoem", root_for="network namespaces and raw sockets",
                         install="the optional extra akdctl[soem]")
    if skipped is not None:
        return skipped
    from servers import sim_server

    from tests.netns import VethPair

    env = {"AKDCTL_STATE_DIR": str(s.tmp / "scope-pdo")}
    n = s.block
    with VethPair() as ours_wire, VethPair() as soem_wire, \
            sim_server("--name", "pdoA", "--ethercat-raw", ours_wire.if_b, env=env, netns=ours_wire.b), \
            sim_server("--name", "pdoB", "--ethercat-raw", soem_wire.if_b, env=env, netns=soem_wire.b):
        ours = Worker("ours", ours_wire.a, ours_wire.if_a)
        try:
            soem = Worker("pysoem", soem_wire.a, soem_wire.if_a)
            try:
                run: Interleaved = interleave(lambda: ours.sample("pdo", n), lambda: ours.sample("poll", n),
                                              lambda: soem.sample("soem", n), rounds=s.rounds)
            except WorkerDied as exc:  # a crashed master is the row's value, not a crash of the run
                return Result(str(exc), False, [f"{exc.kind} ended mid-run; its last words: {exc.last_words}"])
            finally:
                soem.stop()
        finally:
            ours.stop()
    cpu = lambda x: x.cpu_us  # noqa: E731
    to_poll = run.ratio(0, 1, cpu)
    to_soem = run.ratio(0, 2, cpu)
    return Result(f"{fmt_ratio(to_poll)} of a polled sample", to_poll <= 0.6, [
        f"client CPU: pdo {fmt_us(run.median(0, cpu))} per cycle, poll {fmt_us(run.median(1, cpu))} per sample, "
        f"pysoem {fmt_us(run.median(2, cpu))} per cycle ({fmt_ratio(to_soem)}× pysoem's)",
        f"wall per cycle: pdo {fmt_us(run.median(0))}, pysoem {fmt_us(run.median(2))}"],
        {"pdo_to_poll_cpu": to_poll, "pdo_to_pysoem_cpu": to_soem, "pdo_cpu_us": run.median(0, cpu),
         "poll_cpu_us": run.median(1, cpu), "pysoem_cpu_us": run.median(2, cpu)})
