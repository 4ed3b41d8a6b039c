"""The simulated AKD against statements both manual families share (issue 16 items 12, 13).

Each test quotes the statement it checks; rulings of our own are docs/fidelity.md F1..; SPEC-NOTES numbers are
named where a test relies on one. The CLI runs in process (``akd_inproc``), the simulator over its real codecs.
"""

from __future__ import annotations

import json

from akdctl.profiles import statusword as sw
from akdctl.sim.drive import SimDrive


def _json(akd_inproc, *args: str) -> dict:
    code, out, err = akd_inproc("--json", *args)
    assert code == 0, (args, code, err)
    return json.loads(out)


# ---------------------------------------------------------------------------------------------------- item 12
def _trip_watchdog() -> None:
    """Run the axis in velocity mode, then let virtual time pass with no request: the watchdog stops it."""
    with SimDrive("default").transaction() as model:
        for word in sw.TELEGRAM1_ENABLE_SEQUENCE:
            model.pnu_write_raw(1, 0, 0x42, [word])
        model.pnu_write_raw(5, 0, 0x42, [1638])                       # 600 rpm
        model.advance(0.5)
        model.advance(model.motion.watchdog_s * model.time_scale + 5.0)
        assert model.motion.standstill


def test_watchdog_warning_has_a_number_and_a_text(akd_inproc) -> None:
    """``004`` 5.10.1 "Warning or Fault handling: case of warning, ZSW1 Bit 7 is set"; ``001`` 5.4.3 "Bit 7:
    warning ... The reason for this warning can be revealed by using the Object 20subindex manufacturer warnings"
    (0x2000). The simulator's watchdog (docs/simulator.md) is not an AKD function, so its warning is the
    simulator's own n990, marked so in the fault table (docs/fidelity.md F4)."""
    _trip_watchdog()
    status = _json(akd_inproc, "status")["status"]
    assert status["warning"] and status["word"] & sw.ZSW1_WARNING
    assert _json(akd_inproc, "sdo", "read", "0x2000:1")["value"] == 990
    code, out, _ = akd_inproc("fault", "dump")
    assert code == 0 and "n990" in out and "not an AKD warning" in out
    code, out, _ = akd_inproc("fault", "explain", "n990")
    assert code == 0 and "Simulator only" in out and "watchdog" in out
    _json(akd_inproc, "--yes", "pnu", "set", "1=0x047E")               # the next control word clears it
    assert _json(akd_inproc, "sdo", "read", "0x2000:1")["value"] == 0
    assert not _json(akd_inproc, "status")["status"]["warning"]


# ---------------------------------------------------------------------------------------------------- item 13
def test_torque_interpolated_and_cyclic_synchronous_modes_show_their_effect(akd_inproc) -> None:
    """``001`` 5.8: "Torque DRV.OPMODE 0 ... 0x6060sub0 Data: 4 Commands torque in % of drive peak torque";
    "Interpolated position ... 0x6060Sub0 Data: 7 In this mode of operation the EtherCAT master sends cyclic
    position command values to the AKD. These command values are interpolated by the AKD according to the
    fieldbus sample rate"; "Cyclic Synchronous Position ... Data: 8 Master calculates move profile and commands
    motion with position points"; 5.7: 0x6071 "Target Torque ... 0.1% resolution", 0x60C1 sub 1 "Interpolation
    data record in IP-mode". docs/fidelity.md F8: the simulator acts on each (acyclic) set point write."""
    t = ["-T", "sim?drive=cia402"]
    _json(akd_inproc, "sim", "speed", "--realtime")       # torque runs until stopped: keep the travel short
    # torque: 10 % of peak accelerates the load up to the torque mode's velocity limit
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x6060", "i8", "4")[0] == 0
    assert _json(akd_inproc, *t, "--yes", "enable")["status"]["enabled"]         # enabled with halt (bit 8) set
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x6071", "i16", "100")[0] == 0
    assert _json(akd_inproc, *t, "status")["status"]["velocity_rpm"] == 0           # halt: no torque
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x6040", "u16", "0x0F")[0] == 0  # halt cleared
    status = _json(akd_inproc, *t, "status")["status"]
    assert status["mode"] == 4 and status["velocity_rpm"] > 0
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x6071", "i16", "0")[0] == 0
    _json(akd_inproc, "sim", "speed", "100000")
    assert _json(akd_inproc, *t, "status")["status"]["velocity_rpm"] == 0   # friction brings it to rest
    # cyclic synchronous position: the drive reaches each target position
    assert _json(akd_inproc, *t, "--yes", "disable")["status"]["enabled"] is False
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x6060", "i8", "8")[0] == 0
    _json(akd_inproc, *t, "--yes", "enable")
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x6040", "u16", "0x0F")[0] == 0
    start = _json(akd_inproc, *t, "status")["status"]["position_counts"]
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x607A", "i32", str(start + 65536))[0] == 0
    status = _json(akd_inproc, *t, "status")["status"]
    assert status["position_counts"] == start + 65536 and status["word"] & (1 << 12)
    # interpolated position: with ip mode enabled (controlword bit 4) the drive follows 0x60C1:1
    assert _json(akd_inproc, *t, "--yes", "disable")["status"]["enabled"] is False
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x6060", "i8", "7")[0] == 0
    _json(akd_inproc, *t, "--yes", "enable")
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x6040", "u16", "0x1F")[0] == 0
    assert akd_inproc(*t, "--yes", "sdo", "write", "0x60C1:1", "i32", str(start + 3 * 65536))[0] == 0
    status = _json(akd_inproc, *t, "status")["status"]
    assert status["position_counts"] == start + 3 * 65536 and status["word"] & (1 << 12)
    assert any(b["bit"] == 12 and b["name"] == "ip mode active" for b in status["bits"])
