"""``akdctl ecat foe write|read``: file access over EtherCAT (FoE), and the run ``firmware update`` shares.

Why apart from cli/ecat.py: a firmware download is its own job with its own rendering (a transfer progress
bar, the before/after document); the rules are in :mod:`akdctl.drive.firmware` and
:mod:`akdctl.drive.ecat_files`, this module only parses, plans, asks, executes and renders.
"""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.ecat_common import read_user_file, write_user_file
from akdctl.cli.output import Doc


class TransferProgress:
    """Bytes and ETA of a file transfer: a rich bar on a terminal (stderr), one plain line a second when piped,
    nothing with ``--json``. Its instance is the FoE client's progress callback."""

    def __init__(self, what: str, total: int | None, quiet: bool) -> None:
        import sys

        self.what, self.total, self.stream = what, total, sys.stderr
        self.quiet = quiet
        self.terminal = not quiet and self.stream.isatty()
        self._bar: Any = None
        self._task: Any = None
        self._last = 0.0

    def __enter__(self) -> "TransferProgress":
        if self.terminal:
            from rich.progress import (
                BarColumn,
                DownloadColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
                TransferSpeedColumn,
            )

            from akdctl.cli.output import console

            self._bar = Progress(TextColumn("{task.description}"), BarColumn(), DownloadColumn(),
                                 TransferSpeedColumn(), TimeRemainingColumn(), console=console(stderr=True),
                                 transient=True)
            self._bar.start()
            self._task = self._bar.add_task(self.what, total=self.total)
        return self

    def __call__(self, done: int, total: int | None) -> None:
        import time

        if self._bar is not None:
            self._bar.update(self._task, completed=done, total=total)
            return
        now = time.monotonic()
        if not self.quiet and now - self._last >= 1.0:
            self._last = now
            of = f" of {total}" if total else ""
            self.stream.write(f"akdctl: {self.what}: {done}{of} bytes\n")
            self.stream.flush()

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()


def firmware_run(operation: str, file: str, name: str | None, password: int, dry_run: bool,
                  restart_timeout: float) -> None:
    """``ecat foe write`` and ``firmware update``: parse, plan, consent, execute, render."""
    from akdctl.cli.consent import consent_plan, render_dry_run
    from akdctl.drive import firmware

    app = get_app()
    data = read_user_file(file, firmware.MAX_FIRMWARE_BYTES)
    request = firmware.FirmwareRequest(file, data, name, password, restart_timeout)
    plan = firmware.plan(app.connection, request, operation)
    if dry_run:
        return render_dry_run(app, plan)
    consent_plan(app, plan)
    with TransferProgress(f"FoE write {request.name}", len(data), quiet=app.json) as progress:
        result = firmware.execute(app.connection, plan, progress)
    doc = Doc(f"{operation}: {request.name}", app.target.display)
    before, after = result["before"], result["after"]
    doc.kv("before", f"{_who(before)} firmware {before['firmware'] or '?'}")
    dl = result["download"]
    doc.kv("download", f"{result['bytes']} bytes" + (f" in {dl['packets']} packets of {dl['packet_bytes']} "
                                                      f"({dl['busy']} busy)" if dl.get("packets") else " (through SOEM)"))
    doc.kv("restart", f"{result['restart_s']:.1f} s")
    doc.kv("after", f"{_who(after)} firmware {after['firmware'] or '?'}")
    doc.kv("file check", result["header_check"])
    doc.line(result["verdict"])
    app.emit(result, doc)


def _who(state: dict[str, Any]) -> str:
    ident = state.get("identity") or {}
    return f"serial {ident.get('serial', '?')}"


@click.group("foe")
def foe_group() -> None:
    """File access over EtherCAT (FoE): firmware download and file read (target ecat:// or ecat+soem://).

    \b
    Examples:
      akdctl -T ecat://eth1 ecat foe write AKD_01-20-00-003.i00
      akdctl -T ecat://eth1 ecat foe read NAME -o copy.bin
    """


@foe_group.command("write")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--name", help="File name on the slave (default: FILE's base name, as IgH's foe_write).")
@click.option("--password", default=0, type=click.IntRange(0, 0xFFFFFFFF), help="FoE password (u32, default 0).")
@click.option("--restart-timeout", default=50.0, type=click.FloatRange(0.5, 600),
              help="Seconds to wait for the drive to answer after the download (ESI back-to-INIT: 50 s).")
@click.option("--dry-run", is_flag=True, help="Check the file and the drive, print the plan, write nothing.")
def foe_write(file: str, name: str | None, password: int, restart_timeout: float, dry_run: bool) -> None:
    """Download FILE in BOOT: INIT, bootstrap mailbox, BOOT, FoE write, INIT; the drive restarts.

    Refused while the drive's power stage is on; needs consent (--yes) because the drive restarts.

    \b
    Examples:
      akdctl -T ecat://eth1 -y ecat foe write firmware.i00
      akdctl -T ecat://eth1 ecat foe write firmware.i00 --dry-run
    """
    firmware_run("ecat foe write", file, name, password, dry_run, restart_timeout)


@foe_group.command("read")
@click.argument("name")
@click.option("-o", "--output", "output", required=True, type=click.Path(dir_okay=False),
              help="Where to store the file.")
@click.option("--password", default=0, type=click.IntRange(0, 0xFFFFFFFF), help="FoE password (u32, default 0).")
@click.option("--max-size", default=16 * 1024 * 1024, type=click.IntRange(1, 256 * 1024 * 1024),
              help="Refuse a file larger than this many bytes (default 16 MiB).")
def foe_read(name: str, output: str, password: int, max_size: int) -> None:
    """Read file NAME from the slave (in its current mailbox state, PRE-OP or higher) into OUTPUT.

    \b
    Examples:
      akdctl -T ecat://eth1 ecat foe read config.txt -o config.txt
    """
    from akdctl.drive.ecat_files import read_file

    app = get_app()
    with TransferProgress(f"FoE read {name}", None, quiet=app.json) as progress:
        data = read_file(app.connection, name, password, max_size, progress)
    write_user_file(output, data)
    app.emit({"target": app.target.display, "name": name, "bytes": len(data), "output": output},
             Doc(f"FoE read {name}", app.target.display).kv("bytes", len(data)).kv("written to", output))
