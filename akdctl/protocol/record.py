"""``Record``: the base of akdctl's small value classes (codec messages, catalogue rows, results).

Why not dataclasses or named tuples: both generate and compile code when a class is *defined* (a frozen dataclass
about 0.4 ms, a named tuple about 0.07 ms), and every command pays that at start for every record class the modules
it imports define. A Record subclass lists its fields in ``__slots__`` and writes its own ``__init__``; all its
methods come from the bytecode cache, so defining one costs about 10 µs.

What a subclass gets, as the frozen dataclasses these were gave it: equality by value with records of the same class
only (never with a tuple or another record class of the same shape), a hash of the fields (a mutable record sets
``__hash__ = None``), a ``Name(field=value, ...)`` repr, and :meth:`Record.replace` for a copy with some fields
changed. Fields are every name of the class's own ``__slots__`` (no inheritance of fields), in order, and
``__init__`` takes them by those names. Records are not frozen by force: treat the catalogue's and the codecs' as
immutable, as their docstrings say.
"""

from __future__ import annotations

from typing import Any, TypeVar

R = TypeVar("R", bound="Record")


class Record:
    """Slots, equality and hash by value, a dataclass-like repr, ``replace`` (module docstring)."""

    __slots__ = ()

    def _values(self) -> tuple[Any, ...]:
        return tuple([getattr(self, name) for name in self.__slots__])

    def __eq__(self, other: object) -> bool:
        if other.__class__ is not self.__class__:
            return NotImplemented
        return self._values() == other._values()  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash(self._values())

    def __repr__(self) -> str:
        return f"{self.__class__.__name__}({', '.join(f'{n}={getattr(self, n)!r}' for n in self.__slots__)})"

    def replace(self: R, **changes: Any) -> R:
        """A copy with ``changes`` applied (``dataclasses.replace`` for records)."""
        values = {name: getattr(self, name) for name in self.__slots__}
        values.update(changes)
        return self.__class__(**values)
