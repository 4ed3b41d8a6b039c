"""The AKD's text parameter file: ``NAME value`` lines, ``#`` comments, CRLF or LF, Latin-1.

Why this form: it is what the service channel itself replays (every non-comment line is a command the drive
accepts, reference akd-ascii-channel.md 4), what aakd writes, and -- written from names, not addresses -- what
lets a file dumped over one transport be restored over another. Reading is lenient the way the reference
suggests [I]: ``'`` comments, a trailing ``# ...`` comment, a ``(default)`` or ``[unit]`` tail are accepted.
Today's TOML/JSON backups (``param backup``) are told apart by content (:func:`kind_of`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from akdctl.errors import UsageError

#: A parameter file is small: the AKD has about 1100 parameters.
LIMIT = 1 << 20
_TAIL = re.compile(r"\s*(\([^)]*\)|\[[^\]]*\])\s*$")


def kind_of(data: bytes) -> str:
    """'akd' (NAME value lines), 'json' or 'toml' (``param backup`` files), by content."""
    text = data.decode("latin-1").lstrip("\ufeff")
    if text.lstrip().startswith("{"):
        return "json"
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped or stripped[0] in "#'":
            continue
        if stripped.startswith("[") or re.match(r"^[\w.\"-]+\s*=", stripped):
            return "toml"
        return "akd"
    return "akd"


def parse(data: bytes, shown: str) -> list[tuple[int, str, str]]:
    """(line number, NAME, value text) of every parameter line; UsageError naming the first bad line."""
    text = data.decode("latin-1")
    entries: list[tuple[int, str, str]] = []
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if not stripped or stripped[0] in "#'":
            continue
        if "#" in stripped:
            stripped = stripped[:stripped.index("#")].rstrip()
        name, _, value = stripped.partition(" ")
        value = value.strip()
        while True:
            cut = _TAIL.sub("", value)
            if cut == value:
                break
            value = cut
        if not re.fullmatch(r"[A-Za-z][A-Za-z0-9]*\.[A-Za-z0-9.]+", name) or not value:
            raise UsageError(f"{shown} line {number}: expected 'NAME value', got {line.strip()[:60]!r}")
        entries.append((number, name.upper(), value))
    if not entries:
        raise UsageError(f"{shown}: no 'NAME value' lines")
    return entries


def render(pairs: Iterable[tuple[str, str]], header: Iterable[str]) -> bytes:
    """The file: ``# header`` lines, then ``NAME value`` lines, CRLF, Latin-1 (unencodable characters as ?)."""
    lines = [f"# {h}" for h in header] + [f"{name} {value}" for name, value in pairs]
    return ("\r\n".join(lines) + "\r\n").encode("latin-1", errors="replace")


__all__ = ["LIMIT", "kind_of", "parse", "render"]
