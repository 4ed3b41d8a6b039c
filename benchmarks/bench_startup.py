"""Cold-start cost of `akdctl --help` and `akdctl pnu get 930` (simulated drive), as ratios.

The baseline is a minimal click application's `--help`, measured in the same run
on the same interpreter, so the ratios hold across machines. Aim (Foundation
issue): --help ≤ 1.3×, pnu get ≤ 2×. Prints medians of N runs; no assertions.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RUNS = int(os.environ.get("BENCH_RUNS", "15"))
ROOT = Path(__file__).resolve().parent.parent

MINIMAL_CLICK = """
import click

@click.group()
@click.option("--json", is_flag=True)
def cli(json):
    '''Minimal click application.'''

@cli.command()
def hello():
    '''Say hello.'''

cli()
"""


def median_seconds(argv: list[str], env: dict[str, str]) -> float:
    samples = []
    for _ in range(RUNS):
        start = time.perf_counter()
        subprocess.run(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, AKDCTL_STATE_DIR=tmp, PYTHONPATH=str(ROOT))
        # An installed package has compiled bytecode (pip writes it); measure that, not recompiles.
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        minimal = Path(tmp) / "minimal_click.py"
        minimal.write_text(MINIMAL_CLICK)
        subprocess.run([sys.executable, "-m", "akdctl", "pnu", "get", "930"], env=env, capture_output=True)  # warm
        base = median_seconds([sys.executable, str(minimal), "--help"], env)
        help_t = median_seconds([sys.executable, "-m", "akdctl", "--help"], env)
        get_t = median_seconds([sys.executable, "-m", "akdctl", "pnu", "get", "930"], env)
    print(f"baseline minimal click --help : {base * 1000:7.1f} ms")
    print(f"akdctl --help                 : {help_t * 1000:7.1f} ms  ratio {help_t / base:.2f}x (aim <= 1.3x)")
    print(f"akdctl pnu get 930 (sim)      : {get_t * 1000:7.1f} ms  ratio {get_t / base:.2f}x (aim <= 2.0x)")


if __name__ == "__main__":
    main()
