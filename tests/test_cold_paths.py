"""The shortcuts that keep regular expressions out of the usual cold start decide as the patterns do (issue 15.4).

``pnu get 930``, ``sdo read 0x6041``, a plain table cell and an option such as ``--help`` are read without compiling
a pattern (a compile costs 0.1-0.3 ms at every start); every other input goes through the pattern. Each shortcut is
checked against its pattern on generated text, including the near misses (leading zeros, other digits, whitespace,
``h`` suffixes, control and format characters).
"""

from __future__ import annotations

import re

from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.cli import output, parsing
from akdctl.drive import objects, params

_TRICKY = st.sampled_from(["0x", "0X", "h", "H", ":", ".", "[", "]", "..", " ", "\t", "\u00a0", "0", "9", "٣", "²",
                           "a", "F", "g", "-", "e", "i", "n", "inf", "nan", "_", "\x1b", "\u202e", "\n", "é"])
_TEXT = st.one_of(st.text(max_size=12), st.lists(_TRICKY, max_size=6).map("".join),
                  st.integers(0, 0x1FFFF).map(lambda n: f"0x{n:X}"), st.integers(0, 99999).map(str))


def _spec_by_pattern(text: str) -> tuple[str, str | None, str | None] | None:
    match = re.match(params._SPEC, text)
    return (match.group("pnu"), match.group("a"), match.group("b")) if match else None


def _address_by_pattern(text: str) -> tuple[str, str | None] | None:
    match = re.match(objects._ADDRESS, text)
    return (match.group("index"), match.group("sub")) if match else None


@settings(max_examples=400)
@given(_TEXT)
def test_pnu_address_shortcut_reads_as_the_pattern(text: str) -> None:
    assert params._spec_parts(text) == _spec_by_pattern(text)


@settings(max_examples=400)
@given(_TEXT)
def test_object_address_shortcut_reads_as_the_pattern(text: str) -> None:
    assert objects._address_parts(text) == _address_by_pattern(text)


@settings(max_examples=400)
@given(st.one_of(_TEXT, _TEXT.map(lambda t: "-" + t), _TEXT.map(lambda t: "--" + t)))
def test_negative_number_shortcut_decides_as_the_pattern(token: str) -> None:
    assert parsing.is_negative_number(token) == bool(re.match(parsing._NEGATIVE, token))


@settings(max_examples=400)
@given(_TEXT, st.booleans())
def test_printable_text_shortcut_shows_what_the_pattern_shows(text: str, lines: bool) -> None:
    pattern = output._CONTROL_KEEP_LINES if lines else output._CONTROL
    assert output.inert(text, lines=lines) == re.sub(pattern, output._visible, text)
