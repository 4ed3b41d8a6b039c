"""Every goal row of the performance issue, measured in one run, each with its goal and a pass/short mark.

    python benchmarks/run_all.py              # every row (a few minutes on a 2-core machine)
    python benchmarks/run_all.py --quick      # fewer rounds: a quick look, not a figure to quote
    python benchmarks/run_all.py --only raw --only cold-start
    python benchmarks/run_all.py --list       # the row names

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

from benchlib import Result, Settings, akdctl_root  # noqa: E402


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
        "≤ 40 µs, independent of the state's size", "row_network", "sim_cpu"),
    Row("state-writes", "state file writes by a read-only command", "0", "row_state", "state_writes"),
    Row("ecat-udp", "ETG.8200 SDO upload end to end / bare UDP round trip", "≥ 0.25", "row_network", "ecat_udp"),
    Row("client-cpu", "client CPU per gateway SDO upload", "≤ 30 µs", "row_network", "client_cpu"),
    Row("pn", "PROFINET single PNU read / bare UDP round trip", "≥ 0.15", "row_network", "profinet"),
    Row("batch", "each extra PNU in a 39-PNU batch (worst of sim, pn://)", "≤ 8 µs", "row_network", "batch"),
    Row("raw", "raw ecat:// SDO uploads/s vs pysoem, same sim slave", "≥ 1.2×, frames ≤ pysoem",
        "row_raw", "raw_vs_pysoem"),
    Row("cold-start", "cold start pnu get / sdo read / status vs minimal click",
        "≤ 1.5/1.6/1.7× (--help ≤ 1.15×)", "row_startup", "cold_start"),
    Row("home", "home at sim 1000×: return after the drive is done", "≤ 10 ms", "row_motion", "home_after_done"),
    Row("canopen", "CANopen SDO uploads/s, can:// vs python-canopen's own sdo.upload, same bus",
        "≥ 1.1×, client CPU ≤ the peer's", "row_peers", "canopen_vs_python_canopen"),
    Row("cip", "CIP Get_Attribute_Single/s, eip:// vs pycomm3 generic_message, same face",
        "≥ 1.2×, client CPU ≤ the peer's", "row_peers", "cip_vs_pycomm3"),
    Row("line", "commission 32 simulated drives with --inventory / 32 single runs (and CPU per drive)",
        "≤ 0.25", "row_line", "line"),
    Row("scope-pdo", "scope --source pdo client CPU per bus cycle / per polled sample, same ecat:// slave "
        "(and vs pysoem's cycle)", "≤ 0.6", "row_scope_pdo", "scope_pdo_cpu"),
)
BY_NAME = {row.name: row for row in ROWS}


def _mark(ok: bool | None) -> str:
    return {True: "pass", False: "SHORT", None: "skip"}[ok]


def _table(results: list[tuple[Row, Result]]) -> str:
    head = ("row", "metric", "measured", "goal", "mark")
    lines = [(row.name, row.metric, result.value, row.goal, _mark(result.ok)) for row, result in results]
    widths = [max(len(str(x[i])) for x in [head, *lines]) for i in range(len(head))]
    out = ["  ".join(str(c).ljust(w) for c, w in zip(head, widths)).rstrip(),
           "  ".join("-" * w for w in widths)]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines]
    return "\n".join(out)


def _settings(quick: bool, tmp: Path) -> Settings:
    if quick:
        return Settings(quick=True, tmp=tmp, rounds=5, block=100, process_rounds=5)
    return Settings(quick=False, tmp=tmp, rounds=15, block=400, process_rounds=15)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="rows: " + ", ".join(BY_NAME))
    parser.add_argument("--only", action="append", metavar="ROW", default=[],
                        help="measure only this row (repeatable, or comma-separated)")
    parser.add_argument("--quick", action="store_true", help="fewer rounds and smaller blocks")
    parser.add_argument("--json", action="store_true", help="print the results as JSON after the table")
    parser.add_argument("--list", action="store_true", help="list the rows and their goals")
    args = parser.parse_args(argv)
    if args.list:
        for row in ROWS:
            print(f"{row.name:13} {row.metric}  [goal {row.goal}]")
        return 0
    wanted = [name.strip() for item in args.only for name in item.split(",") if name.strip()]
    unknown = [name for name in wanted if name not in BY_NAME]
    if unknown:
        parser.error(f"unknown row(s) {', '.join(unknown)}; rows: {', '.join(BY_NAME)}")
    rows = [row for row in ROWS if not wanted or row.name in wanted]
    load = os.getloadavg()
    print(f"akdctl measured: {akdctl_root()}  (python {sys.version.split()[0]}, {os.cpu_count()} CPUs, "
          f"load {load[0]:.2f}, uid {os.geteuid()}{', quick' if args.quick else ''})", flush=True)
    results: list[tuple[Row, Result]] = []
    with tempfile.TemporaryDirectory(prefix="akdctl-bench-") as tmp:
        for row in rows:
            start = time.monotonic()
            print(f"\n[{row.name}] {row.metric} (goal {row.goal})", flush=True)
            where = Path(tmp) / row.name
            where.mkdir()
            try:
                result = row.measure()(_settings(args.quick, where))
            except Exception as exc:  # noqa: BLE001 - one broken row must not hide the others
                result = Result(f"error: {type(exc).__name__}", False, [str(exc)[:500]])
                if os.environ.get("BENCH_DEBUG"):
                    traceback.print_exc()
            print(f"  -> {result.value}  [{_mark(result.ok)}]  ({time.monotonic() - start:.0f} s)")
            for note in result.notes:
                print(f"     {note}")
            sys.stdout.flush()
            results.append((row, result))
    print()
    print(_table(results))
    if args.json:
        print(json.dumps({row.name: {"value": r.value, "ok": r.ok, "goal": row.goal, "figures": r.figures,
                                     "notes": r.notes} for row, r in results}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
