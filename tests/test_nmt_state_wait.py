"""An NMT command's new state is confirmed past a heartbeat sent before the command took effect.

A node's heartbeat producer can send its old state just as an NMT command arrives; that frame reaches the master
after the command was sent, so the first state after the command is not yet the new one (a full suite run once saw
`can nmt stop` answered by a last OPERATIONAL heartbeat over slcan, exit 5). ``_StateWatch.wait_after`` with a
``wanted`` test waits past such a state; a node that really stays elsewhere is still reported, at the wait's end.
"""

from __future__ import annotations

import threading
import time

from akdctl.protocol.nmt import state_name
from akdctl.transport.canopen_bus import _StateWatch

OPERATIONAL, STOPPED = 0x05, 0x04


def _stopped(code: int) -> bool:
    return state_name(code) == "STOPPED"


def test_a_late_heartbeat_of_the_old_state_is_waited_past() -> None:
    watch = _StateWatch()
    since = time.monotonic()
    watch.seen(OPERATIONAL)  # sent before the command took effect, received after it was sent
    later = threading.Timer(0.05, watch.seen, (STOPPED,))
    later.start()
    try:
        assert watch.wait_after(since, 5.0, _stopped) == STOPPED
        assert watch.wait_after(since, 5.0) == STOPPED
    finally:
        later.cancel()


def test_without_a_wanted_test_the_first_state_after_since_answers() -> None:
    watch = _StateWatch()
    since = time.monotonic()
    watch.seen(OPERATIONAL)
    assert watch.wait_after(since, 0.01) == OPERATIONAL


def test_a_node_that_stays_in_another_state_is_reported_when_the_wait_ends() -> None:
    watch = _StateWatch()
    since = time.monotonic()
    watch.seen(OPERATIONAL)
    began = time.monotonic()
    assert watch.wait_after(since, 0.1, _stopped) == OPERATIONAL
    assert time.monotonic() - began >= 0.09  # it waited for the wanted state until the end, then said what came


def test_nothing_after_since_is_no_answer() -> None:
    watch = _StateWatch()
    watch.seen(STOPPED)
    assert watch.wait_after(time.monotonic() + 1.0, 0.05, _stopped) is None
