"""The ``akdctl`` root command: global options, the lazy command table, the one error handler.

Subcommands live in their own modules and are imported only when invoked, so
``akdctl --help`` imports neither transports nor rich nor canopen. The short
help shown in the command list is kept here for the same reason.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from typing import Any

import click

from akdctl import __version__
from akdctl.cli.context import AppContext
from akdctl.cli.parsing import Duration
from akdctl.errors import EXIT_USAGE, AkdError, InternalError, Interrupted, UsageError

# name -> (module, attribute, short help). Order is the order of `akdctl --help`.
COMMANDS: dict[str, tuple[str, str, str]] = {
    "status": ("akdctl.cli.motion", "status", "Show drive state, mode, status-word bits, position, velocity, faults."),
    "enable": ("akdctl.cli.motion", "enable", "Bring the drive to operation enabled."),
    "disable": ("akdctl.cli.motion", "disable", "Disable the power stage (ramp to standstill first)."),
    "stop": ("akdctl.cli.motion", "stop", "Stop the axis (ramp; --quick for quick stop)."),
    "jog": ("akdctl.cli.motion", "jog", "Jog at a velocity for a bounded time or distance."),
    "home": ("akdctl.cli.motion", "home", "Run the homing procedure."),
    "move": ("akdctl.cli.motion", "move", "Move to a position (absolute or relative) and wait for target reached."),
    "task": ("akdctl.cli.task", "task", "List, show, set and start the drive's stored motion tasks."),
    "pnu": ("akdctl.cli.pnu", "pnu", "Read, write, describe and list PROFIdrive parameters (PNUs)."),
    "sdo": ("akdctl.cli.sdo", "sdo", "Read and write CANopen/CoE objects by SDO."),
    "pdo": ("akdctl.cli.pdo", "pdo", "Show, plan and apply process-data (PDO) mapping."),
    "telegram": ("akdctl.cli.telegram", "telegram", "Show and select the PROFIdrive telegram."),
    "fault": ("akdctl.cli.fault", "fault", "Fault buffer dump, acknowledge, history and explanations."),
    "support": ("akdctl.cli.support", "support", "Write or show a support bundle."),
    "param": ("akdctl.cli.param", "param", "AKD parameters by name (DRV.OPMODE, VL.KP): get, set, list, save, dump, restore, diff."),
    "params": ("akdctl.cli.param", "param", "Alias of 'param' (backup, restore and diff of drive parameters)."),
    "cmd": ("akdctl.cli.cmd", "cmd", "Send one line to the AKD's command channel (akd://): safe reads run, the rest is gated."),
    "scope": ("akdctl.cli.scope", "scope", "Record signals (poll, the drive's recorder, PDO) and plot them."),
    "commission": ("akdctl.cli.commission", "commission", "Run a commissioning recipe (TOML)."),
    "info": ("akdctl.cli.info", "info", "Identify the drive (vendor, type, firmware, profile)."),
    "discover": ("akdctl.cli.discover", "discover", "Find drives on every transport given and write an inventory of the line."),
    "targets": ("akdctl.cli.targets", "targets", "List the transports and whether their dependencies are present."),
    "pn": ("akdctl.cli.pn", "pn", "PROFINET: discover (DCP), name, address and blink devices."),
    "ecat": ("akdctl.cli.ecat", "ecat", "EtherCAT: scan slaves, change AL state, read the SII."),
    "can": ("akdctl.cli.can", "can", "CANopen: scan nodes, send NMT commands."),
    "cip": ("akdctl.cli.cip", "cip", "Read and write CIP attributes (EtherNet/IP explicit messaging)."),
    "eip": ("akdctl.cli.eip", "eip", "EtherNet/IP: ListIdentity scan, AKD parameters by the Parameter object."),
    "sim": ("akdctl.cli.sim", "sim", "The simulated AKD: reset, show, inject faults, serve on the network."),
    "firmware": ("akdctl.cli.firmware", "firmware", "Update the drive's firmware over EtherCAT (FoE in BOOT)."),
}


def _module_present(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None


class LazyGroup(click.Group):
    """A group whose subcommands are imported on first use."""

    def __init__(self, *args: Any, lazy: dict[str, tuple[str, str, str]] | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.lazy = dict(lazy or {})

    def list_commands(self, ctx: click.Context) -> list[str]:
        present = [name for name, (module, _, _) in self.lazy.items() if _module_present(module)]
        return present + sorted(set(self.commands) - set(present))

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        """The subcommand, imported on first use and adopted into the tree's parsing rules (cli/parsing.py)."""
        from akdctl.cli.parsing import adopt

        command = self.commands.get(name)
        if command is None:
            entry = self.lazy.get(name)
            if entry is None or not _module_present(entry[0]):
                return None
            command = getattr(importlib.import_module(entry[0]), entry[1])
            self.commands[name] = command
        return adopt(command, cli)  # the root of the tree, whichever context asked

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The listing from the table's short help (nothing imported), else the one rule of cli/parsing.py."""
        from akdctl.cli.parsing import short_help

        rows = []
        for name in self.list_commands(ctx):
            if name in self.lazy:
                rows.append((name, self.lazy[name][2]))
            else:
                rows.append((name, short_help(self.commands[name])))
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)


def _line_only(ctx: click.Context, param: click.Parameter, value: Any) -> None:
    """The line options reach click only without --inventory (main() hands a line run to cli/line.py first)."""
    if value:
        raise click.UsageError(f"{param.opts[0]} works only with --inventory FILE (before any '--')", ctx)


EPILOG = (
    "Global options may also follow the command (akdctl pnu get 930 --json). "
    "Targets: sim (default), sim://NAME, pn://HOST, ecat-udp://HOST/STATION, ecat://IFNAME[/POS], "
    "can://INTERFACE/CHANNEL/NODE, eip://HOST, akd://HOST, mb://HOST. Exit codes: 0 ok, 1 drive refused, 2 usage, 3 communication, "
    "4 safety refusal, 5 check failed, 130 interrupted."
)


@click.group(cls=LazyGroup, lazy=COMMANDS, epilog=EPILOG, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("-T", "--target", "target", metavar="TARGET", help="Drive to talk to (default: $AKDCTL_TARGET, config profile, sim).")
@click.option("--config", "config_path", metavar="FILE", type=click.Path(dir_okay=False), help="Config file (default: ~/.config/akdctl/config.toml).")
@click.option("--profile", "profile_name", metavar="NAME", help="Named profile of the config file.")
@click.option("--json", "json_output", is_flag=True, help="Machine-readable JSON on stdout.")
@click.option("--timeout", type=Duration(0.001, 3600), metavar="DURATION",
              help="How long a request may wait for the drive, repeats included (default 2 s; 2, 2s, 500ms); a "
                   "command against a silent drive gives up after about this long.")
@click.option("--retries", type=click.IntRange(min=0, max=10), metavar="N",
              help="Repeats of a request that got no answer, within --timeout (default 2). A write is "
                   "repeated only where the drive recognises the repeat (PROFINET); elsewhere it is sent "
                   "once and a lost answer is checked by reading back.")
@click.option("-y", "--yes", is_flag=True, help="Consent to motion without a prompt (scripts, CI).")
@click.option("-v", "--verbose", count=True, help="More detail on stderr (repeatable).")
@click.option("--trace", is_flag=True, help="Hex dump of every request and response frame on stderr.")
@click.option("--pcap", metavar="FILE", type=click.Path(dir_okay=False), help="Capture every frame to a pcap file (Wireshark/tshark).")
@click.option("--debug", is_flag=True, help="Show tracebacks for errors.")
@click.option("--inventory", metavar="FILE", expose_value=False, callback=_line_only,
              help="Run the command on every drive of this inventory (see 'akdctl discover'), one process per drive.")
@click.option("--select", metavar="TAG|NAME", multiple=True, expose_value=False, callback=_line_only,
              help="With --inventory: only the drives with this name or tag (repeatable, or comma-separated).")
@click.option("--parallel", metavar="N", expose_value=False, callback=_line_only,
              help="With --inventory: drives worked on at once (default 4).")
@click.option("--stop-on-error", is_flag=True, expose_value=False, callback=_line_only,
              help="With --inventory: start no further drive after one failed.")
@click.option("--reference", metavar="NAME", expose_value=False, callback=_line_only,
              help="With --inventory and param diff: compare with this drive instead of the majority.")
@click.version_option(__version__, "--version", prog_name="akdctl")
@click.pass_context
def cli(ctx: click.Context, target: str | None, config_path: str | None, profile_name: str | None,
        json_output: bool, timeout: float | None, retries: int | None, yes: bool, verbose: int, trace: bool, pcap: str | None,
        debug: bool) -> None:
    """Commission and diagnose Kollmorgen AKD servo drives.

    Reads and writes PROFIdrive parameters and CANopen objects, runs the drive
    through its state machine and moves the axis safely, over PROFINET,
    EtherCAT, CANopen or the built-in simulated AKD (the default target).
    """
    from akdctl.cli.parsing import APP_FIELDS

    app = ctx.ensure_object(AppContext)
    for name, field in APP_FIELDS.items():  # the same fields the options after a command fill (cli/parsing.py)
        setattr(app, field, ctx.params[name])
    ctx.call_on_close(app.close)


def _json_wanted(app: AppContext | None, args: list[str]) -> bool:
    """``--json`` anywhere before ``--`` (also when parsing failed before any option took effect)."""
    if app is not None and app.json:
        return True
    return "--json" in (args[: args.index("--")] if "--" in args else args)


def _click_hint(exc: click.ClickException) -> list[str]:
    """click's usage line and its ``Try '... --help'`` hint, kept under our one error line."""
    ctx = getattr(exc, "ctx", None)
    if ctx is None:
        return []
    option = "--help" if "--help" in ctx.help_option_names else (ctx.help_option_names or ["--help"])[0]
    return [ctx.get_usage(), f"Try '{ctx.command_path} {option}' for help."]


def _from_click(exc: click.ClickException) -> AkdError:
    """A click error in our words: every click error is an input error (exit 2), its usage line kept as detail."""
    error = UsageError(re.sub(r"[ \t]*\n[ \t]*", " ", exc.format_message()))  # one line: "Choose from: a, b"
    hint = _click_hint(exc)
    if hint:
        error.details["usage"] = hint[0].removeprefix("Usage: ")
    return error


def _message_lines(message: str) -> list[str]:
    """A refusal listing its reasons ("...:\n  - reason") prints one reason per line, never a literal "\n"; only an
    indented continuation breaks the line, so a newline inside quoted input stays escaped on its own line."""
    lines: list[str] = []
    for part in message.split("\n"):
        if lines and not part.startswith("  "):
            lines[-1] += "\n" + part
        else:
            lines.append(part)
    return lines


def _print_error(app: AppContext | None, exc: AkdError, *, json_wanted: bool = False, hint: list[str] = ()) -> None:
    """The one error style: ``akdctl: error: <message> [target T]`` (plus click's usage hint for usage errors),
    and with ``--json`` the error document on stdout unless the command already printed its result."""
    from akdctl.cli.output import emit_json, inert

    if exc.target is None and app is not None and app._target is not None:
        exc.target = app._target.display
    target = exc.target
    first, *more = _message_lines(exc.message)
    line = f"akdctl: error: {first}"
    if target and target not in exc.message:
        line += f" [target {target}]"
    sys.stderr.write("".join(inert(text) + "\n" for text in [line, *more, *hint]))
    if (json_wanted or (app is not None and app.json)) and not exc.reported:
        emit_json({"error": exc.to_json()})


def _line_run(args: list[str]) -> bool:
    from akdctl.cli.line import wanted

    return wanted(args)


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI and map every error to its documented exit code, in one style."""
    args = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in args or os.environ.get("AKDCTL_DEBUG") == "1"
    app: AppContext | None = None
    error: AkdError | None = None
    hint: list[str] = []
    try:
        if any(a == "--inventory" or a.startswith("--inventory=") for a in args) and _line_run(args):
            from akdctl.cli import line

            code = line.run(args)  # one process per drive of the inventory (cli/line.py)
        else:
            with cli.make_context("akdctl", list(args)) as ctx:  # click consumes the list it parses
                app = ctx.ensure_object(AppContext)  # the root callback fills this same object
                cli.invoke(ctx)
            code = 0
    except click.exceptions.Exit as exc:
        code = exc.exit_code
    except click.exceptions.Abort:
        error = Interrupted("aborted")
    except click.exceptions.NoArgsIsHelpError as exc:  # a group without its command: its help, exit 2
        exc.show()
        code = EXIT_USAGE
        if _json_wanted(app, args):
            error = _from_click(click.UsageError("missing command", exc.ctx))
    except click.ClickException as exc:
        error, hint = _from_click(exc), _click_hint(exc) if isinstance(exc, click.UsageError) else []
    except AkdError as exc:
        if debug:
            import traceback

            traceback.print_exc()
        error = exc
    except KeyboardInterrupt:
        error = Interrupted("interrupted")
    except BrokenPipeError:
        # stdout closed early (e.g. piped into `head`): not an error worth a message.
        try:
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - silence the flush at exit
        except OSError:
            pass
        code = 0
    except Exception as exc:  # a bug: one line unless --debug
        if debug:
            raise
        error = InternalError(f"internal error: {type(exc).__name__}: {exc} (run with --debug for a traceback)")
    if error is not None:
        _print_error(app, error, json_wanted=_json_wanted(app, args), hint=hint)
        code = error.exit_code
    sys.exit(code)
