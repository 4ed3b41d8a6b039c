"""CiA 402 homing with no method configured (0x6098 = 0) is refused in words, not a bare homing error."""

from __future__ import annotations

from akdctl.errors import EXIT_OK, EXIT_USAGE


def test_home_without_method_names_the_fix(akd) -> None:
    assert akd("sim", "speed", "1000")[0] == EXIT_OK
    code, _, err = akd("-T", "sim?drive=cia402", "--yes", "home")
    assert code == EXIT_USAGE, err
    assert "0x6098 is 0" in err and "--mode" in err and "Traceback" not in err
    code, out, err = akd("-T", "sim?drive=cia402", "--yes", "--json", "home", "--mode", "35")
    assert code == EXIT_OK, err
