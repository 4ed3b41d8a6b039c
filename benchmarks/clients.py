"""The client operations the rows time, through akdctl's public wiring (Connection, channels).

Why one module: these are the only calls into akdctl's Python API from the benchmarks, so when a work package
changes that API, one file follows. Every operation goes through :class:`akdctl.connection.Connection`, exactly as
a command does (tracer off, as without ``--trace``).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def connection(target: str, timeout: float = 2.0) -> Iterator[object]:
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target

    conn = Connection(parse_target(target), LinkOptions(timeout=timeout))
    try:
        yield conn
    finally:
        conn.close()


def sdo_upload(conn: object, index: int = 0x1018, subindex: int = 1) -> Callable[[], bytes]:
    """One SDO upload (0x1018:01, 4 bytes expedited by default)."""
    objects = conn.objects()  # type: ignore[attr-defined]
    return lambda: objects.upload(index, subindex)


def sdo_download(conn: object, index: int, subindex: int, data: bytes) -> None:
    conn.objects().download(index, subindex, data)  # type: ignore[attr-defined]


def batch_pnus(count: int) -> list[int]:
    """``count`` distinct readable single-value 16-bit PNUs of the catalogue (a batch that fits one request),
    padded with PNU 930 when the catalogue has fewer."""
    from akdctl.catalog.pnus import pnu_table

    table = pnu_table()
    picked = [p for p, info in sorted(table.items()) if info.elements in (None, 1) and info.bits == 16]
    picked = picked[:count]
    return picked + [930] * (count - len(picked))


def pnu_read(conn: object, pnus: list[int]) -> Callable[[], object]:
    """One read of ``pnus`` (the channel batches them as it would for ``pnu get``)."""
    from akdctl.protocol.bmp import ParameterAddress

    channel = conn.parameters()  # type: ignore[attr-defined]
    addresses = [ParameterAddress(p) for p in pnus]

    def read() -> object:
        results = channel.read(addresses)
        if len(results) != len(addresses):
            raise RuntimeError("short read")
        return results

    return read


def requests_of(conn: object) -> int | None:
    """PROFIdrive requests the connection's parameter channel sent so far (None if it does not count)."""
    return getattr(conn.parameters(), "requests", None)  # type: ignore[attr-defined]


@contextlib.contextmanager
def state_dir(path: str) -> Iterator[None]:
    """Point this process's in-process simulator at ``path`` for the block (the ``sim`` target reads the env)."""
    old = os.environ.get("AKDCTL_STATE_DIR")
    os.environ["AKDCTL_STATE_DIR"] = path
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("AKDCTL_STATE_DIR", None)
        else:
            os.environ["AKDCTL_STATE_DIR"] = old
