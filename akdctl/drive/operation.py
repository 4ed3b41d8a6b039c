"""Plan -> consent -> execute: the one shape of every writing operation.

Why one shape: the motion planner (:mod:`akdctl.drive.motion_plan`) showed that a
rule kept in its callers drifts -- the CLI and the recipe each named the gated
PNUs, each worded the PRE-OP precondition, each compared a read-back. So an
operation in ``drive/`` (``pnu set``, ``sdo write``, ``param set``, a telegram or
PDO map, a restore, an alias or firmware write, ...) offers two functions:

* ``plan(conn, request) -> WritePlan``: reads (never writes) what it must, checks
  every value and precondition, and returns what it will write in which order,
  which writes need consent and why, and the notes a reader of ``--dry-run``
  needs. A request that cannot run raises here (UsageError, SafetyRefusal, ...),
  before anything is written;
* ``execute(conn, plan) -> result``: writes exactly the plan, reads back when the
  plan says so and raises one :class:`~akdctl.errors.CheckFailed` worded by
  :func:`check_readback`.

Callers (CLI commands, recipe steps, the shell) only parse, plan, ask
(:func:`consent_needed` / :attr:`WritePlan.consent_text`), execute and render;
``--dry-run`` renders :meth:`WritePlan.lines` / :meth:`WritePlan.to_json`.
The gate's classification of an address (:class:`akdctl.drive.gate.Gated`) is
carried by each :class:`PlannedWrite`, so the consent a plan asks for is decided
where the addresses are known, once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any

from akdctl.errors import CheckFailed
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.drive.gate import Gated


class PlannedWrite(Record):
    """One write of a plan: where (``address`` as a user reads it, e.g. ``PNU 930 (operating mode)``,
    ``0x6060:0 (Modes of operation)``, ``DRV.OPMODE``), the value as it goes on the wire (``raw``) and as a
    user reads it (``display``, with its unit), and the gate's verdict (``gated``: None when the write can
    neither power nor move the axis)."""

    __slots__ = ("address", "raw", "display", "gated")

    def __init__(self, address: str, raw: Any, display: str, gated: "Gated | None" = None) -> None:
        self.address = address
        self.raw = raw
        self.display = display
        self.gated = gated

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {"address": self.address, "value": self.display, "raw": _jsonable(self.raw)}
        if self.gated is not None:
            data["gated"] = {"reason": self.gated.reason, "when_enabled": self.gated.when_enabled}
        return data


class WritePlan:
    """What an operation will write, checked and not yet done.

    ``operation``: the command's words (``pnu set``, ``pdo map``); ``target``: the target's display name;
    ``writes``: in the order they will be sent; ``preconditions``: the states the plan found and relies on,
    in words (``EtherCAT state PRE-OP``, ``drive disabled``); ``notes``: what a reader should know
    (``the drive saves all RAM parameters on this write``); ``enabled``: the power stage as read while
    planning (None: not read, or unreadable -- counts as enabled for writes gated only while enabled);
    ``verify``: execute reads every write back; ``data``: the operation's own values for its ``execute``.
    """

    __slots__ = ("operation", "target", "writes", "preconditions", "notes", "_enabled", "verify", "data")

    def __init__(self, operation: str, target: str, writes: Sequence[PlannedWrite] = (), *,
                 preconditions: Iterable[str] = (), notes: Iterable[str] = (),
                 enabled: "bool | None | Callable[[], bool | None]" = None,
                 verify: bool = False, data: dict[str, Any] | None = None) -> None:
        self.operation = operation
        self.target = target
        self.writes = list(writes)
        self.preconditions = list(preconditions)
        self.notes = list(notes)
        self._enabled = enabled
        self.verify = verify
        self.data = dict(data or {})

    @property
    def enabled(self) -> bool | None:
        """The power stage as the plan found it; a reader (:func:`read_enabled`) runs once, on first use: only
        a consent question or a dry run needs it, so ``--yes`` and a recipe's run cost no read."""
        if callable(self._enabled):
            self._enabled = self._enabled()
        return self._enabled

    # ------------------------------------------------------------ consent
    @property
    def needing_consent(self) -> list["Gated"]:
        """The gated writes that need consent now (a write gated only while enabled counts unless the plan
        read the drive as disabled)."""
        from akdctl.drive.gate import needing_consent

        gated = [w.gated for w in self.writes if w.gated is not None]
        return needing_consent(gated, self.enabled) if gated else []  # no gated write: the drive is never read

    @property
    def gated(self) -> bool:
        """Whether any write can power or move the axis (such a plan owns the axis while it runs)."""
        return any(w.gated is not None for w in self.writes)

    @property
    def consent_text(self) -> str:
        """The one sentence a consent prompt shows: what will be written and why it needs consent."""
        needing = self.needing_consent
        if not needing:
            return ""
        by_reason: dict[str, list[str]] = {}  # one reason once, however many addresses share it (a PDO map)
        for gated in needing:
            addresses = by_reason.setdefault(gated.reason, [])
            if gated.address not in addresses:
                addresses.append(gated.address)
        return "write " + "; ".join(f"{', '.join(a)}: {r}" for r, a in by_reason.items())

    # ------------------------------------------------------------ rendering
    def lines(self) -> list[str]:
        """The plan in words, one line each (``--dry-run`` prints these)."""
        out = [f"{self.operation} on {self.target}: {len(self.writes)} write(s)"
               + (", each read back" if self.verify else "")]
        out += [f"  precondition: {text}" for text in self.preconditions]
        for number, write in enumerate(self.writes, 1):
            why = ""
            if write.gated is not None and write.gated in self.needing_consent:
                why = f"  [needs consent: {write.gated.reason}]"
            out.append(f"  {number}. {write.address} = {write.display}{why}")
        out += [f"  note: {text}" for text in self.notes]
        return out

    def to_json(self) -> dict[str, Any]:
        return {"operation": self.operation, "target": self.target,
                "writes": [w.to_json() for w in self.writes], "preconditions": list(self.preconditions),
                "notes": list(self.notes), "verify": self.verify,
                "needs_consent": [g.text() for g in self.needing_consent]}

    def __repr__(self) -> str:
        return f"WritePlan({self.operation!r}, {len(self.writes)} writes, consent={bool(self.needing_consent)})"


def consent_needed(plan: WritePlan, ask: Callable[[str], None], *, given: bool = False) -> None:
    """Ask ``ask(plan.consent_text)`` when the plan needs consent; ``given`` (``--yes``) skips the question.

    ``ask`` raises :class:`~akdctl.errors.SafetyRefusal` when consent is refused (the CLI's prompt, a
    recipe's missing ``--yes``), so returning means the plan may run.
    """
    if not given and plan.needing_consent:  # given first: --yes never reads the power stage
        ask(plan.consent_text)


def read_enabled(conn: Any, writes: Iterable[PlannedWrite]) -> "bool | Callable[[], bool | None]":
    """The power stage as a plan needs it: ``False`` when no write is gated only while enabled (nothing depends
    on it), else a reader of :func:`akdctl.drive.gate.drive_enabled` that :attr:`WritePlan.enabled` runs when
    the consent or a dry run first asks."""
    if not any(w.gated is not None and w.gated.when_enabled for w in writes):
        return False
    from akdctl.drive.gate import drive_enabled

    return lambda: drive_enabled(conn)


def check_readback(pairs: Iterable[tuple[str, Any, Any]]) -> None:
    """The one read-back comparison (exit 5): ``pairs`` of (address, written, read back).

    A read back that equals what was written passes; every difference is named in one CheckFailed.
    ``read back`` may be an exception text (str starting with ``"refused: "``) when the read failed.
    """
    differences = [f"{address}: wrote {_shown(wrote)}, read back {_shown(back)}"
                   for address, wrote, back in pairs if back != wrote]
    if differences:
        raise CheckFailed("read-back differs: " + "; ".join(differences),
                          details={"differences": differences})


def _shown(value: Any) -> str:
    if isinstance(value, (list, tuple)) and len(value) == 1:
        value = value[0]
    if isinstance(value, (bytes, bytearray)):
        return value.hex(" ") or "(empty)"
    return str(value)


def _jsonable(value: Any) -> Any:
    if isinstance(value, (bytes, bytearray)):
        return value.hex()
    if isinstance(value, tuple):
        return list(value)
    return value


__all__ = ["PlannedWrite", "WritePlan", "check_readback", "consent_needed", "read_enabled"]
