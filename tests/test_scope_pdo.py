"""The scope's pdo source without root: the cycle -> row logic (pre-trigger ring, trigger index, gaps of a late
host, a trigger that never fires, the cycle stopping) against an in-process fake of CyclicInputs; the bus adapter's
pacing and verdicts against a fake cycle and clock; and ``scope --source pdo`` planned and recorded through the
real raw master against the simulated slave over a socketpair (tests/test_ecat_raw_inprocess.Wire)."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import pytest

from akdctl.catalog.objects import PdoEntry
from akdctl.connection import Connection
from akdctl.drive import scope as op
from akdctl.drive import scope_pdo
from akdctl.drive.ecat_pdo_watch import Layout
from akdctl.drive.scope_model import Recording
from akdctl.drive.scope_pdo_bus import WARMUP_S, BusInputs
from akdctl.drive.scope_poll import RateNotReached
from akdctl.drive.scope_trigger import parse_trigger
from akdctl.errors import CommError, DriveError, Interrupted, TriggerTimeout, UsageError
from akdctl.protocol import ethercat as ec
from akdctl.sim.drive import SimDrive

CYCLE = 0.002
TX = Layout([(0x1A00, (PdoEntry(0x606C, 0, 32), PdoEntry(0x6041, 0, 16)))])


class FakeInputs:
    """Cycles of (velocity counts/s, status word); ``late`` cycle numbers are skipped (a late host); the cycle
    stops with ``error`` after ``stop_after`` images."""

    cycle_s = CYCLE

    def __init__(self, rows: list[tuple[int, int]], late: frozenset[int] = frozenset(),
                 stop_after: int | None = None, error: Exception | None = None) -> None:
        self.rows, self.late = rows, late
        self.number = -1
        self.given = 0
        self.stop_after, self.error = stop_after, error

    def next_inputs(self, timeout: float) -> tuple[int, bytes]:
        if self.stop_after is not None and self.given >= self.stop_after:
            raise self.error or CommError("no frame")
        self.number += 1
        while self.number in self.late:
            self.number += 1
        velocity, status = self.rows[min(self.number, len(self.rows) - 1)]
        self.given += 1
        return self.number, struct.pack("<iH", velocity, status)

    def bus_time(self, host_t: float) -> float:
        return host_t


def _spec(names: list[str], trigger: str | None = None, cycles: int = 10, pre: float = 0.0) -> tuple[
        scope_pdo.PdoSpec, object]:
    trig = parse_trigger(trigger)
    columns, width, tslot, sslot = scope_pdo.resolve_columns(TX, names, trig)
    spec = scope_pdo.PdoSpec(columns, width, CYCLE, cycles, min(cycles - 1, round(cycles * pre / 100)),
                             trigger_slot=tslot, status_slot=sslot)
    return spec, trig


def _record(inputs: FakeInputs, names: list[str], trigger: str | None = None, cycles: int = 10, pre: float = 0.0,
            timeout: float = 1.0) -> tuple[Recording, Exception | None]:
    spec, trig = _spec(names, trigger, cycles, pre)
    recording = Recording("t", "pdo", [c.channel for c in spec.columns[:spec.width]], trigger=trig.text)  # type: ignore[attr-defined]
    failure = scope_pdo.record(inputs, spec, recording, trig, stopped=lambda: False, timeout_s=timeout)  # type: ignore[arg-type]
    return recording, failure


def _ramp(n: int, step: int = 65536) -> list[tuple[int, int]]:
    return [(k * step, 0x0237) for k in range(n)]


def test_immediate_rows_are_cycles_on_the_bus_clock_in_the_signal_units() -> None:
    recording, failure = _record(FakeInputs(_ramp(20)), ["VL.FB", "0x606C"], cycles=10)
    assert failure is None and recording.partial is None
    assert len(recording) == 10 and recording.trigger_index == 0
    assert recording.times == pytest.approx([k * CYCLE for k in range(10)])
    assert recording.column("VL.FB") == pytest.approx([60.0 * k for k in range(10)])  # 65536 counts/s = 60 rpm
    assert recording.column("0x606C") == [65536.0 * k for k in range(10)]
    assert recording.channels[0].unit == "rpm" and recording.channels[0].address == "TxPDO 0x606C:0"


def test_pretrigger_ring_keeps_the_cycles_before_the_trigger() -> None:
    # velocity crosses 5.5 * 65536 at cycle 6; 40 % of 10 cycles = 4 before it
    recording, failure = _record(FakeInputs(_ramp(40)), ["0x606C"], trigger="rise:0x606C:360000", cycles=10,
                                 pre=40)
    assert failure is None
    assert recording.trigger_index == 4 and len(recording) == 10
    assert recording.column("0x606C")[4] == 6 * 65536
    assert recording.times[:5] == pytest.approx([-4 * CYCLE, -3 * CYCLE, -2 * CYCLE, -CYCLE, 0.0])
    assert recording.times[-1] == pytest.approx(5 * CYCLE)


def test_the_trigger_is_looked_for_only_once_the_ring_is_full() -> None:
    # above fires at once, but 3 cycles must come first: the trigger is cycle 3
    recording, _ = _record(FakeInputs(_ramp(40)), ["0x606C"], trigger="above:0x606C:-1", cycles=8, pre=40)
    assert recording.trigger_index == 3 and recording.column("0x606C")[3] == 3 * 65536


def test_a_status_bit_trigger_reads_the_mapped_status_word_hidden() -> None:
    rows = [(0, 0x0237)] * 5 + [(0, 0x0238)] * 20  # bit 3 (fault) rises at cycle 5
    recording, failure = _record(FakeInputs(rows), ["0x606C"], trigger="fault", cycles=6, pre=50)
    assert failure is None and recording.trigger_index == 3
    assert [c.name for c in recording.channels] == ["0x606C"]  # the status word is not a recorded column


def test_a_trigger_that_never_fires_is_exit_3_and_keeps_the_pretrigger_cycles() -> None:
    recording, failure = _record(FakeInputs(_ramp(10, step=0)), ["0x606C"], trigger="rise:0x606C:5", cycles=10,
                                 pre=30, timeout=0.05)
    assert isinstance(failure, TriggerTimeout) and failure.exit_code == 3
    assert recording.partial and "did not fire" in recording.partial and recording.trigger_index is None
    assert 1 <= len(recording) <= 4  # the ring: at most the pre-trigger cycles and the one looked at


def test_late_cycles_are_gaps_and_too_many_are_rate_not_reached() -> None:
    recording, failure = _record(FakeInputs(_ramp(40), late=frozenset({3, 4})), ["0x606C"], cycles=20)
    assert failure is None  # 18 of 20 cycles: within the tolerance
    assert recording.times[3] - recording.times[2] == pytest.approx(3 * CYCLE)
    assert any("no sample for 2 of 20 bus cycles" in n for n in recording.notes)
    recording, failure = _record(FakeInputs(_ramp(40), late=frozenset(range(2, 12, 2))), ["0x606C"], cycles=20)
    assert isinstance(failure, RateNotReached) and failure.exit_code == 3
    assert recording.partial and "15 of 20" in recording.partial


def test_cycles_spent_in_the_recorded_motions_sdo_requests_do_not_count_against_the_rate() -> None:
    import time

    spec, trig = _spec(["0x606C"], None, 20)
    recording = Recording("t", "pdo", [c.channel for c in spec.columns[:spec.width]])
    # the jog's start takes the host 11+ cycles (SDO writes, the drive enabling): those cycles are gaps
    failure = scope_pdo.record(FakeInputs(_ramp(40), late=frozenset(range(1, 11))), spec, recording, trig,  # type: ignore[arg-type]
                               stopped=lambda: False, timeout_s=1.0, on_first=lambda: time.sleep(0.022))
    assert failure is None and recording.partial is None
    assert recording.times[1] - recording.times[0] == pytest.approx(11 * CYCLE)
    assert any("the recorded motion's SDO requests" in n for n in recording.notes)


def test_the_cycle_stopping_keeps_the_rows_taken() -> None:
    recording, failure = _record(FakeInputs(_ramp(40), stop_after=5,
                                            error=CommError("working counter 0 where 1 was expected")),
                                 ["0x606C"], cycles=20)
    assert isinstance(failure, CommError) and failure.exit_code == 3
    assert len(recording) == 5 and recording.partial and "working counter 0" in recording.partial


def test_an_unmapped_signal_names_what_is_mapped() -> None:
    with pytest.raises(UsageError, match=r"0x6064:00 is not in the mapped TxPDO \(0x606C:00, 0x6041:00\)"):
        _spec(["PL.FB"])
    with pytest.raises(UsageError, match="0x6077:00 is not in the mapped TxPDO"):
        _spec(["0x606C"], trigger="rise:IL.FB:5")
    layout = Layout([(0x1A00, (PdoEntry(0x606C, 0, 32),))])
    with pytest.raises(UsageError, match="0x6041:00 is not in the mapped"):
        scope_pdo.resolve_columns(layout, ["0x606C"], parse_trigger("fault"))


@pytest.mark.parametrize(("rate", "problem"), [(8000.0, "shortest cycle is 250 us"), (300.0, "multiple of 62.5 us"),
                                               (5.0, "at least")])
def test_a_rate_the_bus_cannot_run_is_exit_2(rate: float, problem: str) -> None:
    with pytest.raises(UsageError, match=problem) as info:
        scope_pdo.cycle_for(rate, None)
    assert info.value.exit_code == 2


def test_the_cycle_is_the_rate_or_the_drives_0x60c2() -> None:
    assert scope_pdo.cycle_for(500.0, None)[0] == pytest.approx(0.002)
    assert scope_pdo.cycle_for(4000.0, None)[0] == pytest.approx(0.00025)
    assert scope_pdo.cycle_for(None, (4, -3))[0] == pytest.approx(0.004)
    assert scope_pdo.cycle_for(None, (3, -4))[0] == pytest.approx(0.002)  # 300 us is off the grid: the default


# ---------------------------------------------------------------------- the bus adapter
class FakeCycle:
    rx_bytes, tx_bytes, cycles = 4, 6, 0
    safeop_wkc = 1

    def __init__(self, wkc: list[int] | None = None, al: int = ec.AlState.SAFEOP) -> None:
        self.calls: list[str] = []
        self.wkc = wkc or []
        self.al = al
        self.state = ec.AlState.PREOP

    def al_status(self) -> tuple[int, int]:
        return self.state, 0x001B if self.al != ec.AlState.SAFEOP else 0

    def request_state(self, state: int) -> tuple[int, int]:
        self.calls.append(f"state {ec.al_state_name(state)}")
        self.state = state
        return state, 0

    def configure(self) -> None:
        self.calls.append("configure")

    def exchange(self, outputs: bytes, with_status: bool = True) -> tuple[bytes, int, int | None]:
        assert outputs == bytes(4)  # the all-zero outputs, every cycle
        self.cycles += 1
        self.calls.append("exchange")
        wkc = self.wkc.pop(0) if self.wkc else 1
        return bytes(6), wkc, (self.al if with_status else None)


class Clock:
    def __init__(self) -> None:
        self.now = 100.0
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.slept.append(seconds)
        self.now += seconds


def test_bus_paces_cycles_and_numbers_late_ones_as_gaps() -> None:
    cycle, clock = FakeCycle(), Clock()
    with BusInputs(cycle, CYCLE, clock=clock, sleep=clock.sleep) as bus:
        warm = cycle.cycles - 1  # exchanged and dropped after SAFE-OP, before cycle 0
        assert warm == round(WARMUP_S / CYCLE) and sum(clock.slept) == pytest.approx(WARMUP_S)
        clock.slept.clear()
        assert bus.next_inputs(1.0)[0] == 0
        assert bus.next_inputs(1.0)[0] == 1 and clock.slept == [pytest.approx(CYCLE)]
        clock.now += 3.5 * CYCLE  # the host was busy (an SDO between cycles)
        # 4.5 cycles after cycle 0: no sleep, no burst; cycles 2 and 3 are gaps, this is cycle 4 (half late)
        assert bus.next_inputs(1.0)[0] == 4 and len(clock.slept) == 1
        assert bus.next_inputs(1.0)[0] == 5 and clock.slept[-1] == pytest.approx(CYCLE / 2)
        assert bus.bus_time(clock.now) == pytest.approx(5 * CYCLE)
    assert cycle.calls[:3] == ["configure", "state SAFEOP", "exchange"]
    assert "state OP" not in cycle.calls  # outputs are never applied
    assert cycle.calls[-2:] == ["exchange", "state PREOP"]  # outputs 0 once more, then PRE-OP


def test_bus_wkc_drop_is_comm_error_and_leaving_safeop_is_drive_error_both_left_in_preop() -> None:
    cycle, clock = FakeCycle(), Clock()
    with pytest.raises(CommError, match="working counter 0 where 1") as info:
        with BusInputs(cycle, CYCLE, clock=clock, sleep=clock.sleep) as bus:
            cycle.wkc = [1, 1, 0]
            for _ in range(5):
                bus.next_inputs(1.0)
    assert info.value.exit_code == 3 and cycle.calls[-1] == "state PREOP"
    cycle = FakeCycle(al=ec.AlState.SAFEOP | ec.AL_ERROR_FLAG)
    with pytest.raises(DriveError, match="left SAFEOP.*0x001B") as drive_info:
        with BusInputs(cycle, CYCLE, clock=clock, sleep=clock.sleep) as bus:
            bus.next_inputs(1.0)
    assert drive_info.value.exit_code == 1 and cycle.calls[-1] == "state PREOP"


def test_a_lost_frame_is_a_gap_and_frames_lost_past_the_limit_stop_the_cycle() -> None:
    from akdctl.errors import NoAnswer

    cycle, clock = FakeCycle(), Clock()
    real = cycle.exchange
    lose = {"n": 0}

    def exchange(outputs: bytes, with_status: bool = True) -> tuple[bytes, int, int | None]:
        if lose["n"]:
            lose["n"] -= 1
            clock.now += 0.2  # the master's frame timeout
            raise NoAnswer("no EtherCAT frame came back")
        return real(outputs, with_status)

    cycle.exchange = exchange  # type: ignore[method-assign]
    with pytest.raises(NoAnswer) as info:
        with BusInputs(cycle, CYCLE, clock=clock, sleep=clock.sleep, lost_limit_s=1.0) as bus:
            assert bus.next_inputs(1.0)[0] == 0
            lose["n"] = 1
            number, _ = bus.next_inputs(1.0)  # cycle 1's frame lost: 0.2 s of slots passed, the next is a gap later
            assert number in (100, 101) and bus.lost == 1  # 0.202 s after cycle 0 (float rounding either side)
            lose["n"] = 10
            bus.next_inputs(1.0)  # lost for more than 1 s: the cycle stopped
    assert info.value.exit_code == 3 and cycle.calls[-1] == "state PREOP"


def test_bus_is_left_in_preop_on_ctrl_c() -> None:
    cycle, clock = FakeCycle(), Clock()
    with pytest.raises(KeyboardInterrupt):
        with BusInputs(cycle, CYCLE, clock=clock, sleep=clock.sleep) as bus:
            bus.next_inputs(1.0)
            raise KeyboardInterrupt
    assert cycle.calls[-1] == "state PREOP"


# ---------------------------------------------------------------------- the real master, in-process
# The simulated slave with its process data running, its wire and a Connection over it: the fixtures the
# ``ecat pdo watch`` tests use.
from tests.test_ecat_process_data import conn, drive, wire  # noqa: E402,F401


def test_plan_refuses_a_target_that_is_not_a_cyclic_master(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target

    monkeypatch.setenv("AKDCTL_STATE_DIR", str(tmp_path))
    sim = Connection(parse_target("sim"), LinkOptions())
    try:
        assert not sim.has_process_data
        with pytest.raises(UsageError, match="needs this host as the EtherCAT master"):
            op.plan(sim, op.build_request(["0x6041"], source="pdo"))
    finally:
        sim.close()


def test_record_over_the_raw_master_in_safeop_and_back_to_preop(conn: Connection, drive: SimDrive) -> None:
    assert conn.has_process_data
    request = op.build_request(["STATUSWORD", "0x6063"], samples=30, rate_hz=100.0, source="pdo")
    plan = op.plan(conn, request)
    assert not plan.needing_consent and any("SAFE-OP" in n for n in plan.notes)
    recording, failure = op.execute(conn, plan, stopped=lambda: False)
    # a loaded machine may make the host late for cycles: then the recording says so (partial, exit 3)
    assert failure is None or isinstance(failure, RateNotReached), failure
    assert recording.source == "pdo" and recording.times[-1] == pytest.approx(0.29)
    assert all(round((b - a) / 0.01) >= 1 and (b - a) / 0.01 == pytest.approx(round((b - a) / 0.01))
               for a, b in zip(recording.times, recording.times[1:]))  # whole bus cycles apart
    assert all(int(v) & 0x4F == 0x40 for v in recording.column("STATUSWORD"))  # switch on disabled, from the TxPDO
    assert conn.al_state() == "PREOP"


def test_a_trigger_that_never_fires_over_the_raw_master_is_partial_and_leaves_preop(conn: Connection) -> None:
    request = op.build_request(["STATUSWORD"], samples=20, rate_hz=100.0, source="pdo", trigger="bit:3",
                               pretrigger=20, timeout_s=0.2)
    recording, failure = op.execute(conn, op.plan(conn, request), stopped=lambda: False)
    assert isinstance(failure, TriggerTimeout) and recording.partial and "did not fire" in recording.partial
    assert conn.al_state() == "PREOP"


def test_ctrl_c_over_the_raw_master_ends_partial_and_leaves_preop(conn: Connection) -> None:
    calls = {"n": 0}

    def stopped() -> bool:
        calls["n"] += 1
        return calls["n"] > 5

    request = op.build_request(["STATUSWORD"], samples=200, rate_hz=100.0, source="pdo")
    recording, failure = op.execute(conn, op.plan(conn, request), stopped=stopped)
    assert isinstance(failure, Interrupted) and len(recording) == 5 and recording.partial
    assert conn.al_state() == "PREOP"


def test_cli_and_recipe_build_the_same_pdo_plan(conn: Connection) -> None:
    from akdctl.recipe.loader import RawStep
    from akdctl.recipe.schema import Context, validate_step

    raw = RawStep({"action": "scope", "signals": ["STATUSWORD"], "source": "pdo", "rate": 500, "samples": 50,
                   "trigger": "bit:3", "pretrigger": 10}, Path("r.toml"), 4, number=1)
    step = validate_step(raw, Context(folder=Path("."), conn=conn))
    cli = op.build_request(["STATUSWORD"], source="pdo", rate_hz=500, samples=50, trigger="bit:3", pretrigger=10)
    assert step.params["request"] == cli
    recipe_plan, cli_plan = op.plan(conn, step.params["request"]), op.plan(conn, cli)
    assert recipe_plan.to_json() == cli_plan.to_json()
    assert (recipe_plan.data["pdo"].cycles, recipe_plan.data["pdo"].pre) == (50, 5)


def test_the_slave_leaving_safeop_ends_the_recording_with_exit_1(conn: Connection, drive: SimDrive) -> None:
    import threading

    def leave() -> None:
        with drive.transaction() as model:
            model.pdo.set_al_state("PREOP")  # someone else took the slave out of SAFE-OP

    request = op.build_request(["STATUSWORD"], samples=300, rate_hz=100.0, source="pdo")
    plan = op.plan(conn, request)
    timer = threading.Timer(0.3, leave)
    timer.start()
    try:
        recording, failure = op.execute(conn, plan, stopped=lambda: False)
    finally:
        timer.cancel()
    assert isinstance(failure, DriveError) and failure.exit_code == 1 and "left SAFEOP" in failure.message
    assert recording.partial and "left SAFEOP" in recording.partial and 5 <= len(recording) < 300
    assert conn.al_state() == "PREOP"


def test_a_silent_slave_stops_the_cycle_with_exit_3_after_the_link_timeout(conn: Connection, wire: Any) -> None:
    import threading

    request = op.build_request(["STATUSWORD"], samples=300, rate_hz=100.0, source="pdo")
    plan = op.plan(conn, request)
    # The link timeout under test is the master's frame wait: the real one (the transport's 0.5 s), not the 20 s the
    # fixture gives tests that are not about lost frames -- each wait for the silent slave (the lost cycle, then
    # leaving SAFE-OP: outputs 0 and PRE-OP with its retries) would otherwise take 20 s, ~100 s in all. A loaded
    # host that holds the slave past it before the silence merely loses a frame (a gap) sooner.
    conn.transport().master.frame_timeout = 0.5  # type: ignore[attr-defined]
    timer = threading.Timer(0.3, lambda: setattr(wire, "silent", True))
    timer.start()
    try:
        recording, failure = op.execute(conn, plan, stopped=lambda: False)
    finally:
        timer.cancel()
    assert failure is not None and failure.exit_code == 3 and "no EtherCAT frame came back" in failure.message
    assert recording.partial and 5 <= len(recording) < 300
    assert any("did not come back" in n for n in recording.notes)
