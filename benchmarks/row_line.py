"""Row: commissioning a line of N simulated drives with ``--inventory`` (goal: CPU per drive <= 0.1 s at N = 32;
the wall time against N single runs is reported beside it).

The work: one recipe (set the operating mode by object with read-back, check it, check faults, a wait of 0.3 s --
the drive-side time a real recipe spends enabling, homing or settling, during which a single run only waits) on
N simulated drives, each its own ``sim://lineK``. The baseline is the same recipe run once on one drive by the
plain ``commission`` command, measured in the same run, interleaved with the line runs: the ratio is the line's
wall time over N x the single run's. CPU per drive is the children's CPU (``RUSAGE_CHILDREN``: the line's
process and every process it starts) over N: the median of the rounds at N = 32 is the row's figure.
"""

from __future__ import annotations

import resource
import subprocess
import sys
import time
from pathlib import Path

from benchlib import Result, Settings, akdctl_env

#: The issue's goal: CPU per drive when commissioning N = 32 drives.
CPU_GOAL_S = 0.1

RECIPE = """[recipe]
name = "line ${name}"
[[step]]
action = "set"
objects = { "0x6060:0" = ${vars.mode} }
[[step]]
action = "expect"
object = "0x6060:0"
value = ${vars.mode}
[[step]]
action = "check_faults"
[[step]]
action = "wait"
seconds = 0.3
"""


def _inventory(path: Path, n: int) -> None:
    lines = []
    for k in range(n):
        lines += ["[[drive]]", f'name = "line{k}"', f'target = "sim://line{k}"', "[drive.vars]",
                  f"mode = {3 if k % 4 == 0 else 1}", ""]
    path.write_text("\n".join(lines), encoding="utf-8")


def _timed(argv: list[str], env: dict[str, str]) -> tuple[float, float]:
    """(wall s, CPU s of the process and its children)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "akdctl", *argv], env=env, capture_output=True, text=True,
                          timeout=600)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"akdctl {' '.join(argv[:6])} ... exit {proc.returncode}: {proc.stderr.strip()[-400:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def line(s: Settings) -> Result:
    env = akdctl_env(AKDCTL_STATE_DIR=str(s.tmp / "state"), XDG_CONFIG_HOME=str(s.tmp / "config"))
    recipe = s.tmp / "line.toml"
    recipe.write_text(RECIPE, encoding="utf-8")
    single_recipe = s.tmp / "single.toml"
    single_recipe.write_text(RECIPE.replace("${name}", "one").replace("${vars.mode}", "3"), encoding="utf-8")
    sizes = (1, 8, 32)
    inventories = {}
    for n in sizes:
        inventories[n] = s.tmp / f"inv{n}.toml"
        _inventory(inventories[n], n)
    rounds = 1 if s.quick else 3
    singles: list[float] = []
    lines: dict[int, list[tuple[float, float]]] = {n: [] for n in sizes}
    # warm the drives' state files once (a first run creates them), then interleave single and line runs
    _timed(["--yes", "--inventory", str(inventories[32]), "--parallel", "8", "commission", str(recipe)], env)
    for _ in range(rounds):
        for n in sizes:
            singles.append(_timed(["--yes", "-T", "sim://single", "commission", str(single_recipe)], env)[0])
            lines[n].append(_timed(["--yes", "--inventory", str(inventories[n]), "--parallel", "8", "commission",
                                    str(recipe)], env))
    single = sorted(singles)[len(singles) // 2]
    notes = [f"single commission run: {single:.2f} s (median of {len(singles)})"]
    figures: dict[str, float | None] = {"single_s": single}
    ratio32 = None
    cpu32 = None
    for n in sizes:
        walls = sorted(w for w, _ in lines[n])
        cpus = sorted(c for _, c in lines[n])
        wall, cpu = walls[len(walls) // 2], cpus[len(cpus) // 2]
        ratio = wall / (n * single)
        figures[f"ratio_{n}"] = ratio
        figures[f"cpu_per_drive_{n}"] = cpu / n
        notes.append(f"N={n:2}: {wall:.2f} s = {ratio:.3f} x N single runs; CPU per drive {cpu / n * 1000:.0f} ms")
        if n == 32:
            ratio32, cpu32 = ratio, cpu / n
    ok = cpu32 is not None and cpu32 <= CPU_GOAL_S
    value = (f"CPU {cpu32 * 1000:.0f} ms per drive, {ratio32:.3f} x 32 single runs"
             if cpu32 is not None and ratio32 is not None else "-")
    return Result(value, ok, notes, figures)
