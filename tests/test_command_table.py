"""The command list comes from the click tree alone (issue 22, item 8).

No ``find_spec`` probe decides which commands exist: every entry of the root table imports, and a module that is
missing (a packaging slip) fails here instead of silently dropping the command from ``akdctl --help``. The short
help is written once, in the docstrings; the table ``--help`` reads is generated from them and must match.
"""

from __future__ import annotations

import importlib

import click
from click.testing import CliRunner

from akdctl.cli.main import COMMANDS, SHORT_HELP, LazyGroup, cli
from akdctl.cli.parsing import short_help


def test_every_listed_command_imports_and_is_a_click_command() -> None:
    for name, (module, attr) in COMMANDS.items():
        command = vars(importlib.import_module(module))[attr]
        assert isinstance(command, click.Command), name


def test_the_listing_is_the_table_and_its_help_is_the_docstrings() -> None:
    ctx = click.Context(cli, info_name="akdctl")
    assert cli.list_commands(ctx) == list(COMMANDS)
    assert set(SHORT_HELP) == set(COMMANDS)
    stale = {name: (SHORT_HELP[name], short_help(cli.get_command(ctx, name)))  # type: ignore[arg-type]
             for name in COMMANDS if SHORT_HELP[name] != short_help(cli.get_command(ctx, name))}  # type: ignore[arg-type]
    assert not stale, f"run tools/gen_docs.py: {stale}"


def test_a_missing_command_module_is_an_error_not_a_hidden_command() -> None:
    @click.group(cls=LazyGroup, lazy={"ghost": ("akdctl.cli.no_such_module", "ghost", "Never there.")})
    def root() -> None:
        """Root."""

    listing = CliRunner().invoke(root, ["--help"])
    assert "ghost" in listing.output  # listed from the table: the slip is not hidden
    result = CliRunner().invoke(root, ["ghost"])
    assert isinstance(result.exception, ModuleNotFoundError)
