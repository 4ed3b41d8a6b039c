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


def counted(request: bytes) -> bool:
    """Whether ``request`` carries a counter (byte 5, bits 4-6; 0 = none): only such a mailbox can be a repeat.
    A caller that sees the same request bytes again (the gateway's datagram memo) asks once and calls
    :meth:`MailboxRepeats.answer_counted` for those that do."""
    return len(request) >= 6 and bool(request[5] & 0x70)


class MailboxRepeats:
    """Per link: the last mailbox with a counter and the replies it got.

    Each link's entry is one list ``[request, replies, time]`` changed in place, and the entry used last is known by
    identity with its link: the usual mailbox (a new request on the link that sent the last one) finds its entry by
    comparing the link with that one's, without hashing it (a gateway's link is a new (address, port) pair per
    datagram, whose hash is computed afresh), and changes the age order not at all."""

    def __init__(self, max_links: int = MAX_LINKS) -> None:
        self.max_links = max_links
        self.repeats = 0  # repeats answered without executing them (for tests and stats)
        self._last: OrderedDict[Hashable, list[Any]] = OrderedDict()   # oldest first
        self._newest: list[Any] | None = None   # the entry at the end of _last (used last), or None
        self._newest_link: Hashable = None   # its link (meaningful while _newest is not None)

    def answer(self, link: Hashable, request: bytes, handle: Callable[[bytes], list[bytes]]) -> list[bytes]:
        """``handle(request)``'s replies, or the replies of the previous mailbox when ``request`` repeats it.

        The list ``handle`` returned is kept as it is for a repeat (each repeat gets a copy): callers read it and
        do not change it."""
        if counted(request):
            return self.answer_counted(link, request, handle)
        if self._last.pop(link, None) is self._newest:  # a mailbox without a counter ends the sequence
            self._newest = None
        return handle(request)

    def answer_counted(self, link: Hashable, request: bytes, handle: Callable[[bytes], list[bytes]]
                       ) -> list[bytes]:
        """:meth:`answer` for a ``request`` that :func:`counted` says carries a counter."""
        now = time.monotonic()
        entry = self._newest
        if entry is None or self._newest_link != link:
            return self._answer_other(link, request, handle, now)
        if entry[0] == request and now - entry[2] <= REPEAT_WINDOW_S:
            self.repeats += 1
            return list(entry[1])
        replies = handle(request)
        entry[0] = request if request.__class__ is bytes else bytes(request)
        entry[1] = replies
        entry[2] = now
        return replies

    def _answer_other(self, link: Hashable, request: bytes, handle: Callable[[bytes], list[bytes]], now: float
                      ) -> list[bytes]:
        """:meth:`answer_counted` on a link other than the one used last: its entry looked up, and moved to the end
        of the age order once the request was answered."""
        last_of = self._last
        entry = last_of.get(link)
        if entry is None:
            replies = handle(request)
            last_of[link] = entry = [request if request.__class__ is bytes else bytes(request), replies, now]
            if len(last_of) > self.max_links:
                last_of.popitem(last=False)
                if not last_of:  # max_links 0: the new entry itself is forgotten
                    self._newest = None
                    return replies
        elif entry[0] == request and now - entry[2] <= REPEAT_WINDOW_S:
            self.repeats += 1
            replies = list(entry[1])
            last_of.move_to_end(link)
        else:
            replies = handle(request)
            entry[0] = request if request.__class__ is bytes else bytes(request)
            entry[1] = replies
            entry[2] = now
            last_of.move_to_end(link)
        self._newest = entry
        self._newest_link = link
        return replies
