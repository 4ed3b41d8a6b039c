"""Which mailbox reply belongs to the request just sent: the counter rule, written once.

Why a rule of its own: UDP duplicates, delays and loses datagrams, and a mailbox gateway sends nothing for a
request it could not forward, so a client that takes "the next reply that looks right" takes a duplicate of
the previous write's answer for the current one (both read ``60 40 60 00 ...``) and reports a write as done
that never arrived. The mailbox header's counter (1..7) tells replies apart, but how depends on the master:

* a link that **echoes** the request's counter (the simulator, masters that hand the slave's reply back with
  the requester's counter) is recognised after two replies in a row that carry the counter of their request;
  from then on a reply with another counter answers some other request and is dropped;
* a master that **rewrites** the counter (reference notes, ETG.8200: it numbers its own mailbox traffic)
  hands back the slave's own counter, which the slave advances with every mailbox it sends: a reply that is
  byte for byte one of the last few accepted ones, counter included, is a duplicate and is dropped;
* a reply without a counter (0) can only be matched by its content (CoE service, SDO command, index,
  subindex, segment toggle: the channel checks those for every link).

If the echo was a coincidence (a rewriting master whose counter happened to run in step with ours), the first
request that goes unanswered while replies with foreign counters came in ends the echo assumption, so the
next attempt accepts them again.
"""

from __future__ import annotations

from collections import deque

#: Accepted replies remembered for duplicate detection: fewer than the 7 counter values, so a new reply
#: that legitimately repeats an old one's counter (7 mailboxes later) is never taken for a duplicate.
WINDOW = 6
#: Consecutive echoed counters after which the link is taken to echo them.
ECHO_AFTER = 2


class ReplyFilter:
    """Counter bookkeeping of one mailbox client (one per channel)."""

    __slots__ = ("_recent", "_sent", "_streak", "_foreign", "strict")

    def __init__(self, strict: bool = False) -> None:
        #: ``strict``: the link is known to echo counters (no learning needed).
        self.strict = strict
        self._recent: deque[bytes] = deque(maxlen=WINDOW)
        self._sent = 0
        self._streak = 0
        self._foreign = False

    @property
    def echoes(self) -> bool:
        """True while the link is taken to echo the request's counter."""
        return self.strict or self._streak >= ECHO_AFTER

    def sent(self, counter: int) -> None:
        """A request with ``counter`` went out: replies are now judged against it."""
        self._sent = counter
        self._foreign = False

    def admit(self, raw: bytes, counter: int) -> bool:
        """False for a reply that is certainly not the answer to the request just sent."""
        if not counter:
            return True
        if raw in self._recent:
            return False  # a duplicate of an answer already taken
        if self.echoes and counter != self._sent:
            self._foreign = True
            return False  # the answer to some other (earlier) request
        return True

    def mine(self, counter: int) -> bool:
        """True when the reply's counter proves it answers the request just sent (an echoing link)."""
        return self.echoes and counter == self._sent and counter != 0

    def accepted(self, raw: bytes, counter: int) -> None:
        """The channel took this reply as the answer: remember it and learn whether counters echo."""
        if not counter:
            return
        self._recent.append(bytes(raw))
        self._streak = self._streak + 1 if counter == self._sent else 0

    def unanswered(self) -> None:
        """The request got no answer: if replies with foreign counters came meanwhile, stop assuming echo."""
        if self._foreign and not self.strict:
            self._streak = 0
        self._foreign = False

    def take(self, raw: bytes, counter: int, sent: int = -1) -> bool | None:
        """:meth:`admit`, then :meth:`mine` and :meth:`accepted` for a reply the channel takes whatever the
        counter says (its content answers the request): None when it is not admitted, else whether it is proven
        ours. One call for a client's one-pass path; tests/test_sdo_fast_path_parity.py holds it equal to the three.
        ``sent``: the counter of the request this reply is the first look after, when :meth:`sent` was not called
        for it yet (the same call does it: tests/test_gateway_sdo_parity.py holds it equal to the two calls)."""
        if sent < 0:
            sent = self._sent
        else:
            self._sent = sent
            self._foreign = False
        if not counter:
            return False
        if raw in self._recent:
            return None
        echoes = self.strict or self._streak >= ECHO_AFTER
        if echoes and counter != sent:
            self._foreign = True
            return None
        self._recent.append(raw if raw.__class__ is bytes else bytes(raw))
        self._streak = self._streak + 1 if counter == sent else 0
        return echoes and counter == sent
