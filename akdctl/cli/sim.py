"""``akdctl sim``: the simulated AKD — reset, show, inject faults, serve it on the network."""

from __future__ import annotations

import signal
import sys
import threading
import time
from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.main import LazyGroup
from akdctl.cli.output import Doc
from akdctl.errors import UsageError
from akdctl.sim import face_akd, face_can, face_ethercat_raw, face_ethercat_udp, face_ethernetip, face_modbus, face_profinet
from akdctl.sim.face import FaceOption

# Network faces of `sim serve`, one module each (see docs/internals.md): each declares ``OPTIONS`` (data) and
# ``from_options(drive, **kwargs) -> Face | None``. Listed by import, so a face missing from a package fails loudly.
FACES = (face_profinet, face_ethercat_udp, face_ethercat_raw, face_can, face_ethernetip, face_akd, face_modbus)

SIM_COMMANDS = {
    "fault": ("akdctl.cli.sim_fault", "fault", "Inject a fault (e.g. F501) into the simulated drive."),
    "clear": ("akdctl.cli.sim_fault", "clear", "Remove the cause of injected faults (they still need acknowledging)."),
    "speed": ("akdctl.cli.sim_time", "speed", "Set how fast virtual time runs (1 = real time)."),
    "set": ("akdctl.cli.sim_set", "set_", "Set conditions: hardware enable, disable sources, limit switches, AL state, mode."),
}


def _sim_drive(name: str | None) -> Any:
    from akdctl.sim.drive import SimDrive

    if name is None:
        app = get_app()
        target = app.target
        if target.scheme != "sim":
            raise UsageError(f"'akdctl sim' works on simulated drives; the target is {target.display}")
        name = target.host or "default"
    return SimDrive(name)


@click.group(cls=LazyGroup, lazy=SIM_COMMANDS)
def sim() -> None:
    """The simulated AKD (the default target): its state persists between invocations.

    \b
    Examples:
      akdctl sim show
      akdctl sim fault F501
      akdctl sim serve --profinet 127.0.0.1:34964
    """


@sim.command("reset")
@click.option("--name", help="Simulated drive name (default: the target's, i.e. 'default').")
def reset(name: str | None) -> None:
    """Restore factory state (also recovers from a corrupt state file).

    \b
    Examples:
      akdctl sim reset
      akdctl sim reset --name bench2
    """
    drive = _sim_drive(name)
    drive.reset()
    get_app().emit({"drive": drive.name, "reset": True}, f"simulated drive {drive.name!r} reset to factory state")


@sim.command("show")
@click.option("--name", help="Simulated drive name (default: the target's).")
def show(name: str | None) -> None:
    """Print the simulated drive's state: clock, changed PNUs and objects, components.

    \b
    Examples:
      akdctl sim show
      akdctl -T sim://bench2 sim show --json
    """
    from akdctl.catalog.pnus import lookup

    drive = _sim_drive(name)
    state = drive.snapshot()

    def human() -> Doc:
        meta = state.get("sim", {})
        doc = Doc(f"simulated drive {drive.name!r}", f"sim://{drive.name}")
        doc.kv("state file", str(drive.path)).kv("virtual time", f"{state['clock']:.3f} s")
        doc.kv("time scale", meta.get("time_scale")).kv("accepted writes", state.get("writes", 0))
        for comp, comp_state in state.get("components", {}).items():
            for key, value in comp_state.items():
                if isinstance(value, (int, float, str, bool)) or value is None:
                    doc.kv(f"{comp}.{key}", value)
        pnu_rows = []
        for key, values in state.get("pnus", {}).items():
            info = lookup(int(key))
            if info is not None and values != info.default_values():
                pnu_rows.append([key, info.name, ",".join(str(v) for v in values)])
        if pnu_rows:
            doc.table(["PNU", "name", "value"], pnu_rows, title="PNUs changed from factory values")
        obj_rows = [[key, value] for key, value in state.get("objects", {}).items()]
        if obj_rows:
            doc.table(["object", "bytes (hex, LE)"], obj_rows, title="objects written")
        return doc

    get_app().emit(state, human)


def _serve_callback(**kwargs: Any) -> None:
    from akdctl.cli.output import message

    duration = kwargs.pop("duration")
    drive = _sim_drive(kwargs.pop("name"))  # the target's drive unless --name says otherwise (issue 23.9)
    drive.serve_faces()  # busy answered before the client's timeout (issue 23.15); the lock kept between requests
    name = drive.name
    faces = []
    orphans: list[str] = []
    for module in FACES:
        face = module.from_options(drive, **kwargs)
        if face is not None:
            faces.append(face)
        else:
            orphans.extend(_orphan_options(module.OPTIONS, kwargs))
    if orphans:
        raise UsageError(f"{'; '.join(orphans)}: a face is served only with its own option")
    if not faces:
        flags = ", ".join(module.OPTIONS[0].flag for module in FACES)
        raise UsageError(f"choose at least one face to serve: {flags}")
    stop = threading.Event()

    def _stop(signum: int, frame: Any) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, _stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    started = []
    try:
        for face in faces:
            face.start()
            started.append(face)
            sys.stdout.write(f"listening: {face.describe()}\n")
            for warning in face.warnings():
                message(f"akdctl: warning: {warning}")
        sys.stdout.flush()
        message(f"serving simulated drive {name!r}; Ctrl-C to stop")
        # Wait in slices: Python runs signal handlers only in the main thread, between bytecodes, and an
        # untimed wait would not wake when the kernel hands SIGTERM to one of the faces' threads.
        end = None if duration is None else time.monotonic() + duration
        while not stop.wait(0.25 if end is None else max(0.0, min(0.25, end - time.monotonic()))):
            if end is not None and time.monotonic() >= end:
                break
    finally:
        for face in reversed(started):
            try:
                face.stop()
            except Exception as exc:  # keep stopping the others
                message(f"akdctl: warning: stopping {face.describe()} failed: {exc}")
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _orphan_options(options: Any, values: dict[str, Any]) -> list[str]:
    """A face's options given without the face itself (``--dcp eth0`` without ``--profinet``), in words.

    Why: such an option used to be ignored without a word, and the user believed DCP was answered. The first
    option of every face is the one that turns it on; any other one set away from its default needs it.
    """
    switch, *rest = options
    given = [option.flag for option in rest if values.get(option.dest) not in (None, option.default)]
    return [f"{', '.join(given)} {'needs' if len(given) == 1 else 'need'} {switch.flag}"] if given else []


def click_option(option: FaceOption) -> click.Option:
    """The click option for one face option (the one place that turns face data into ``sim serve`` options)."""
    kind: Any = option.type
    if option.range is not None:
        kind = click.IntRange(*option.range)
    extra: dict[str, Any] = {}
    if option.flag_value is not None:
        extra.update(is_flag=False, flag_value=option.flag_value)
    elif option.is_flag:
        extra.update(is_flag=True)
    if kind is not None:
        extra["type"] = kind
    return click.Option([option.flag, option.dest], default=option.default, metavar=option.metavar,
                        help=option.help, show_default=option.show_default, **extra)


def _build_serve() -> click.Command:
    params: list[click.Parameter] = [
        click.Option(["--name"], default=None, help="Simulated drive to serve (default: the target's, i.e. 'default')."),
        click.Option(["--duration"], type=click.FloatRange(min=0), default=None,
                     help="Stop after this many seconds (default: until Ctrl-C/SIGTERM)."),
    ]
    for module in FACES:
        params.extend(click_option(option) for option in module.OPTIONS)
    return click.Command(
        "serve",
        callback=_serve_callback,
        params=params,
        help="Serve the simulated drive on the network (PROFINET, EtherCAT, CANopen, EtherNet/IP faces).\n\n"
        "Each face prints one 'listening: ...' line on stdout when ready.\n\n"
        "\b\nExamples:\n  akdctl sim serve --profinet 127.0.0.1:34964\n"
        "  akdctl sim serve --ethercat-udp 127.0.0.1:0 --ecat-stations 1001=default --duration 60",
        short_help="Serve the simulated drive on the network.",
    )


sim.add_command(_build_serve())
