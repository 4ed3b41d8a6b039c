"""Row: how long ``akdctl home`` takes to return after the simulated drive (at 1000× speed) reports done.

The real CLI runs in a subprocess (``python -c`` running ``akdctl.cli.main.main``) with the axis' ``read_status``
and ``home_finished`` observed: each status poll notes when its read started and whether it showed homing finished.
The drive finished after the start of the last poll that said "not yet", so ``return - that start`` is an upper
bound of the wait after done (the figure printed); ``return - end of the first poll that said done`` is a lower
bound. "Return" is when ``main`` ends, before the interpreter's exit. The runs alternate homing mode 1 (search the
negative limit switch) and 3 (the home switch), so each homing travels some revolutions (a few ms at 1000×).
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys

from benchlib import Result, Settings, akdctl_env

SPEED = 1000

OBSERVED_HOME = r"""
import json, sys, time
from akdctl.drive.axis import choice as axis_module
polls = []

def leaves(cls):
    subs = cls.__subclasses__()
    return [c for s in subs for c in leaves(s)] if subs else [cls]

def observe(cls):
    read, finished = cls.read_status, cls.home_finished
    def read_status(self, *a, **k):
        t0 = time.perf_counter()
        status = read(self, *a, **k)
        polls.append([t0, time.perf_counter(), "unasked"])
        return status
    def home_finished(self, status):
        result = finished(self, status)
        if polls:
            polls[-1][2] = result
        return result
    cls.read_status, cls.home_finished = read_status, home_finished

# every axis class, so every leaf is observed (axis.choice imports only the profile it picks)
import akdctl.drive.axis.akd_ascii, akdctl.drive.axis.cia402, akdctl.drive.axis.cip, akdctl.drive.axis.profidrive  # noqa: E401,F401
for cls in leaves(axis_module.Axis):
    observe(cls)
from akdctl.cli.main import main
code = 0
try:
    main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code or 0
end = time.perf_counter()
print(json.dumps({"code": code, "end": end, "polls": polls}), file=sys.stderr)
"""


def _run(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *args], env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          timeout=120)


def home_after_done(s: Settings) -> Result:
    env = akdctl_env(AKDCTL_STATE_DIR=str(s.tmp / "home"), XDG_CONFIG_HOME=str(s.tmp / "home-config"))
    setup = _run(env, "-m", "akdctl", "sim", "speed", str(SPEED))
    if setup.returncode != 0:
        return Result("error", False, [f"sim speed {SPEED}: {setup.stderr.strip()}"])
    upper, lower, intervals, polls_per_run = [], [], [], []
    runs = max(4, s.process_rounds)
    for i in range(runs + 1):
        mode = "1" if i % 2 == 0 else "3"
        proc = _run(env, "-c", OBSERVED_HOME, "-y", "home", "--mode", mode)
        report = json.loads(proc.stderr.strip().splitlines()[-1])
        if report["code"] != 0:
            return Result("error", False, [f"home --mode {mode} exited {report['code']}: {proc.stderr.strip()[:300]}"])
        if i == 0:
            continue  # the first homing starts wherever the drive stood: warm-up
        polls = [p for p in report["polls"] if p[2] != "unasked"]  # reads before homing started
        first_done = next((k for k, p in enumerate(polls) if p[2] is True), None)
        if first_done is None or first_done == 0:
            continue  # done at the first poll (or not observed): no "not yet" poll to bound the wait from
        upper.append((report["end"] - polls[first_done - 1][0]) * 1e3)
        lower.append((report["end"] - polls[first_done][1]) * 1e3)
        starts = [p[0] for p in polls]
        intervals.extend((b - a) * 1e3 for a, b in zip(starts, starts[1:]))
        polls_per_run.append(len(polls))
    if not upper:
        return Result("not observed", False, ["no homing run showed a 'not finished' poll before 'finished'"])
    worst = statistics.median(upper)
    return Result(f"≤ {worst:.1f} ms", worst <= 10.0, [
        f"return after done: upper bound median {worst:.1f} ms (max {max(upper):.1f}), lower bound median "
        f"{statistics.median(lower):.1f} ms, over {len(upper)} homing runs at {SPEED}×",
        f"status polls per homing {statistics.median(polls_per_run):g}, interval between poll starts median "
        f"{statistics.median(intervals):.1f} ms (min {min(intervals):.1f}, max {max(intervals):.1f})"],
        {"upper_ms": worst, "lower_ms": statistics.median(lower), "poll_interval_ms": statistics.median(intervals)})
