"""The PDO mapping's one PRE-OP precondition and the AL state's one spelling (issue 22: two texts, two
normalisations). ``pdo map`` and a recipe's map step both run ``drive/pdo.py`` ``plan``; SPEC-NOTES 18."""

from __future__ import annotations

from typing import Any

import pytest

from akdctl.drive import pdo as dp
from akdctl.errors import AkdError, CommError, UsageError


class _Transport:
    def __init__(self, state: str | None) -> None:
        self.state = state

    def al_state(self) -> str | None:
        return self.state


class _Axis:
    def read_status(self) -> Any:
        raise CommError("no answer")  # the power stage unknown: counts as enabled


class _Target:
    display = "fake"


class _Conn:
    target = _Target()

    def __init__(self, state: str | None) -> None:
        self._transport = _Transport(state)

    def transport(self) -> _Transport:
        return self._transport

    def objects(self) -> object:
        return object()

    def axis(self) -> _Axis:
        return _Axis()


@pytest.mark.parametrize("spelling", ["PREOP", "pre-op", "Pre_Op", "PRE-OP", " preop"])
def test_every_spelling_of_pre_op_is_one_state(spelling: str) -> None:
    assert dp.normal_al_state(spelling) == "PREOP"
    assert dp.al_state_of(_Transport(spelling)) == "PREOP"


@pytest.mark.parametrize("state", ["SAFE-OP", "OP", "init"])
def test_outside_pre_op_the_plan_refuses_in_the_one_wording(state: str) -> None:
    request = dp.map_request(dp.build_plan(["0x1701"], ["0x1B20"]))
    with pytest.raises(UsageError) as refused:
        dp.plan(_Conn(state), request)
    assert dp.PREOP_ONLY in refused.value.message and "nothing was written" in refused.value.message
    assert refused.value.details["al_state"] == dp.normal_al_state(state)


def test_forced_the_plan_notes_the_state_and_asks_consent_for_an_unknown_power_stage() -> None:
    request = dp.map_request(dp.build_plan(["0x1701"], ["0x1B20"]), force=True)
    plan = dp.plan(_Conn("OP"), request)
    assert any(dp.PREOP_ONLY in note for note in plan.notes)
    assert plan.enabled is None and plan.needing_consent  # mapping writes are gated while (maybe) enabled
    assert plan.consent_text.count("the process-data mapping") == 1  # one reason, named once


def test_an_unknown_al_state_is_a_precondition_in_words_not_a_refusal() -> None:
    plan = dp.plan(_Conn(None), dp.map_request(dp.build_plan(["0x1701"], ["0x1B20"])))
    assert plan.preconditions == ["EtherCAT state not known on this target (the drive's own check answers)"]
    assert isinstance(plan.writes[0].address, str) and not isinstance(plan, AkdError)
