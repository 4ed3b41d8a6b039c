"""Stand-ins for the drive model that tests hand to the simulator's servers.

One copy, because the CoE reliability tests, the lossy-gateway tests and whatever comes next all need the same
thing: objects whose every applied write is counted, so "applied twice" shows as a count of 2.
"""

from __future__ import annotations

import threading
from collections import Counter

from akdctl.sim.sdo_server import SdoAccessError


class CountingObjects:
    """Objects (``VALUES``, copied per instance) an SdoServer reads and writes; ``writes`` counts each applied
    (index, subindex, data); an unknown object is abort 0x06020000."""

    VALUES: dict[tuple[int, int], bytes] = {}

    def __init__(self) -> None:
        self.values: dict[tuple[int, int], bytes] = dict(self.VALUES)
        self.writes: Counter[tuple[int, int, bytes]] = Counter()
        self.lock = threading.Lock()

    def object_read(self, index: int, subindex: int) -> bytes:
        try:
            return self.values[(index, subindex)]
        except KeyError:
            raise SdoAccessError(0x06020000) from None

    def object_write(self, index: int, subindex: int, data: bytes) -> None:
        self.object_read(index, subindex)
        self.values[(index, subindex)] = bytes(data)
        self.writes[(index, subindex, bytes(data))] += 1
