"""Target strings: one URL-like string selects the transport and the drive.

``sim`` (the default), ``sim://bench2`` (a second simulated drive),
``pn://192.168.0.10?slot=1``, ``ecat-udp://10.0.0.5:34980/1001``,
``ecat://eth0/0``, ``can://socketcan/can0/1?bitrate=500000``.
Parsing is pure and cheap: it never imports a transport.
"""

from __future__ import annotations

from urllib.parse import parse_qsl, urlsplit

from akdctl.errors import UsageError
from akdctl.protocol.record import Record


class Target(Record):
    """A parsed target. ``source`` says where it came from (shown with ``-v``)."""

    __slots__ = ("raw", "scheme", "host", "port", "path", "query", "source")
    __hash__ = None  # type: ignore[assignment]  # its query is a dict

    def __init__(self, raw: str, scheme: str, host: str = "", port: int | None = None, path: str = "",
                 query: dict[str, str] | None = None, source: str = "default") -> None:
        self.raw = raw
        self.scheme = scheme
        self.host = host
        self.port = port
        self.path = path
        self.query: dict[str, str] = {} if query is None else query
        self.source = source

    @property
    def display(self) -> str:
        return self.raw

    @property
    def path_parts(self) -> list[str]:
        return [p for p in self.path.split("/") if p]

    def query_int(self, name: str, default: int) -> int:
        """An integer query parameter (decimal or 0x-hex), or ``default``."""
        text = self.query.get(name)
        if text is None:
            return default
        try:
            return int(text, 0)
        except ValueError:
            raise UsageError(f"target {self.raw!r}: query parameter {name}={text!r} is not a number") from None


def split_target(text: str, source: str = "--target") -> Target:
    """Split a target string into its parts; scheme-specific checks come later."""
    raw = text.strip()
    if not raw:
        raise UsageError(f"empty target (from {source})")
    if "://" not in raw:
        # bare scheme, optionally with a query: "sim", "sim?drive=cia402"
        scheme, _, query = raw.partition("?")
        if not scheme.replace("-", "").replace("+", "").isalnum():
            raise UsageError(f"malformed target {raw!r} (from {source}): expected SCHEME://ADDRESS or 'sim'")
        return Target(raw=raw, scheme=scheme.lower(), query=_query(raw, query), source=source)
    try:
        parts = urlsplit(raw)
        port = parts.port
    except ValueError as exc:
        raise UsageError(f"malformed target {raw!r} (from {source}): {exc}") from None
    if not parts.scheme:
        raise UsageError(f"malformed target {raw!r} (from {source}): no scheme")
    return Target(
        raw=raw,
        scheme=parts.scheme.lower(),
        host=parts.hostname or "",
        port=port,
        path=parts.path,
        query=_query(raw, parts.query),
        source=source,
    )


def _query(raw: str, query: str) -> dict[str, str]:
    try:
        return dict(parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query)))
    except ValueError:
        raise UsageError(f"malformed target {raw!r}: bad query string {query!r}") from None
