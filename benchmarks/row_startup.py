"""Row: cold start of the real CLI against a minimal click application, in interleaved pairs of process starts.

Each pair starts the minimal app and then the akdctl command (``--help`` against the app's ``--help``, the drive
commands against the app running a subcommand), both with stdout piped as in a script. What is compared is the CPU
time of each process (user + system, from ``wait4``: what the process itself cost, whatever else the machine runs);
the ratio is the median of the per-pair ratios, and the wall time is shown beside it. Both processes of a pair run
on one CPU, the pairs taking the CPUs in turn (:class:`benchlib.OnCpu`: each CPU here has speed phases of its own, and
a pair split across two CPUs compared their phases as much as the programs). The drive commands talk to the
default target, the in-process simulator, in a state directory of their own whose state file exists (``sim reset``
first, as after any first use: the start includes reading it), with an empty config directory.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

from benchlib import OnCpu, Result, Settings, akdctl_env, allowed_cpus, fmt_ratio

MINIMAL_CLICK = '''
import click


@click.group()
@click.option("--json", is_flag=True, help="JSON output.")
def cli(json):
    """Minimal click application."""


@cli.command()
def hello():
    """Say hello."""
    click.echo("hello")


cli()
'''

# (label, akdctl arguments, the minimal app's arguments, goal ratio) - issue 29's goals
COMMANDS = (
    ("--help", ("--help",), ("--help",), 1.1),
    ("pnu get 930", ("pnu", "get", "930"), ("hello",), 1.3),
    ("sdo read 0x6041", ("sdo", "read", "0x6041"), ("hello",), 1.3),
    ("status", ("status",), ("hello",), 1.3),
    ("param get DRV.OPMODE", ("param", "get", "DRV.OPMODE"), ("hello",), 1.35),
)


def _start(argv: list[str], env: dict[str, str]) -> tuple[float, float]:
    """One process start: (CPU seconds of the process - user + system, from wait4 -, wall seconds)."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = start + 120
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.perf_counter() > deadline:
            proc.kill()
            proc.wait()
            raise RuntimeError(f"{' '.join(argv[-3:])} did not end within 120 s")
        time.sleep(0.002)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(argv[-3:])} failed ({proc.returncode}); run it by hand to see why")
    return usage.ru_utime + usage.ru_stime, wall


def cold_start(s: Settings) -> Result:
    import statistics

    env = akdctl_env(AKDCTL_STATE_DIR=str(s.tmp / "cold"), XDG_CONFIG_HOME=str(s.tmp / "cold-config"))
    app = s.tmp / "minimal_click.py"
    app.write_text(MINIMAL_CLICK)
    akdctl = [sys.executable, "-m", "akdctl"]
    minimal = [sys.executable, str(app)]
    _start(akdctl + ["sim", "reset"], env)  # the state file exists, as after any first use
    for _, args, base, _ in COMMANDS:  # warm: page cache, bytecode
        _start(akdctl + list(args), env)
        _start(minimal + list(base), env)
    cpus = allowed_cpus()
    ratios: dict[str, float] = {}
    notes = []
    ok = True
    for label, args, base, goal in COMMANDS:
        pairs = []
        for k in range(s.process_rounds):
            with OnCpu(cpus[k % len(cpus)] if cpus else None):
                b = _start(minimal + list(base), env)
                a = _start(akdctl + list(args), env)
            pairs.append((a, b))
        ratio = statistics.median(a[0] / b[0] for a, b in pairs)
        ratios[label] = ratio
        ok = ok and ratio <= goal
        notes.append(f"{label}: {fmt_ratio(ratio)}× (goal ≤ {goal}×), CPU akdctl "
                     f"{statistics.median(a[0] for a, _ in pairs) * 1e3:.0f} ms, minimal "
                     f"{statistics.median(b[0] for _, b in pairs) * 1e3:.0f} ms (wall "
                     f"{statistics.median(a[1] for a, _ in pairs) * 1e3:.0f} / "
                     f"{statistics.median(b[1] for _, b in pairs) * 1e3:.0f} ms)")
    value = " / ".join(f"{fmt_ratio(ratios[label])}×" for label, *_ in COMMANDS[1:4]) \
        + f", param get {fmt_ratio(ratios['param get DRV.OPMODE'])}× (--help {fmt_ratio(ratios['--help'])}×)"
    notes.append(f"CPU time per process (user + system); medians of {s.process_rounds} interleaved pairs of "
                 "process starts, each pair on one CPU")
    return Result(value, ok, notes, {k: v for k, v in ratios.items()})
