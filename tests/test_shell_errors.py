"""Issue 14, exit codes and messages: one error style, JSON errors for usage errors too, global options after the
command on every command, negative numbers as values, a wrong user type is exit 2, the hex reading of a decimal index.

Most cases run the real entry point in-process (``akd_inproc``); one runs ``python -m akdctl``.
"""

from __future__ import annotations

import json

import pytest

from akdctl.cli.parsing import is_negative_number
from akdctl.errors import EXIT_DRIVE, EXIT_OK, EXIT_USAGE


def error_lines(err: str) -> list[str]:
    assert "Traceback" not in err
    return [line for line in err.splitlines() if line.startswith("akdctl:")]


# ---------------------------------------------------------------------------- one error style
@pytest.mark.parametrize("argv", [
    ["move", "--bogus", "3"], ["pnu", "get"], ["pnu", "list", "--group", "x"], ["bogus"], ["sdo", "read"],
    ["--timeout", "-1", "pnu", "get", "930"],
])
def test_click_usage_errors_in_our_style(akd_inproc, argv: list[str]) -> None:
    code, out, err = akd_inproc(*argv)
    assert code == EXIT_USAGE, err
    lines = err.splitlines()
    assert lines[0].startswith("akdctl: error: ") and len(error_lines(err)) == 1, err
    assert lines[1].startswith("Usage: akdctl") and lines[2].startswith("Try 'akdctl") and "--help" in lines[2]
    assert "Error:" not in err and out == ""


@pytest.mark.parametrize("argv", [
    ["--json", "pnu", "get"], ["pnu", "get", "--json"], ["--json", "bogus"], ["--json", "pnu", "list", "--group", "x"],
    ["--json", "pnu"], ["sdo", "read", "0x6041", "u8", "--json"],
])
def test_usage_errors_with_json_print_a_json_document(akd_inproc, argv: list[str]) -> None:
    code, out, err = akd_inproc(*argv)
    assert code == EXIT_USAGE, err
    error = json.loads(out)["error"]
    assert error["kind"] == "usage" and error["exit_code"] == EXIT_USAGE and error["message"]


def test_no_json_document_without_json(akd_inproc) -> None:
    assert akd_inproc("pnu", "get")[1] == ""


# ---------------------------------------------------------------------------- options after the command
def test_json_after_the_command_everywhere(akd_inproc) -> None:
    for argv in (["pnu", "get", "930", "--json"], ["sdo", "read", "0x6041", "--json"], ["info", "--json"],
                 ["targets", "--json"], ["fault", "dump", "--json"], ["sim", "show", "--json"],
                 ["status", "--json"], ["pnu", "--json", "get", "930"]):
        code, out, err = akd_inproc(*argv)
        assert code == EXIT_OK, (argv, err)
        json.loads(out)


def test_other_global_options_after_the_command(akd_inproc) -> None:
    code, out, _ = akd_inproc("pnu", "get", "930", "-T", "sim://late", "--timeout", "3")
    assert code == EXIT_OK and "sim://late" in out
    code, _, err = akd_inproc("pnu", "get", "930", "--trace")
    assert code == EXIT_OK and "trace -> bmp" in err
    code, out, err = akd_inproc("home", "--timeout", "5", "--json")  # home's own --timeout; no consent: refused
    assert code == 4 and json.loads(out)["error"]["kind"] == "safety"


# ---------------------------------------------------------------------------- negative numbers
@pytest.mark.parametrize("token,negative", [
    ("-1", True), ("-0.5", True), ("-.5", True), ("-1e3", True), ("-0x10", True), ("-5", True),
    ("-v", False), ("--json", False), ("-", False), ("-1x", False), ("--1", False),
])
def test_negative_number_tokens(token: str, negative: bool) -> None:
    assert is_negative_number(token) is negative


def test_negative_numbers_as_values(akd_inproc) -> None:
    code, out, err = akd_inproc("--yes", "sdo", "write", "0x607A:0", "-1")
    assert code == EXIT_OK, err
    assert json.loads(akd_inproc("sdo", "read", "0x607A", "--json")[1])["value"] == -1
    code, out, err = akd_inproc("sdo", "write", "0x6081:0", "-1")  # u32: a value error, not "no such option"
    assert code == EXIT_USAGE and "out of range" in err and "No such option" not in err
    code, _, err = akd_inproc("-y", "pnu", "set", "1004=-5")
    assert code == EXIT_OK, err
    code, out, err = akd_inproc("-y", "jog", "-100", "--for", "0.1s", "--json")
    assert code == EXIT_OK, err
    assert json.loads(out)["velocity_rpm"] == -100
    code, _, err = akd_inproc("jog", "-100", "--bogus")  # a mistyped option stays an error
    assert code == EXIT_USAGE and "No such option '--bogus'" in err


# ---------------------------------------------------------------------------- user types and addresses
def test_wrong_user_type_is_a_usage_error(akd_inproc) -> None:
    code, out, err = akd_inproc("sdo", "read", "0x6041", "u8")
    assert code == EXIT_USAGE
    (line,) = error_lines(err)
    assert "type u8 does not fit" in line and "2 byte(s)" in line


def test_decimal_index_suggests_hex(akd_inproc) -> None:
    code, _, err = akd_inproc("sdo", "read", "6041")
    assert code == EXIT_USAGE
    assert "did you mean 0x6041 (Statusword)" in error_lines(err)[0]
    code, _, err = akd_inproc("sdo", "read", "6041", "u16")  # the drive says the object does not exist
    assert code == EXIT_DRIVE and "did you mean 0x6041" in err
    code, _, err = akd_inproc("sdo", "read", "0x1799", "u16")  # written in hex: no guess
    assert code == EXIT_DRIVE and "did you mean" not in err
    code, out, _ = akd_inproc("sdo", "read", "4096")  # decimal 4096 = 0x1000 exists: read as asked
    assert code == EXIT_OK and "Device type" in out


@pytest.mark.slow
def test_error_style_through_the_real_cli(akd) -> None:
    code, out, err = akd("pnu", "get", "930", "--bogus", "--json")
    assert code == EXIT_USAGE
    assert err.splitlines()[0].startswith("akdctl: error: No such option '--bogus'.")
    assert json.loads(out)["error"]["details"]["usage"].startswith("akdctl pnu get")
