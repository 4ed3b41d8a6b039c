"""PROFIdrive signals and the AKD's IO telegrams, as data.

Why here: the simulator (PNU 915/916/922/923), the ``telegram`` commands and the
docs need one answer to "which words travel in telegram 9?". The manuals give
the layouts as tables (``004`` 5.11, ``003`` 6.11); where they disagree the
rulings of SPEC-NOTES 10 (telegram 9 actual values end with XIST_A) and 11
(telegram 351 = ZSW1, NIST_A, ITIST_GLATT, XIST_A — uncertain) apply. Both are
plain tuples below so a correction is a one-line change.

PNU 915/916 are *word indexed*: element i names the signal carried in IO data
word i+1, and a double-word signal fills two consecutive elements with its
number. Ten elements = ten words, exactly telegram 9's set-point length.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = [
    "Signal", "SIGNALS", "TELEGRAMS", "TelegramLayout", "FREE_TELEGRAM", "PZD_MAX_WORDS", "SIGNAL_LIST_LENGTH",
    "signal", "signal_by_name", "telegram", "free_mappable", "signal_list", "expand_words", "words_to_signals",
    "WordSlot", "word_layout", "TelegramDataError", "SUBMODES", "missing_for_submode",
]

PZD_MAX_WORDS = 10          # PNU 915/916 have 10 elements
SIGNAL_LIST_LENGTH = 53     # PNU 923 elements 0..52 (element n = PNU of signal n)
FREE_TELEGRAM = 0


class TelegramDataError(ValueError):
    """A word list (PNU 915/916 contents) or a signal list that does not form a valid telegram.

    ``index`` is the offending element of a word list (the simulator answers it as the
    PROFIdrive additional info), None when no single element is to blame.
    """

    def __init__(self, message: str, index: int | None = None) -> None:
        super().__init__(message)
        self.index = index


class Signal(Record):
    """One PROFIdrive signal: number, name, IO words, direction and the PNU that also reads it.

    direction: "setpoint" (controller -> drive) or "actual" (drive -> controller).
    pnu: the PNU carrying the same value (AKD: equal to the signal number, 5.8), or None for
    the standard signals the AKD only offers inside standard telegrams (not in PNU 923).
    """

    __slots__ = ("number", "name", "words", "direction", "signed", "pnu", "text")

    def __init__(self, number: int, name: str, words: int, direction: str, signed: bool, pnu: int | None,
                 text: str) -> None:
        self.number = number
        self.name = name
        self.words = words
        self.direction = direction
        self.signed = signed
        self.pnu = pnu
        self.text = text

    @property
    def free_mappable(self) -> bool:
        """In the signal list (PNU 923), hence allowed in telegram 0 (5.6: 'all supported ... signals')."""
        return self.pnu is not None


def _s(number: int, name: str, words: int, direction: str, signed: bool, pnu: int | None, text: str) -> Signal:
    return Signal(number, name, words, direction, signed, pnu, text)


# AKD signal table (004 5.8; signal number = PNU) plus STW2/ZSW2/XIST_A of the standard telegrams
# (PROFIdrive signal numbers 3, 4, 28): 5.8 "Each signal can be read/write with the same PNU number" and 5.6
# "All supported PROFIdrive and manufacture specific signals can be mapped into telegram 0", so they are PNUs
# 3, 4, 28 and free mappable like the others (docs/fidelity.md F7).
SIGNALS: dict[int, Signal] = {s.number: s for s in (
    _s(1, "STW1", 1, "setpoint", False, 1, "control word 1"),
    _s(2, "ZSW1", 1, "actual", False, 2, "status word 1"),
    _s(3, "STW2", 1, "setpoint", False, 3, "control word 2"),
    _s(4, "ZSW2", 1, "actual", False, 4, "status word 2"),
    _s(5, "NSOLL_A", 1, "setpoint", True, 5, "velocity set point (VL.CMD)"),
    _s(6, "NIST_A", 1, "actual", True, 6, "velocity actual value (VL.FB)"),
    _s(28, "XIST_A", 2, "actual", True, 28, "position actual value"),
    _s(32, "SATZANW", 1, "setpoint", False, 32, "motion task selection (MT.MOVE)"),
    _s(33, "AKTSATZ", 1, "actual", False, 33, "actual motion task (MT.PARAMS)"),
    _s(34, "MDI_TARPOS", 2, "setpoint", True, 34, "MDI target position (MT.P)"),
    _s(35, "MDI_VELOCITY", 2, "setpoint", False, 35, "MDI velocity (MT.V)"),
    _s(36, "MDI_ACC", 1, "setpoint", False, 36, "MDI acceleration (MT.ACC)"),
    _s(37, "MDI_DEC", 1, "setpoint", False, 37, "MDI deceleration (MT.DEC)"),
    _s(38, "MDI_MOD", 1, "setpoint", False, 38, "MDI mode (MT.CNTL)"),
    _s(52, "ITIST_GLATT", 1, "actual", True, 52, "active current (IL.FB)"),
)}


class TelegramLayout(Record):
    """A standard/manufacturer telegram: set-point and actual-value signals in IO order."""

    __slots__ = ("number", "setpoint", "actual", "text", "source")

    def __init__(self, number: int, setpoint: tuple[int, ...], actual: tuple[int, ...], text: str,
                 source: str) -> None:
        self.number = number
        self.setpoint = setpoint
        self.actual = actual
        self.text = text
        self.source = source

    @property
    def setpoint_words(self) -> int:
        return sum(SIGNALS[n].words for n in self.setpoint)

    @property
    def actual_words(self) -> int:
        return sum(SIGNALS[n].words for n in self.actual)


TELEGRAMS: dict[int, TelegramLayout] = {t.number: t for t in (
    TelegramLayout(1, (1, 5), (2, 6), "standard telegram 1 (velocity mode, application class 1)", "004 5.11.2"),
    TelegramLayout(7, (1, 32), (2, 33), "standard telegram 7 (motion task selection, application class 3)",
                   "004 5.11.3"),
    TelegramLayout(9, (1, 32, 3, 34, 35, 36, 37, 38), (2, 33, 4, 28),
                   "standard telegram 9 (MDI positioning, application class 3)", "004 5.11.4, SPEC-NOTES 10"),
    TelegramLayout(350, (1, 5), (2, 6, 52), "manufacturer telegram 350 (velocity + actual current)", "004 5.11.5"),
    TelegramLayout(351, (1, 5), (2, 6, 52, 28),
                   "manufacturer telegram 351 (velocity + actual current + position)", "003 6.11.6, SPEC-NOTES 11"),
)}


def signal(number: int) -> Signal | None:
    return SIGNALS.get(number)


def signal_by_name(name: str) -> Signal | None:
    wanted = name.strip().upper()
    for sig in SIGNALS.values():
        if sig.name == wanted:
            return sig
    return None


def telegram(number: int) -> TelegramLayout | None:
    """A fixed telegram's layout; None for telegram 0 (free) and unknown numbers."""
    return TELEGRAMS.get(number)


def free_mappable(direction: str) -> list[Signal]:
    """Signals allowed in telegram 0 for one direction ("setpoint"/"actual")."""
    return [s for s in SIGNALS.values() if s.free_mappable and s.direction == direction]


def signal_list() -> list[int]:
    """PNU 923 contents: element n holds the PNU of signal n, 0 where signal n is not offered."""
    values = [0] * SIGNAL_LIST_LENGTH
    for sig in SIGNALS.values():
        if sig.pnu is not None and sig.number < SIGNAL_LIST_LENGTH:
            values[sig.number] = sig.pnu
    return values


def expand_words(signals: list[int] | tuple[int, ...], length: int = PZD_MAX_WORDS) -> list[int]:
    """Signal numbers in IO order -> PNU 915/916 word list (double words twice), zero-padded to ``length``.

    Raises TelegramDataError for unknown signals or more words than ``length``.
    """
    words: list[int] = []
    for number in signals:
        sig = SIGNALS.get(number)
        if sig is None:
            raise TelegramDataError(f"signal {number} is not a signal of the AKD")
        words.extend([number] * sig.words)
    if len(words) > length:
        raise TelegramDataError(f"{len(words)} IO words, at most {length} fit")
    return words + [0] * (length - len(words))


def words_to_signals(words: list[int] | tuple[int, ...]) -> list[int]:
    """PNU 915/916 word list -> signal numbers in IO order.

    The list ends at the first 0; a double-word signal must fill two consecutive words.
    Raises TelegramDataError naming the offending element (``index`` attribute).
    """
    signals: list[int] = []
    i = 0
    ended = False
    while i < len(words):
        number = words[i]
        if number == 0:
            ended = True
            i += 1
            continue
        if ended:
            raise TelegramDataError(f"element {i}: signal {number} after the end of the list (a 0 ends it)", i)
        sig = SIGNALS.get(number)
        if sig is None:
            raise TelegramDataError(f"element {i}: {number} is not a signal of the AKD", i)
        if sig.words == 2:
            if i + 1 >= len(words) or words[i + 1] != number:
                raise TelegramDataError(f"element {i}: {sig.name} is a double word and needs two elements", i)
        signals.append(number)
        i += sig.words
    return signals


class WordSlot(Record):
    """One IO data word: its number (1-based), the signal and which part of it (for double words)."""

    __slots__ = ("word", "signal", "part")

    def __init__(self, word: int, signal: Signal, part: str) -> None:
        self.word = word
        self.signal = signal
        self.part = part  # "" for a single word, "high"/"low" for a double word (PROFINET is big-endian: high first)

    @property
    def label(self) -> str:
        return f"{self.signal.name} ({self.part} word)" if self.part else self.signal.name


def word_layout(signals: Sequence[int]) -> list[WordSlot]:
    """Signals in IO order -> word by word slots."""
    slots: list[WordSlot] = []
    for number in signals:
        sig = SIGNALS.get(number)
        if sig is None:
            raise TelegramDataError(f"signal {number} is not a signal of the AKD")
        if sig.words == 1:
            slots.append(WordSlot(len(slots) + 1, sig, ""))
        else:
            slots.append(WordSlot(len(slots) + 1, sig, "high"))
            slots.append(WordSlot(len(slots) + 1, sig, "low"))
    return slots


# Position mode submodes (004 5.10.1/5.10.2, 000 5.9.1/5.9.2, 003 6.10.1/6.10.2): "Standard telegram 7 needs to be
# configured" (program mode) / "Standard telegram 9 needs to be configured" (MDI). Ruling docs/fidelity.md F9: what
# the requirement protects is that the submode's set-point signals travel in the selected telegram, so telegram 0
# carrying them counts too (5.6: every signal can be mapped into telegram 0). Each submode names the telegram
# akdctl selects when the current one lacks its signals.
class Submode(Record):
    __slots__ = ("name", "signals", "telegram")

    def __init__(self, name: str, signals: tuple[int, ...], telegram: int) -> None:
        self.name = name
        self.signals = signals  # set-point signals the submode reads
        self.telegram = telegram  # the standard telegram that carries them


SUBMODES: dict[str, Submode] = {
    "program": Submode("program mode (SATZANW selects a stored motion task)", (1, 32), 7),
    "mdi": Submode("MDI (SATZANW bit 15, MDI_TARPOS .. MDI_MOD)", (1, 32, 34, 35, 36, 37, 38), 9),
}


def missing_for_submode(submode: str, setpoint: list[int] | tuple[int, ...]) -> list[int]:
    """The set-point signals ``submode`` needs that the selected telegram (its PNU 915 signals) lacks."""
    return [n for n in SUBMODES[submode].signals if n not in setpoint]
