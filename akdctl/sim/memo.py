"""The one rule of the simulator's bounded memos (request shapes, datagrams, plans kept by their bytes).

Why start over rather than evict one by one: a client polls with a handful of requests, so a memo that fills up
means many distinct requests (many clients, or a fuzzer), where keeping any particular one buys nothing; clearing
is O(1) per entry and keeps the memo within its bound with no bookkeeping on the hot path, which only reads it.
"""

from __future__ import annotations

from typing import Any, TypeVar

V = TypeVar("V")


def remember(memo: dict[Any, V], key: Any, value: V, limit: int) -> V:
    """Keep ``value`` under ``key`` in ``memo``, which holds at most ``limit`` entries (full: it starts over)."""
    if len(memo) >= limit:
        memo.clear()
    memo[key] = value
    return value
