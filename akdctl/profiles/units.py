"""PROFIdrive normalisation of the AKD (SPEC-NOTES 13), in one place.

Velocity signals are X2/X4 fractions of the AKD's 12000 rpm, accelerations
fractions of 50,000,000 rpm/s, currents fractions of DRV.IPEAK, positions
counts of 2^singleturn-bits per revolution. Also here: the EtherCAT cycle time
grid (0x60C2 in multiples of 62.5 µs, at least 250 µs), which the simulated drive
enforces and ``pdo plan`` checks before anything is written.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from fractions import Fraction

MAX_RPM = 12000.0
MAX_ACC_RPM_S = 50_000_000.0


def x_to_rpm(value: int, x: int) -> float:
    """A velocity normalised with 2^x = 12000 rpm, in rpm (x=15: NSOLL_A/NIST_A; x=32: MDI_VELOCITY)."""
    return value * MAX_RPM / (1 << x)


def rpm_to_x(rpm: float, x: int) -> int:
    """rpm → normalised integer, truncated toward zero as the manual's own example does:
    "(60 / 12000) * 2^15 = 163" (004 5.12.1) — 163.84 becomes 163, so the example truncates (rounding
    would give 164); -60 rpm → -163 (docs/fidelity.md F6). Float noise below 1e-6 of a step is not a step:
    a velocity computed as 59.6923828125 rpm minus 1e-14 still reads 163."""
    return int(round(rpm * (1 << x) / MAX_RPM, 6))


def acc_to_rpm_s(value: int, x: int = 16) -> float:
    return value * MAX_ACC_RPM_S / (1 << x)


def rpm_s_to_acc(rpm_s: float, x: int = 16) -> int:
    return round(rpm_s * (1 << x) / MAX_ACC_RPM_S)


def current_to_amps(value: int, ipeak: float) -> float:
    """N2 current (2^14 = DRV.IPEAK) in A: with a 9 A peak, -182 → -0.1 A (the seed's example)."""
    return value * ipeak / (1 << 14)


def counts_to_rev(counts: int, singleturn_bits: int = 16) -> float:
    return counts / (1 << singleturn_bits)


def rev_to_counts(rev: float, singleturn_bits: int = 16) -> int:
    return round(rev * (1 << singleturn_bits))


def describe_scaled(unit: str, value: int, singleturn_bits: int = 16) -> str:
    """The value in physical units for a catalogue ``unit`` tag (``N2:12000rpm`` …), or ''.

    Positions (``counts``) count 2^``singleturn_bits`` per revolution: PNU 1002 (004 5.12.2 "The number
    of singleturn bits (default 16) can be changed through PNU 1002"), so 1.5 rev with 4 bits is 24 counts."""
    if unit == "N2:12000rpm":
        return f"{x_to_rpm(value, 15):.4g} rpm"
    if unit == "X4:12000rpm":
        return f"{x_to_rpm(value, 32):.4g} rpm"
    if unit == "X2:50000000rpm/s":
        return f"{acc_to_rpm_s(value):.6g} rpm/s"
    if unit == "counts":
        return f"{counts_to_rev(value, singleturn_bits):.6g} rev"
    if unit == "N2:DRV.IPEAK":
        return f"{value * 100 / (1 << 14):.3g} % of DRV.IPEAK"
    return ""


#: CiA 402 position/velocity/acceleration units of the AKD as akdctl uses it: counts of 2^16 per revolution
#: (FBUS.PARAM05 bit 4 scaling, one count per encoder increment), counts/s, counts/s². The client's CiA 402 axis
#: and the simulated drive use this one value.
CIA_COUNTS_PER_REV = 65536


def cia_rpm(counts_per_s: float) -> float:
    """CiA 402 counts/s → rpm (and counts/s² → rpm/s): 0x6081/0x6083/0x6084, MT.V/MT.ACC/MT.DEC."""
    return counts_per_s * 60.0 / CIA_COUNTS_PER_REV


def cia_per_s(rpm: float) -> int:
    """rpm → counts/s (rpm/s → counts/s²), truncated toward zero like every set point (F6: never rounded up)."""
    return int(round(rpm * CIA_COUNTS_PER_REV / 60.0, 6))


#: EtherCAT cycle time (EtherCAT manual 5.9/5.10, SPEC-NOTES 20): FBUS.SAMPLEPERIOD counts 62.5 µs ticks, and the
#: drive's minimum cycle time is 250 µs in every interface (position, velocity, torque). :func:`cycle_tick_s`
#: (1/16000 s) and :func:`min_cycle_s` (1/4000 s) are exact fractions, made on first use: ``fractions`` (with
#: ``decimal``) costs every start that imports this module more than the few commands that check a cycle time spend.
#: (Functions, not a module ``__getattr__``: a name that exists only when asked hides from readers and checkers.)
_CYCLE_TICK = (1, 16000)
_MIN_CYCLE = (1, 4000)
CYCLE_TOO_SHORT = "too-short"
CYCLE_OFF_GRID = "off-grid"


def cycle_tick_s() -> Fraction:
    """One FBUS.SAMPLEPERIOD tick, 62.5 µs, exactly."""
    from fractions import Fraction

    return Fraction(*_CYCLE_TICK)


def min_cycle_s() -> Fraction:
    """The AKD's shortest EtherCAT cycle time, 250 µs, exactly."""
    from fractions import Fraction

    return Fraction(*_MIN_CYCLE)


def cycle_time_s(units: int, exponent: int) -> Fraction:
    """0x60C2: sub 1 units × 10^(sub 2) seconds, exactly."""
    from fractions import Fraction

    return Fraction(units) * Fraction(10) ** exponent


def cycle_time_problem(units: int, exponent: int) -> str | None:
    """Why ``units`` × 10^``exponent`` s is not an AKD cycle time (:data:`CYCLE_TOO_SHORT`,
    :data:`CYCLE_OFF_GRID`), or None; the words are ``catalog.texts.cycle_time_text``."""
    period = cycle_time_s(units, exponent)
    if period < min_cycle_s():
        return CYCLE_TOO_SHORT
    if (period / cycle_tick_s()).denominator != 1:
        return CYCLE_OFF_GRID
    return None


def cycle_time_write_order(current: tuple[int, int], target: tuple[int, int]) -> tuple[int, int]:
    """The order (sub-indices) to write 0x60C2 from ``current`` to ``target`` (units, exponent) so the drive, which
    checks every write against the other sub-index's value, never sees an invalid pair in between: the manual's
    order (1 then 2) unless the new units with the old exponent are refused (docs/fidelity.md F5)."""
    if cycle_time_problem(target[0], current[1]) is not None and cycle_time_problem(current[0], target[1]) is None:
        return (2, 1)
    return (1, 2)
