"""Process data in OP between our raw master and the simulated slave (in-process, no root): SM2/SM3 and FMMUs,
LRW with the working counter of the mapping (3 in OP, 1 in SAFE-OP), the RxPDO driving the drive model (the
mapped controlword wins over SDO writes, SPEC-NOTES 23), TxPDO carrying the model's values, the SM watchdog,
the P->S SM length check, and ``ecat pdo watch``'s early ends."""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path

import pytest

from akdctl.connection import Connection
from akdctl.drive import ecat_pdo_watch as watch
from akdctl.errors import CommError, DriveError, UsageError
from akdctl.protocol import ethercat as ec
from akdctl.sim.drive import SimDrive
from akdctl.transport.ethercat_raw import ProcessDataCycle
from tests.test_ecat_raw_inprocess import Wire, transport


@pytest.fixture
def drive(tmp_path: Path) -> SimDrive:
    return SimDrive("default", tmp_path)


@pytest.fixture
def wire(drive: SimDrive) -> Iterator[Wire]:
    w = Wire(drive)
    assert w.face.pd is not None
    w.face.pd.start()
    try:
        yield w
    finally:
        w.face.pd.stop()
        w.close()


@pytest.fixture
def conn(wire: Wire) -> Iterator[Connection]:
    c = Connection.over(transport(wire))
    try:
        yield c
    finally:
        c.close()


def _op(conn: Connection) -> tuple[ProcessDataCycle, watch.WritePlan]:
    plan = watch.plan(conn, {})
    t = conn.transport()
    cycle = ProcessDataCycle(t.master, t.slave.station, plan.data["rx"].bytes, plan.data["tx"].bytes)  # type: ignore[attr-defined]
    cycle.configure()
    t.master.request_state(t.slave.station, ec.AlState.SAFEOP)  # type: ignore[attr-defined]
    return cycle, plan


def test_wkc_is_1_in_safeop_and_3_in_op_and_the_controlword_drives_the_model(conn: Connection, wire: Wire,
                                                                             drive: SimDrive) -> None:
    cycle, plan = _op(conn)
    rx = plan.data["rx"]
    assert rx.has(0x6040, 0) and cycle.expected_wkc == 3
    assert cycle.exchange(rx.encode({}))[1] == 1  # SAFE-OP: inputs only
    t = conn.transport()
    t.master.request_state(t.slave.station, ec.AlState.OP)  # type: ignore[attr-defined]
    import time
    for word in (0x06, 0x07, 0x0F):
        for _ in range(5):
            inputs, wkc, al = cycle.exchange(rx.encode({(0x6040, 0): word}))
            assert wkc == 3 and al & 0x0F == ec.AlState.OP
            time.sleep(0.01)
    values = {v["address"]: v["value"] for v in plan.data["tx"].decode(inputs)}
    assert values["0x6041:00"] & 0x6F == 0x27  # operation enabled, reported by the TxPDO
    # an SDO write of the controlword has no effect while the mapped one is cycled (SPEC-NOTES 23)
    conn.objects().download(0x6040, 0, struct.pack("<H", 0))
    time.sleep(0.05)
    inputs, wkc, _al = cycle.exchange(rx.encode({(0x6040, 0): 0x0F}))
    assert {v["address"]: v["value"] for v in plan.data["tx"].decode(inputs)}["0x6041:00"] & 0x6F == 0x27
    for _ in range(5):
        cycle.exchange(rx.encode({}))  # controlword 0: disable voltage
        time.sleep(0.01)
    with drive.transaction() as model:
        assert model.object_value(0x6041, 0) & 0x4F == 0x40  # switch on disabled


def test_sm_watchdog_takes_the_slave_to_safeop_error(conn: Connection, wire: Wire) -> None:
    import time

    cycle, plan = _op(conn)
    t = conn.transport()
    t.master.request_state(t.slave.station, ec.AlState.OP)  # type: ignore[attr-defined]
    cycle.exchange(plan.data["rx"].encode({}))
    time.sleep(0.3)  # no outputs for longer than the 100 ms watchdog
    status, code = t.master.al_status(t.slave.station)  # type: ignore[attr-defined]
    assert status == ec.AlState.SAFEOP | ec.AL_ERROR_FLAG and code == 0x001B


def test_safeop_refuses_an_sm2_of_the_wrong_length(conn: Connection) -> None:
    plan = watch.plan(conn, {})
    t = conn.transport()
    cycle = ProcessDataCycle(t.master, t.slave.station, plan.data["rx"].bytes + 2, plan.data["tx"].bytes)  # type: ignore[attr-defined]
    cycle.configure()
    with pytest.raises(DriveError, match="0x0017"):
        t.master.request_state(t.slave.station, ec.AlState.SAFEOP)  # type: ignore[attr-defined]


def test_watch_runs_and_leaves_preop(conn: Connection, wire: Wire) -> None:
    seen: list[int] = []
    result = watch.execute(conn, watch.plan(conn, {}), 0.3, 0.005, lambda v, w, e, c: seen.append(w))
    assert result["cycles"] > 5 and set(seen) == {3} and result["ended"] == "time"
    assert any(v["address"] == "0x6041:00" for v in result["inputs"])
    assert wire.face.esc.al_status & 0x0F == ec.AlState.PREOP


def test_watch_ends_with_exit_3_on_a_wkc_drop(conn: Connection, wire: Wire) -> None:
    real = wire.face.esc._process_logical  # noqa: SLF001
    count = {"n": 0}

    def flaky(d: ec.Datagram) -> None:
        count["n"] += 1
        real(d)
        if count["n"] == 10:
            d.wkc = 1  # the outputs were not taken
    wire.face.esc._process_logical = flaky  # type: ignore[method-assign]  # noqa: SLF001
    with pytest.raises(CommError, match="working counter 1 where 3") as info:
        watch.execute(conn, watch.plan(conn, {}), 5.0, 0.005, lambda *a: None)
    assert info.value.exit_code == 3
    assert wire.face.esc.al_status & 0x0F == ec.AlState.PREOP


def test_watch_ends_with_exit_1_when_the_slave_leaves_op(conn: Connection, wire: Wire) -> None:
    import threading

    threading.Timer(0.15, wire.face.esc.watchdog_expired).start()
    with pytest.raises(DriveError, match="left OP.*0x001B") as info:
        watch.execute(conn, watch.plan(conn, {}), 5.0, 0.005, lambda *a: None)
    assert info.value.exit_code == 1


def test_an_output_that_is_not_mapped_is_refused(conn: Connection) -> None:
    with pytest.raises(UsageError, match="not in the assigned RxPDOs"):
        watch.plan(conn, {(0x6060, 0): 3})
    plan = watch.plan(conn, {(0x6040, 0): 15})
    assert plan.needing_consent


def test_lrd_and_lwr_count_1_and_2(conn: Connection, wire: Wire) -> None:
    """Separate LRD/LWR datagrams (masters that do not use LRW): WKC +1 for the read, +2 for the write in OP."""
    from akdctl.transport.ethercat_raw import LOGICAL_BASE

    cycle, plan = _op(conn)
    t = conn.transport()
    t.master.request_state(t.slave.station, ec.AlState.OP)  # type: ignore[attr-defined]
    rx_bytes, tx_bytes = plan.data["rx"].bytes, plan.data["tx"].bytes
    got = t.master.txrx([ec.logical_datagram(ec.Cmd.LWR, LOGICAL_BASE, bytes(rx_bytes)),  # type: ignore[attr-defined]
                         ec.logical_datagram(ec.Cmd.LRD, LOGICAL_BASE + rx_bytes, bytes(tx_bytes))])
    assert [d.wkc for d in got] == [2, 1]
    outside = t.master.txrx([ec.logical_datagram(ec.Cmd.LRW, 0x00200000, bytes(4))])  # type: ignore[attr-defined]
    assert outside[0].wkc == 0  # no FMMU maps that logical address


def test_missing_frames_while_enabled_raise_f125(conn: Connection, wire: Wire, drive: SimDrive) -> None:
    """Seed 001 5.14: FBUS.PARAM04 = 1 (the EtherCAT default) and more than seven frames missed while the drive is
    enabled: F125 "Synchronization lost". The SM watchdog is switched off (0x0420 = 0) so that this, not the
    watchdog, is what notices the silent master."""
    import time

    cycle, plan = _op(conn)
    t = conn.transport()
    t.master.fpwr(t.slave.station, 0x0420, b"\x00\x00")  # type: ignore[attr-defined]
    t.master.request_state(t.slave.station, ec.AlState.OP)  # type: ignore[attr-defined]
    rx = plan.data["rx"]
    for word in (0x06, 0x07) + (0x0F,) * 10:
        cycle.exchange(rx.encode({(0x6040, 0): word}), with_status=False)
        time.sleep(0.01)
    with drive.transaction() as model:
        assert model.object_value(0x6041, 0) & 0x6F == 0x27
    time.sleep(0.4)  # the master falls silent
    assert wire.face.pd is not None and wire.face.pd.f125 == 1
    with drive.transaction() as model:
        assert 125 in model.faults.situations[0]
        assert model.object_value(0x6041, 0) & 0x6F != 0x27  # no longer operation enabled
