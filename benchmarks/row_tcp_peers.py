"""What the Modbus and ASCII-channel peer rows share: a worker process running a script of the row's own, and
an interleaved comparison of akdctl against one peer (plus optional yardsticks) that reports a crashed worker as
a row instead of crashing the run.

Why not :mod:`row_peers` as it is: its worker script holds the CANopen and CIP clients; these rows bring their own
script (the clients they compare) and otherwise follow the same protocol (``ready``, then one ``wall cpu`` line
per block of N operations, **process** CPU so every thread of the client counts), so the measuring rule is the
one :class:`row_peers.Worker` and :func:`benchlib.interleave` already implement.
"""

from __future__ import annotations

from benchlib import Result, Settings, comparison_cpu, fmt_ratio, fmt_us, interleave
from row_peers import Worker

# The block loop every script ends with (``op`` is the one operation; it raises on a wrong answer).
BLOCK_LOOP = r"""
op()
print("ready", flush=True)
for line in sys.stdin:
    n = int(line)
    c0, t0 = time.process_time(), time.perf_counter()
    for _ in range(n):
        op()
    print(time.perf_counter() - t0, time.process_time() - c0, flush=True)
"""


class ScriptWorker(Worker):
    """A :class:`row_peers.Worker` running ``script`` (which defines ``op`` for ``kind``) instead of the CANopen/CIP
    worker."""

    def __init__(self, script: str, kind: str, where: str) -> None:
        super().__init__(kind, where, script=script + BLOCK_LOOP)


def compare(script: str, where: dict[str, str], s: Settings, n: int, *, peer: str, yardsticks: tuple[str, ...] = (),
            speed_goal: float = 1.0, cpu_goal: bool = False) -> Result:
    """akdctl (kind ``akdctl``) against ``peer`` and any ``yardsticks`` (names of kinds in ``script``), each in its
    own worker, in interleaved blocks of ``n`` operations; pass when ours is ``speed_goal`` x the peer's ops/s or
    better (and, with ``cpu_goal``, its client CPU per op no more than the peer's: the CPU ratio is shown either
    way). A worker that does not start or dies is the row's value (``<kind> crashed``), not an exception.

    Every client worker starts on one CPU, and the server too (the row starts it through
    :func:`benchlib.started_on_comparison_cpu`): :func:`benchlib.comparison_cpu` says why.
    Measured both ways for ascii: the server pinned across CPUs gave 1.01-1.04x, on the clients' CPU 1.06-1.08x."""
    kinds = ("akdctl", peer, *yardsticks)
    workers: list[ScriptWorker] = []
    try:
        try:
            with comparison_cpu():  # every client on one CPU: see compare's docstring
                for kind in kinds:
                    workers.append(ScriptWorker(script, kind, where[kind]))
            run = interleave(*(lambda w=w: w.sample(n) for w in workers), rounds=s.rounds)
        except RuntimeError as exc:
            failed = next((k for k in kinds if str(exc).startswith(k + " ")), "a worker")
            return Result(f"{failed} crashed", False, [str(exc)[:400]])
    finally:
        for worker in workers:
            worker.stop()
    speed = run.ratio(1, 0)  # the peer's time per op / ours = our ops/s / the peer's
    cpu = run.ratio(0, 1, key=lambda x: x.cpu_us)
    ok = speed >= speed_goal and (cpu <= 1.0 or not cpu_goal)
    per_op = [f"{kind} {fmt_us(run.median(k))} wall, {fmt_us(run.median(k, lambda x: x.cpu_us))} CPU"
              for k, kind in enumerate(kinds)]
    notes = [f"per op: {'; '.join(per_op)} (process CPU, all threads)"]
    figures: dict[str, float | None] = {"speed_ratio": speed, "cpu_ratio": cpu}
    for k, kind in enumerate(yardsticks, start=2):
        figures[f"speed_ratio_{kind}"] = run.ratio(k, 0)
        notes.append(f"yardstick {kind}: ours {fmt_ratio(run.ratio(k, 0))}× its ops/s, client CPU "
                     f"{fmt_ratio(run.ratio(0, k, key=lambda x: x.cpu_us))}× its")
    return Result(f"{fmt_ratio(speed)}× ops/s, client CPU {fmt_ratio(cpu)}× the peer's", ok, notes, figures)
