"""``ecat+soem://`` opens with SOEM's ``config_init`` repeated within ``--timeout`` while it finds no slave
(akdctl.transport.ethercat_soem._config_init): a slave that answers SOEM's first frames late is not "no slave", and
one that never answers ends the open after the timeout with exit 3. A stepped clock: no test waits or times."""

from __future__ import annotations

import pytest

from akdctl.transport import ethercat_soem


class FakeMaster:
    def __init__(self, counts: list[int]) -> None:
        self.counts, self.calls = counts, 0

    def config_init(self) -> int:
        self.calls += 1
        return self.counts.pop(0) if self.counts else 0


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> list[float]:
    now = [100.0]
    import time

    monkeypatch.setattr(time, "monotonic", lambda: now[0])
    monkeypatch.setattr(time, "sleep", lambda s: now.__setitem__(0, now[0] + s))
    return now


def test_a_late_slave_is_found_on_a_later_attempt(clock: list[float]) -> None:
    master = FakeMaster([0, 0, 1])
    assert ethercat_soem._config_init(master, 1.0) == 1
    assert master.calls == 3 and clock[0] == pytest.approx(100.1)


def test_a_silent_bus_ends_after_the_timeout(clock: list[float]) -> None:
    master = FakeMaster([])
    assert ethercat_soem._config_init(master, 1.0) == 0
    assert 101.0 <= clock[0] <= 101.05 + 1e-6  # gave up at the first look past the timeout, not before
    assert master.calls == round((clock[0] - 100.0) / 0.05) + 1  # one attempt per 50 ms pause, and the last


def test_found_at_once_is_one_call(clock: list[float]) -> None:
    master = FakeMaster([2])
    assert ethercat_soem._config_init(master, 1.0) == 2
    assert master.calls == 1 and clock[0] == 100.0
