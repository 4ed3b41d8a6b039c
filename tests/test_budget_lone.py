"""links.Budget.lone (issue 29): a single-attempt request begun without a Deadline object is counted exactly as one
begun with ``budget.request(1)`` -- the same end, the same unanswered time, the same words for its error."""

from __future__ import annotations

import time

import pytest

from akdctl.errors import CommError, NoAnswer
from akdctl.links import PROBE, Budget


def test_lone_gives_the_whole_timeout_when_nothing_is_counted_or_open() -> None:
    budget = Budget(2.0, retries=2)
    before = time.monotonic()
    at = budget.lone()
    assert at is not None and before + 2.0 <= at <= time.monotonic() + 2.0
    with budget.request():
        assert budget.lone() is None   # inside another request: that one's deadline rules
    budget.silent = 0.5
    assert budget.lone() is None       # unanswered time counted: the general path gives what is left


def test_a_lone_request_continued_keeps_its_end_and_is_counted_when_unanswered() -> None:
    budget = Budget(1.0, retries=2)
    at = budget.lone()
    assert at is not None
    with pytest.raises(NoAnswer):
        with budget.request(attempts=1, at=at) as deadline:
            assert deadline.at == at and deadline.total == 1.0 and deadline.describe() == "1 s"
            raise NoAnswer("silent")
    assert budget.silent == 1.0
    assert budget.lone() is None
    with budget.request(attempts=1) as deadline:   # what is left: the probe share
        assert deadline.probe and deadline.total == pytest.approx(PROBE)
    assert budget.silent == 0.0                    # an answer clears the count
    assert budget.lone() is not None


def test_a_lone_request_that_fails_otherwise_clears_nothing_it_should_not() -> None:
    budget = Budget(1.0)
    at = budget.lone()
    with pytest.raises(CommError):
        with budget.request(attempts=1, at=at):
            raise CommError("refused")
    assert budget.silent == 0.0
