"""PROFIdrive normalisation of the AKD (SPEC-NOTES 13), in one place.

Velocity signals are X2/X4 fractions of the AKD's 12000 rpm, accelerations
fractions of 50,000,000 rpm/s, currents fractions of DRV.IPEAK, positions
counts of 2^singleturn-bits per revolution.
"""

from __future__ import annotations

MAX_RPM = 12000.0
MAX_ACC_RPM_S = 50_000_000.0


def x_to_rpm(value: int, x: int) -> float:
    """A velocity normalised with 2^x = 12000 rpm, in rpm (x=15: NSOLL_A/NIST_A; x=32: MDI_VELOCITY)."""
    return value * MAX_RPM / (1 << x)


def rpm_to_x(rpm: float, x: int) -> int:
    """rpm → normalised integer (rounded), e.g. 60 rpm with x=15 → 164 (the seed truncates to 163)."""
    return round(rpm * (1 << x) / MAX_RPM)


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


def describe_scaled(unit: str, value: int) -> str:
    """The value in physical units for a catalogue ``unit`` tag (``N2:12000rpm`` …), or ''."""
    if unit == "N2:12000rpm":
        return f"{x_to_rpm(value, 15):.4g} rpm"
    if unit == "X4:12000rpm":
        return f"{x_to_rpm(value, 32):.4g} rpm"
    if unit == "X2:50000000rpm/s":
        return f"{acc_to_rpm_s(value):.6g} rpm/s"
    if unit == "counts":
        return f"{counts_to_rev(value):.6g} rev"
    if unit == "N2:DRV.IPEAK":
        return f"{value * 100 / (1 << 14):.3g} % of DRV.IPEAK"
    return ""
