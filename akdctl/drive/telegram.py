"""PROFIdrive telegrams over any ParameterChannel: read PNU 922/915/916/923, select a telegram, map telegram 0.

Why: what travels cyclically on PROFINET is chosen by PNU 922 and, for the free
telegram 0, by the signal numbers in PNU 915 (set points) and 916 (actual values)
taken from the signal list PNU 923 (PROFINET manual 5.8, 5.11). The layouts of
the fixed telegrams are catalogue data (:mod:`akdctl.catalog.telegrams`); this
module reads what the drive says, checks a wanted free mapping before anything is
written, writes it and reads it back.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from akdctl.catalog import telegrams as tc
from akdctl.drive.operation import WritePlan, check_readback
from akdctl.drive.values import pnu_refused, pnu_spec, read_pnus, write_pnus
from akdctl.errors import MalformedReply, ParameterRefused, UsageError
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.connection import Connection
    from akdctl.drive.gate import Gated


@dataclass
class TelegramState:
    """What the drive reports: the selected telegram and the IO words of both directions."""

    number: int
    setpoint_words: list[int]
    actual_words: list[int]
    signal_list: list[int]

    @property
    def setpoint(self) -> list[int]:
        return _signals(self.setpoint_words, "PNU 915")

    @property
    def actual(self) -> list[int]:
        return _signals(self.actual_words, "PNU 916")

    def to_json(self) -> dict[str, Any]:
        layout = tc.telegram(self.number)
        return {
            "telegram": self.number,
            "description": layout.text if layout else ("free mapping (PNU 915/916)" if self.number == 0 else "unknown"),
            "source": layout.source if layout else "",
            "pnu915": self.setpoint_words, "pnu916": self.actual_words,
            "setpoint": words_json(self.setpoint), "actual": words_json(self.actual),
            "signal_list": [n for n, pnu in enumerate(self.signal_list) if pnu],
        }


def _signals(words: list[int], what: str) -> list[int]:
    try:
        return tc.words_to_signals(words)
    except tc.TelegramDataError as exc:
        raise MalformedReply(f"{what} does not describe a telegram: {exc}") from None


def words_json(signals: Sequence[int]) -> list[dict[str, Any]]:
    """Word by word: number (1-based), signal number and name, part of a double word, direction, meaning."""
    return [{"word": s.word, "signal": s.signal.number, "name": s.signal.name, "part": s.part,
             "label": s.label, "text": s.signal.text} for s in tc.word_layout(signals)]


def read_state(channel: Any) -> TelegramState:
    """PNU 922, 915, 916 and 923 in one batched read."""
    readings = read_pnus(channel, [pnu_spec(922), pnu_spec(915), pnu_spec(916), pnu_spec(923)])
    for reading in readings:
        if not reading.ok:
            raise pnu_refused(reading, "read")
    number, setpoint, actual, offered = (list(r.values or []) for r in readings)
    return TelegramState(number[0], setpoint, actual, offered)


def parse_signals(text: str) -> list[int]:
    """``1,5`` or ``STW1,NSOLL_A`` -> signal numbers (known to the catalogue)."""
    out: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        sig = tc.signal_by_name(part)
        if sig is None:
            try:
                number = int(part, 0)
            except ValueError:
                raise UsageError(f"unknown signal {part!r}; signals: "
                                 + ", ".join(f"{s.number} {s.name}" for s in tc.SIGNALS.values())) from None
            sig = tc.signal(number)
            if sig is None:
                raise UsageError(f"signal {number} is not a signal of the AKD; signals: "
                                 + ", ".join(f"{s.number} {s.name}" for s in tc.SIGNALS.values()))
        out.append(sig.number)
    return out


def validate_free_map(setpoint: Sequence[int], actual: Sequence[int], offered: Sequence[int] | None = None) -> list[str]:
    """Why a telegram 0 mapping cannot work (empty: fine): signal in PNU 923, right direction, <= 10 words."""
    listed = list(offered) if offered is not None else tc.signal_list()
    problems: list[str] = []
    for signals, direction, pnu in ((setpoint, "setpoint", 915), (actual, "actual", 916)):
        for number in signals:
            sig = tc.signal(number)
            if sig is None:
                problems.append(f"signal {number} is not a signal of the AKD")
                continue
            if number >= len(listed) or not listed[number]:
                problems.append(f"signal {number} ({sig.name}) is not in the signal list (PNU 923); "
                                "it exists only inside the standard telegrams")
            if sig.direction != direction:
                problems.append(f"signal {number} ({sig.name}) is a{'n' if sig.direction == 'actual' else ''} "
                                f"{sig.direction} signal; it cannot go into PNU {pnu}")
        words = sum(tc.SIGNALS[n].words for n in signals if n in tc.SIGNALS)
        if words > tc.PZD_MAX_WORDS:
            problems.append(f"PNU {pnu}: {words} IO words, at most {tc.PZD_MAX_WORDS}")
        if len(set(signals)) != len(signals):
            problems.append(f"PNU {pnu}: a signal is mapped twice")
    return problems


def select_telegram(channel: Any, number: int) -> TelegramState:
    """Write PNU 922 and read back the whole telegram state; CheckFailed if 922 reads back differently."""
    result = write_pnus(channel, [(pnu_spec(922), [number])])[0]
    if not result.ok:
        raise pnu_refused(result, "change")
    state = read_state(channel)
    check_readback([("PNU 922 (Telegram selection)", number, state.number)])
    return state


def map_free(channel: Any, setpoint: Sequence[int] | None, actual: Sequence[int] | None) -> TelegramState:
    """Write PNU 915 and/or 916 (all ten words each, zero-padded) and verify by reading back."""
    items = _map_items(setpoint, actual)
    for result in write_pnus(channel, items):
        if not result.ok:
            raise pnu_refused(result, "change")
    state = read_state(channel)
    check_readback([(f"PNU {spec.pnu} ({spec.info.name if spec.info else ''})", words,
                     state.setpoint_words if spec.pnu == 915 else state.actual_words) for spec, words in items])
    return state


def _map_items(setpoint: Sequence[int] | None, actual: Sequence[int] | None) -> list[tuple[Any, list[int]]]:
    items = []
    try:
        if setpoint is not None:
            items.append((pnu_spec(915), tc.expand_words(list(setpoint))))
        if actual is not None:
            items.append((pnu_spec(916), tc.expand_words(list(actual))))
    except tc.TelegramDataError as exc:
        raise UsageError(str(exc)) from None
    return items


# ---------------------------------------------------------------------------- the operation (plan -> execute)
class TelegramRequest(Record):
    """``telegram set N`` (``number``) or ``telegram map`` (``setpoint``/``actual`` signal numbers, None: keep);
    ``force``: send what akdctl's own checks refuse and let the drive answer."""

    __slots__ = ("number", "setpoint", "actual", "force")

    def __init__(self, number: int | None = None, setpoint: Sequence[int] | None = None,
                 actual: Sequence[int] | None = None, force: bool = False) -> None:
        self.number = number
        self.setpoint = list(setpoint) if setpoint is not None else None
        self.actual = list(actual) if actual is not None else None
        self.force = force

    @property
    def operation(self) -> str:
        return "telegram set" if self.number is not None else "telegram map"


def select_request(number: int, *, force: bool = False) -> TelegramRequest:
    """A telegram selection, checked without the drive: one the AKD offers (PROFINET manual 5.8), or --force."""
    known = (*tc.TELEGRAMS, tc.FREE_TELEGRAM)
    if not 0 <= number <= 0xFFFF:
        raise UsageError(f"telegram {number} is outside 0..65535 (nothing was written)")
    if number not in known and not force:
        raise UsageError(f"telegram {number} is not one the AKD offers; choose one of "
                         + ", ".join(str(n) for n in sorted(known)) + " (nothing was written)")
    return TelegramRequest(number=number, force=force)


def map_request(setpoint: Sequence[int] | None, actual: Sequence[int] | None, *,
                force: bool = False) -> TelegramRequest:
    """A free mapping for telegram 0; refused here (drive-free) when nothing is given."""
    if setpoint is None and actual is None:
        raise UsageError("nothing to map: give the set-point and/or the actual-value signals")
    request = TelegramRequest(setpoint=setpoint, actual=actual, force=force)
    _map_items(request.setpoint, request.actual)  # more words than a telegram holds: refused before the drive
    return request


def gated(request: TelegramRequest) -> list[Gated]:
    """What the request writes that the gate classifies (PNU 922, or 915/916): known without the drive."""
    pnus = [922] if request.number is not None else [p for p, w in ((915, request.setpoint), (916, request.actual))
                                                     if w is not None]
    return [g for g in (_gate(p) for p in pnus) if g is not None]


def _pnu_name(pnu: int) -> str:
    spec = pnu_spec(pnu)
    return spec.info.name if spec.info is not None else ""


def refusal(problems: Sequence[str]) -> UsageError:
    """The one wording of a refused telegram mapping: one problem per line."""
    return UsageError("telegram mapping refused, nothing was written:\n  - " + "\n  - ".join(problems),
                      details={"problems": list(problems)})


def plan(conn: "Connection", request: TelegramRequest) -> WritePlan:
    """Select: PNU 922; map: reads PNU 922/923 first (telegram 0 selected, every signal offered) and refuses
    what cannot work unless forced (then each problem is a note)."""
    from akdctl.drive.operation import PlannedWrite, read_enabled

    notes: list[str] = []
    preconditions: list[str] = []
    conn.parameters()  # a target without PNU access is refused before any consent is asked
    if request.number is not None:
        if request.number not in (*tc.TELEGRAMS, tc.FREE_TELEGRAM):
            notes.append(f"--force: telegram {request.number} is not one the AKD documents; the drive answers")
        layout = tc.telegram(request.number)
        shown = f"{request.number} ({layout.text})" if layout else str(request.number)
        writes = [PlannedWrite(f"PNU 922 ({_pnu_name(922)})", [request.number], shown, _gate(922))]
    else:
        state = read_state(conn.parameters())
        problems = validate_free_map(request.setpoint or [], request.actual or [], state.signal_list)
        if state.number != 0:
            problems.insert(0, f"telegram {state.number} is selected; PNU 915/916 change only in telegram 0 "
                               "(run 'akdctl telegram set 0' first)")
        if problems and not request.force:
            raise refusal(problems)
        notes += [f"--force: {p}" for p in problems]
        preconditions.append(f"telegram {state.number} selected (PNU 922)")
        writes = [PlannedWrite(f"PNU {spec.pnu} ({_pnu_name(spec.pnu)})", words,
                               ", ".join(_signal_text(n) for n in signals) or "(no words)",
                               _gate(spec.pnu))
                  for (spec, words), signals in zip(_map_items(request.setpoint, request.actual),
                                                    [w for w in (request.setpoint, request.actual) if w is not None])]
    return WritePlan(request.operation, conn.target.display, writes, preconditions=preconditions, notes=notes,
                     enabled=read_enabled(conn, writes), verify=True, data={"request": request})


def _signal_text(number: int) -> str:
    sig = tc.signal(number)
    return f"{number} {sig.name}" if sig is not None else str(number)


def _gate(pnu: int) -> "Gated | None":
    from akdctl.drive.gate import classify_pnu

    return classify_pnu(pnu, _pnu_name(pnu))


def execute(conn: "Connection", plan: WritePlan) -> TelegramState:
    """Write the plan and read the whole telegram state back (CheckFailed on a difference)."""
    request: TelegramRequest = plan.data["request"]
    if request.number is not None:
        return select_telegram(conn.parameters(), request.number)
    return map_free(conn.parameters(), request.setpoint, request.actual)


def ensure_submode(channel: Any, submode: str) -> int | None:
    """Make the selected telegram carry what a position submode reads (``program`` or ``mdi``).

    Why: the manuals require "Standard telegram 7 (program mode) / 9 (MDI) needs to be configured" (004
    5.10.1/5.10.2); the drive starts no task otherwise (docs/fidelity.md F9). A telegram that already carries the
    signals (9 for both, 7 for program mode, or 0 mapping them) is kept; else the submode's standard telegram is
    selected. Returns the telegram selected, or None when nothing changed.
    """
    wanted = tc.SUBMODES[submode]
    state = read_state(channel)
    if not tc.missing_for_submode(submode, state.setpoint):
        return None
    try:
        select_telegram(channel, wanted.telegram)
    except ParameterRefused as exc:
        raise ParameterRefused(f"{wanted.name} needs telegram {wanted.telegram} (PROFINET manual 5.10), and the "
                               f"drive refused to select it: {exc.message}", code=exc.code) from None
    return wanted.telegram
