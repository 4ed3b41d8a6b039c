"""``akdctl telegram`` through the real CLI against the simulated AKD (PROFINET manual 5.8/5.11, SPEC-NOTES 10-11)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.catalog import telegrams as tc

# Word-by-word layouts: 004 5.11.2-5.11.5, 003 6.11.6; telegram 9 with XIST_A (SPEC-NOTES 10),
# telegram 351 = ZSW1, NIST_A, ITIST_GLATT, XIST_A (SPEC-NOTES 11).
LAYOUTS = {
    1: (["STW1", "NSOLL_A"], ["ZSW1", "NIST_A"]),
    7: (["STW1", "SATZANW"], ["ZSW1", "AKTSATZ"]),
    9: (["STW1", "SATZANW", "STW2", "MDI_TARPOS", "MDI_TARPOS", "MDI_VELOCITY", "MDI_VELOCITY", "MDI_ACC",
         "MDI_DEC", "MDI_MOD"], ["ZSW1", "AKTSATZ", "ZSW2", "XIST_A", "XIST_A"]),
    350: (["STW1", "NSOLL_A"], ["ZSW1", "NIST_A", "ITIST_GLATT"]),
    351: (["STW1", "NSOLL_A"], ["ZSW1", "NIST_A", "ITIST_GLATT", "XIST_A", "XIST_A"]),
}


def _pnu_writes(state_dir: Path) -> int:
    from akdctl.sim.drive import SimDrive

    with SimDrive("default", state_dir).transaction() as model:
        return model.writes


def _names(words: list[dict]) -> list[str]:
    return [w["name"] for w in words]


def test_default_is_telegram_1(akd_inproc) -> None:
    code, out, err = akd_inproc("--json", "telegram", "show")
    assert code == 0, err
    data = json.loads(out)
    assert data["telegram"] == 1
    assert (_names(data["setpoint"]), _names(data["actual"])) == LAYOUTS[1]


@pytest.mark.parametrize("number", sorted(LAYOUTS))
def test_set_shows_the_layout(akd_inproc, number: int) -> None:
    code, out, err = akd_inproc("--json", "telegram", "set", str(number))
    assert code == 0, err
    data = json.loads(out)
    assert data["telegram"] == number
    assert (_names(data["setpoint"]), _names(data["actual"])) == LAYOUTS[number]
    assert [w["word"] for w in data["actual"]] == list(range(1, len(LAYOUTS[number][1]) + 1))
    # the drive's PNU 915/916 agree with the catalogue, and a later show reads the same
    code, out, _ = akd_inproc("--json", "telegram", "show")
    again = json.loads(out)
    assert again["telegram"] == number and again["pnu915"] == data["pnu915"]
    assert len(again["pnu915"]) == tc.PZD_MAX_WORDS


def test_telegram_9_human_output_names_double_words(akd_inproc) -> None:
    code, out, _ = akd_inproc("telegram", "set", "9")
    assert code == 0
    assert "XIST_A (high word)" in out and "XIST_A (low word)" in out
    assert "10 words" in out and "5 words" in out


def test_unknown_telegram(akd_inproc, isolated_env: Path) -> None:
    before = _pnu_writes(isolated_env)
    code, _, err = akd_inproc("telegram", "set", "2")
    assert code == 2 and "nothing was written" in err
    assert _pnu_writes(isolated_env) == before
    code, _, err = akd_inproc("telegram", "set", "2", "--force")
    assert code == 1 and "0x14" in err  # the drive: value impermissible
    code, out, _ = akd_inproc("--json", "telegram", "show")
    assert json.loads(out)["telegram"] == 1


def test_free_mapping_in_telegram_0(akd_inproc) -> None:
    assert akd_inproc("telegram", "set", "0")[0] == 0
    code, out, err = akd_inproc("--json", "telegram", "map", "--setpoint", "STW1,MDI_TARPOS,5", "--actual", "2,6,52")
    assert code == 0, err
    data = json.loads(out)
    assert data["pnu915"] == [1, 34, 34, 5, 0, 0, 0, 0, 0, 0]
    assert _names(data["setpoint"]) == ["STW1", "MDI_TARPOS", "MDI_TARPOS", "NSOLL_A"]
    assert _names(data["actual"]) == ["ZSW1", "NIST_A", "ITIST_GLATT"]
    code, out, _ = akd_inproc("--json", "telegram", "show")
    assert json.loads(out)["pnu916"][:4] == [2, 6, 52, 0]


@pytest.mark.parametrize("args,fragment", [
    (("--setpoint", "2"), "cannot go into PNU 915"),            # ZSW1 is an actual value
    (("--actual", "1"), "cannot go into PNU 916"),              # STW1 is a set point
    (("--setpoint", "1,34,35,35,36"), "mapped twice"),
    (("--setpoint", "1,34,35,5,32,36,37,38,34"), "at most 10"),  # 12 words
])
def test_free_mapping_refused_before_any_write(akd_inproc, isolated_env: Path, args, fragment: str) -> None:
    assert akd_inproc("telegram", "set", "0")[0] == 0
    before = _pnu_writes(isolated_env)
    code, _, err = akd_inproc("telegram", "map", *args)
    assert code == 2 and fragment in err, err
    assert _pnu_writes(isolated_env) == before


def test_free_mapping_forced_is_refused_by_the_drive(akd_inproc) -> None:
    assert akd_inproc("telegram", "set", "0")[0] == 0
    code, _, err = akd_inproc("telegram", "map", "--setpoint", "1,2", "--force")
    assert code == 1 and "0x14" in err and "element 1" in err


def test_mapping_needs_telegram_0(akd_inproc, isolated_env: Path) -> None:
    before = _pnu_writes(isolated_env)
    code, _, err = akd_inproc("telegram", "map", "--setpoint", "1,5")
    assert code == 2 and "telegram set 0" in err
    assert _pnu_writes(isolated_env) == before
    code, _, err = akd_inproc("telegram", "map", "--setpoint", "1,5", "--force")
    assert code == 1 and "0x11" in err  # operating state: 915 changes only in telegram 0


def test_unknown_signal_names(akd_inproc) -> None:
    code, _, err = akd_inproc("telegram", "map", "--setpoint", "STW9")
    assert code == 2 and "unknown signal" in err


def test_signal_list_pnu_923(akd_inproc) -> None:
    code, out, _ = akd_inproc("--json", "telegram", "show")
    # STW2, ZSW2, XIST_A too: every signal is a PNU (004 5.8; docs/fidelity.md F7)
    assert json.loads(out)["signal_list"] == [1, 2, 3, 4, 5, 6, 28, 32, 33, 34, 35, 36, 37, 38, 52]


def test_signal_missing_from_the_drives_list_is_refused() -> None:
    """A drive whose PNU 923 lacks a signal (an older firmware) cannot map it into telegram 0."""
    from akdctl.drive.telegram import validate_free_map

    offered = [0 if n == 28 else pnu for n, pnu in enumerate(tc.signal_list())]
    assert any("not in the signal list" in p for p in validate_free_map([1], [2, 28], offered))


def test_catalogue_word_lists_round_trip() -> None:
    for layout in tc.TELEGRAMS.values():
        for signals in (layout.setpoint, layout.actual):
            assert tc.words_to_signals(tc.expand_words(signals)) == list(signals)
    assert tc.TELEGRAMS[9].setpoint_words == 10 and tc.TELEGRAMS[9].actual_words == 5
    with pytest.raises(tc.TelegramDataError):
        tc.words_to_signals([34, 5])  # a double word cut in half
    with pytest.raises(tc.TelegramDataError):
        tc.words_to_signals([1, 0, 5])  # after the end


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 0xFFFF), max_size=12))
def test_word_list_parser_raises_only_its_error(words: list[int]) -> None:
    try:
        signals = tc.words_to_signals(words)
    except tc.TelegramDataError:
        return
    assert tc.expand_words(signals, len(words)) == words  # a valid list is exactly its signals re-expanded


@settings(max_examples=100, deadline=None)
@given(st.lists(st.sampled_from([0, 0, 0, 1, 2, 3, 5, 6, 28, 32, 34, 35, 36, 38, 52, 60]), min_size=10, max_size=10))
def test_sim_915_accepts_only_valid_free_mappings(words: list[int]) -> None:
    """Whatever reaches PNU 915 in telegram 0, what the drive keeps is a valid set-point telegram."""
    from akdctl.sim.model import DriveModel
    from akdctl.sim.pnu_server import PnuAccessError

    model = DriveModel()
    model.pnu_write_raw(922, 0, 0x42, [0])
    try:
        model.pnu_write_raw(915, 0, 0x42, words)
    except PnuAccessError as exc:
        assert exc.error == 0x14
        return
    kept = model.pnu_read_raw(915, 0, 10)[1]
    signals = tc.words_to_signals(kept)
    assert all(tc.SIGNALS[n].direction == "setpoint" and tc.SIGNALS[n].free_mappable for n in signals)
