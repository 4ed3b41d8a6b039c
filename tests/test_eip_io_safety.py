"""Issue 23 items 2 and 3: `eip io` as a motion command.

* The face applies no Idle data (run/idle header Run bit clear): a PLC in program mode enables nothing.
* `eip io` passes the planner's limits (60 s cap, the profile's max_jog_duration and max_velocity).
* The I/O connection's timeout (RPI x multiplier) is bounded (drive/eip_io.MAX_CONNECTION_TIMEOUT_S): a killed
  akdctl leaves the axis running at most about that long; an RPI that cannot meet it is refused.
* SIGINT/SIGTERM: the command returns only after the axis is at standstill.

All against `sim serve --ethernetip` on 127.0.0.1 (ports chosen by the OS), every process stopped.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from akdctl.drive import eip_io
from akdctl.errors import SafetyRefusal
from tests.test_eip_e2e import Server, _env, akdctl

pytestmark = pytest.mark.slow


def _sim_status(tmp_path: Path) -> dict:
    """The served drive's state as the simulator holds it (the face and this read share the state directory)."""
    out = subprocess.run([sys.executable, "-m", "akdctl", "-T", "sim", "--json", "status"], capture_output=True,
                         text=True, env=_env(tmp_path / "state"), timeout=60)
    return json.loads(out.stdout)["status"]


@pytest.fixture
def served(tmp_path: Path):
    server = Server(tmp_path / "state")
    try:
        yield server
    finally:
        server.stop()


def _config(tmp_path: Path, target: str, body: str) -> list[str]:
    path = tmp_path / "akd.toml"
    path.write_text(f'default_profile = "bench"\n[profiles.bench]\ntarget = "{target}"\n' + body)
    return ["--config", str(path)]


# ---------------------------------------------------------------- item 2: Idle data is not applied
def test_idle_data_does_not_enable_the_drive(served, tmp_path: Path) -> None:
    from akdctl.protocol import akd_assembly as asm
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.eip_io import IoConnection
    from akdctl.transport.ethernetip import EnipSession

    session = EnipSession("127.0.0.1", served.port, LinkOptions(timeout=2.0), "plc")
    session.register()
    conn = IoConnection(session, "127.0.0.1", rpi_ms=10, port=served.io_port, timeout=2.0)
    try:
        assert conn.run is False                        # nothing is meant yet: Idle
        conn.open()
        conn.set_output(asm.Command(control=asm.CTL_ENABLE), run=False)   # a PLC in program mode
        for _ in range(5):
            idle = conn.wait_input(lambda r: True, "a response")
        assert not idle.status1 & asm.ST1_ENABLED
        assert _sim_status(tmp_path)["enabled"] is False
        conn.set_output(asm.Command(control=asm.CTL_ENABLE))               # Run: now it is meant
        conn.wait_input(lambda r: bool(r.status1 & asm.ST1_ENABLED), "Enabled")
        conn.idle()                                                         # back to Idle: the drive disables
        conn.wait_input(lambda r: not r.status1 & asm.ST1_ENABLED, "disabled after Idle")
    finally:
        conn.close()
        session.close()


# ---------------------------------------------------------------- item 3: the planner's limits
def test_timed_io_motion_is_bounded_like_jog(served, tmp_path: Path) -> None:
    target = served.target
    long = akdctl(tmp_path, target, "-y", "eip", "io", "jog", "300", "--for", "3600", "--port", str(served.io_port))
    assert long.returncode == 2 and "at most 60 s" in long.stderr, long.stderr
    t = _config(tmp_path, target, "[profiles.bench.limits]\nmax_jog_duration = 10\nmax_velocity = 1\n")
    over = akdctl(tmp_path, target, *t, "-y", "eip", "io", "velocity", "10", "--for", "20s",
                  "--port", str(served.io_port))
    assert over.returncode == 4 and "max_jog_duration 10" in over.stderr, over.stderr
    fast = akdctl(tmp_path, target, *t, "-y", "eip", "io", "jog", "100000", "--for", "1",
                  "--port", str(served.io_port))
    assert fast.returncode == 4 and "max_velocity" in fast.stderr, fast.stderr
    assert _sim_status(tmp_path)["enabled"] is False and _sim_status(tmp_path)["standstill"]


def test_connection_timeout_is_bounded_and_shown_in_the_plan(served, tmp_path: Path) -> None:
    slow = akdctl(tmp_path, served.target, "-y", "eip", "io", "jog", "300", "--for", "2", "--rpi", "1000")
    assert slow.returncode == 4 and "0.5 s" in slow.stderr and "125 ms" in slow.stderr, slow.stderr
    dry = akdctl(tmp_path, served.target, "--json", "eip", "io", "jog", "300", "--for", "2s", "--dry-run")
    assert dry.returncode == 0, dry.stderr
    plan = json.loads(dry.stdout)["plan"]
    assert plan["timeout_multiplier"] * plan["rpi_ms"] / 1000 == plan["connection_timeout_s"] <= 0.5
    assert _sim_status(tmp_path)["enabled"] is False


@pytest.mark.parametrize("rpi_ms", [10, 20, 33, 100, 125])
def test_multiplier_keeps_the_timeout_within_the_bound(rpi_ms: float) -> None:
    code = eip_io.timeout_multiplier(rpi_ms)
    assert rpi_ms / 1000 * (4 << code) <= eip_io.MAX_CONNECTION_TIMEOUT_S
    assert code == 7 or rpi_ms / 1000 * (4 << (code + 1)) > eip_io.MAX_CONNECTION_TIMEOUT_S


def test_an_rpi_that_cannot_meet_the_bound_is_refused() -> None:
    with pytest.raises(SafetyRefusal, match="at most 125 ms"):
        eip_io.timeout_multiplier(126)


def _moving(tmp_path: Path) -> bool:
    status = _sim_status(tmp_path)
    return abs(status["velocity_rpm"]) > 1


def _start_jog(tmp_path: Path, served) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-m", "akdctl", "-T", served.target, "-y", "eip", "io", "jog",
                             "327680", "--for", "30", "--port", str(served.io_port)], env=_env(tmp_path / "state"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL)
    deadline = time.monotonic() + 20
    while not _moving(tmp_path):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the I/O jog never moved the axis"
        time.sleep(0.1)
    return proc


def test_a_killed_tool_leaves_the_axis_running_at_most_the_bound(served, tmp_path: Path) -> None:
    proc = _start_jog(tmp_path, served)
    os.kill(proc.pid, signal.SIGKILL)
    killed = time.monotonic()
    proc.communicate(timeout=10)
    while _sim_status(tmp_path)["enabled"]:
        # the bound plus the face's own poll (50 ms) and this loop's status reads (one process start each)
        assert time.monotonic() - killed < eip_io.MAX_CONNECTION_TIMEOUT_S + 2.0, "the axis ran on"
        time.sleep(0.05)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_returns_only_after_standstill(served, tmp_path: Path, sig: int) -> None:
    proc = _start_jog(tmp_path, served)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 128 + sig, err
    assert "the axis stopped" in err, err
    assert _sim_status(tmp_path)["standstill"], "the command returned while the axis still turned"


# ---------------------------------------------------------------- item 20: what a user trips over on eip://
def test_home_then_move_gives_the_real_reason_and_hints_name_what_the_target_has(served, tmp_path: Path) -> None:
    target = served.target
    home = akdctl(tmp_path, target, "-y", "home", "--mode", "0", timeout=3)
    assert home.returncode == 0 and "True" not in home.stdout, home.stdout
    move = akdctl(tmp_path, target, "-y", "move", "1")
    assert move.returncode == 4 and "absolute moves are not possible over this link" in move.stderr, move.stderr
    assert "not homed" not in move.stderr
    for argv in (["pnu", "get", "1"], ["sdo", "read", "0x6041"]):
        hint = akdctl(tmp_path, target, *argv)
        assert hint.returncode == 2 and "this target offers 'cip' and 'eip' commands" in hint.stderr, hint.stderr
        assert "use 'sdo' commands" not in hint.stderr and "use 'pnu' commands" not in hint.stderr


def test_io_move_after_io_jog_works(served, tmp_path: Path) -> None:
    io = ["--port", str(served.io_port)]
    assert akdctl(tmp_path, served.target, "-y", "home", "--mode", "0", timeout=3).returncode == 0
    jog = akdctl(tmp_path, served.target, "-y", "eip", "io", "jog", "327680", "--for", "0.5", *io)
    assert jog.returncode == 0, jog.stderr
    move = akdctl(tmp_path, served.target, "--json", "-y", "eip", "io", "move", "10000", "--velocity", "65536", *io)
    assert move.returncode == 0, move.stderr
    assert json.loads(move.stdout)["actual_position"] == 10000


def test_io_position_on_an_unhomed_axis_says_home_first(served, tmp_path: Path) -> None:
    refused = akdctl(tmp_path, served.target, "-y", "eip", "io", "position", "1000", "--port", str(served.io_port))
    assert refused.returncode == 1 and "akdctl home" in refused.stderr, refused.stderr
