"""drive/operation.py: the plan every writing operation returns, its consent and its one read-back comparison."""

from __future__ import annotations

import pytest

from akdctl.drive.gate import classify_object, classify_pnu
from akdctl.drive.operation import PlannedWrite, WritePlan, check_readback, consent_needed
from akdctl.errors import CheckFailed, SafetyRefusal


def _plan(enabled: bool | None) -> WritePlan:
    return WritePlan("pnu set", "sim", [PlannedWrite("PNU 930 (Operating mode)", [2], "2", classify_pnu(930)),
                                        PlannedWrite("PNU 1002 (Singleturn bits)", [16], "16")],
                     enabled=enabled, verify=True)


def test_a_write_gated_only_while_enabled_needs_consent_unless_the_drive_was_read_disabled() -> None:
    assert _plan(False).needing_consent == [] and _plan(False).consent_text == ""
    for enabled in (True, None):  # None: not readable, counts as enabled
        plan = _plan(enabled)
        assert [g.address for g in plan.needing_consent] == ["PNU 930"]
        assert plan.consent_text.startswith("write PNU 930: the operating mode")
        assert "[needs consent:" in plan.lines()[1] and "needs consent" not in plan.lines()[2]


def test_consent_is_asked_once_and_given_skips_the_question() -> None:
    asked: list[str] = []

    def refuse(text: str) -> None:
        asked.append(text)
        raise SafetyRefusal("not confirmed")

    with pytest.raises(SafetyRefusal):
        consent_needed(_plan(True), refuse)
    consent_needed(_plan(True), refuse, given=True)
    consent_needed(_plan(False), refuse)
    assert len(asked) == 1


def test_one_reason_shared_by_many_addresses_is_named_once() -> None:
    writes = [PlannedWrite(f"0x1600:{n}", b"", "", classify_object(0x1600, n)) for n in range(3)]
    text = WritePlan("pdo map", "sim", writes, enabled=True).consent_text
    assert text.count("process-data mapping") == 1 and "0x1600:0, 0x1600:1, 0x1600:2" in text


def test_check_readback_names_every_difference_and_passes_on_equal_values() -> None:
    check_readback([("PNU 930", [2], [2]), ("0x2031:0", "axis", "axis")])
    with pytest.raises(CheckFailed) as failed:
        check_readback([("PNU 930", [2], [1]), ("0x6060:0", 3, 3), ("0x2013:1", b"\x01", b"\x02")])
    assert failed.value.message == "read-back differs: PNU 930: wrote 2, read back 1; 0x2013:1: wrote 01, read back 02"
    assert failed.value.exit_code == 5 and len(failed.value.details["differences"]) == 2
