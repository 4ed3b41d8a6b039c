"""Reading a JSON document without importing the ``json`` package: the simulator's state on every start.

Why: every command against the default target reads the simulated drive's state file, and ``import json``
compiles six regular expressions (its pure-Python scanner's and encoder's) that the C scanner never uses - about
as much CPU as the whole state load. :func:`loads` drives CPython's C scanner (``_json.make_scanner``, what
``json.loads`` itself runs) with the same settings, and falls back to ``json.loads`` where there is no C scanner.
The result and the errors are those of ``json.loads`` (``tests/test_json_text.py`` compares the two on valid and
damaged documents): a ``ValueError`` (``json.JSONDecodeError`` where the scanner raises one) or a
``RecursionError`` for nesting too deep.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

_WHITESPACE = " \t\n\r"  # JSON's insignificant whitespace (RFC 8259)


class _Settings:
    """What the C scanner reads from a ``JSONDecoder``: these attributes, nothing else."""

    __slots__ = ("strict", "object_hook", "object_pairs_hook", "parse_float", "parse_int", "parse_constant", "memo")

    def __init__(self, parse_float: Callable[[str], Any], parse_constant: Callable[[str], Any]) -> None:
        self.strict = True
        self.object_hook = None
        self.object_pairs_hook = None
        self.parse_float = parse_float
        self.parse_int = int
        self.parse_constant = parse_constant
        self.memo: dict[str, str] = {}


def loads(text: str, *, parse_float: Callable[[str], Any], parse_constant: Callable[[str], Any]) -> Any:
    """``json.loads(text, parse_float=..., parse_constant=...)``, without importing ``json`` on the way."""
    try:
        from _json import make_scanner
    except ImportError:  # an interpreter without the C scanner
        import json

        return json.loads(text, parse_float=parse_float, parse_constant=parse_constant)
    scan = make_scanner(_Settings(parse_float, parse_constant))  # type: ignore[arg-type]  # duck-typed decoder
    start = len(text) - len(text.lstrip(_WHITESPACE))
    try:
        value, end = scan(text, start)
    except StopIteration as stop:
        raise ValueError(f"Expecting value: char {stop.value}") from None
    if text[end:].strip(_WHITESPACE):
        raise ValueError(f"Extra data: char {end}")
    return value
