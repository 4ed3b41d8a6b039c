"""The root's ``--version`` and file options, as click's ``version_option`` and ``click.Path(dir_okay=False)`` made
them before issue 29 wrote ``--version`` out and shared one path type between ``--config`` and ``--pcap`` (cli/main.py:
each saved a gettext catalogue lookup of every start). What a user sees stays the same."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.mark.parametrize("args", [("--version",), ("--version", "pnu", "get", "930"), ("-T", "sim", "--version"),
                                  ("--json", "--version")])
def test_version_prints_one_line_and_exits_0_before_any_command(akd_inproc, args: tuple[str, ...]) -> None:
    from akdctl import __version__

    assert akd_inproc(*args) == (0, f"akdctl, version {__version__}\n", "")


def test_version_is_listed_in_the_root_help_only(akd_inproc) -> None:
    code, out, _ = akd_inproc("--help")
    assert code == 0
    assert [line.split() for line in out.splitlines() if "--version" in line] == [
        ["--version", "Show", "the", "version", "and", "exit."]]
    code, _, err = akd_inproc("pnu", "get", "930", "--version")
    assert code == 2 and "No such option '--version'" in err


@pytest.mark.parametrize("option", ["--config", "--pcap"])
def test_a_file_option_refuses_a_directory_in_clicks_words(akd_inproc, option: str, tmp_path: Path) -> None:
    code, out, err = akd_inproc(option, str(tmp_path), "pnu", "get", "930")
    assert (code, out) == (2, "")
    assert err.splitlines()[0] == f"akdctl: error: Invalid value for '{option}': File '{tmp_path}' is a directory."


def test_both_file_options_keep_clicks_path_rules() -> None:
    import click

    from akdctl.cli.main import cli

    types = {p.name: p.type for p in cli.params if p.name in ("config_path", "pcap")}
    assert set(types) == {"config_path", "pcap"}
    for kind in types.values():
        assert isinstance(kind, click.Path)
        assert (kind.exists, kind.file_okay, kind.dir_okay, kind.name) == (False, True, False, "file")
