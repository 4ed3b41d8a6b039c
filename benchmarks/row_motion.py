"""Row: how long ``akdctl home`` takes to return after the simulated drive (at 1000× speed) finished homing.

The real CLI runs in a subprocess (``python -c`` running ``akdctl.cli.main.main``) against the in-process simulator,
observed in three places:

* **the instant homing finished**, from the simulator's own integration: the drive model advances its clock lazily,
  at each request, by the wall time since the last one; the step that ends the homing's return move
  (``Kinematics._generator_done``) starts ``dt`` virtual seconds before the end of that advance, where ``dt`` is what
  ``Kinematics.integrate`` had left to integrate. So it happened ``dt / time_scale`` wall seconds before the request
  that advanced the clock read the wall time;
* each status poll (``read_status``/``home_finished``): when its read started and ended, and whether it said done;
* the return: when ``main`` ends, before the interpreter's exit.

The figure is ``return - homing finished``. The polls give two bounds it must lie within, printed beside it as a
check of the observation: the start of the last poll that said "not yet" (the drive finished after it) and the end
of the first poll that said done (it finished before that). Why not the upper bound itself, as this row first did:
it includes up to a whole poll interval before the drive was done, and a slower phase of this machine (fewer, longer
polls per homing) moved it by a step of ~4 ms with the same code. The runs alternate homing mode 1 (search the
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
from akdctl.sim import kinematics, model as sim_model
polls, finished_at, advancing = [], [], [None]

def leaves(cls):
    subs = cls.__subclasses__()
    return [c for s in subs for c in leaves(s)] if subs else [cls]

def observe(cls):
    read, finished = cls.read_status, cls.home_finished
    def read_status(self, *a, **k):
        t0 = time.time()
        status = read(self, *a, **k)
        polls.append([t0, time.time(), "unasked"])
        return status
    def home_finished(self, status):
        result = finished(self, status)
        if polls:
            polls[-1][2] = result
        return result
    cls.read_status, cls.home_finished = read_status, home_finished

# every axis class, so every leaf is observed (axis.choice imports only the profile it picks)
import akdctl.drive.axis.akd_ascii, akdctl.drive.axis.cia402, akdctl.drive.axis.profidrive, akdctl.drive.axis.cip  # noqa: E401,F401
for cls in leaves(axis_module.Axis):
    observe(cls)

advance = sim_model.DriveModel.advance
def observed_advance(self, dt):
    # the wall time this advance brings the clock to (read a microsecond after the simulator read it), the clock
    # it ends at and the scale between the two
    advancing[0] = (time.time(), self.clock + max(dt, 0.0), self.time_scale or 1.0, self)
    advance(self, dt)
sim_model.DriveModel.advance = observed_advance

generator_done = kinematics.Kinematics._generator_done
def observed_generator_done(self):
    homing = self.homing
    if homing is not None and homing.get("phase") == "return" and advancing[0] is not None:
        frame = sys._getframe(1)
        while frame is not None and frame.f_code.co_name != "integrate":
            frame = frame.f_back
        wall, end_clock, scale, model = advancing[0]
        if frame is not None:  # this step starts `left` virtual seconds before the end of the model's current step
            done_clock = model.clock - frame.f_locals["dt"]
            finished_at.append(wall - (end_clock - done_clock) / scale)
    generator_done(self)
kinematics.Kinematics._generator_done = observed_generator_done

from akdctl.cli.main import main
code = 0
try:
    main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code or 0
end = time.time()
print(json.dumps({"code": code, "end": end, "polls": polls, "finished": finished_at}), file=sys.stderr)
"""


def _run(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *args], env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          timeout=120)


def home_after_done(s: Settings) -> Result:
    env = akdctl_env(AKDCTL_STATE_DIR=str(s.tmp / "home"), XDG_CONFIG_HOME=str(s.tmp / "home-config"))
    setup = _run(env, "-m", "akdctl", "sim", "speed", str(SPEED))
    if setup.returncode != 0:
        return Result("error", False, [f"sim speed {SPEED}: {setup.stderr.strip()}"])
    after, upper, lower, intervals, polls_per_run, outside = [], [], [], [], [], 0
    runs = max(4, s.process_rounds)
    for i in range(runs + 1):
        mode = "1" if i % 2 == 0 else "3"
        proc = _run(env, "-c", OBSERVED_HOME, "-y", "home", "--mode", mode)
        try:
            report = json.loads(proc.stderr.strip().splitlines()[-1])
        except (IndexError, ValueError):
            return Result("error", False, [f"home --mode {mode}: no report ({proc.stderr.strip()[:300]})"])
        if report["code"] != 0:
            return Result("error", False, [f"home --mode {mode} exited {report['code']}: {proc.stderr.strip()[:300]}"])
        if i == 0:
            continue  # the first homing starts wherever the drive stood: warm-up
        if len(report["finished"]) != 1:
            return Result("not observed", False, [f"home --mode {mode}: {len(report['finished'])} homing ends seen "
                                                  "in the simulator, not one"])
        finished = report["finished"][0]
        after.append((report["end"] - finished) * 1e3)
        polls = [p for p in report["polls"] if p[2] != "unasked"]  # reads before homing started
        first_done = next((k for k, p in enumerate(polls) if p[2] is True), None)
        if first_done is None:
            return Result("not observed", False, [f"home --mode {mode}: no status poll said homing finished"])
        # the bounds the polls give: finished before the first "done" poll's read ended, after the last "not yet"
        # poll's read started (none: the homing was done at the first poll)
        high = polls[first_done - 1][0] if first_done else None
        low = polls[first_done][1]
        if finished > low + 1e-4 or (high is not None and finished < high - 1e-4):
            outside += 1
        lower.append((report["end"] - low) * 1e3)
        if high is not None:
            upper.append((report["end"] - high) * 1e3)
        starts = [p[0] for p in polls]
        intervals.extend((b - a) * 1e3 for a, b in zip(starts, starts[1:]))
        polls_per_run.append(len(polls))
    figure = statistics.median(after)
    lines = [f"return after homing finished (the simulator's instant): median {figure:.1f} ms, max {max(after):.1f}, "
             f"over {len(after)} homing runs at {SPEED}×",
             f"check against the polls: the instant lay between the last 'not yet' poll and the first 'done' one in "
             f"{len(after) - outside} of {len(after)} runs; bounds of the return: lower median "
             f"{statistics.median(lower):.1f} ms" + (f", upper median {statistics.median(upper):.1f} ms" if upper else ""),
             f"status polls per homing {statistics.median(polls_per_run):g}" + (
                 f", interval between poll starts median {statistics.median(intervals):.1f} ms (min "
                 f"{min(intervals):.1f}, max {max(intervals):.1f})" if intervals else "")]
    if outside:
        return Result(f"{figure:.1f} ms (instant outside the poll bounds)", False, lines)
    return Result(f"{figure:.1f} ms", figure <= 10.0, lines,
                  {"after_ms": figure, "lower_ms": statistics.median(lower),
                   "upper_ms": statistics.median(upper) if upper else None,
                   "poll_interval_ms": statistics.median(intervals) if intervals else None})
