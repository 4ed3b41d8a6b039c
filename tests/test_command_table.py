"""The command list comes from the click tree alone (issue 22, item 8).

No ``find_spec`` probe decides which commands exist: every entry of the root table imports, and a module that is
missing (a packaging slip) fails here instead of silently dropping the command from ``akdctl --help``. The short
help is written once, in the docstrings; the table ``--help`` reads is generated from them and must match.
"""

from __future__ import annotations

import importlib
import re

import click
from click.testing import CliRunner

from akdctl.cli.main import COMMANDS, SHORT_HELP, LazyGroup, alias_of, cli, listed_help
from akdctl.cli.parsing import short_help


def test_every_listed_command_imports_and_is_a_click_command() -> None:
    for name, (module, attr) in COMMANDS.items():
        command = vars(importlib.import_module(module))[attr]
        assert isinstance(command, click.Command), name


def test_the_listing_is_the_table_and_its_help_is_the_docstrings() -> None:
    ctx = click.Context(cli, info_name="akdctl")
    assert cli.list_commands(ctx) == list(COMMANDS)
    assert set(SHORT_HELP) == set(COMMANDS)
    expected = {name: listed_help(name, short_help(cli.get_command(ctx, name)))  # type: ignore[arg-type]
                for name in COMMANDS}
    stale = {name: (SHORT_HELP[name], text) for name, text in expected.items() if SHORT_HELP[name] != text}
    assert not stale, f"run tools/gen_docs.py: {stale}"


def test_an_alias_is_listed_as_one_and_runs_its_command() -> None:
    assert alias_of("params") == "param" and alias_of("param") is None
    listing = CliRunner().invoke(cli, ["--help"]).output
    assert re.search(r"^  params +Another name for 'param'\.$", listing, re.MULTILINE), listing
    assert listing.count("restore AKD parameters by name") == 1  # the help once, under its first name
    help_of = {name: CliRunner().invoke(cli, [name, "--help"], prog_name="akdctl").output for name in ("param", "params")}
    usage = {name: text.split("\n", 1) for name, text in help_of.items()}
    assert usage["params"][0] == "Usage: akdctl params [OPTIONS] COMMAND [ARGS]..."
    assert usage["param"][1] == usage["params"][1]  # the same command: the same help below the usage line


def test_a_missing_command_module_is_an_error_not_a_hidden_command() -> None:
    @click.group(cls=LazyGroup, lazy={"ghost": ("akdctl.cli.no_such_module", "ghost", "Never there.")})
    def root() -> None:
        """Root."""

    listing = CliRunner().invoke(root, ["--help"])
    assert "ghost" in listing.output  # listed from the table: the slip is not hidden
    result = CliRunner().invoke(root, ["ghost"])
    assert isinstance(result.exception, ModuleNotFoundError)


#: The commands without ``--dry-run``, and why none is needed: each only reads, only takes power or motion away
#: (never delayed by a plan), or works on the simulator rather than a drive. A writing command born without a dry
#: run fails the test below until it has one (plan -> consent -> execute, cli/consent.render_dry_run).
NO_DRY_RUN = {
    "reads": {"status", "task list", "task show", "pnu describe", "pnu get", "pnu list", "sdo list", "sdo read",
              "pdo presets", "pdo show", "telegram show", "fault dump", "fault explain", "fault list",
              "support bundle", "support diff", "support show", "param backup", "param diff", "param dump",
              "param get", "param help", "param list", "diagnose", "info", "discover", "targets", "pn scan",
              "ecat foe read", "ecat reg read", "ecat scan", "ecat sii read", "can monitor", "can scan", "cip get",
              "eip param get", "eip scan"},
    "takes power or motion away": {"disable", "stop"},
    "asks the device to show itself (DCP blink: a LED)": {"pn blink"},
    "runs other commands, each with its own": {"shell"},
    "the simulator, not a drive": {"sim fault", "sim clear", "sim speed", "sim set", "sim reset", "sim serve",
                                   "sim show"},
}


def _leaves(command: click.Command, path: tuple[str, ...] = ()) -> dict[str, click.Command]:
    if not isinstance(command, click.Group):
        return {" ".join(path): command}
    ctx = click.Context(command)
    found: dict[str, click.Command] = {}
    for name in command.list_commands(ctx):
        if not path and alias_of(name) is not None:
            continue  # 'params' is 'param'
        found.update(_leaves(command.get_command(ctx, name), (*path, name)))  # type: ignore[arg-type]
    return found


def test_every_writing_command_has_a_dry_run() -> None:
    leaves = _leaves(cli)
    without = {name for name, command in leaves.items()
               if not any(isinstance(p, click.Option) and "--dry-run" in p.opts for p in command.params)}
    allowed = set().union(*NO_DRY_RUN.values())
    assert without == allowed, (f"no --dry-run and not listed: {sorted(without - allowed)}; "
                                f"listed but has one or is gone: {sorted(allowed - without)}")
