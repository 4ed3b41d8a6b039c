"""Issue 14, live output: ``status --watch`` redraws in place on a terminal and prints JSON lines with ``--json``;
``move``/``jog``/``home`` show target, distance to go, percent and a time estimate while they run."""

from __future__ import annotations

import json
import select
import signal
import time
from types import SimpleNamespace

import pytest

from akdctl.cli.progress import measure
from akdctl.errors import EXIT_OK
from tests.harness import finish, run_akdctl, run_akdctl_tty, start_akdctl


def _plan(kind: str, **kw: object) -> SimpleNamespace:
    q = lambda v: SimpleNamespace(executed=v)  # noqa: E731
    base = dict(request=SimpleNamespace(kind=kind), start_rev=None, end_rev=None, duration_s=None, deadline_s=0.0,
                velocity=q(60.0), accel=q(600.0), decel=q(600.0))
    base.update(kw)
    return SimpleNamespace(**base)


def test_measure_a_move_a_timed_jog_and_homing() -> None:
    status = SimpleNamespace(position_rev=1.5, velocity_rpm=60.0)
    m = measure(_plan("move", start_rev=1.0, end_rev=3.0), status, 0.5)
    assert m.fraction == pytest.approx(0.25) and m.to_go == "1.5000 rev to go" and m.target == "to 3.0000 rev"
    assert m.eta_s == pytest.approx(1.5 + 1.0 / 20)  # 1.5 rev at 1 rev/s, plus the deceleration ramp
    m = measure(_plan("jog", duration_s=2.0), status, 0.5)
    assert m.fraction == pytest.approx(0.25) and m.eta_s == pytest.approx(1.5)
    m = measure(_plan("home", deadline_s=60.0), status, 10.0)
    assert m.fraction is None and "at 1.5000 rev" in m.to_go and "gives up in 50 s" in m.to_go
    m = measure(_plan("move", start_rev=0.0, end_rev=1.0), SimpleNamespace(position_rev=None, velocity_rpm=None), 0)
    assert m.fraction is None and m.to_go == "position not readable"


@pytest.mark.slow
def test_watch_json_prints_one_document_per_line() -> None:
    result = run_akdctl_tty("status", "--watch", "--json", "--interval", "0.1",
                            interrupt_when=lambda out: out.count("\n") >= 3)
    assert result.code in (EXIT_OK, 130), result.out
    lines = [line for line in result.out.splitlines() if line.startswith("{")]
    assert len(lines) >= 3
    for line in lines:
        doc = json.loads(line)
        assert doc["target"] == "sim" and doc["status"]["profile"] == "profidrive" and "T" in doc["time"]


@pytest.mark.slow
def test_watch_redraws_in_place_on_a_terminal() -> None:
    result = run_akdctl_tty("status", "--watch", "--interval", "0.1",
                            interrupt_when=lambda out: out.count("axis status") >= 3)
    assert result.code in (EXIT_OK, 130), result.out
    assert result.out.count("axis status") >= 3
    assert "\x1b[1A" in result.out  # the cursor goes back up: the view is redrawn, not appended
    assert "bits set" in result.out and "ZSW1 bits" not in result.out  # compact: fits a screen


@pytest.mark.slow
def test_watch_piped_prints_plain_documents() -> None:
    proc = start_akdctl("status", "--watch", "--interval", "0.1")
    assert proc.stdout is not None
    seen, deadline = "", time.monotonic() + 30
    while seen.count("axis status") < 2 and time.monotonic() < deadline:
        if select.select([proc.stdout], [], [], 0.5)[0]:
            seen += proc.stdout.readline()
    proc.send_signal(signal.SIGINT)
    result = finish(proc)
    out = seen + result.out
    assert out.count("axis status") >= 2 and "\x1b" not in out


@pytest.mark.slow
def test_motion_progress_plain_lines_and_quiet_with_json() -> None:
    result = run_akdctl("-y", "jog", "100", "--for", "0.3s")
    assert result.code == EXIT_OK, result.err
    assert "akdctl: jog for 0.3 s:" in result.err and "%" in result.err and "s left" in result.err
    result = run_akdctl("-y", "jog", "100", "--for", "0.3s", "--json")
    assert result.code == EXIT_OK and "akdctl: jog" not in result.err
    json.loads(result.out)


@pytest.mark.slow
def test_move_progress_on_a_terminal() -> None:
    assert run_akdctl("-y", "home").code == EXIT_OK
    result = run_akdctl_tty("-y", "move", "--relative", "2")
    assert result.code == EXIT_OK, result.out
    assert "rev to go" in result.out and "%" in result.out and "target reached" in result.out
