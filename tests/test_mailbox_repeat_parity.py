"""sim/mailbox_repeat.MailboxRepeats (entries changed in place, the newest known by identity) answers as the plain
rule it replaced: a reference kept here -- store, look up and move to the end on every mailbox -- given the same
mailboxes from a few links, with counters, repeats, mailboxes without a counter, time passing past the repeat
window and more links than it remembers. Same replies, same calls of the handler, same links remembered in the
same order."""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable, Hashable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.sim import mailbox_repeat
from akdctl.sim.mailbox_repeat import REPEAT_WINDOW_S, MailboxRepeats


class Reference:
    """The rule as first written: every mailbox with a counter stores a new (request, replies, time)."""

    def __init__(self, max_links: int) -> None:
        self.max_links = max_links
        self.repeats = 0
        self.last: OrderedDict[Hashable, tuple[bytes, list[bytes], float]] = OrderedDict()

    def answer(self, link: Hashable, request: bytes, handle: Callable[[bytes], list[bytes]], now: float
               ) -> list[bytes]:
        if len(request) < 6 or not request[5] & 0x70:
            self.last.pop(link, None)
            return handle(request)
        last = self.last.get(link)
        if last is not None and last[0] == request and now - last[2] <= REPEAT_WINDOW_S:
            self.repeats += 1
            self.last.move_to_end(link)
            return list(last[1])
        replies = handle(request)
        self.last[link] = (bytes(request), replies, now)
        self.last.move_to_end(link)
        if len(self.last) > self.max_links:
            self.last.popitem(last=False)
        return replies


STEP = st.tuples(
    st.sampled_from([("a", 1), ("b", 1), ("a", 2), ("c", 7)]),   # link
    st.integers(0, 7),                                         # counter (0: none)
    st.sampled_from([b"\x01", b"\x02"]),                       # body
    st.sampled_from([0.0, 0.0, 0.3, REPEAT_WINDOW_S + 0.2]),   # time passing before it
    st.booleans(),                                             # a short mailbox (no counter field)
)


@settings(max_examples=300, deadline=None)
@given(st.lists(STEP, max_size=40), st.integers(1, 3))
def test_repeats_answer_as_the_reference_rule(steps: list[tuple[tuple[str, int], int, bytes, float, bool]],
                                              max_links: int) -> None:
    clock = [1000.0]
    real = time.monotonic
    mailbox_repeat.time.monotonic = lambda: clock[0]  # type: ignore[attr-defined]
    try:
        fast, ref = MailboxRepeats(max_links), Reference(max_links)
        fast_calls: list[bytes] = []
        ref_calls: list[bytes] = []
        for n, (link, counter, body, passing, short) in enumerate(steps):
            clock[0] += passing
            request = b"\x00" * 3 if short else bytes([6, 0, 0, 0, 0, counter << 4 | 3]) + body
            got = fast.answer(link, request, lambda r, n=n: fast_calls.append(r) or [b"r%d" % n])
            want = ref.answer(link, request, lambda r, n=n: ref_calls.append(r) or [b"r%d" % n], clock[0])
            assert got == want
            assert fast_calls == ref_calls and fast.repeats == ref.repeats
            assert list(fast._last) == list(ref.last)
            assert [tuple(entry) for entry in fast._last.values()] == list(ref.last.values())
    finally:
        mailbox_repeat.time.monotonic = real  # type: ignore[attr-defined]


def test_a_failing_handler_leaves_the_last_mailbox_as_it_was() -> None:
    repeats = MailboxRepeats()
    first = bytes([6, 0, 0, 0, 0, 0x13, 1])
    repeats.answer("link", first, lambda r: [b"one"])

    def fail(request: bytes) -> list[bytes]:
        raise RuntimeError("drive failed")

    with pytest.raises(RuntimeError):
        repeats.answer("link", bytes([6, 0, 0, 0, 0, 0x23, 2]), fail)
    assert repeats.answer("link", first, lambda r: [b"again"]) == [b"one"]  # still the repeat of the first
