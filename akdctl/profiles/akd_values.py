"""The AKD's value forms: how a parameter's value is written as text (the ASCII channel, parameter files) and as
a scaled integer on a fieldbus. Shared by the client (``drive/names.py``) and the simulated drive's faces.

Why one module: the service channel prints floats with three decimals and a ``[unit]`` tail and refuses more
decimals (aakd: "floats are rejected when they have more than 3 digits", reference akd-ascii-channel.md 2.1); the
fieldbuses carry the same float as an integer times a factor (CoE per object, EtherNet/IP and Modbus x1000).
Written once here, a value read over one transport compares equal to the same value read over another.
"""

from __future__ import annotations

import re

#: EtherNet/IP and Modbus carry float parameters as integers x1000 [V: AKD EtherNet/IP manual, Modbus pages].
FLOAT_WIRE = 1000
_REPLY = re.compile(r"^\s*(\S+)(?:\s+\[(.*)\])?\s*$", re.S)


class ValueFormError(ValueError):
    """A text that is not a value of the parameter's kind (the message says why, in words)."""


def format_value(kind: str, value: object, unit: str = "") -> str:
    """The drive's text for a value: ``1.000 [A]``, ``2``, ``No-Name``."""
    if kind == "float" and isinstance(value, (int, float)) and not isinstance(value, bool):
        text = f"{float(value):.3f}"
    else:
        text = str(value)
    return f"{text} [{unit}]" if unit else text


def parse_text(kind: str, text: str) -> object:
    """A value of ``kind`` from the text a user or a file gave (ints also as 0x..; floats at most 3 decimals)."""
    text = text.strip()
    if kind in ("string", "text"):
        return text
    if not text:
        raise ValueFormError("no value given")
    if kind == "float":
        if not re.fullmatch(r"[-+]?(\d+(\.\d*)?|\.\d+)", text):
            raise ValueFormError(f"{text!r} is not a number")
        decimals = len(text.partition(".")[2])
        if decimals > 3:
            raise ValueFormError(f"{text} has {decimals} decimals; the AKD takes at most 3")
        return float(text)
    try:
        return int(text, 0)
    except ValueError:
        try:
            number = float(text)
        except ValueError:
            raise ValueFormError(f"{text!r} is not an integer") from None
        if number.is_integer():
            return int(number)
        raise ValueFormError(f"{text!r} is not an integer") from None


def split_reply(reply: str) -> tuple[str, str | None]:
    """(value text, unit or None) of a one-line read reply ``123.456 [rpm]``; the text itself when it is not
    of that shape (a name, a multi-word reply)."""
    match = _REPLY.match(reply)
    if match is None or "\n" in reply.strip():
        return reply.strip(), None
    return match.group(1), match.group(2)


def to_fixed(value: object, factor: int) -> int:
    """A value as the integer a fieldbus carries (``1.5`` at factor 1000 -> 1500)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueFormError(f"{value!r} is not a number")
    return int(round(float(value) * factor))


def from_fixed(raw: int, kind: str, factor: int) -> object:
    """The value a fieldbus integer stands for (float kinds divided by ``factor``, integers as they are)."""
    if kind == "float":
        return raw / factor
    return raw


def same_value(kind: str, a: object, b: object) -> bool:
    """Equal as the drive would print them (floats to 3 decimals)."""
    if kind == "float" and isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return round(float(a), 3) == round(float(b), 3)
    return a == b
