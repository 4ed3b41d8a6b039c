"""Issue 14: every command and subcommand of the click tree — walked programmatically, so a command added tomorrow
is covered — answers ``--help`` with an example, answers ``--json`` with a JSON document (its result or its
error), runs on a terminal, and says something with ``-v``; none of them ends in an internal error (exit 70) or a
traceback. The examples in the help texts are themselves valid command lines.
"""

from __future__ import annotations

import json
import shlex
from collections.abc import Iterator

import click
import pytest

from akdctl.cli.main import cli
from tests.harness import run_akdctl_tty

INTERNAL = 70


def walk(command: click.Command = cli, path: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], click.Command]]:
    """Every command of the tree with its path, groups included (the root is ``()``)."""
    yield path, command
    if isinstance(command, click.Group):
        ctx = click.Context(command, info_name=path[-1] if path else "akdctl")
        for name in command.list_commands(ctx):
            sub = command.get_command(ctx, name)
            assert sub is not None, f"{' '.join(path)} lists {name!r} but cannot load it"
            if not sub.hidden:
                yield from walk(sub, (*path, name))


COMMANDS = [path for path, _ in walk() if path]
IDS = [" ".join(path) for path in COMMANDS]


def examples(command: click.Command) -> list[str]:
    """The command lines of the help text's ``Examples:`` block (the one mechanism: a ``\\b`` paragraph)."""
    text = command.help or ""
    if "Examples:" not in text:
        return []
    block = text.split("Examples:", 1)[1].split("\n\n", 1)[0]
    return [line.strip() for line in block.splitlines() if line.strip().startswith(("akdctl ", "echo "))]


def _clean(result_err: str, result_out: str = "") -> None:
    both = result_out + result_err
    assert "Traceback" not in both and "internal error" not in both, both


def test_the_walk_finds_the_whole_tree() -> None:
    assert {"status", "pnu get", "sdo list", "eip param set", "sim serve", "sim fault"} <= set(IDS)


@pytest.mark.parametrize("path", [(), *COMMANDS], ids=["akdctl", *IDS])
def test_help_has_an_example_and_is_not_cut(akd_inproc, path: tuple[str, ...]) -> None:
    command = dict(walk())[path]
    if path:
        assert examples(command), f"'akdctl {' '.join(path)} --help' has no Examples: block"
    code, out, err = akd_inproc(*path, "--help")
    assert code == 0, err
    _clean(err, out)
    assert "..." not in out.split("Commands:", 1)[-1] if "Commands:" in out else True  # listings not cut


@pytest.mark.parametrize("path", COMMANDS, ids=IDS)
def test_examples_are_valid_command_lines(path: tuple[str, ...]) -> None:
    """Each example parses through the real tree (types, choices, required arguments), without running."""
    lines = examples(dict(walk())[path])
    assert any(path[-1] in line for line in lines), f"no example of {' '.join(path)} names it: {lines}"
    for line in lines:
        words = shlex.split(line.split("|")[-1].split(">")[0])
        assert words[0] == "akdctl", line
        args = words[1:]
        command: click.Command = cli
        ctx = cli.make_context("akdctl", list(args))
        while isinstance(command, click.Group):
            rest = [*getattr(ctx, "_protected_args", []), *ctx.args]
            if not rest and command.invoke_without_command:
                break  # a group that runs by itself (``ecat sii`` decodes the SII; ``ecat sii read`` copies it)
            name, sub, rest = command.resolve_command(ctx, rest)
            assert sub is not None, line
            ctx = sub.make_context(name or "", list(rest), parent=ctx)
            command = sub


@pytest.mark.parametrize("path", COMMANDS, ids=IDS)
def test_json_always_prints_a_json_document(akd_inproc, path: tuple[str, ...]) -> None:
    """Bare (no arguments), with --json and -v: a result or an error document on stdout, the -v lines on stderr."""
    code, out, err = akd_inproc(*path, "--json", "-v")
    assert code != INTERNAL, err
    _clean(err)
    doc = json.loads(out)
    assert ("error" in doc) == (code != 0), (code, out)
    assert "akdctl: done in" in err, err


@pytest.mark.slow
@pytest.mark.parametrize("path", COMMANDS, ids=IDS)
def test_every_command_on_a_terminal(path: tuple[str, ...]) -> None:
    """Bare, on a pseudo-terminal (rich rendering, live views, colour): never an internal error."""
    result = run_akdctl_tty(*path, stdin_tty=False, timeout=60)
    assert result.code != INTERNAL, result.out
    _clean(result.out)
    assert "MarkupError" not in result.out
