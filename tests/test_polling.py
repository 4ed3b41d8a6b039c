"""The poll rule of the axis' waits (akdctl/drive/polling.py): fast after a command or a change, steady at 20 reads/s
on a real drive, scaled down for the simulator under ``sim speed``. The pauses are checked as values handed to
``sleep`` (a fake clock), never as measured durations; the CLI test runs ``home`` on the simulator at 1000×."""

from __future__ import annotations

import pytest

from akdctl.drive import polling
from akdctl.drive.polling import POLL_FIRST_S, POLL_MIN_S, POLL_S, Poll


class FakeClock:
    """monotonic/sleep for the polling module: sleeping advances the clock and is recorded."""

    def __init__(self) -> None:
        self.now = 100.0
        self.pauses: list[float] = []

    def monotonic(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.pauses.append(seconds)
        self.now += seconds


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> FakeClock:
    fake = FakeClock()
    monkeypatch.setattr(polling, "monotonic", fake.monotonic)
    monkeypatch.setattr(polling, "sleep", fake.sleep)
    return fake


def test_real_drive_starts_fast_and_settles_at_twenty_reads_a_second(clock: FakeClock) -> None:
    poll = Poll()
    for _ in range(40):
        poll.read(lambda: 0)
        poll.observe(0x0237)
        poll.pause()
    assert clock.pauses[0] == POLL_FIRST_S
    assert all(b >= a for a, b in zip(clock.pauses, clock.pauses[1:]))
    assert clock.pauses[-1] == POLL_S
    # the request rate a real drive sees: at most 16 reads in the first quarter second, then 20 reads/s
    elapsed, reads = 0.0, 0
    for pause in clock.pauses:
        if elapsed >= 0.25:
            break
        elapsed += pause
        reads += 1
    assert reads <= 16


def test_a_change_of_the_status_word_polls_fast_again(clock: FakeClock) -> None:
    poll = Poll()
    for word in [1] * 20 + [2, 2]:
        poll.read(lambda: 0)
        poll.observe(word)
        poll.pause()
    assert clock.pauses[19] > 10 * POLL_FIRST_S
    assert clock.pauses[20] == POLL_FIRST_S
    assert clock.pauses[21] == POLL_FIRST_S * polling.POLL_GROWTH


def test_a_flickering_status_word_cannot_keep_the_polling_fast(clock: FakeClock) -> None:
    poll = Poll()
    for k in range(400):
        poll.read(lambda: 0)
        poll.observe(k % 2)
        poll.pause()
    elapsed = sum(clock.pauses)
    assert len(clock.pauses) / elapsed <= 16 / polling.POLL_BURST_S
    window, start = 0, 0
    for end in range(len(clock.pauses)):  # no 0.25 s window holds more than 16 reads
        window += clock.pauses[end]
        while window > polling.POLL_BURST_S:
            window -= clock.pauses[start]
            start += 1
        assert end - start + 1 <= 16


def test_a_slow_link_is_never_polled_more_often_than_its_reads_take(clock: FakeClock) -> None:
    poll = Poll()

    def slow_read() -> int:
        clock.now += 0.02
        return 0

    poll.read(slow_read)
    poll.pause()
    assert clock.pauses == [pytest.approx(0.02)]


def test_simulator_speed_scales_the_pauses_down_to_the_floor(clock: FakeClock) -> None:
    poll = Poll(time_scale=1000.0)

    def slow_read() -> int:
        clock.now += 0.003
        return 0

    for _ in range(10):
        poll.read(slow_read)
        poll.pause()
    assert clock.pauses == [POLL_MIN_S] * 10  # the simulator's own cost does not pace it
    assert Poll(time_scale=10.0).steady == POLL_S / 10
    for odd in (0.0, -5.0, float("nan"), float("inf")):
        assert Poll(time_scale=odd).steady == POLL_S


def test_no_pause_runs_past_the_deadline(clock: FakeClock) -> None:
    poll = Poll(deadline=clock.now + 0.001)
    poll.next = POLL_S
    poll.pause()
    assert clock.pauses == [pytest.approx(0.001)]


def test_home_at_simulator_speed_polls_at_the_scaled_pause(akd_inproc, monkeypatch: pytest.MonkeyPatch) -> None:
    """Through the CLI: with ``sim speed 10`` (homing takes a few tenths of a wall second) every pause of ``home``
    is the 10× shorter one, and homing finishes; at real time no pause is shorter than the first real one."""
    import time

    pauses: list[float] = []

    def sleep(seconds: float) -> None:
        pauses.append(seconds)
        time.sleep(seconds)

    monkeypatch.setattr(polling, "sleep", sleep)
    assert akd_inproc("sim", "speed", "10")[0] == 0
    code, out, err = akd_inproc("--json", "-y", "home", "--mode", "1")
    assert code == 0, err
    assert '"homed": true' in out
    assert pauses and all(POLL_MIN_S <= p <= POLL_S / 10 for p in pauses), pauses
    pauses.clear()
    assert akd_inproc("sim", "speed", "1")[0] == 0
    code, out, err = akd_inproc("--json", "-y", "home", "--mode", "0")  # 'current position': done at once
    assert code == 0, err
    assert all(p >= POLL_FIRST_S for p in pauses)


def test_a_pause_that_a_signal_may_end_sleeps_in_short_slices_and_stops_at_once(clock: FakeClock) -> None:
    assert polling.pause_unless_stopped(0.12, lambda: False) is False
    assert clock.pauses == pytest.approx([0.05, 0.05, 0.02]) and max(clock.pauses) <= polling.STOP_SLICE_S
    clock.pauses.clear()
    asked = iter([False, False, True])
    assert polling.pause_unless_stopped(10.0, lambda: next(asked)) is True
    assert clock.pauses == pytest.approx([0.05, 0.05])  # the rest of the 10 s is not slept
    clock.pauses.clear()
    assert polling.pause_unless_stopped(1.0, lambda: True) is True and clock.pauses == []
