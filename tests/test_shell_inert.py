"""Issue 14 / 17.11: text from a user, a drive or a file is shown inert, on a terminal and in a pipe.

One rule (``akdctl/cli/output.py`` ``inert`` and the rich renderer that never parses markup): control characters
are shown as escapes (``\\x1b``), rich markup is shown as the characters it is. The terminal cases run the real CLI
under a pseudo-terminal (``tests.harness.run_akdctl_tty``).
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.cli.output import Doc, inert, render_plain, rich_doc
from akdctl.errors import EXIT_OK, EXIT_USAGE
from tests.harness import run_akdctl, run_akdctl_tty

HOSTILE = "Line 3 [/axis1] \x1b]0;owned\x07 \x1b[2J \x9b31m [link=file:///etc/passwd]x[/link] \u202eevil\r\n[bold"
CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")


def test_inert_shows_every_control_character() -> None:
    assert inert("a\x1bb") == "a\\x1bb"
    assert inert("\x1b]0;t\x07") == "\\x1b]0;t\\x07"
    assert inert("\x9b2J") == "\\x9b2J"
    assert inert("x\ny\tz\r") == "x\\ny\\tz\\r"
    assert inert("x\ny\tz\r", lines=True) == "x\ny\tz\\r"
    assert inert("\u202eabc\u2066") == "\\u202eabc\\u2066"
    assert inert("Grüße [bold]") == "Grüße [bold]"  # printable text and markup-like text unchanged
    assert inert(5) == "5"


@given(st.text())
@settings(max_examples=300)
def test_inert_never_leaves_a_control_character(value: str) -> None:
    assert not CONTROL.search(inert(value))
    assert "\n" not in inert(value)


def _rich_text(doc: Doc) -> str:
    from rich.console import Console

    buffer = io.StringIO()
    Console(file=buffer, force_terminal=True, color_system=None, width=200, markup=False).print(rich_doc(doc))
    return buffer.getvalue()


@given(st.text(), st.text(), st.text())
@settings(max_examples=200)
def test_any_text_renders_with_rich_and_plain(title: str, key: str, value: str) -> None:
    """No MarkupError, no control character reaches the terminal, whatever the drive or file said."""
    doc = Doc(title, value).kv(key, value).table([key], [[value]], title=title).line(value)
    shown = _rich_text(doc)  # colour off: any ESC would come from the data
    assert not CONTROL.search(shown)
    buffer = io.StringIO()
    render_plain(doc, buffer)
    assert not CONTROL.search(buffer.getvalue())


def test_markup_is_shown_literally() -> None:
    doc = Doc("recipe Line 3 [/axis1]", "sim").kv("name", "[link=file:///etc/passwd]x[/link]").line("[red]no[/red]")
    shown = _rich_text(doc)
    assert "Line 3 [/axis1]" in shown and "[link=file:///etc/passwd]x[/link]" in shown and "[red]no[/red]" in shown


def test_error_messages_are_inert(akd_inproc) -> None:
    code, _, err = akd_inproc("sdo", "read", "\x1b]0;owned\x07")
    assert code == EXIT_USAGE
    assert "\x1b" not in err and "\\x1b]0;owned\\x07" in err


# ---------------------------------------------------------------------------- on a terminal (pty), the real CLI
def _no_raw(out: str, *sequences: str) -> None:
    for sequence in sequences:
        assert sequence not in out, (sequence, out)


@pytest.mark.slow
def test_targets_on_a_terminal() -> None:
    result = run_akdctl_tty("targets")
    assert result.code == EXIT_OK, result.out
    assert "MarkupError" not in result.out and "[/POSITION]" in result.out.replace("\n", "")


@pytest.mark.slow
def test_recipe_with_markup_and_escapes_in_its_names(tmp_path: Path) -> None:
    recipe = tmp_path / "r.toml"
    recipe.write_text(
        '[recipe]\nname = "Line 3 [/axis1] \\u001b]0;owned\\u0007 [link=file:///etc/passwd]x[/link]"\n\n'
        '[[step]]\nname = "check [/axis1] \\u001b[2J"\naction = "expect"\npnu = 930\nvalue = 1\n')
    for args in (("commission", "--dry-run", str(recipe)), ("commission", str(recipe))):
        result = run_akdctl_tty(*args)
        assert result.code == EXIT_OK, result.out
        assert "Line 3 [/axis1]" in result.out and "[link=file:///etc/passwd]x[/link]" in result.out
        assert "\\x1b]0;owned\\x07" in result.out
        _no_raw(result.out, "\x1b]0;owned", "\x07", "\x1b[2J")
    piped = run_akdctl("commission", str(recipe))
    assert piped.code == EXIT_OK and "\x1b" not in piped.out + piped.err and "\\x1b[2J" in piped.err + piped.out


@pytest.mark.slow
def test_visible_string_with_control_bytes() -> None:
    """``sdo read 0x6041 vs``: the statusword's bytes read as text include control bytes; they are shown escaped."""
    for run in (run_akdctl_tty, run_akdctl):
        result = run("sdo", "read", "0x6041", "vs")
        assert result.code == EXIT_OK, result
        assert "\\x02" in result.out and "\x02" not in result.out


@pytest.mark.slow
def test_support_bundle_fields_are_shown_inert(tmp_path: Path) -> None:
    """17.11: a bundle whose fields carry an OSC title, a clear-screen and a rich link shows them as text."""
    import json
    import zipfile

    bundle = tmp_path / "b.zip"
    assert run_akdctl("support", "bundle", "-o", str(bundle)).code == EXIT_OK
    with zipfile.ZipFile(bundle) as zf:
        members = {name: zf.read(name) for name in zf.namelist()}
    data = json.loads(members["bundle.json"])
    hostile = "\x1b]0;owned\x07\x1b[2J[link=file:///etc/passwd]x[/link]"
    data["target"]["display"] = hostile
    data["identity"]["canopen"]["device_name"] = hostile
    members["bundle.json"] = json.dumps(data).encode()
    with zipfile.ZipFile(bundle, "w") as zf:
        for name, content in members.items():
            zf.writestr(name, content)
    for run in (run_akdctl_tty, run_akdctl):
        result = run("support", "show", str(bundle))
        assert result.code == EXIT_OK, result
        _no_raw(result.out + result.err, "\x1b]0;owned", "\x07", "\x1b[2J")
        assert "\\x1b]0;owned\\x07" in result.out and "[link=file:///etc/passwd]x[/link]" in result.out
