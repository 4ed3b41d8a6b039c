"""``akdctl sim speed``: how fast the simulated drive's virtual time runs, and its watchdog.

Why a knob: a human at a shell wants the simulated axis to take as long as a
real one (real time, the default); tests and demos of long moves want it
faster (tests run at 1000× and more). The watchdog is in wall-clock seconds
whatever the speed, so a dead tool stops a fast simulated axis as quickly as a
slow one.
"""

from __future__ import annotations

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc
from akdctl.errors import UsageError


@click.command()
@click.argument("factor", type=float, required=False)
@click.option("--realtime", is_flag=True, help="Run virtual time at wall-clock speed (factor 1).")
@click.option("--watchdog", type=click.FloatRange(min=0), metavar="SECONDS",
              help="Wall seconds without a request before the drive stops a moving axis (0 = off; default 1).")
@click.option("--name", help="Simulated drive name (default: the target's).")
def speed(factor: float | None, realtime: bool, watchdog: float | None, name: str | None) -> None:
    """Set how fast virtual time runs (FACTOR × wall time; 1 = real time); without arguments, show it.

    \b
    Examples:
      akdctl sim speed
      akdctl sim speed 10
      akdctl sim speed --realtime
    """
    from akdctl.cli.sim import _sim_drive
    from akdctl.sim.drive import MAX_TIME_SCALE

    if realtime and factor is not None:
        raise UsageError("give either FACTOR or --realtime, not both")
    if realtime:
        factor = 1.0
    if factor is not None and not 0 < factor <= MAX_TIME_SCALE:
        raise UsageError(f"FACTOR must be greater than 0 and at most {MAX_TIME_SCALE:.0f}")
    drive = _sim_drive(name)
    with drive.transaction() as model:
        if factor is not None:
            drive.meta["time_scale"] = float(factor)
        if watchdog is not None:
            model.motion.watchdog_s = float(watchdog)
        scale = float(drive.meta.get("time_scale", 1.0))
        wd = model.motion.watchdog_s
    data = {"drive": drive.name, "time_scale": scale, "watchdog_s": wd}
    get_app().emit(data, lambda: Doc(f"simulated drive {drive.name!r}", f"sim://{drive.name}")
                   .kv("time scale", f"{scale:g}× wall time" + (" (real time)" if scale == 1 else ""))
                   .kv("watchdog", "off" if not wd else f"{wd:g} s of wall time"))
