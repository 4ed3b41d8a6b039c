"""``akdctl sim fault`` / ``akdctl sim clear``: inject and remove fault causes in the simulated AKD.

Why a command and not a test hook only: a technician rehearsing a fault
dump, or a PLC programmer testing their fault handling against ``sim serve``,
needs faults on demand. ``--after-reads N`` raises the fault *between* two
reads of the fault buffer, the case PNU 944 exists for.
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.errors import UsageError


def _component(model: Any) -> Any:
    return model.faults


@click.command("fault")
@click.argument("codes", nargs=-1, required=True, metavar="CODE...")
@click.option("--after-reads", type=click.IntRange(min=1), default=None, metavar="N",
              help="Raise only after the drive answered N more reads of its fault PNUs/objects (tests a dump's consistency loop).")
@click.option("--persist", is_flag=True, help="Keep the cause: the fault returns after each acknowledge until 'sim clear'.")
@click.option("--name", help="Simulated drive name (default: the target's).")
def fault(codes: tuple[str, ...], after_reads: int | None, persist: bool, name: str | None) -> None:
    """Inject faults or warnings, e.g. F501 F502 or n503 (several join one fault situation).

    \b
    Examples:
      akdctl sim fault F501
      akdctl sim fault n503 --persist
    """
    from akdctl.catalog.faults import by_code
    from akdctl.cli.sim import _sim_drive

    unknown = [c for c in codes if (f := by_code(c)) is None or not f.code]
    if unknown:
        raise UsageError(f"unknown AKD fault/warning {', '.join(unknown)} (see 'akdctl fault list')")
    normalised = [by_code(c).code for c in codes]  # type: ignore[union-attr]
    drive = _sim_drive(name)
    with drive.transaction() as model:
        comp = _component(model)
        _refuse_overflow(comp, normalised, armed=after_reads is not None)
        for code in normalised:
            if after_reads is None:
                comp.raise_fault(code, persist=persist)
            else:
                comp.arm(code, after_reads, persist=persist)
        active = comp.active()
        counter = comp.counter
    data = {"drive": drive.name, "injected": normalised, "after_reads": after_reads, "persist": persist,
            "active": active, "fault_message_counter": counter}
    when = f" after {after_reads} fault read(s)" if after_reads else ""
    get_app().emit(data, f"simulated drive {drive.name!r}: {' '.join(normalised)} armed{when}" if after_reads
                   else f"simulated drive {drive.name!r}: active now {' '.join(active) or 'none'} "
                        f"(fault message counter {counter})")


def _refuse_overflow(comp: Any, codes: list[str], *, armed: bool) -> None:
    """Refuse an injection whose faults do not all fit one fault situation.

    Why: PNU 947 keeps at most 8 fault numbers per situation (PROFINET manual
    5.14); the model drops a ninth, so the command says so before it changes
    anything instead of reporting success for a fault that never appears.
    Warnings do not enter PNU 947 and do not count.
    """
    from akdctl.catalog.faults import by_code
    from akdctl.sim.faults import FAULTS_PER_SITUATION

    fault_numbers = {by_code(c).number for c in codes if not by_code(c).is_warning}  # type: ignore[union-attr]
    present = set() if armed else set(comp.situations[0])
    if len(fault_numbers | present) > FAULTS_PER_SITUATION:
        raise UsageError(
            f"{len(fault_numbers | present)} faults do not fit one fault situation (PNU 947 holds "
            f"{FAULTS_PER_SITUATION}; {len(present)} active now); inject at most "
            f"{max(FAULTS_PER_SITUATION - len(present), 0)} more, or acknowledge first ('akdctl fault ack')"
        )


@click.command("clear")
@click.option("--name", help="Simulated drive name (default: the target's).")
def clear(name: str | None) -> None:
    """Remove the causes of injected faults and warnings (faults still need acknowledging).

    \b
    Examples:
      akdctl sim clear
    """
    from akdctl.cli.sim import _sim_drive

    drive = _sim_drive(name)
    with drive.transaction() as model:
        comp = _component(model)
        removed = comp.clear_causes()
        active = comp.active()
    get_app().emit(
        {"drive": drive.name, "removed_causes": removed, "active": active},
        f"simulated drive {drive.name!r}: causes removed ({' '.join(removed) or 'none'}); "
        f"active {' '.join(active) or 'none'}" + ("; acknowledge with 'akdctl fault ack'" if active else ""),
    )
