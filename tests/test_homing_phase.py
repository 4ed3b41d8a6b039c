"""Issue 28 item 7: the progress view of `home` shows the homing's phase where the drive's status word reports it
(CiA 402 homing-mode bits 13/12/10; PROFIdrive ZSW1 bits 11/13, SPEC-NOTES 9)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from akdctl.cli.progress import measure
from akdctl.drive.axis.base import AxisStatus


def _status(profile: str, word: int, mode: int, standstill: bool = False) -> AxisStatus:
    return AxisStatus(profile=profile, state="x", state_text="x", word=word, control=0, mode=mode, mode_text="",
                      enabled=True, fault=False, warning=False, standstill=standstill, position_rev=0.25,
                      velocity_rpm=30.0)


@pytest.mark.parametrize("word, words", [(0x0000, "homing in progress"), (0x0400, "interrupted or not started"),
                                         (0x1000, "still moving to it"), (0x1400, "homing completed"),
                                         (0x2000, "homing error, still moving"), (0x2400, "error at standstill")])
def test_cia402_homing_phases(word: int, words: str) -> None:
    assert words in _status("cia402", 0x0237 | word, 6).homing_phase()


def test_profidrive_homing_phases_and_none_elsewhere() -> None:
    assert _status("profidrive", 0x0237, 2).homing_phase() == "searching for the reference"
    assert _status("profidrive", 0x2837, 2, standstill=True).homing_phase() == "homing completed"
    assert _status("cia402", 0x0237, 1).homing_phase() is None          # not in homing mode: nothing to say
    assert _status("cip", 0x0001, 0).homing_phase() is None


def test_the_progress_line_of_home_carries_the_phase() -> None:
    plan = SimpleNamespace(request=SimpleNamespace(kind="home"), duration_s=None, end_rev=None, start_rev=None,
                           deadline_s=60.0)
    m = measure(plan, _status("cia402", 0x0237, 6), 1.0)
    assert m.to_go.startswith("homing in progress, at 0.2500 rev")
    assert "gives up in 59 s" in m.to_go


def test_a_completed_homing_has_no_deadline_left_in_its_progress_line() -> None:
    plan = SimpleNamespace(request=SimpleNamespace(kind="home"), duration_s=None, end_rev=None, start_rev=None,
                           deadline_s=60.0)
    m = measure(plan, _status("profidrive", 0x2837, 2, standstill=True), 1.0)
    assert m.to_go.startswith("homing completed, at 0.2500 rev") and "gives up" not in m.to_go
