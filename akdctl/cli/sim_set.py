"""``akdctl sim set``: raise the conditions a real AKD shows outside its fault list, on demand.

Why: ``akdctl diagnose`` names every cause that keeps a drive from enabling; each needs a way to be raised so
every branch has a test, and a technician rehearsing with the simulator needs the same. Faults and STO (F602 /
n602) come from ``sim fault``; this sets the rest: DRV.DISSOURCES bits (hardware enable low, in-rush, ...), the
limit switch inputs (0x60FD), the EtherCAT AL state, the operation mode. The simulated drive honours them (an
injected disable source keeps it from enabling).
"""

from __future__ import annotations

import struct

import click

from akdctl.cli.context import get_app
from akdctl.errors import UsageError

#: name -> (help, allowed values or None for a number)
SETTINGS: dict[str, str] = {
    "hw-enable": "low | high: the hardware enable input (DRV.DISSOURCES bit 2)",
    "dissources": "N: the DRV.DISSOURCES bits 2..10 to raise (0 clears; bits 0 and 1 follow the drive's state)",
    "limit": "none | negative | positive | both: the limit switch inputs (0x60FD bits 0 and 1)",
    "al-state": "INIT | PREOP | SAFEOP | OP: the EtherCAT AL state",
    "mode": "N: the CiA 402 operation mode (0x6060), e.g. 1 profile position, 3 profile velocity, 8 CSP",
    "cycle-time": "UNITS,EXPONENT: 0x60C2 as a master left it, off the drive's grid too (e.g. 3,-4 = 300 µs)",
}
LIMITS = {"none": 0, "negative": 1, "positive": 2, "both": 3}


def _apply(model: object, key: str, value: str) -> str:
    m: object = model
    if key == "hw-enable":
        if value not in ("low", "high"):
            raise UsageError(f"hw-enable={value!r}: use low or high")
        current = int.from_bytes(m.stored_object(0x3443, 0), "little")  # type: ignore[attr-defined]
        bits = current | 4 if value == "low" else current & ~4
        m.set_stored_object(0x3443, 0, struct.pack("<H", bits & 0xFFFC))  # type: ignore[attr-defined]
        return f"hardware enable {value}"
    if key == "dissources":
        try:
            bits = int(value, 0)
        except ValueError:
            raise UsageError(f"dissources={value!r} is not a number") from None
        if not 0 <= bits <= 0x7FF:
            raise UsageError(f"dissources={value}: bits 0..10 only (0..0x7FF)")
        m.set_stored_object(0x3443, 0, struct.pack("<H", bits & 0x7FC))  # type: ignore[attr-defined]
        return f"DRV.DISSOURCES injected bits 0x{bits & 0x7FC:04X}"
    if key == "limit":
        if value not in LIMITS:
            raise UsageError(f"limit={value!r}: use {', '.join(LIMITS)}")
        m.set_stored_object(0x60FD, 0, struct.pack("<I", LIMITS[value]))  # type: ignore[attr-defined]
        return f"limit switches: {value}"
    if key == "al-state":
        from akdctl.sim.pdo import normalise_al_state

        try:
            state = normalise_al_state(value)
        except (ValueError, KeyError):
            raise UsageError(f"al-state={value!r}: use INIT, PREOP, SAFEOP or OP") from None
        m.pdo.set_al_state(state)  # type: ignore[attr-defined]
        return f"AL state {state}"
    if key == "mode":
        try:
            mode = int(value, 0)
        except ValueError:
            raise UsageError(f"mode={value!r} is not a number") from None
        if not -128 <= mode <= 127:
            raise UsageError(f"mode={mode}: an operation mode is -128..127")
        m.object_write(0x6060, 0, struct.pack("<b", mode))  # type: ignore[attr-defined]
        return f"operation mode {mode}"
    if key == "cycle-time":
        units, comma, exponent = value.partition(",")
        try:
            pair = (int(units, 0), int(exponent, 0))
        except ValueError:
            raise UsageError(f"cycle-time={value!r}: expected UNITS,EXPONENT, e.g. 1,-3") from None
        if not comma or not 0 <= pair[0] <= 255 or not -128 <= pair[1] <= 127:
            raise UsageError(f"cycle-time={value!r}: UNITS 0..255, EXPONENT -128..127")
        # stored directly: the drive's own write rule (the 62.5 µs grid) is what diagnose must catch afterwards
        m.set_stored_object(0x60C2, 1, struct.pack("<B", pair[0]))  # type: ignore[attr-defined]
        m.set_stored_object(0x60C2, 2, struct.pack("<b", pair[1]))  # type: ignore[attr-defined]
        return f"cycle time {pair[0]}e{pair[1]} s"
    raise UsageError(f"unknown setting {key!r}; known: {', '.join(SETTINGS)}")


@click.command("set")
@click.argument("settings", nargs=-1, required=True, metavar="NAME=VALUE...")
@click.option("--name", help="Simulated drive name (default: the target's).")
def set_(settings: tuple[str, ...], name: str | None) -> None:
    """Set conditions of the simulated drive: hw-enable, dissources, limit, al-state, mode, cycle-time.

    \b
    hw-enable=low|high      the hardware enable input (DRV.DISSOURCES bit 2)
    dissources=N            DRV.DISSOURCES bits 2..10 (0 clears)
    limit=none|negative|positive|both   limit switch inputs (0x60FD)
    al-state=PREOP|SAFEOP|OP  the EtherCAT AL state
    mode=N                  the CiA 402 operation mode (0x6060)
    cycle-time=U,E          0x60C2 (units, exponent), stored as given

    \b
    Examples:
      akdctl sim set hw-enable=low
      akdctl sim set limit=positive al-state=SAFEOP
      akdctl sim set dissources=0 limit=none
    """
    from akdctl.cli.sim import _sim_drive

    pairs = []
    for item in settings:
        key, eq, value = item.partition("=")
        if not eq or not value:
            raise UsageError(f"{item!r}: expected NAME=VALUE, e.g. hw-enable=low")
        if key not in SETTINGS:
            raise UsageError(f"unknown setting {key!r}; known: {', '.join(SETTINGS)}")
        pairs.append((key, value.strip()))
    drive = _sim_drive(name)
    done = []
    with drive.transaction() as model:
        for key, value in pairs:
            done.append(_apply(model, key, value))
    get_app().emit({"drive": drive.name, "set": dict(pairs)}, f"simulated drive {drive.name!r}: " + "; ".join(done))
