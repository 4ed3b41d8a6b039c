"""Durations on the command line: one spelling everywhere (``2``, ``2s``, ``500ms``, ``1.5m``).

Why one place: ``jog --for 2s`` was accepted while ``home --timeout 2s`` and the global ``--timeout 2s`` were
refused (issue 23 item 22). Every option that takes a duration uses :class:`Duration`; a bare number is seconds.
"""

from __future__ import annotations

import math
import re
from typing import Any

import click

_DURATION = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(ms|s|m|min)?\s*$")


def parse(text: str, what: str = "duration") -> float:
    """Seconds from ``2``, ``2s``, ``500ms``, ``1.5m``/``1.5min``; UsageError (exit 2) otherwise."""
    from akdctl.errors import UsageError

    match = _DURATION.match(str(text))
    if not match:
        raise UsageError(f"{what}: bad duration {text!r}: use e.g. 2s, 500ms, 1.5")
    value = float(match.group(1))
    unit = match.group(2) or "s"
    seconds = value / 1000.0 if unit == "ms" else value * 60.0 if unit in ("m", "min") else value
    if not math.isfinite(seconds):
        raise UsageError(f"{what} must be finite, got {text!r}")
    return seconds


class Duration(click.ParamType):
    """A click option type for :func:`parse`, with optional bounds in seconds (exclusive ``low`` of 0)."""

    name = "duration"

    def __init__(self, low: float | None = None, high: float | None = None) -> None:
        self.low, self.high = low, high

    def convert(self, value: Any, param: Any, ctx: Any) -> float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            seconds = float(value)
        else:
            match = _DURATION.match(str(value))
            if not match:
                self.fail(f"{value!r} is not a duration: use e.g. 2s, 500ms, 1.5", param, ctx)
            seconds = parse(str(value))
        if (self.low is not None and seconds < self.low) or (self.high is not None and seconds > self.high):
            self.fail(f"{value!r} is outside {self.low:g}..{self.high:g} s", param, ctx)
        return seconds
