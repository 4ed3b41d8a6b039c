"""``akdctl scope``: the sample model, the poll and recorder sources, the outputs and every bad input.

The simulated drive is the peer: a polled recording during a simulated jog must show the ramp in CSV and SVG with
monotonic time and the rate achieved; a recorder recording over the simulated ASCII channel must hold exactly the
requested samples at the gap's spacing (foe-alias-recorder.md §C1: t = k x REC.GAP x 62.5 us).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from akdctl.drive.scope_model import Channel, Recording
from akdctl.drive.scope_poll import PollSpec, record
from akdctl.drive.scope_trigger import parse_trigger
from akdctl.errors import (
    EXIT_COMM,
    EXIT_DRIVE,
    EXIT_USAGE,
    CommError,
    TriggerTimeout,
    UsageError,
)


# ------------------------------------------------------------------ model
def _recording() -> Recording:
    rec = Recording("sim", "poll", [Channel("VL.FB", "rpm", "PNU 6"), Channel("PL.ERR", "rev", "0x60F4:0")],
                    trigger="rise VL.FB 10", rate_requested=100.0)
    for k in range(11):
        rec.add(k * 0.01, [k * 5.0, k * 0.001])
    rec.trigger_index = 2
    rec.shift_to_trigger()
    return rec


def test_csv_names_units_and_the_recording_facts() -> None:
    text = _recording().to_csv()
    lines = text.splitlines()
    assert lines[0].startswith("# akdctl scope: target=sim source=poll rate=100Hz requested=100Hz")
    assert "trigger=rise VL.FB 10" in lines[0] and "trigger_index=2" in lines[0]
    assert lines[1] == "t [s],VL.FB [rpm],PL.ERR [rev]"
    assert lines[2].startswith("-0.020000,0,0")
    assert lines[4].startswith("0.000000,10,0.002")


def test_json_round_trip_and_partial_marks() -> None:
    rec = _recording()
    rec.mark_partial("stopped after 11 samples: no answer")
    again = Recording.from_json(json.loads(json.dumps(rec.to_json())))
    assert again.to_csv() == rec.to_csv()
    assert "# PARTIAL: stopped after 11 samples" in rec.to_csv()
    with pytest.raises(ValueError):
        Recording.from_json({"format": "akdctl-scope", "channels": [{"name": "a"}], "t": [0.0], "values": []})


# ------------------------------------------------------------------ poll loop (a fake clock: no sleeping)
class _Clock:
    def __init__(self, read_cost: float) -> None:
        self.now = 100.0
        self.read_cost = read_cost

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


def _poll(values: list[float], spec: PollSpec, read_cost: float = 0.001) -> tuple[Recording, object]:
    clock = _Clock(read_cost)
    stream = iter(values)

    def read() -> list[float]:
        clock.now += clock.read_cost
        return [next(stream)]

    rec = Recording("t", "poll", [Channel("X", "u")], trigger=spec.trigger.text, rate_requested=spec.rate_hz)
    failure = record(read, rec, spec, trigger_slot=0, clock=clock, sleep=clock.sleep)
    return rec, failure


def test_poll_paces_to_the_rate_and_stamps_real_times() -> None:
    rec, failure = _poll([float(k) for k in range(100)], PollSpec(samples=20, rate_hz=50.0))
    assert failure is None and len(rec) == 20
    steps = [b - a for a, b in zip(rec.times, rec.times[1:])]
    assert all(step == pytest.approx(0.02) for step in steps)
    assert rec.rate_achieved == pytest.approx(50.0)


def test_an_unreachable_rate_is_reported_not_pretended() -> None:
    rec, failure = _poll([float(k) for k in range(100)], PollSpec(samples=10, rate_hz=1000.0), read_cost=0.01)
    assert isinstance(failure, CommError) and "rate not reached" in failure.message
    assert rec.rate_achieved == pytest.approx(100.0)
    assert rec.partial and "requested 1000" in rec.partial


def test_pretrigger_keeps_the_share_before_the_edge() -> None:
    values = [0.0] * 30 + [float(k) for k in range(1, 60)]
    rec, failure = _poll(values, PollSpec(samples=10, rate_hz=100.0, trigger=parse_trigger("rise:X:2.5"),
                                          pretrigger=30))
    assert failure is None and len(rec) == 10 and rec.trigger_index == 3
    assert rec.values[0][3] == 3.0 and rec.values[0][2] == 2.0  # the crossing sample is t = 0
    assert rec.times[3] == 0.0 and rec.times[0] < 0


def test_a_trigger_that_never_fires_times_out_with_the_pretrigger_samples() -> None:
    rec, failure = _poll([0.0] * 10_000, PollSpec(samples=10, rate_hz=100.0, trigger=parse_trigger("rise:X:5"),
                                                  pretrigger=20, timeout_s=0.5))
    assert isinstance(failure, TriggerTimeout)
    assert rec.partial and "no trigger" in rec.partial and rec.trigger_index is None


@pytest.mark.parametrize("text", ["rise:X", "bit:16", "bit:x", "sideways:X:1", "rise:X:nan", "above::3"])
def test_bad_triggers_are_usage_errors(text: str) -> None:
    with pytest.raises(UsageError, match="trigger"):
        parse_trigger(text)


def test_status_bit_trigger_is_an_edge() -> None:
    fault = parse_trigger("fault")
    assert not fault.fires(None, 0x0008) and not fault.fires(0x0008, 0x0008)
    assert fault.fires(0x0027, 0x0008)
    assert parse_trigger("bit:10=0").fires(0x0400, 0)


# ------------------------------------------------------------------ CLI against the simulated drive
def _csv(path: Path) -> tuple[list[str], list[list[float]]]:
    lines = path.read_text().splitlines()
    rows = [[float(v) for v in line.split(",")] for line in lines if line and not line.startswith(("#", "t ["))]
    return lines, rows


def test_polled_recording_during_a_jog_shows_the_ramp(akd_inproc, tmp_path: Path) -> None:
    csv, svg = tmp_path / "jog.csv", tmp_path / "jog.svg"
    # --for leaves 1.4 s after the jog's 0.8 s for the stop ramp to reach 0 rpm: with 0.8 s, a loaded host (the suite
    # at -n 2) once ended the recording on the last few rpm of the ramp
    code, _out, err = akd_inproc("-y", "scope", "VL.FB", "PL.ERR", "--jog", "600", "--jog-for", "0.8s",
                                "--for", "2.2s", "--csv", str(csv), "--svg", str(svg), "--no-plot")
    assert code == 0, err
    lines, rows = _csv(csv)
    assert lines[0].startswith("# akdctl scope: target=sim source=poll rate=")
    assert lines[next(i for i, l in enumerate(lines) if l.startswith("t ["))] == "t [s],VL.FB [rpm],PL.ERR [rev]"
    times = [r[0] for r in rows]
    assert times == sorted(set(times)) and times[0] == 0.0  # strictly monotonic host time
    velocity = [r[1] for r in rows]
    assert velocity[0] == 0.0 and max(velocity) == pytest.approx(600.0, abs=1.0) and velocity[-1] == 0.0
    ramp = velocity[: velocity.index(max(velocity))]
    assert len([v for v in ramp if 50 < v < 550]) >= 2  # samples on the ramp, not a step
    achieved = float(re.search(r"rate=([\d.]+)Hz", lines[0]).group(1))
    assert achieved == pytest.approx((len(rows) - 1) / (times[-1] - times[0]), rel=1e-3)
    assert "samples/s achieved" in err
    picture = svg.read_text()
    for text in ("VL.FB [rpm] (PNU 6)", "PL.ERR [rev] (0x60F4:0)", ">rpm<", ">rev<", "time [s]", ">trigger<"):
        assert text in picture
    assert "<polyline" in picture


def test_recorder_over_the_simulated_ascii_channel_has_exact_samples(akd_inproc, tmp_path: Path) -> None:
    out_json = tmp_path / "rec.json"
    code, out, err = akd_inproc("--json", "scope", "VL.FB", "VL.CMD", "PL.ERR", "--source", "recorder",
                                "--samples", "300", "--rate", "4000")
    assert code == 0, err
    data = json.loads(out)["recording"]
    assert data["samples"] == 300 and data["source"] == "recorder"
    steps = {round(b - a, 9) for a, b in zip(data["t"], data["t"][1:])}
    assert steps == {0.00025}  # REC.GAP 4 x 62.5 us
    assert data["rate_hz"]["achieved"] == pytest.approx(4000.0)
    out_json.write_text(out)


def test_dry_run_shows_the_rec_writes_and_records_nothing(akd_inproc) -> None:
    code, out, err = akd_inproc("scope", "VL.FB", "--source", "recorder", "--samples", "100", "--rate", "1000",
                                "--trigger", "rise:VL.FB:50", "--pretrigger", "25", "--dry-run")
    assert code == 0, err
    for text in ("REC.GAP = 16", "REC.NUMPOINTS = 100", "REC.CH1 = VL.FB", "REC.CH2 = CLR", "REC.TRIGTYPE = 2",
                 "REC.TRIGPOS = 25", "REC.TRIG"):
        assert text in out


@pytest.mark.parametrize("args, code, words", [
    (["NOPE.X"], EXIT_USAGE, "unknown signal"),
    (["VL.FB"] * 7 + ["--source", "recorder"], EXIT_USAGE, "6 channels"),
    (["VL.FB", "--source", "recorder", "--rate", "20000"], EXIT_USAGE, "at most 16000"),
    (["VL.FB", "--source", "recorder", "--samples", "20000"], EXIT_USAGE, "2..10000"),
    (["VL.FB", "--source", "pdo"], EXIT_USAGE, "ecat://"),
    (["VL.FB", "--for", "1s", "--samples", "3"], EXIT_USAGE, "not both"),
    (["VL.FB", "--trigger", "rise:VL.FB"], EXIT_USAGE, "trigger"),
    (["VL.FB", "--pretrigger", "20"], EXIT_USAGE, "pretrigger"),
    (["VL.FB", "--jog", "100"], EXIT_USAGE, "--jog-for"),
    (["0x6040:0", "--samples", "3"], 0, ""),
])
def test_bad_input_is_one_line_with_its_exit_code(akd_inproc, args: list[str], code: int, words: str) -> None:
    got, _out, err = akd_inproc("scope", *args, "--no-plot")
    assert got == code, err
    if code:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("akdctl: error:") and words in lines[0]
        assert "Traceback" not in err


def test_unreachable_rate_writes_a_marked_partial_file(akd_inproc, tmp_path: Path) -> None:
    csv = tmp_path / "fast.csv"
    code, _out, err = akd_inproc("scope", "VL.FB", "PL.ERR", "--samples", "20", "--rate", "100000",
                                "--csv", str(csv), "--no-plot")
    assert code == EXIT_COMM
    assert "rate not reached" in err and str(csv) in err
    assert "# PARTIAL: requested 100000 samples/s" in csv.read_text()


def test_a_drive_that_never_triggers_is_a_marked_partial_file(akd_inproc, tmp_path: Path) -> None:
    csv = tmp_path / "never.csv"
    code, _out, err = akd_inproc("scope", "VL.FB", "--trigger", "fault", "--pretrigger", "50", "--for", "0.2s",
                                "--timeout", "0.3", "--csv", str(csv), "--no-plot")
    assert code == EXIT_COMM and "did not fire" in err
    text = csv.read_text()
    assert "# PARTIAL:" in text and "no trigger" in text


def test_recorder_that_never_triggers_and_retrieval_overflow(akd_inproc, tmp_path: Path) -> None:
    csv = tmp_path / "rec.csv"
    code, _out, err = akd_inproc("scope", "VL.FB", "--source", "recorder", "--samples", "10", "--rate", "1000",
                                "--trigger", "rise:VL.FB:100", "--timeout", "0.3", "--csv", str(csv), "--no-plot")
    assert code == EXIT_COMM and "REC.DONE stayed 0" in err
    assert "# PARTIAL:" in csv.read_text()


def test_retrieval_overflow_is_a_partial_recording() -> None:
    from akdctl.drive.scope_recorder import RecorderSpec, channels_for
    from akdctl.drive.scope_recorder import record as rec_record
    from akdctl.errors import DriveError

    class Link:
        """A drive whose second REC.RETRIEVEDATA chunk overflowed (the AKD's error reply)."""

        def __init__(self) -> None:
            self.chunks = 0

        def command(self, line: str) -> str:
            if line == "REC.DONE":
                return "1"
            if line == "REC.RETRIEVEHDR":
                return "Recording\r\n4,16\r\nVL.FB"
            if line.startswith("REC.RETRIEVEDATA"):
                self.chunks += 1
                if self.chunks > 1:
                    raise DriveError("REC.RETRIEVEDATA: Error: Recorder retrieve overflow")
                return "0,2\r\nF30x1\r\nF3-0x2"
            return ""

    spec = RecorderSpec(["VL.FB"], 4, 16, parse_trigger(None), 0, 1.0)
    rec = Recording("t", "recorder", channels_for(spec.signals))
    failure = rec_record(Link(), spec, rec, stopped=lambda: False)
    assert isinstance(failure, DriveError) and failure.exit_code == EXIT_DRIVE
    assert rec.values[0] == [0.001, -0.002] and rec.times == [0.0, 0.001]
    assert rec.partial and "overflow" in rec.partial


# ------------------------------------------------------------------ pictures
def test_terminal_svg_and_png_pictures(tmp_path: Path) -> None:
    from akdctl.drive.scope_plot import terminal_plot
    from akdctl.drive.scope_svg import render_svg

    rec = _recording()
    text = terminal_plot(rec, width=60, height=10)
    for words in ("VL.FB [rpm] (PNU 6)", "PL.ERR [rev]", "(rpm)", "(rev)", "t [s]", "trigger (rise VL.FB 10) at t = 0 s"):
        assert words in text
    svg = render_svg(rec)
    assert svg.count("<polyline") == 2 and svg.count(">trigger<") == 2
    import xml.dom.minidom

    xml.dom.minidom.parseString(svg)  # well-formed


@pytest.mark.slow  # matplotlib's font cache runs fc-list once
def test_png_picture(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from akdctl.drive.scope_plot import write_png

    png = tmp_path / "p.png"
    write_png(_recording(), str(png))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000


def test_png_without_the_extra_is_one_line(akd_inproc, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "matplotlib", None)
    code, _out, err = akd_inproc("scope", "VL.FB", "--samples", "3", "--png", str(tmp_path / "x.png"))
    assert code == EXIT_USAGE and "akdctl[plot]" in err and len(err.strip().splitlines()) == 1


def test_a_recording_travels_in_a_support_bundle(akd_inproc, tmp_path: Path) -> None:
    code, out, err = akd_inproc("--json", "scope", "VL.FB", "--samples", "5")
    assert code == 0, err
    rec = tmp_path / "rec.json"
    rec.write_text(out)
    bundle = tmp_path / "b.json"
    code, out, err = akd_inproc("support", "bundle", "-o", str(bundle), "--scope", str(rec))
    assert code == 0, err
    data = json.loads(bundle.read_text())
    assert data["scope"]["format"] == "akdctl-scope" and data["scope"]["samples"] == 5
    code, out, err = akd_inproc("support", "show", str(bundle))
    assert code == 0, err
    assert "scope recording" in out and "VL.FB [rpm] (PNU 6)" in out and "(rpm)" in out
    (tmp_path / "bad.json").write_text("{}")
    code, out, err = akd_inproc("support", "bundle", "-o", str(bundle), "--scope", str(tmp_path / "bad.json"))
    assert code == EXIT_USAGE and "not an akdctl scope recording" in err


def test_a_stop_request_ends_the_recording_partial_and_stops_the_jog() -> None:
    from akdctl.connection import Connection
    from akdctl.drive import scope as op
    from akdctl.errors import Interrupted
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.target import split_target

    conn = Connection(split_target("sim"), LinkOptions())
    plan = op.plan(conn, op.build_request(["VL.FB"], jog_rpm=300, jog_s=5.0))
    calls = {"n": 0}

    def stopped() -> bool:  # Ctrl-C arrives after 20 checks, while the jog runs
        calls["n"] += 1
        return calls["n"] > 20

    recording, failure = op.execute(conn, plan, stopped=stopped)
    assert isinstance(failure, Interrupted) and recording.partial and "interrupted" in recording.partial
    assert 0 < len(recording) < 25
    status = conn.axis().read_status()
    assert status.standstill  # the axis was stopped before the error is reported
    conn.close()


def test_a_continuous_recording_streams_past_the_ring(akd_inproc) -> None:
    code, out, err = akd_inproc("--json", "scope", "VL.FB", "--source", "recorder", "--continuous", "--ring", "1000",
                                "--samples", "3000", "--rate", "4000")
    assert code == 0, err
    data = json.loads(out)["recording"]
    assert data["samples"] == 3000  # three rings' worth, every row once and in order
    assert {round(b - a, 9) for a, b in zip(data["t"], data["t"][1:])} == {0.00025}


def test_a_continuous_recording_the_host_cannot_keep_up_with_overflows(akd_inproc, tmp_path: Path) -> None:
    csv = tmp_path / "ov.csv"
    code, _out, err = akd_inproc("scope", "VL.FB", "--source", "recorder", "--continuous", "--ring", "20",
                                "--samples", "5000", "--rate", "16000", "--csv", str(csv), "--no-plot")
    errors = [line for line in err.splitlines() if line.startswith("akdctl: error:")]
    assert code == EXIT_DRIVE and len(errors) == 1 and "overflow" in errors[0] and "Traceback" not in err
    assert "# PARTIAL: streaming stopped" in csv.read_text()


@pytest.mark.parametrize("args, words", [
    (["--ring", "100"], "--continuous"), (["--continuous"], "--source recorder"),
    (["--continuous", "--ring", "1", "--source", "recorder"], "2..10000"),
    (["--continuous", "--ring", "0", "--source", "recorder"], "2..10000"),
    (["--csv", "/"], "it is a directory"), (["--svg", "/nonexistent-dir/x.svg"], "does not exist"),
    (["--rate", "nan"], "positive number"), (["--for", "0"], "more than 0"), (["--timeout", "0"], "between 0"),
])
def test_continuous_options_are_checked(akd_inproc, args: list[str], words: str) -> None:
    code, _out, err = akd_inproc("scope", "VL.FB", *args, "--no-plot")
    assert code == EXIT_USAGE and words in err


def test_names_resolve_through_the_akd_names_catalogue_when_it_is_installed(monkeypatch: pytest.MonkeyPatch) -> None:
    """The row shape of catalog/akd_params.py (branch wip/names): coe (index, sub), coe_type, scale text, unit."""
    import sys
    import types

    from akdctl.drive.scope_signals import Resolver

    class Row:
        coe, coe_type, scale, unit = (0x3548, 0), "u32", "1000", "A/(rad/s)"

        def mark(self, fact: str) -> str:
            return "I" if fact == "scale" else "V"

    fake = types.ModuleType("akdctl.catalog.akd_params")
    fake.lookup = lambda name: Row() if name == "VL.KP" else None  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "akdctl.catalog.akd_params", fake)
    import akdctl.catalog

    monkeypatch.setattr(akdctl.catalog, "akd_params", fake, raising=False)
    signal = Resolver(False, True).resolve("VL.KP")
    assert (signal.index, signal.sub, signal.type, signal.unit) == (0x3548, 0, "u32", "A/(rad/s)")
    assert signal.convert(1500) == pytest.approx(1.5) and "[I]" in signal.address
    with pytest.raises(UsageError, match="unknown signal"):
        Resolver(False, True).resolve("NOPE.X")


def test_a_fault_during_a_recorded_jog_ends_it_partial_and_stopped() -> None:
    from akdctl.connection import Connection
    from akdctl.drive import scope as op
    from akdctl.errors import DriveFault
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.target import split_target

    conn = Connection(split_target("sim"), LinkOptions())
    plan = op.plan(conn, op.build_request(["VL.FB"], jog_rpm=300, jog_s=3.0))
    calls = {"n": 0}

    def stopped() -> bool:  # the drive faults (F501, bus overvoltage) while the jog runs
        calls["n"] += 1
        if calls["n"] == 30:
            with conn.transport().drive.transaction() as model:  # type: ignore[attr-defined]
                model.faults.raise_fault("F501")
        return False

    recording, failure = op.execute(conn, plan, stopped=stopped)
    assert isinstance(failure, DriveFault) and failure.exit_code == EXIT_DRIVE and "F501" in failure.message
    assert recording.partial and "F501" in recording.partial and len(recording) >= 20
    conn.close()


def test_pdo_source_decodes_the_txpdo_image_of_each_cycle() -> None:
    """drive/scope_pdo.py against its CyclicInputs interface: the statusword and velocity of each cycle's TxPDO
    image (little-endian, mapping order), one row per cycle, t = cycles x cycle time, trigger on a bit edge.
    (tests/test_scope_pdo.py covers the pre-trigger ring, gaps, the bus adapter and the real master.)"""
    import struct

    from akdctl.catalog.objects import PdoEntry
    from akdctl.drive import scope_pdo
    from akdctl.drive.ecat_pdo_watch import Layout
    from akdctl.drive.scope_model import Recording

    class Inputs:
        cycle_s = 0.001

        def __init__(self) -> None:
            self.k = 0

        def next_inputs(self, timeout: float) -> tuple[int, bytes]:
            self.k += 1
            word = 0x0637 if self.k >= 5 else 0x0631  # bit 2 (operation enabled) from cycle 5 on
            return self.k - 1, struct.pack("<Hi", word, 1000 * self.k)

        def bus_time(self, host_t: float) -> float:
            return host_t

    tx = Layout([(0x1A00, (PdoEntry(0x6041, 0, 16), PdoEntry(0x606C, 0, 32)))])
    trigger = parse_trigger("bit:2")
    columns, width, trigger_slot, status_slot = scope_pdo.resolve_columns(tx, ["0x6041:0", "0x606C:0"], trigger)
    assert (width, trigger_slot, status_slot) == (2, 2, 2)  # the status word rides along hidden
    spec = scope_pdo.PdoSpec(columns, width, 0.001, 4, 0, trigger_slot=trigger_slot, status_slot=status_slot)
    rec = Recording("ecat://x", "pdo", [c.channel for c in columns[:width]], trigger=trigger.text)
    failure = scope_pdo.record(Inputs(), spec, rec, trigger, stopped=lambda: False, timeout_s=1.0)
    assert failure is None and len(rec) == 4 and rec.trigger_index == 0
    assert rec.values[0] == [0x0637] * 4 and rec.values[1] == [5000.0, 6000.0, 7000.0, 8000.0]
    assert rec.times == pytest.approx([0.0, 0.001, 0.002, 0.003])
    with pytest.raises(UsageError, match="not in the mapped TxPDO"):
        scope_pdo.resolve_columns(tx, ["0x6077:0"], parse_trigger(None))


def test_poll_over_the_ascii_channel_reads_value_and_unit_lines() -> None:
    """akd:// (Connection.commands(), branch wip/names): a polled AKD name is the line NAME -> 'value [unit]'
    (akd-ascii-channel.md §2.1); a text reply is a MalformedReply, never a number made up."""
    from akdctl.drive.scope_signals import Resolver, Sampler, parse_reading
    from akdctl.errors import MalformedReply

    class Link:
        def command(self, line: str) -> str:
            return {"VL.FB": "12.500 [rpm]", "DRV.ACTIVE": "1", "DRV.INFO": "AKD-P00306"}[line]

    class Conn:
        def commands(self) -> Link:
            return Link()

    resolver = Resolver(False, False, has_commands=True)
    signals = [resolver.resolve("VL.FB"), resolver.resolve("drv.active")]
    sampler = Sampler(Conn(), signals)
    assert sampler.read() == [12.5, 1.0] and sampler.requests_per_sample == 2
    assert signals[0].unit == "rpm" and signals[0].address == "VL.FB (ASCII)"
    with pytest.raises(MalformedReply, match="not a number"):
        parse_reading("AKD-P00306", "DRV.INFO")


def test_a_long_recording_is_drawn_as_an_envelope_that_keeps_a_spike() -> None:
    from akdctl.drive.scope_svg import MAX_DRAWN, envelope, render_svg

    rec = Recording("sim", "poll", [Channel("X", "u")])
    for k in range(50_000):
        rec.add(k * 1e-4, [7.0 if k == 31_337 else 0.0])
    rec.trigger_index = 0
    drawn_t, drawn_v = envelope(rec.times, rec.values[0])
    assert len(drawn_t) <= MAX_DRAWN and max(drawn_v) == 7.0 and drawn_t == sorted(drawn_t)
    svg = render_svg(rec)
    assert "min/max envelope" in svg and len(svg) < 200_000


# ------------------------------------------------------------------ a recorded motion starts when the trigger is armed
def test_a_recorded_motion_starts_only_once_the_pretrigger_share_is_taken() -> None:
    """A recorded jog with a rise trigger and pre-trigger: the motion used to start at the first sample, so its
    edge passed while the pre-trigger share was still being taken (the trigger was not yet looked for) and the
    recording timed out with no trigger. It starts when the trigger is armed; the edge is seen."""
    clock = _Clock(0.001)
    moving = {"since": None}

    def read() -> list[float]:
        clock.now += clock.read_cost
        if moving["since"] is None:
            return [0.0]
        return [min(600.0, (clock.now - moving["since"]) * 4000.0)]  # a 4000 rpm/s ramp, fast against the ring

    def start() -> None:
        moving["since"] = clock.now

    spec = PollSpec(samples=40, rate_hz=100.0, trigger=parse_trigger("rise:X:50"), pretrigger=25, timeout_s=1.0)
    rec = Recording("t", "poll", [Channel("X", "rpm")], trigger=spec.trigger.text, rate_requested=spec.rate_hz)
    failure = record(read, rec, spec, trigger_slot=0, clock=clock, sleep=clock.sleep, on_first=start)
    assert failure is None, failure
    assert rec.trigger_index == 10 and rec.values[0][:9] == [0.0] * 9  # at rest, the ramp's start, the edge at t = 0
    assert 0 < rec.values[0][9] <= 50 < rec.values[0][10]


def test_a_recorded_motion_on_the_bus_starts_only_once_the_pretrigger_ring_is_full() -> None:
    """The pdo source's form of the same rule (one sample per bus cycle)."""
    import struct

    from akdctl.catalog.objects import PdoEntry
    from akdctl.drive import scope_pdo
    from akdctl.drive.ecat_pdo_watch import Layout

    moving = {"at": None}

    class Inputs:
        cycle_s = 0.001

        def __init__(self) -> None:
            self.k = -1

        def next_inputs(self, timeout: float) -> tuple[int, bytes]:
            self.k += 1
            v = 0 if moving["at"] is None else min(600, 200 * (self.k - moving["at"]))
            return self.k, struct.pack("<i", v)

        def bus_time(self, host_t: float) -> float:
            return host_t

    inputs = Inputs()
    tx = Layout([(0x1A00, (PdoEntry(0x606C, 0, 32),))])
    trigger = parse_trigger("rise:0x606C:0:100")
    columns, width, trigger_slot, status_slot = scope_pdo.resolve_columns(tx, ["0x606C:0"], trigger)
    spec = scope_pdo.PdoSpec(columns, width, 0.001, 20, 5, trigger_slot=trigger_slot, status_slot=status_slot)
    rec = Recording("ecat://x", "pdo", [c.channel for c in columns[:width]], trigger=trigger.text)
    failure = scope_pdo.record(inputs, spec, rec, trigger, stopped=lambda: False, timeout_s=1.0,
                               on_first=lambda: moving.update(at=inputs.k))
    assert failure is None, failure
    assert moving["at"] == 5 and rec.trigger_index == 5 and rec.values[0][:5] == [0.0] * 5
