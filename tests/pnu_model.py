"""The model failures the PNU server's planned reads are held to the general path with: one copy for
test_pnu_server (a planned one-parameter read) and test_pnu_batch_plan (a planned batch)."""

from __future__ import annotations

from collections.abc import Callable

from akdctl.sim.errors import PnuAccessError


def failing_reader(failure: str) -> Callable[[int, int], list[int]]:
    """A component's PNU reader that fails as ``failure`` says: an access error, a bug, a wrong number of values,
    a value that does not fit (``"wrong format"`` and ``"fine"`` answer one small value: the caller binds the
    format)."""

    def reader(sub: int, count: int) -> list[int]:
        if failure == "refused":
            raise PnuAccessError(0x14, 7)
        if failure == "bug":
            raise RuntimeError("model bug")
        if failure == "wrong count":
            return [1, 2]
        return [1 << 40] if failure == "too big" else [3]

    return reader
