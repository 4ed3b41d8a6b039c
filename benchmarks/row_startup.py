"""Row: cold start of the real CLI against a minimal click application, in interleaved pairs of process starts.

Each pair starts the minimal app and then the akdctl command (``--help`` against the app's ``--help``, the drive
commands against the app running a subcommand), both with stdout piped as in a script. The ratio is the median of
the per-pair ratios. The drive commands talk to the default target, the in-process simulator, in a state directory
of their own (created before the first pair), with an empty config directory.
"""

from __future__ import annotations

import subprocess
import sys
import time

from benchlib import Result, Settings, akdctl_env, fmt_ratio

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

# (label, akdctl arguments, the minimal app's arguments, goal ratio)
COMMANDS = (
    ("--help", ("--help",), ("--help",), 1.15),
    ("pnu get 930", ("pnu", "get", "930"), ("hello",), 1.5),
    ("sdo read 0x6041", ("sdo", "read", "0x6041"), ("hello",), 1.6),
    ("status", ("status",), ("hello",), 1.7),
)


def _wall(argv: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    proc = subprocess.run(argv, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          timeout=120)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(argv[-3:])} failed ({proc.returncode}): {proc.stderr.decode().strip()[-300:]}")
    return wall


def cold_start(s: Settings) -> Result:
    import statistics

    env = akdctl_env(AKDCTL_STATE_DIR=str(s.tmp / "cold"), XDG_CONFIG_HOME=str(s.tmp / "cold-config"))
    app = s.tmp / "minimal_click.py"
    app.write_text(MINIMAL_CLICK)
    akdctl = [sys.executable, "-m", "akdctl"]
    minimal = [sys.executable, str(app)]
    for _, args, base, _ in COMMANDS:  # warm: state file, page cache, bytecode
        _wall(akdctl + list(args), env)
        _wall(minimal + list(base), env)
    ratios: dict[str, float] = {}
    notes = []
    ok = True
    for label, args, base, goal in COMMANDS:
        pairs = []
        for _ in range(s.process_rounds):
            b = _wall(minimal + list(base), env)
            a = _wall(akdctl + list(args), env)
            pairs.append((a, b))
        ratio = statistics.median(a / b for a, b in pairs)
        ratios[label] = ratio
        ok = ok and ratio <= goal
        notes.append(f"{label}: {fmt_ratio(ratio)}× (goal ≤ {goal}×), akdctl {statistics.median(a for a, _ in pairs) * 1e3:.0f} ms, "
                     f"minimal {statistics.median(b for _, b in pairs) * 1e3:.0f} ms")
    value = " / ".join(f"{fmt_ratio(ratios[label])}×" for label, *_ in COMMANDS[1:]) \
        + f" (--help {fmt_ratio(ratios['--help'])}×)"
    notes.append(f"medians of {s.process_rounds} interleaved pairs of process starts")
    return Result(value, ok, notes, {k: v for k, v in ratios.items()})
