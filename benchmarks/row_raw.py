"""Row: our raw EtherCAT master (``ecat://``) against pysoem (SOEM), SDO uploads on the same simulated slave.

Set-up (root only): two veth pairs from the measured tree's ``tests.netns.VethPair``, each with ``akdctl sim serve
--ethercat-raw`` on its device end (the same simulated AKD slave: same code, factory state, its own drive name so
neither waits for the other's lock). One worker process per master sits in its client namespace for the whole run
and uploads 0x1018:01 in blocks when told; the blocks alternate (ours, pysoem, ours, ...). Two wires instead of
one, because two masters on one wire would each see the other's frames and reconfigure the one slave.

Frames per upload are the client interface's ``tx_packets`` over the block, counted in the worker's namespace.
"""

from __future__ import annotations

import os
import subprocess
import sys

from benchlib import Result, Sample, Settings, akdctl_env, akdctl_root, fmt_ratio, fmt_us, interleave

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


class Worker:
    """One master in its own process inside a namespace, driven block by block over its stdin."""

    def __init__(self, kind: str, netns: str, ifname: str) -> None:
        self.proc = subprocess.Popen(["ip", "netns", "exec", netns, sys.executable, "-c", WORKER, kind, ifname],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, env=akdctl_env())
        assert self.proc.stdout is not None
        if self.proc.stdout.readline().strip() != "ready":
            err = self.proc.stderr.read() if self.proc.stderr else ""
            self.stop()
            raise RuntimeError(f"{kind} master did not start: {err.strip()[-300:]}")

    def block(self, n: int) -> Sample:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(f"{n}\n")
        self.proc.stdin.flush()
        wall, cpu, frames = self.proc.stdout.readline().split()
        return Sample(n, float(wall), float(cpu), extra={"frames": int(frames) / n})

    def stop(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def raw_vs_pysoem(s: Settings) -> Result:
    if os.geteuid() != 0:
        return Result("skipped", None, ["needs root (network namespaces and raw sockets); run as root"])
    try:
        import pysoem  # noqa: F401
    except ImportError:
        return Result("skipped", None, ["pysoem is not installed (the optional extra akdctl[soem])"])
    root = str(akdctl_root())
    if root not in sys.path:
        sys.path.insert(0, root)
    from servers import sim_server
    from tests.netns import VethPair

    env = {"AKDCTL_STATE_DIR": str(s.tmp / "raw")}
    n = s.block
    with VethPair() as ours_wire, VethPair() as soem_wire, \
            sim_server("--name", "rawA", "--ethercat-raw", ours_wire.if_b, env=env, netns=ours_wire.b), \
            sim_server("--name", "rawB", "--ethercat-raw", soem_wire.if_b, env=env, netns=soem_wire.b):
        ours = Worker("ours", ours_wire.a, ours_wire.if_a)
        try:
            soem = Worker("pysoem", soem_wire.a, soem_wire.if_a)
            try:
                run = interleave(lambda: ours.block(n), lambda: soem.block(n), rounds=s.rounds)
            finally:
                soem.stop()
        finally:
            ours.stop()
    speed = run.ratio(1, 0)  # pysoem's time per upload / ours = our uploads/s / pysoem's
    frames_ours = run.median(0, lambda x: x.extra["frames"])
    frames_soem = run.median(1, lambda x: x.extra["frames"])
    assert frames_ours is not None and frames_soem is not None
    ok = speed >= 1.2 and frames_ours <= frames_soem
    return Result(f"{fmt_ratio(speed)}×, frames {frames_ours:.2g} vs {frames_soem:.2g}", ok, [
        f"per upload: ours {fmt_us(run.median(0))} wall, {fmt_us(run.median(0, lambda x: x.cpu_us))} CPU; pysoem "
        f"{fmt_us(run.median(1))} wall, {fmt_us(run.median(1, lambda x: x.cpu_us))} CPU (client side)"],
        {"speed_ratio": speed, "frames_ours": frames_ours, "frames_pysoem": frames_soem})
