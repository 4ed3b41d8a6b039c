"""Process data in OP between our raw master and the simulated slave (in-process, no root): SM2/SM3 and FMMUs,
LRW with the working counter of the mapping (3 in OP, 1 in SAFE-OP), the RxPDO driving the drive model (the
mapped controlword wins over SDO writes, SPEC-NOTES 23), TxPDO carrying the model's values, the SM watchdog,
the P->S SM length check, and ``ecat pdo watch``'s early ends.

Why no test here sleeps to let the slave act: the slave's application is a free-running thread (every 4 ms) that
takes the outputs of the latest frame only; on a loaded machine (the suite runs ``-n 2`` on 2 cores) it may not run
for a hundred milliseconds, so a word sent for a fixed time may never be seen. The master here does what a real
one does instead: it keeps cycling and watches the statusword (or the slave's state) until the drive followed,
within a generous deadline. And a master stalled that long is what the SM watchdog (100 ms) and F125 supervision
(seven frames) exist to catch: the tests that are not about them switch them off (0x0420 = 0, FBUS.PARAM04 = 0);
the tests that are about them check what the slave counted (``pd.expired``, ``pd.f125``), not a time.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from akdctl.connection import Connection
from akdctl.drive import ecat_pdo_watch as watch
from akdctl.errors import CommError, DriveError, UsageError
from akdctl.protocol import ethercat as ec
from akdctl.sim.drive import SimDrive
from akdctl.transport.ethercat_raw import ProcessDataCycle
from tests.harness import wait_until
from tests.test_ecat_raw_inprocess import Wire, transport

#: Statusword (mask 0x6F) the drive reports once it followed each controlword of the enable sequence (CiA 402).
FOLLOWED = {0x06: 0x21, 0x07: 0x23, 0x0F: 0x27}
DEADLINE = 20.0  # seconds a condition may take on a loaded machine; a quiet one meets it in milliseconds


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
    t = transport(wire)
    # The slave answers from a thread of this process: a loaded machine can hold it past a real master's 0.2 s
    # frame wait (a lost frame ends a cyclic exchange at once). Nothing here is about lost frames, so the wait is
    # the generous one every other condition gets.
    t.master.frame_timeout = DEADLINE
    c = Connection.over(t)
    try:
        yield c
    finally:
        c.close()


def _no_supervision(conn: Connection) -> None:
    """Switch off the SM watchdog (0x0420 = 0) and F125 synchronization supervision (FBUS.PARAM04 = 0): for the
    tests that are about something else, so a stall of this process cannot end OP under them."""
    t = conn.transport()
    t.master.fpwr(t.slave.station, 0x0420, b"\x00\x00")  # type: ignore[attr-defined]
    conn.objects().download(0x36E8, 0, (0).to_bytes(4, "little"))


def _statusword(plan: watch.WritePlan, inputs: bytes) -> int:
    return int({v["address"]: v["value"] for v in plan.data["tx"].decode(inputs)}["0x6041:00"])


def _cycle_until(cycle: ProcessDataCycle, outputs: bytes, done: Callable[[bytes], object], what: str,
                 with_status: bool = True) -> bytes:
    """Exchange *outputs* every 5 ms until ``done(inputs)`` holds (the inputs of that exchange); every exchange in
    OP must count the mapping's working counter 3. Fails naming *what* after :data:`DEADLINE` s."""
    deadline = time.monotonic() + DEADLINE
    while True:
        inputs, wkc, al = cycle.exchange(outputs, with_status=with_status)
        assert wkc == 3 and (al is None or al & 0x0F == ec.AlState.OP), (wkc, al)
        if done(inputs):
            return inputs
        assert time.monotonic() < deadline, f"timed out after {DEADLINE} s waiting for {what}"
        time.sleep(0.005)


def _enable(cycle: ProcessDataCycle, plan: watch.WritePlan, with_status: bool = True) -> bytes:
    """Controlwords 0x06, 0x07, 0x0F through the RxPDO, each cycled until the TxPDO's statusword shows the drive
    followed it (the slave takes only the latest frame: a word it never saw would leave the sequence undone)."""
    rx = plan.data["rx"]
    inputs = b""
    for word, state in FOLLOWED.items():
        inputs = _cycle_until(cycle, rx.encode({(0x6040, 0): word}), lambda i, s=state: _statusword(plan, i) & 0x6F == s,
                              f"statusword 0x{state:02X} after controlword 0x{word:02X}", with_status)
    return inputs


def _op(conn: Connection) -> tuple[ProcessDataCycle, watch.WritePlan]:
    plan = watch.plan(conn, {})
    t = conn.transport()
    cycle = ProcessDataCycle(t.master, t.slave.station, plan.data["rx"].bytes, plan.data["tx"].bytes)  # type: ignore[attr-defined]
    cycle.configure()
    t.master.request_state(t.slave.station, ec.AlState.SAFEOP)  # type: ignore[attr-defined]
    return cycle, plan


def test_wkc_is_1_in_safeop_and_3_in_op_and_the_controlword_drives_the_model(conn: Connection, wire: Wire,
                                                                             drive: SimDrive) -> None:
    _no_supervision(conn)
    cycle, plan = _op(conn)
    rx = plan.data["rx"]
    assert rx.has(0x6040, 0) and cycle.expected_wkc == 3
    assert cycle.exchange(rx.encode({}))[1] == 1  # SAFE-OP: inputs only
    t = conn.transport()
    t.master.request_state(t.slave.station, ec.AlState.OP)  # type: ignore[attr-defined]
    inputs = _enable(cycle, plan)
    assert _statusword(plan, inputs) & 0x6F == 0x27  # operation enabled, reported by the TxPDO
    # an SDO write of the controlword has no effect while the mapped one is cycled (SPEC-NOTES 23): not on the
    # model now, and not on the TxPDO after the application ran two more cycles behind fresh frames
    conn.objects().download(0x6040, 0, struct.pack("<H", 0))
    with drive.transaction() as model:
        assert model.object_value(0x6041, 0) & 0x6F == 0x27
    assert wire.face.pd is not None
    after = wire.face.pd.cycles
    _cycle_until(cycle, rx.encode({(0x6040, 0): 0x0F}), lambda _i: wire.face.pd.cycles >= after + 2,  # type: ignore[union-attr]
                 "two application cycles after the SDO write")
    inputs, _wkc, _al = cycle.exchange(rx.encode({(0x6040, 0): 0x0F}))
    assert _statusword(plan, inputs) & 0x6F == 0x27
    _cycle_until(cycle, rx.encode({}), lambda i: _statusword(plan, i) & 0x4F == 0x40,  # controlword 0: disable voltage
                 "switch on disabled after controlword 0")
    with drive.transaction() as model:
        assert model.object_value(0x6041, 0) & 0x4F == 0x40  # switch on disabled


def test_sm_watchdog_takes_the_slave_to_safeop_error(conn: Connection, wire: Wire) -> None:
    """The watchdog is armed once the slave is in OP with outputs taken: armed before, it could expire while a
    loaded machine is still polling for OP (then OP looks refused with the same code)."""
    cycle, plan = _op(conn)
    t = conn.transport()
    station = t.slave.station  # type: ignore[attr-defined]
    armed = t.master.fprd(station, 0x0420, 2)  # type: ignore[attr-defined]
    assert armed == struct.pack("<H", 1000)  # power-on value: 1000 units of 100 us
    t.master.fpwr(station, 0x0420, b"\x00\x00")  # type: ignore[attr-defined]
    t.master.request_state(station, ec.AlState.OP)  # type: ignore[attr-defined]
    assert cycle.exchange(plan.data["rx"].encode({}))[1:] == (3, ec.AlState.OP)
    assert wire.face.pd is not None and wire.face.pd.expired == 0
    t.master.fpwr(station, 0x0420, armed)  # type: ignore[attr-defined]
    # no outputs any more: once 100 ms passed without one the watchdog expires (a loaded machine may take longer
    # to notice, never less)
    wait_until(lambda: t.master.al_status(station)[0] & ec.AL_ERROR_FLAG, "the SM watchdog",  # type: ignore[attr-defined]
               timeout=DEADLINE)
    status, code = t.master.al_status(station)  # type: ignore[attr-defined]
    assert status == ec.AlState.SAFEOP | ec.AL_ERROR_FLAG and code == 0x001B
    assert wire.face.pd.expired == 1


def test_safeop_refuses_an_sm2_of_the_wrong_length(conn: Connection) -> None:
    plan = watch.plan(conn, {})
    t = conn.transport()
    cycle = ProcessDataCycle(t.master, t.slave.station, plan.data["rx"].bytes + 2, plan.data["tx"].bytes)  # type: ignore[attr-defined]
    cycle.configure()
    with pytest.raises(DriveError, match="0x0017"):
        t.master.request_state(t.slave.station, ec.AlState.SAFEOP)  # type: ignore[attr-defined]


def test_watch_runs_and_leaves_preop(conn: Connection, wire: Wire) -> None:
    _no_supervision(conn)  # a stall of this process must not end the watch early (exit 1 has its own test)
    seen: list[int] = []
    result = watch.execute(conn, watch.plan(conn, {}), 1.0, 0.005, lambda v, w, e, c: seen.append(w))
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
    _no_supervision(conn)  # the drop must be what ends the watch, not a watchdog a stalled test would trip
    with pytest.raises(CommError, match="working counter 1 where 3") as info:
        watch.execute(conn, watch.plan(conn, {}), 5.0, 0.005, lambda *a: None)
    assert info.value.exit_code == 3
    assert wire.face.esc.al_status & 0x0F == ec.AlState.PREOP


def test_watch_ends_with_exit_1_when_the_slave_leaves_op(conn: Connection, wire: Wire) -> None:
    """The slave leaves OP while the watch cycles: taken out at the watch's second display refresh (in OP by
    then), not after a fixed time that a loaded machine may reach before OP."""
    _no_supervision(conn)  # the slave leaves OP when this test says, not when a stall trips the watchdog first
    samples = {"n": 0}

    def on_sample(*_a: object) -> None:
        samples["n"] += 1
        if samples["n"] == 2:
            wire.face.esc.watchdog_expired()

    with pytest.raises(DriveError, match="left OP.*0x001B") as info:
        watch.execute(conn, watch.plan(conn, {}), 60.0, 0.005, on_sample)
    assert info.value.exit_code == 1 and samples["n"] == 2


def test_an_output_that_is_not_mapped_is_refused(conn: Connection) -> None:
    with pytest.raises(UsageError, match="not in the assigned RxPDOs"):
        watch.plan(conn, {(0x6060, 0): 3})
    plan = watch.plan(conn, {(0x6040, 0): 15})
    assert plan.needing_consent


def test_an_output_no_class_gates_still_needs_consent(conn: Connection) -> None:
    """Any value given with --out is written every cycle in OP: the plan asks consent for it even where the
    object's class does not gate it (0x60FE:1, the physical outputs); the CLI only asks what the plan says
    (cli/consent.consent_plan)."""
    sdo = conn.objects()   # RxPDO 0x1600 = the physical outputs, which no write class gates
    for index, sub, value in ((0x1C12, 0, 0), (0x1600, 0, 0), (0x1600, 1, 0x60FE0120), (0x1600, 0, 1),
                              (0x1C12, 1, 0x1600), (0x1C12, 0, 1)):
        sdo.download(index, sub, value.to_bytes(1 if sub == 0 else 2 if index == 0x1C12 else 4, "little"))
    fields = [(entry.index, entry.subindex) for entry, *_ in watch.plan(conn, {}).data["rx"].fields]
    assert fields == [(0x60FE, 1)] and not watch.plan(conn, {}).needing_consent
    for address in fields:
        plan = watch.plan(conn, {address: 1})
        assert len(plan.needing_consent) == 1 and f"0x{address[0]:04X}:" in plan.needing_consent[0].address


def test_lrd_and_lwr_count_1_and_2(conn: Connection, wire: Wire) -> None:
    """Separate LRD/LWR datagrams (masters that do not use LRW): WKC +1 for the read, +2 for the write in OP."""
    from akdctl.transport.ethercat_raw import LOGICAL_BASE

    _no_supervision(conn)  # no frame cycles here: a stall before the first one must not trip the watchdog
    _cycle, plan = _op(conn)
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
    cycle, plan = _op(conn)
    t = conn.transport()
    t.master.fpwr(t.slave.station, 0x0420, b"\x00\x00")  # type: ignore[attr-defined]
    t.master.request_state(t.slave.station, ec.AlState.OP)  # type: ignore[attr-defined]
    rx = plan.data["rx"]
    # one frame every 50 ms: seven missed frames are then 0.35 s, more than this loop stalls on a loaded machine
    # while the drive is enabled (it reads the statusword at once); a real stall would show as F125 below anyway
    deadline = time.monotonic() + DEADLINE
    for word, state in FOLLOWED.items():
        while True:
            inputs, wkc, _al = cycle.exchange(rx.encode({(0x6040, 0): word}), with_status=False)
            if wkc == 3 and _statusword(plan, inputs) & 0x6F == state:
                break
            assert time.monotonic() < deadline, f"the drive did not follow controlword 0x{word:02X}"
            time.sleep(0.05)
    assert wire.face.pd is not None and wire.face.pd.f125 == 0
    with drive.transaction() as model:
        assert model.object_value(0x6041, 0) & 0x6F == 0x27
    # the master falls silent: more than seven frame periods pass (a loaded machine notices later, never sooner)
    wait_until(lambda: wire.face.pd.f125, "F125 after the master fell silent", timeout=DEADLINE)  # type: ignore[union-attr]
    assert wire.face.pd.f125 == 1
    with drive.transaction() as model:
        assert 125 in model.faults.situations[0]
        assert model.object_value(0x6041, 0) & 0x6F != 0x27  # no longer operation enabled
