"""How every command of the tree reads its command line — one rule for all of them, applied where they are found.

Why here and not in each command module: a technician types ``akdctl pnu get 930 --json`` as readily as
``akdctl --json pnu get 930``, and ``sdo write 0x6081:0 -1`` means minus one, not an option named ``-1``. Putting
``--json`` on some commands and ``ignore_unknown_options`` on others made the answer depend on the command (issue
14). Instead the root group *adopts* every command it resolves (:func:`adopt`, called from ``LazyGroup``), so a
command added tomorrow follows the same rules without doing anything:

* **global options after the command** — each root option (``-T``, ``--json``, ``--timeout``, ``-y``, ``-v``,
  ``--trace``, ``--pcap``, ``--debug``, ``--config``, ``--profile``) is also accepted after any group or command
  name, unless that command has an option of the same spelling (``home --timeout`` is home's own). They are hidden
  in the command's help (the root help lists them) and land in the same :class:`AppContext` fields;
* **group listings are not cut** — a subcommand's line in ``--help`` is its whole first sentence, wrapped;
* **negative numbers are values** — a token such as ``-1``, ``-0.5`` or ``-0x10`` that is not one of the
  command's options is an argument, while a mistyped option (``--bogus``) is still an error.
"""

from __future__ import annotations

import re
from typing import Any

import click

try:  # click >= 8.2
    from click.parser import _OptionParser as _Parser
except ImportError:  # click 8.1
    from click.parser import OptionParser as _Parser  # type: ignore[attr-defined,no-redef]

#: Root option name -> AppContext field (the root callback and the late copies both use it).
APP_FIELDS = {
    "target": "target_text", "config_path": "config_path", "profile_name": "profile_name", "json_output": "json",
    "timeout": "timeout", "retries": "retries", "yes": "yes", "verbose": "verbose", "trace": "trace", "pcap": "pcap", "debug": "debug",
}

_NEGATIVE = r"^-(?:\d[\d_]*(?:\.\d*)?(?:[eE][-+]?\d+)?|\.\d+|0[xX][0-9A-Fa-f_]+|inf|nan)$"


def is_negative_number(token: str) -> bool:
    """``-1``, ``-2.5``, ``-.5``, ``-1e3``, ``-0x10``: a value, not an option."""
    second = token[1:2]
    if token[:1] != "-" or not (second.isdecimal() or second in (".", "i", "n")):
        return False  # an option (``--help``, ``-v``): decided without compiling the pattern at every start
    return bool(re.match(_NEGATIVE, token))


class _NumberAwareParser(_Parser):  # type: ignore[misc,valid-type]
    """click's parser, except that a negative number that is no option of the command is an argument."""

    def _process_opts(self, arg: str, state: Any) -> None:
        if is_negative_number(arg) and arg not in self._short_opt and arg not in self._long_opt:
            state.largs.append(arg)
            return
        super()._process_opts(arg, state)


def _make_parser(command: click.Command, ctx: click.Context) -> Any:
    parser = _NumberAwareParser(ctx)
    for param in command.get_params(ctx):
        param.add_to_parser(parser, ctx)
    return parser


_LATE = "akdctl_global_"  # the copies' parameter names, apart from any name a command uses


def _set_late(ctx: click.Context, param: click.Parameter, value: Any) -> Any:
    """A root option given after a command: store it where the root callback stores it."""
    from akdctl.cli.context import AppContext

    if value is None or value is False or value == 0:
        return value
    app = ctx.find_object(AppContext) or ctx.ensure_object(AppContext)
    field = APP_FIELDS[(param.name or "").removeprefix(_LATE)]
    if getattr(param, "count", False):
        setattr(app, field, getattr(app, field) + value)
    else:
        setattr(app, field, value)
    return value


def _late_copies(root: click.Command, command: click.Command) -> list[click.Option]:
    """Hidden copies of the root's options that ``command`` does not spell itself."""
    taken = {decl for param in command.params for decl in (*param.opts, *getattr(param, "secondary_opts", []))}
    copies = []
    for option in root.params:
        if not isinstance(option, click.Option) or option.name not in APP_FIELDS:
            continue
        decls = [d for d in option.opts if d not in taken]
        if not decls:
            continue
        kwargs: dict[str, Any] = {"hidden": True, "expose_value": False, "callback": _set_late, "help": option.help}
        if option.count:
            kwargs["count"] = True
        elif option.is_flag:
            kwargs["is_flag"] = True
        else:
            kwargs["type"] = option.type
            kwargs["metavar"] = option.metavar
        copies.append(click.Option([*decls, f"{_LATE}{option.name}"], **kwargs))
    return copies


def short_help(command: click.Command) -> str:
    """A command's line in its group's listing: the whole first sentence, wrapped by the formatter, never cut
    off with "..." (click's default cuts it at the terminal width)."""
    return command.get_short_help_str(limit=10_000)


def _format_commands(group: click.Group, ctx: click.Context, formatter: click.HelpFormatter) -> None:
    rows = []
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        if command is not None and not command.hidden:
            rows.append((name, short_help(command)))
    if rows:
        with formatter.section("Commands"):
            formatter.write_dl(rows)


def adopt(command: click.Command, root: click.Command) -> click.Command:
    """Give ``command`` (and every subcommand it already holds) the tree's parsing rules; idempotent.

    The command's own ``params`` list is left as its module wrote it (tools and tests read it); the late copies
    are added where click asks for the parameters of one invocation (``get_params``).
    """
    if getattr(command, "_akdctl_adopted", False) or command is root:
        return command
    command._akdctl_adopted = True  # type: ignore[attr-defined]
    late: list[list[click.Option]] = []  # made when click first asks: only the commands of this invocation pay
    own_params = command.get_params

    def get_params(ctx: click.Context) -> list[click.Parameter]:
        if not late:
            late.append(_late_copies(root, command))
        return [*own_params(ctx), *late[0]]

    command.get_params = get_params  # type: ignore[method-assign]
    command.make_parser = _make_parser.__get__(command)  # type: ignore[method-assign]
    if isinstance(command, click.Group):
        if not hasattr(command, "lazy"):  # LazyGroup lists its own (cli/main.py), with the same rule
            command.format_commands = _format_commands.__get__(command)  # type: ignore[method-assign]
        for sub in command.commands.values():
            adopt(sub, root)
    return command


# ---------------------------------------------------------------------- durations, one spelling everywhere
# Why here: ``jog --for 2s`` was accepted while ``home --timeout 2s`` and the global ``--timeout 2s`` were refused
# (issue 23 item 22). Every option that takes a duration uses :class:`Duration` (the root's ``--timeout`` too, so
# it lives on the path ``--help`` already loads); a bare number is seconds.
_DURATION = r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(ms|s|m|min)?\s*$"


def parse_duration(text: str, what: str = "duration") -> float:
    """Seconds from ``2``, ``2s``, ``500ms``, ``1.5m``/``1.5min``; UsageError (exit 2) otherwise."""
    from akdctl.errors import UsageError

    match = re.match(_DURATION, str(text))
    if not match:
        raise UsageError(f"{what} must be a finite duration such as 2s, 500ms or 1.5, got {text!r}")
    value = float(match.group(1))
    unit = match.group(2) or "s"
    seconds = value / 1000.0 if unit == "ms" else value * 60.0 if unit in ("m", "min") else value
    if seconds - seconds != 0:  # inf (a digit string too long for a float)
        raise UsageError(f"{what} must be a finite duration, got {text!r}")
    return seconds


class Duration(click.ParamType):
    """A click option type for :func:`parse_duration`, within ``low``..``high`` seconds."""

    name = "duration"

    def __init__(self, low: float = 0.0, high: float = 3600.0) -> None:
        self.low, self.high = low, high

    def convert(self, value: Any, param: Any, ctx: Any) -> float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            seconds = float(value)
        elif re.match(_DURATION, str(value)):
            seconds = parse_duration(str(value))
        else:
            self.fail(f"must be a finite duration such as 2s, 500ms or 1.5, got {value!r}", param, ctx)
        if not self.low <= seconds <= self.high:
            self.fail(f"must be between {self.low:g} and {self.high:g} s, got {value!r}", param, ctx)
        return seconds
