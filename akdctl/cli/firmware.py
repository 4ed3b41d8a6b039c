"""``akdctl firmware update FILE``: the task-level firmware download over EtherCAT (FoE in BOOT).

Why a command of its own beside ``ecat foe write``: a technician asks "update the firmware", not "write a FoE
file"; this one says who the drive is and which firmware it runs before and after, checks the file as far as the
format allows, and ends with a one-line verdict (``--json``: the whole document). Both share one plan and one
execution (:mod:`akdctl.drive.firmware`).
"""

from __future__ import annotations

import click


@click.group()
def firmware() -> None:
    """Drive firmware: update over EtherCAT (target ecat://IFNAME[/POS] or ecat+soem://IFNAME[/POS]).

    \b
    Examples:
      akdctl -T ecat://eth1 firmware update AKD_01-20-00-003.i00 --dry-run
      akdctl -T ecat://eth1 -y firmware update AKD_01-20-00-003.i00
    """


@firmware.command("update")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--name", help="File name on the drive (default: FILE's base name).")
@click.option("--password", default=0, type=click.IntRange(0, 0xFFFFFFFF), help="FoE password (u32, default 0).")
@click.option("--restart-timeout", default=50.0, type=click.FloatRange(0.5, 600),
              help="Seconds to wait for the drive to answer after the download (ESI back-to-INIT: 50 s).")
@click.option("--dry-run", is_flag=True, help="Check the file and the drive, print what would happen, write nothing.")
def update(file: str, name: str | None, password: int, restart_timeout: float, dry_run: bool) -> None:
    """Identity and firmware, file check, download in BOOT, restart, identity and firmware again, verdict.

    Refused while the power stage is on; needs consent (--yes): the drive restarts.

    \b
    Examples:
      akdctl -T ecat://eth1 firmware update fw.i00 --dry-run
      akdctl -T ecat://eth1 -y --json firmware update fw.i00
    """
    from akdctl.cli.ecat_foe import firmware_run

    firmware_run("firmware update", file, name, password, dry_run, restart_timeout)
