"""``akdctl.io.json_text.loads`` is ``json.loads`` (issue 29: the state file is read without importing json)."""

from __future__ import annotations

import json
import math
import random
from typing import Any

import pytest

from akdctl.io.json_text import loads


def _constant(name: str) -> float:
    raise ValueError(f"{name} is not allowed")


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is not finite")
    return value


def _both(text: str) -> tuple[Any, Any]:
    results = []
    for load in (loads, lambda t, **kw: json.loads(t, **kw)):
        try:
            results.append(("ok", load(text, parse_float=_finite, parse_constant=_constant)))
        except RecursionError:
            results.append(("deep", None))
        except ValueError:
            results.append(("error", None))
    return results[0], results[1]


DOCUMENTS = [
    '{"version":1,"clock":0.5,"pnus":{"930":[2]},"objects":{"1018:04":"93008399"},"s":"\\u00e9\\n","n":null}',
    ' \n\t{"a": [1, 2.5, -3e2, true, false, null, "x"]} \r\n', "[]", "{}", "1", '"text"', "",
    " ", "{", '{"a": 1} x', '{"a": NaN}', '{"a": Infinity}', '{"a": -Infinity}', '{"a": 1e999}',
    '{"a": "\\x"}', '{"a": "tab\there"}', "[1,]", '{"a" 1}', "\ufeff{}", "[" * 50 + "]" * 50,
    "[" * 100000 + "]" * 100000, '{"a": 01}', '{"a": .5}', '{"a": 1.}', "tru", '{"\\ud800": 1}',
]


@pytest.mark.parametrize("text", DOCUMENTS)
def test_loads_agrees_with_json_loads(text: str) -> None:
    ours, theirs = _both(text)
    assert ours == theirs


def test_loads_agrees_on_damaged_state_files() -> None:
    base = json.dumps({"version": 1, "clock": 1.25, "pnus": {"930": [2], "1002": [20]},
                       "components": {"motion": {"state": "switch_on_disabled", "pos": -0.5, "gen": None}}})
    rng = random.Random(29)
    for _ in range(400):
        chars = list(base)
        for _ in range(rng.randint(1, 4)):
            chars[rng.randrange(len(chars))] = rng.choice('{}[]":,0123456789.eE-+ \\nulltrueaN')
        text = "".join(chars)
        ours, theirs = _both(text)
        assert ours == theirs, text
