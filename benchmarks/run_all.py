"""Every goal row of the performance issue, measured in one run, each with its goal and a pass/short mark.

    python benchmarks/run_all.py              # every row (a few minutes on a 2-core machine)
    python benchmarks/run_all.py --quick      # fewer rounds: a quick look, not a figure to quote
    python benchmarks/run_all.py --only raw --only cold-start
    python benchmarks/run_all.py --list       # the row names
    python benchmarks/run_all.py --runs 2 --markdown   # the issue's "Done when": every goal met in two runs

``--runs N`` measures the whole set N times, one run after the other, prints each run's table and then one
table of all runs whose mark is "pass" only where the row passed in every run (the run as a whole: "every goal
met in N of N runs", or which rows were short in which run). ``--markdown`` prints the tables as Markdown for a
closing note. The goal column is the issue's goal table, word for word; each row module judges its own figure.

The akdctl measured is the one ``import akdctl`` finds: run it from another worktree as
``PYTHONPATH=$PWD python /path/to/benchmarks/run_all.py --only ROW``. How every row measures (interleaved blocks,
ratios against a baseline of the same run, CPU per side) is :mod:`benchlib`; what each row does is its module's
docstring. No row asserts anything: a row that misses its goal is marked "short" and the run goes on.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from benchlib import Result, Settings, akdctl_root, cpu_speed  # noqa: E402


@dataclass(frozen=True)
class Row:
    name: str
    metric: str
    goal: str
    module: str
    function: str

    def measure(self) -> Callable[[Settings], Result]:
        import importlib

        return getattr(importlib.import_module(self.module), self.function)


ROWS = (
    Row("sim-cpu", "sim serve CPU per SDO upload / PNU read (factory / 256 KB state)",
        "≤ 30 µs SDO / ≤ 40 µs PNU, independent of the state's size", "row_network", "sim_cpu"),
    Row("state-writes", "state file writes by a read-only command", "0", "row_state", "state_writes"),
    Row("ecat-udp", "ETG.8200 SDO upload end to end / bare UDP round trip", "≥ 0.30", "row_network", "ecat_udp"),
    Row("client-cpu", "client CPU per gateway SDO upload", "≤ 30 µs", "row_network", "client_cpu"),
    Row("pn", "PROFINET single PNU read / bare UDP round trip", "≥ 0.15", "row_network", "profinet"),
    Row("batch", "each extra PNU in a 39-PNU batch (worst of sim, pn://)", "≤ 8 µs", "row_network", "batch"),
    Row("raw", "raw ecat:// SDO uploads/s vs pysoem, same sim slave",
        "≥ 1.2× median and ≥ 1.0× worst of 5 runs, frames ≤ pysoem", "row_raw", "raw_vs_pysoem"),
    Row("cold-start", "cold start CPU pnu get / sdo read / status, param get vs minimal click",
        "≤ 1.3× each, --help ≤ 1.1×, param get ≤ 1.35×", "row_startup", "cold_start"),
    Row("home", "home at sim 1000×: return after the drive is done", "≤ 10 ms", "row_motion", "home_after_done"),
    Row("canopen", "CANopen SDO uploads/s, can:// vs python-canopen's own sdo.upload, same bus",
        "≥ 1.1×, client CPU ≤ the peer's", "row_peers", "canopen_vs_python_canopen"),
    Row("cip", "CIP Get_Attribute_Single/s, eip:// vs pycomm3 generic_message, same face",
        "≥ 1.2×, client CPU ≤ the peer's", "row_peers", "cip_vs_pycomm3"),
    Row("modbus", "Modbus TCP register reads/s, mb:// vs pymodbus's own ModbusTcpClient, same face",
        "≥ 1.0×", "row_modbus", "modbus_vs_pymodbus"),
    Row("ascii", "AKD ASCII-channel reads/s, akd:// vs a minimal socket client, same face",
        "≥ 1.0×", "row_ascii", "ascii_vs_socket"),
    Row("line", "CPU per drive when commissioning N = 32 simulated drives with --inventory",
        "≤ 0.1 s", "row_line", "line"),
    Row("scope-pdo", "scope --source pdo client CPU per bus cycle / per polled sample, same ecat:// slave "
        "(and vs pysoem's cycle)", "≤ 0.6", "row_scope_pdo", "scope_pdo_cpu"),
)
BY_NAME = {row.name: row for row in ROWS}


def _mark(ok: bool | None) -> str:
    return {True: "pass", False: "SHORT", None: "skip"}[ok]


def _combined(oks: list[bool | None]) -> bool | None:
    """A row over several runs: short if it was short in any run, pass only if it passed in every run."""
    if any(ok is False for ok in oks):
        return False
    return True if oks and all(ok is True for ok in oks) else None


def _columns(runs: list[list[tuple[Row, Result]]]) -> tuple[tuple[str, ...], list[tuple[str, ...]]]:
    """The table's head and lines: one "measured" column per run, the mark over all runs."""
    many = len(runs) > 1
    head = ("row", "metric", *(f"run {k + 1}" if many else "measured" for k in range(len(runs))), "goal", "mark")
    lines = []
    for i, (row, _) in enumerate(runs[0]):
        results = [run[i][1] for run in runs]
        values = [r.value + (f" ({_mark(r.ok)})" if many else "") for r in results]
        lines.append((row.name, row.metric, *values, row.goal, _mark(_combined([r.ok for r in results]))))
    return head, lines


def _table(runs: list[list[tuple[Row, Result]]]) -> str:
    head, lines = _columns(runs)
    widths = [max(len(str(x[i])) for x in [head, *lines]) for i in range(len(head))]
    out = ["  ".join(str(c).ljust(w) for c, w in zip(head, widths)).rstrip(),
           "  ".join("-" * w for w in widths)]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines]
    return "\n".join(out)


def _markdown(runs: list[list[tuple[Row, Result]]]) -> str:
    head, lines = _columns(runs)

    def cells(values: tuple[str, ...]) -> str:
        return "| " + " | ".join(str(v).replace("|", "\\|") for v in values) + " |"

    return "\n".join([cells(head), "|" + "---|" * len(head), *(cells(line) for line in lines)])


def _verdict(runs: list[list[tuple[Row, Result]]]) -> str:
    """One line: every goal met in every run, or which rows were short (or skipped) in which runs."""
    missed = []
    for i, (row, _) in enumerate(runs[0]):
        bad = [str(k) for k, run in enumerate(runs, start=1) if run[i][1].ok is not True]
        if bad:
            marks = sorted({_mark(run[i][1].ok).lower() for run in runs if run[i][1].ok is not True})
            missed.append(f"{row.name} ({'/'.join(marks)} in run{'s' if len(bad) > 1 else ''} {', '.join(bad)})")
    if not missed:
        return f"every goal met in {len(runs)} of {len(runs)} run(s)"
    return f"goals not met: {'; '.join(missed)}"


def _settings(quick: bool, tmp: Path) -> Settings:
    if quick:
        return Settings(quick=True, tmp=tmp, rounds=5, block=100, process_rounds=5)
    return Settings(quick=False, tmp=tmp, rounds=15, block=400, process_rounds=15)


def _speeds(figures: tuple[float, ...]) -> str:
    return " / ".join(f"{ms:.0f}" for ms in figures)


def _measure(rows: list[Row], quick: bool, tmp: Path) -> list[tuple[Row, Result]]:
    """One run: every row in order, each in its own directory; a row that raises is an error row."""
    results: list[tuple[Row, Result]] = []
    for row in rows:
        start = time.monotonic()
        print(f"\n[{row.name}] {row.metric} (goal {row.goal})", flush=True)
        where = tmp / row.name
        where.mkdir()
        before = cpu_speed()
        try:
            result = row.measure()(_settings(quick, where))
        except Exception as exc:  # noqa: BLE001 - one broken row must not hide the others
            result = Result(f"error: {type(exc).__name__}", False, [str(exc)[:500]])
            if os.environ.get("BENCH_DEBUG"):
                traceback.print_exc()
        result.notes.append(f"machine: a fixed loop took {_speeds(before)} ms per CPU before the row, "
                            f"{_speeds(cpu_speed())} after (benchlib.cpu_speed: ~15 fast, ~28 slow here)")
        print(f"  -> {result.value}  [{_mark(result.ok)}]  ({time.monotonic() - start:.0f} s)")
        for note in result.notes:
            print(f"     {note}")
        sys.stdout.flush()
        results.append((row, result))
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="rows: " + ", ".join(BY_NAME))
    parser.add_argument("--only", action="append", metavar="ROW", default=[],
                        help="measure only this row (repeatable, or comma-separated)")
    parser.add_argument("--quick", action="store_true", help="fewer rounds and smaller blocks")
    parser.add_argument("--runs", type=int, default=1, metavar="N",
                        help="measure the whole set N times (1..10); a row passes only if it passed in every run")
    parser.add_argument("--markdown", action="store_true", help="print the tables as Markdown")
    parser.add_argument("--json", action="store_true", help="print the results as JSON after the table")
    parser.add_argument("--list", action="store_true", help="list the rows and their goals")
    args = parser.parse_args(argv)
    if args.list:
        for row in ROWS:
            print(f"{row.name:13} {row.metric}  [goal {row.goal}]")
        return 0
    if not 1 <= args.runs <= 10:
        parser.error("--runs takes 1..10")
    wanted = [name.strip() for item in args.only for name in item.split(",") if name.strip()]
    unknown = [name for name in wanted if name not in BY_NAME]
    if unknown:
        parser.error(f"unknown row(s) {', '.join(unknown)}; rows: {', '.join(BY_NAME)}")
    rows = [row for row in ROWS if not wanted or row.name in wanted]
    load = os.getloadavg()
    print(f"akdctl measured: {akdctl_root()}  (python {sys.version.split()[0]}, {os.cpu_count()} CPUs, "
          f"load {load[0]:.2f}, uid {os.geteuid()}{', quick' if args.quick else ''}"
          f"{f', {args.runs} runs' if args.runs > 1 else ''})", flush=True)
    runs: list[list[tuple[Row, Result]]] = []
    with tempfile.TemporaryDirectory(prefix="akdctl-bench-") as tmp:
        for k in range(args.runs):
            if args.runs > 1:
                print(f"\n=== run {k + 1} of {args.runs} (load {os.getloadavg()[0]:.2f})", flush=True)
            where = Path(tmp) / f"run{k + 1}"
            where.mkdir()
            runs.append(_measure(rows, args.quick, where))
            if args.runs > 1:
                print()
                print(_markdown([runs[-1]]) if args.markdown else _table([runs[-1]]))
    print()
    if args.runs > 1:
        print(f"=== all {args.runs} runs")
    print(_markdown(runs) if args.markdown else _table(runs))
    print()
    print(_verdict(runs))
    if args.json:
        documents = [{row.name: {"value": r.value, "ok": r.ok, "goal": row.goal, "figures": r.figures,
                                 "notes": r.notes} for row, r in run} for run in runs]
        print(json.dumps(documents if args.runs > 1 else documents[0], indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
