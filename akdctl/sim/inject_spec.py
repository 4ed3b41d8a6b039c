"""The one syntax of the simulator's fault injection: ``KIND=N[:EXTRA],...`` — every N-th request.

Why one parser: each face (`--pn-inject`, `--ecat-inject`, `--eip-inject`) injects its own faults,
but a technician writes them the same way and gets the same one-line error for a typo. A face names
the kinds it knows and which of them take an extra value (a delay in seconds, a status code);
counting every N-th rather than "the first N" keeps a retrying client able to recover.
"""

from __future__ import annotations

from akdctl.errors import UsageError


def parse_every_nth(text: str | None, option: str, kinds: dict[str, str]) -> dict[str, tuple[int, str]]:
    """``"drop=3,delay=5:0.3"`` → ``{"drop": (3, ""), "delay": (5, "0.3")}``.

    ``kinds`` maps each accepted kind to the form of its extra value (``""`` for none, e.g.
    ``"SECONDS"``), which is also what the error message shows. A bare ``KIND`` means every request.
    """
    syntax = ",".join(f"{kind}=N" + (f":{extra}" if extra else "") for kind, extra in kinds.items())
    found: dict[str, tuple[int, str]] = {}
    for part in (text or "").split(","):
        part = part.strip()
        if not part:
            continue
        kind, _, value = part.partition("=")
        kind = kind.strip().lower()
        if kind not in kinds:
            raise UsageError(f"{option} {text!r}: unknown fault {kind!r}; expected {syntax} (every N-th request)")
        every, _, extra = value.partition(":")
        if extra and not kinds[kind]:
            raise UsageError(f"{option} {text!r}: {kind} takes no ':' value; expected {syntax}")
        try:
            n = int(every or "1", 0)
        except ValueError:
            raise UsageError(f"{option} {text!r}: {part!r} needs a whole number N; expected {syntax}") from None
        if n < 1:
            raise UsageError(f"{option} {text!r}: {kind}={n}: N must be at least 1 (every N-th request)")
        found[kind] = (n, extra.strip())
    return found


def extra_number(found: dict[str, tuple[int, str]], kind: str, default: float, option: str,
                 *, integer: bool = False, low: float = 0.0, high: float | None = None) -> float:
    """The extra value of ``kind`` as a number (``default`` when absent), checked against ``low..high``."""
    raw = found.get(kind, (0, ""))[1]
    if not raw:
        return default
    try:
        value = float(int(raw, 0)) if integer else float(raw)
    except ValueError:
        raise UsageError(f"{option}: {kind}=N:{raw!r} needs a number after ':'") from None
    if not (value >= low and (high is None or value <= high)):
        bound = f"{low:g}..{high:g}" if high is not None else f"at least {low:g}"
        raise UsageError(f"{option}: {kind}=N:{raw} is out of range ({bound})")
    return value
