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
