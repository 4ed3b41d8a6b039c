"""The benchmark's worker processes: a peer (or our) worker that dies or hangs is a reported row, never a crash or
a hang of the benchmark run (benchmarks/benchlib.BlockWorker, benchmarks/row_raw.compare)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

from benchlib import BlockWorker, WorkerDied

pytestmark = pytest.mark.slow

#: A worker that answers every block with fixed figures (wall cpu frames), standing in for a healthy master.
STEADY = "import sys\nprint('ready', flush=True)\nfor line in sys.stdin:\n    print(0.01, 0.005, 2 * int(line), flush=True)\n"


def worker(kind: str, script: str, **kw: float) -> BlockWorker:
    return BlockWorker(kind, [sys.executable, "-c", script], fields=3, **kw)


def test_a_steady_worker_answers_its_blocks() -> None:
    w = worker("steady", STEADY)
    try:
        assert w.block(5) == [0.01, 0.005, 10.0]
        assert w.block(7) == [0.01, 0.005, 14.0]
    finally:
        w.stop()
    assert w.proc.returncode == 0


def test_a_worker_that_dies_in_a_block_says_its_last_words() -> None:
    script = "import sys\nprint('ready', flush=True)\nsys.stdin.readline()\nraise SystemExit('WkcError: bus gone')\n"
    w = worker("pysoem", script)
    with pytest.raises(WorkerDied) as info:
        w.block(10)
    assert info.value.kind == "pysoem"
    assert info.value.last_words == "WkcError: bus gone"
    assert w.proc.returncode is not None


def test_a_worker_that_answers_nonsense_is_dead_not_a_value_error() -> None:
    w = worker("odd", "import sys\nprint('ready', flush=True)\nsys.stdin.readline()\nprint('1 2', flush=True)\n"
                      "sys.stdin.readline()\n")
    with pytest.raises(WorkerDied, match="answered '1 2'"):
        w.block(1)


def test_a_hanging_worker_is_killed_after_its_timeout() -> None:
    script = "import sys, time\nprint('ready', flush=True)\nsys.stdin.readline()\nprint('stuck', file=sys.stderr, flush=True)\ntime.sleep(60)\n"
    w = worker("stuck", script, block_timeout=0.5)
    with pytest.raises(WorkerDied, match=r"no answer within 0.5 s \(its last words: stuck\)"):
        w.block(1)
    assert w.proc.returncode is not None  # killed, not left behind


def test_a_worker_that_never_gets_ready_is_reported() -> None:
    with pytest.raises(WorkerDied, match="not ready within 0.5 s"):
        worker("slow", "import time\ntime.sleep(60)\n", start_timeout=0.5)
    with pytest.raises(WorkerDied, match="ValueError: no such thing"):
        worker("broken", "raise ValueError('no such thing')\n")


def test_the_raw_row_reports_a_pysoem_worker_fed_a_bogus_interface_as_a_crashed_peer() -> None:
    pytest.importorskip("pysoem")
    import row_raw

    started: list[BlockWorker] = []

    def ours(_run: int) -> BlockWorker:
        started.append(worker("ours", STEADY))
        return started[-1]

    result = row_raw.compare(ours, lambda _run: row_raw.start_worker("pysoem", "akdnosuch0"), runs=2, rounds=2, n=3)
    assert result.ok is False
    assert result.value == "peer crashed: ConnectionError: could not open interface akdnosuch0"
    assert started and all(w.proc.returncode is not None for w in started)  # our side was stopped too


def test_the_raw_row_reports_a_peer_dying_in_a_later_run() -> None:
    import row_raw

    runs = {"peer": 0}

    def peer(run: int) -> BlockWorker:
        runs["peer"] += 1
        if run == 1:
            return worker("pysoem", "import sys\nprint('ready', flush=True)\nsys.stdin.readline()\n"
                                    "raise SystemExit('pysoem.pysoem.WkcError')\n")
        return worker("pysoem", STEADY)

    result = row_raw.compare(lambda _run: worker("ours", STEADY), peer, runs=3, rounds=2, n=3)
    assert result.value == "peer crashed: pysoem.pysoem.WkcError"
    assert "run 2 of 3" in result.notes[0]
    assert runs["peer"] == 2


def test_the_raw_row_judges_median_worst_and_frames() -> None:
    import row_raw

    fast = "import sys\nprint('ready', flush=True)\nfor line in sys.stdin:\n    print(0.004, 0.002, 2 * int(line), flush=True)\n"
    result = row_raw.compare(lambda _run: worker("ours", fast), lambda _run: worker("pysoem", STEADY), runs=2,
                             rounds=2, n=4)
    assert result.value == "2.5× median, 2.5× worst of 2, frames 2 vs 2"
    assert result.ok is True
    assert result.figures["speed_worst"] == pytest.approx(2.5)
    many = "import sys\nprint('ready', flush=True)\nfor line in sys.stdin:\n    print(0.004, 0.002, 3 * int(line), flush=True)\n"
    result = row_raw.compare(lambda _run: worker("ours", many), lambda _run: worker("pysoem", STEADY), runs=2,
                             rounds=2, n=4)
    assert result.ok is False  # more frames than the peer: short whatever the speed
