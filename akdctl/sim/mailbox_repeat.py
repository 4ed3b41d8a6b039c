"""A repeated mailbox is a repeat: the simulated slave and the ETG.8200 gateway do not execute it twice.

Why: the mailbox header's counter (byte 5, bits 4-6, 1..7; 0 = none) exists so that a slave recognises a mailbox
it already received (ETG.1000.4 mailbox; the master's retry and a network that duplicates a datagram both deliver
the same mailbox again). Without this check a duplicated ``sdo write`` datagram was applied twice through a
duplicating relay (issue 23.14: 15 of 60 writes, and a relative move of 0.5 rev moved 1.0 rev). A mailbox that
repeats the previous one of its link -- same counter and same bytes -- is answered with the replies the first
one got (they may have been the ones lost) and changes nothing. Comparing the bytes as well as the counter keeps
two different requests that happen to carry the same counter (two masters behind one gateway, a client that
restarted its count) from being taken for one.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Any

#: Links remembered at once (the gateway keys by client and station); the oldest is forgotten first.
MAX_LINKS = 256
#: How long after a mailbox its repeat is recognised (seconds). A duplicated datagram or a master's retry comes
#: within the master's timeout; a *new* master process starts its counter at 1 again, and a first mailbox equal to
#: the last one of the process before it must be executed, not answered from the past (the simulator's choice:
#: ETG.1000 compares the counter only and names no time).
REPEAT_WINDOW_S = 1.0


class MailboxRepeats:
    """Per link: the last mailbox with a counter and the replies it got.

    Each link's entry is one list ``[request, replies, time]`` changed in place, and the entry used last is known by
    identity: the usual mailbox (a new request on the link that sent the last one) hashes its link key once (the
    lookup), not three times (lookup, store, move to the end of the age order)."""

    def __init__(self, max_links: int = MAX_LINKS) -> None:
        self.max_links = max_links
        self.repeats = 0  # repeats answered without executing them (for tests and stats)
        self._last: OrderedDict[Hashable, list[Any]] = OrderedDict()   # oldest first
        self._newest: list[Any] | None = None   # the entry at the end of _last (used last), or None

    def answer(self, link: Hashable, request: bytes, handle: Callable[[bytes], list[bytes]]) -> list[bytes]:
        """``handle(request)``'s replies, or the replies of the previous mailbox when ``request`` repeats it.

        The list ``handle`` returned is kept as it is for a repeat (each repeat gets a copy): callers read it and
        do not change it."""
        last_of = self._last
        if len(request) < 6 or not request[5] & 0x70:  # the counter (bits 4-6) is 0: none
            if last_of.pop(link, None) is self._newest:  # a mailbox without a counter ends the sequence
                self._newest = None
            return handle(request)
        now = time.monotonic()
        entry = last_of.get(link)
        if entry is None:
            replies = handle(request)
            last_of[link] = self._newest = [request if request.__class__ is bytes else bytes(request), replies, now]
            if len(last_of) > self.max_links:
                last_of.popitem(last=False)
            return replies
        if entry[0] == request and now - entry[2] <= REPEAT_WINDOW_S:
            self.repeats += 1
            if entry is not self._newest:
                last_of.move_to_end(link)
                self._newest = entry
            return list(entry[1])
        replies = handle(request)
        entry[0] = request if request.__class__ is bytes else bytes(request)
        entry[1] = replies
        entry[2] = now
        if entry is not self._newest:
            last_of.move_to_end(link)
            self._newest = entry
        return replies
