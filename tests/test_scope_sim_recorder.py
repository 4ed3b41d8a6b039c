"""The simulated AKD's recorder (sim/recorder.py): REC.* semantics from the simulated motion.

Facts: shared/reference/foe-alias-recorder.md §C1 (16 kHz base, REC.GAP, 6 channels, trigger types, stop types,
retrieval formats and chunking), akd-ascii-channel.md §2.3 (REC.RETRIEVE shape: ``Recording``, ``<N>,<gap>``,
names, rows). The values are checked against the model's kinematics computed independently here (a constant
acceleration ramp), not against the recorder's own output.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.drive.scope_recorder import parse_retrieve, parse_rows, parse_value
from akdctl.errors import MalformedReply
from akdctl.sim.model import DriveModel
from akdctl.sim.recorder import BASE_S, RecorderError, _internal, handle_rec

ACC = 100.0  # rev/s²
TOP = 10.0  # rev/s


def _rec(model: DriveModel, *lines: str) -> list[str]:
    out = []
    for line in lines:
        name, _, arg = line.partition(" ")
        out.append(handle_rec(model, name, arg or None))
    return out


def _jog(model: DriveModel) -> None:
    model.motion.state = "enabled"
    model.motion.axis.run_velocity(TOP, ACC, ACC, "jog")


def _setup(model: DriveModel, points: int, gap: int, *channels: str, fmt: int = 0) -> None:
    _rec(model, f"REC.GAP {gap}", f"REC.NUMPOINTS {points}", f"REC.RETRIEVEFRMT {fmt}",
         *[f"REC.CH{i + 1} {c}" for i, c in enumerate(channels)])


def test_exact_samples_at_the_gap_spacing_follow_the_ramp() -> None:
    model = DriveModel()
    _setup(model, 50, 16, "VL.CMD", "PL.CMD")  # 1 kHz
    _rec(model, "REC.TRIG")
    _jog(model)
    model.advance(0.2)
    assert _rec(model, "REC.DONE") == ["1"]
    points, gap, names, rows = parse_retrieve(_rec(model, "REC.RETRIEVE")[0])
    assert (points, gap, names, len(rows)) == (50, 16, ["VL.CMD", "PL.CMD"], 50)
    for k, (vel_rpm, pos) in enumerate(rows):
        t = k * 16 * BASE_S  # sample k at k x gap x 62.5 us after arming
        assert vel_rpm == pytest.approx(min(ACC * t, TOP) * 60.0, abs=1e-3)
        assert pos == pytest.approx(0.5 * ACC * t * t, abs=1e-3)


def test_a_jog_shows_ramp_plateau_and_stop() -> None:
    model = DriveModel()
    _setup(model, 400, 80, "VL.FB")  # 200 Hz, 2 s
    _rec(model, "REC.TRIG")
    _jog(model)
    model.advance(0.6)
    model.motion.axis.ramp_to_zero(ACC * 60.0, "stop")
    model.advance(1.5)
    rows = [r[0] for r in parse_retrieve(_rec(model, "REC.RETRIEVE")[0])[3]]
    assert rows[0] == 0.0
    assert max(rows) == pytest.approx(600.0, abs=0.01)
    plateau = [v for v in rows if abs(v - 600.0) < 0.01]
    assert len(plateau) > 40  # ~0.5 s at 200 Hz
    assert rows[-1] == 0.0
    rising = rows[: rows.index(plateau[0])]
    assert rising == sorted(rising) and len(rising) > 10  # a ramp, not a step


def test_both_retrieval_formats_carry_the_same_values() -> None:
    model = DriveModel()
    _setup(model, 20, 16, "VL.CMD", "PL.ERR")
    _rec(model, "REC.TRIG")
    _jog(model)
    model.advance(0.05)
    standard = parse_retrieve(_rec(model, "REC.RETRIEVE")[0])[3]
    _rec(model, "REC.RETRIEVEFRMT 1")
    internal_text = _rec(model, "REC.RETRIEVE")[0]
    assert "F6" in internal_text and "0x" in internal_text
    internal = parse_retrieve(internal_text)[3]
    for a, b in zip(standard, internal):
        assert a == pytest.approx(b, abs=1e-3)
    assert parse_value("F3-0x56") == pytest.approx(-0.086)
    assert parse_value("F30x0") == 0.0
    assert parse_value("-0.086") == pytest.approx(-0.086)


def test_edge_trigger_with_pretrigger_puts_the_crossing_at_the_trigger_index() -> None:
    model = DriveModel()
    _setup(model, 100, 16, "VL.CMD")
    _rec(model, "REC.TRIGTYPE 2", "REC.TRIGPARAM VL.CMD", "REC.TRIGVAL 300", "REC.TRIGSLOPE 1", "REC.TRIGPOS 20",
         "REC.TRIG")
    model.advance(0.05)  # the pre-trigger part fills at rest
    assert _rec(model, "REC.DONE", "REC.ACTIVE") == ["0", "1"]
    _jog(model)
    model.advance(0.3)
    rows = [r[0] for r in parse_retrieve(_rec(model, "REC.RETRIEVE")[0])[3]]
    assert len(rows) == 100
    assert rows[19] < 300.0 <= rows[20]  # 20 % of 100 points before the trigger (the crossing sample)
    assert rows[0] == pytest.approx(ACC * 60.0 * 0.03, abs=1e-3)  # 20 samples (20 ms) before the 50 ms crossing


def test_bitmask_trigger_on_the_fault_bit() -> None:
    model = DriveModel()
    _setup(model, 10, 16, "VL.CMD")
    _rec(model, "REC.TRIGTYPE 5", "REC.TRIGPARAM DS402.STATUSWORD", "REC.TRIGMASK 8", "REC.TRIGVAL 8",
         "REC.TRIGPOS 50", "REC.TRIG")
    model.advance(0.1)
    assert _rec(model, "REC.DONE") == ["0"]  # no fault: never fires
    model.faults.raise_fault("F501")
    model.advance(0.1)
    assert _rec(model, "REC.DONE") == ["1"]


def test_next_command_trigger_fires_on_the_next_command() -> None:
    model = DriveModel()
    _setup(model, 5, 16, "VL.CMD")
    _rec(model, "REC.TRIGTYPE 1", "REC.TRIGPOS 20", "REC.TRIG")
    model.advance(0.05)
    assert _rec(model, "REC.DONE") == ["0"]
    model.recorder.note_command()
    model.advance(0.05)
    assert _rec(model, "REC.DONE") == ["1"]


def test_continuous_chunks_and_overflow() -> None:
    model = DriveModel()
    _setup(model, 100, 16, "VL.CMD")
    _rec(model, "REC.STOPTYPE 1", "REC.RETRIEVESIZE 30", "REC.TRIG")
    model.advance(0.0505)  # 51 samples
    first = _rec(model, "REC.RETRIEVEDATA 0")[0]
    assert first.splitlines()[0] == "0,30" and len(parse_rows(first, 1, skip_first=True)) == 30
    second = _rec(model, "REC.RETRIEVEDATA")[0]
    assert second.splitlines()[0] == "30,21"  # continues from the last index
    model.advance(0.3)  # the ring (100) overruns rows 51.. not yet retrieved
    with pytest.raises(RecorderError, match="overflow"):
        _rec(model, "REC.RETRIEVEDATA")
    assert _rec(model, "REC.DONE") == ["1"]  # a full ring
    _rec(model, "REC.OFF")
    assert _rec(model, "REC.ACTIVE") == ["0"]


@pytest.mark.parametrize("line, text", [
    ("REC.GAP 0", "out of range"), ("REC.GAP 70000", "out of range"), ("REC.NUMPOINTS 10001", "out of range"),
    ("REC.GAP x", "not a number"), ("REC.CH1 NOPE.X", "not a recordable"), ("REC.CH7 VL.FB", "not found"),
    ("REC.TRIGTYPE 4", "not a supported"), ("REC.TRIGPOS 0", "out of range"), ("REC.TRIG", "No recording channel"),
    ("REC.RETRIEVEDATA", "No data"), ("REC.NOPE", "not found"), ("REC.DONE 1", "takes no argument"),
])
def test_refusals_carry_the_drives_text(line: str, text: str) -> None:
    model = DriveModel()
    with pytest.raises(RecorderError, match=text):
        _rec(model, line)


def test_settings_are_locked_while_recording_and_state_persists() -> None:
    model = DriveModel()
    _setup(model, 20, 16, "VL.CMD")
    _rec(model, "REC.TRIGTYPE 2", "REC.TRIGPARAM VL.CMD", "REC.TRIGVAL 1", "REC.TRIG")
    with pytest.raises(RecorderError, match="active"):
        _rec(model, "REC.GAP 2")
    model.advance(0.01)
    again = DriveModel.from_state(model.to_state())
    assert again.recorder.state == "armed" and len(again.recorder.pre) == len(model.recorder.pre)
    assert _rec(again, "REC.GAP", "REC.CH1", "REC.CH2") == ["16", "VL.CMD", "0"]


def test_revision_moves_with_the_recording() -> None:
    model = DriveModel()
    _setup(model, 20, 16, "VL.CMD")
    before = model.revision
    _rec(model, "REC.TRIG")
    model.advance(0.005)
    assert model.revision > before  # the store saves a recording in progress (sim/component.Tracked)


def test_a_long_idle_advance_is_bounded() -> None:
    import time

    model = DriveModel()
    _setup(model, 100, 1, "VL.CMD")
    _rec(model, "REC.STOPTYPE 1", "REC.TRIG")
    started = time.perf_counter()
    model.advance(3600.0)  # an hour at 16 kHz would be 57.6 M samples
    assert time.perf_counter() - started < 10
    assert model.clock == pytest.approx(3600.0)
    assert len(model.recorder.rows) == 100


# ------------------------------------------------------------------ the parsers never raise anything but MalformedReply


@given(st.floats(min_value=-1e9, max_value=1e9, allow_nan=False))
def test_internal_format_round_trips(value: float) -> None:
    assert parse_value(_internal(value)) == pytest.approx(value, abs=1e-6)


@settings(max_examples=300)
@given(st.text(max_size=200), st.integers(min_value=1, max_value=6), st.booleans())
def test_any_reply_text_parses_or_is_a_malformed_reply(text: str, width: int, skip: bool) -> None:
    from akdctl.drive.scope_recorder import parse_header

    for parse in (lambda: parse_rows(text, width, skip_first=skip), lambda: parse_header(text),
                  lambda: parse_retrieve(text)):
        try:
            parse()
        except MalformedReply:
            pass
