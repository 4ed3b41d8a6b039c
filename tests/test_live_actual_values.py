"""Issue 23.7: every actual-value object and PNU reads the model's live value, through every view.

Before, 0x2077 (actual current, mA), 0x3618 (VL.FB) and 0x3558 (IL.FB) were stored values reading 0 while 0x6077
read 20 and PNU 52 read 328 on the same moving drive. The test jogs the simulated drive through the real CLI, then
walks the catalogue's actual values (every object named "... actual value" or "*.FB", and the actual-value PNUs)
and compares the views of each quantity at one instant, and reads them through the CLI too.
"""

from __future__ import annotations

import json

import pytest

from akdctl.catalog import objects as object_catalog
from akdctl.profiles.units import CIA_COUNTS_PER_REV
from akdctl.sim.drive import SimDrive
from akdctl.sim.motion import SIM_PEAK_CURRENT_A
from tests.harness import finish, start_akdctl

#: Actual values the simulated AKD has no source for (no second feedback device): 0 is its true value there,
#: docs/fidelity.md says so.
NO_SECOND_FEEDBACK = {(0x2050, 0), (0x60E4, 1), (0x60E4, 2), (0x60E4, 3)}


def _actual_value_objects() -> list[tuple[int, int]]:
    found = []
    for entry in object_catalog.entries().values():
        name, param = entry.name.lower(), (entry.param or "").upper()
        if entry.index < 0x2000 or entry.access != "ro":
            continue
        if "actual value" in name or param.endswith(".FB") or param == "PL.ERR":
            found.append((entry.index, entry.subindex))
    return found


def _rpm_now() -> float:
    drive = SimDrive("default")
    try:
        with drive.transaction() as model:
            return model.object_value(0x606C, 0) / CIA_COUNTS_PER_REV * 60
    finally:
        drive.close()


@pytest.fixture
def jogging(isolated_env):
    """The simulated drive jogging at a steady 300 rpm (past the ramp: constant velocity, friction current)."""
    import signal

    from tests.harness import wait_until

    proc = start_akdctl("-y", "jog", "300", "--for", "30s")
    try:
        wait_until(lambda: abs(_rpm_now() - 300) < 1, "the jog to reach 300 rpm", timeout=20)
        yield
    finally:
        proc.send_signal(signal.SIGINT)  # Ctrl-C: the jog stops the axis and exits
        finish(proc, timeout=30)


@pytest.mark.slow
def test_every_actual_value_object_is_live_and_the_views_agree(jogging, akd_inproc) -> None:
    objects = _actual_value_objects()
    assert {(0x2077, 0), (0x3558, 0), (0x3618, 0), (0x6064, 0), (0x606C, 0), (0x6077, 0)} <= set(objects)
    drive = SimDrive("default")
    with drive.transaction() as model:  # one instant: every view of the same state
        values = {key: model.object_value(*key) for key in objects}
        pnu = {n: model.signed_pnu(n)[0] for n in (6, 28, 52)}
    drive.close()
    dead = [f"0x{i:04X}:{s}" for (i, s), v in values.items() if v == 0 and (i, s) not in NO_SECOND_FEEDBACK]
    assert not dead, f"actual values that read 0 on a moving drive: {dead}"
    rpm = values[(0x606C, 0)] / CIA_COUNTS_PER_REV * 60
    assert rpm == pytest.approx(300, rel=0.02)
    assert values[(0x3618, 0)] == values[(0x606C, 0)]  # VL.FB is 3618h and 606Ch
    assert pnu[6] == pytest.approx(300 / 12000 * (1 << 15), abs=2)  # NIST_A, X2 with 2^15 = 12000 rpm
    current_ma = values[(0x2077, 0)]
    assert current_ma == values[(0x3558, 0)]  # IL.FB
    assert current_ma / 1000 / SIM_PEAK_CURRENT_A == pytest.approx(values[(0x6077, 0)] / 1000, abs=0.002)
    assert current_ma / 1000 / SIM_PEAK_CURRENT_A == pytest.approx(pnu[52] / (1 << 14), abs=0.002)


@pytest.mark.slow
def test_the_cli_reads_the_akd_names_live(jogging, akd_inproc) -> None:
    read = {}
    for index in ("0x2077", "0x3558", "0x3618", "0x606C"):
        code, out, err = akd_inproc("--json", "sdo", "read", index)
        assert code == 0, err
        read[index] = json.loads(out)["value"]
    assert read["0x2077"] != 0 and read["0x3558"] != 0
    assert read["0x3618"] == pytest.approx(read["0x606C"], rel=0.01)
    assert read["0x3618"] / CIA_COUNTS_PER_REV * 60 == pytest.approx(300, rel=0.02)


@pytest.mark.slow
def test_the_cip_view_of_the_same_motion(jogging, akd) -> None:
    """The Position Controller's actual velocity (0x25/1/14, in PROFUNIT counts per revolution per second) over
    the EtherNet/IP face shows the same 300 rpm as 0x606C and VL.FB."""
    from akdctl.sim.cip_axis import DEFAULT_UNIT
    from tests.harness import SimServer

    with SimServer("--ethernetip", "127.0.0.1:0", "--eip-io-port", "0") as server:
        target = "eip://" + next(line.split()[1] for line in server.ready if line.startswith("ethernetip"))
        result = akd("-T", target, "--json", "cip", "get", "0x25/1/14", "i32", timeout=60)
    assert result.returncode == 0, result.stderr
    rev_per_s = json.loads(result.stdout)["value"] / DEFAULT_UNIT
    assert rev_per_s * 60 == pytest.approx(300, rel=0.02)
