"""Issue 13 row 8: the raw EtherCAT master reads the AL state (register 0x0130), so the SPEC-NOTES 23 refusal
(controlword mapped in an active RxPDO while the slave is in OP) fires on ecat:// as on the other links.
Our master against our simulated slave over a socketpair (no root), as in test_ecat_raw_inprocess."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from akdctl.connection import Connection
from akdctl.drive import motion_plan
from akdctl.drive.axis.cia402 import Cia402Axis
from akdctl.errors import SafetyRefusal
from akdctl.protocol import ethercat as ec
from akdctl.sim.drive import SimDrive
from test_ecat_raw_inprocess import Wire, transport


@pytest.fixture
def wire(tmp_path: Path) -> Iterator[Wire]:
    w = Wire(SimDrive("default", tmp_path))
    try:
        yield w
    finally:
        w.close()


def test_raw_master_reports_al_state_and_the_planner_refuses_in_op(wire: Wire) -> None:
    t = transport(wire)
    conn = Connection.over(t)
    conn.transport()
    try:
        assert t.al_state() == "PREOP"
        axis = Cia402Axis(conn.objects(), conn.al_state, timeout=0.5)
        motion_plan.plan(conn, axis, motion_plan.MotionRequest("enable"))  # PRE-OP: SDO controlword obeyed
        for state in (ec.AlState.SAFEOP, ec.AlState.OP):
            t.master.request_state(t.slave.station, state)  # type: ignore[union-attr]
        assert t.al_state() == "OP"
        with pytest.raises(SafetyRefusal) as info:
            motion_plan.plan(conn, axis, motion_plan.MotionRequest("enable"))
        assert "SPEC-NOTES 23" in info.value.message and "0x1701" in info.value.message and "OP" in info.value.message
    finally:
        conn.close()
