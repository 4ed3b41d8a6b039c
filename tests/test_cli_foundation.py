"""The Foundation through the real CLI: parameter access on the simulated drive and every bad input.

Each bad input is checked for its one-line message and its documented exit
code (akdctl/errors.py, README "Exit codes"). Most cases run the real entry
point in-process for speed; a few run ``python -m akdctl`` as a subprocess.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from akdctl.transport.base import Transport

from akdctl.errors import EXIT_CHECK, EXIT_COMM, EXIT_DRIVE, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE


def one_line_error(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("akdctl:")]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


# ---------------------------------------------------------------------------- happy paths
def test_pnu_set_then_get_persists_between_invocations(akd) -> None:
    code, out, err = akd("--yes", "pnu", "set", "930=2", "1004=-500")  # 1004: a gated set point
    assert code == EXIT_OK, err
    code, out, err = akd("--json", "pnu", "get", "930", "1004", "964[0..4]")
    assert code == EXIT_OK, err
    data = json.loads(out)
    assert data["target"] == "sim"
    values = {p["pnu"]: p["values"] for p in data["parameters"]}
    assert values[930] == [2]
    assert values[1004] == [-500]
    assert len(values[964]) == 5


def test_human_output_names_the_target(akd_inproc) -> None:
    code, out, _ = akd_inproc("pnu", "get", "930")
    assert code == EXIT_OK
    assert "(sim)" in out.splitlines()[0]
    code, out, _ = akd_inproc("-T", "sim://bench2", "sdo", "read", "0x1018:1")
    assert code == EXIT_OK
    assert "sim://bench2" in out.splitlines()[0]


def test_sdo_write_read_with_and_without_type(akd_inproc) -> None:
    assert akd_inproc("sdo", "write", "0x6060:0", "i8", "3")[0] == EXIT_OK
    code, out, _ = akd_inproc("--json", "sdo", "read", "0x6060")
    assert code == EXIT_OK
    data = json.loads(out)
    assert data["value"] == 3 and data["type"] == "i8" and data["raw"] == "03"
    assert akd_inproc("sdo", "write", "0x6060:0", "1")[0] == EXIT_OK
    assert json.loads(akd_inproc("--json", "sdo", "read", "0x6060:0", "i8")[1])["value"] == 1


def test_sdo_write_value_from_stdin(akd) -> None:
    code, _, err = akd("--yes", "sdo", "write", "0x607A:0", "-", input="123456\n")  # a gated set point
    assert code == EXIT_OK, err
    code, out, _ = akd("--json", "sdo", "read", "0x607A")
    assert json.loads(out)["value"] == 123456


def test_trace_dumps_request_and_response_bytes(akd_inproc) -> None:
    code, _, err = akd_inproc("--trace", "pnu", "set", "930=2")
    assert code == EXIT_OK
    # SPEC-NOTES 1/2: the seed's change request with attribute 0x10 and big-endian value
    assert "trace -> bmp" in err and "02 00 01 10 01 03 a2 00 00 42 01 00 02" in err
    assert "trace <- bmp" in err


def test_pnu_batching_uses_minimum_round_trips() -> None:
    """100 single-element reads need ceil(100/39) = 3 requests (SPEC-NOTES 4)."""
    from akdctl.connection import Connection
    from akdctl.drive.values import PnuSpec, read_pnus
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.sim import SimTransport
    from akdctl.transport.target import Target

    conn = Connection.over(SimTransport(Target("sim", "sim"), LinkOptions()))
    specs = [PnuSpec(947, i % 64, 1, None) for i in range(100)]
    readings = read_pnus(conn.parameters(), specs)
    assert all(r.ok for r in readings)
    assert conn.parameters().requests == 3


def test_targets_lists_every_scheme(akd_inproc) -> None:
    code, out, _ = akd_inproc("--json", "targets")
    assert code == EXIT_OK
    schemes = {t["scheme"] for t in json.loads(out)["transports"]}
    assert {"sim", "pn", "ecat-udp", "ecat", "can"} <= schemes


def test_target_from_env_and_config_profile(akd_inproc, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = tmp_path / "akd.toml"
    config.write_text('default_profile = "bench"\n[profiles.bench]\ntarget = "sim://benchcfg"\n'
                      '[profiles.other]\ntarget = "sim://other"\n')
    code, out, _ = akd_inproc("--config", str(config), "pnu", "get", "930")
    assert code == EXIT_OK and "sim://benchcfg" in out
    code, out, _ = akd_inproc("--config", str(config), "--profile", "other", "pnu", "get", "930")
    assert code == EXIT_OK and "sim://other" in out
    monkeypatch.setenv("AKDCTL_TARGET", "sim://fromenv")
    code, out, _ = akd_inproc("--config", str(config), "pnu", "get", "930")
    assert code == EXIT_OK and "sim://fromenv" in out
    code, out, _ = akd_inproc("--config", str(config), "-T", "sim://flag", "pnu", "get", "930")
    assert code == EXIT_OK and "sim://flag" in out


# ---------------------------------------------------------------------------- bad input, one by one
BAD_INPUTS = [
    # (argv, exit code, words the message must contain)
    (["pnu", "get", "9999"], EXIT_DRIVE, "impermissible parameter number"),
    (["pnu", "set", "9999=1"], EXIT_USAGE, "not in the catalogue"),
    (["sdo", "read", "0x9999"], EXIT_USAGE, "unknown object 0x9999:0"),
    (["sdo", "read", "0x9999", "u32"], EXIT_DRIVE, "0x06020000"),
    (["sdo", "read", "0x6041:7", "u16"], EXIT_DRIVE, "0x06090011"),
    (["pnu", "set", "964=1"], EXIT_USAGE, "read-only"),
    (["sdo", "write", "0x6041:0", "5"], EXIT_USAGE, "read-only"),
    (["pnu", "set", "930=7"], EXIT_USAGE, "outside 0..2"),
    (["sdo", "write", "0x6060:0", "i8", "300"], EXIT_USAGE, "out of range"),
    (["sdo", "write", "0x6060:0", "u32", "3"], EXIT_DRIVE, "0x06070012"),
    (["sdo", "write", "0x6060:0", "q8", "3"], EXIT_USAGE, "unknown type"),
    (["pnu", "set", "930=abc"], EXIT_USAGE, "not a number"),
    (["pnu", "get", "93x0"], EXIT_USAGE, "cannot parse PNU address"),
    (["sdo", "write", "0x6060:0", "x"], EXIT_USAGE, "bad value"),
    (["pnu", "set", "930=1,2"], EXIT_USAGE, "1 element(s) addressed but 2 value(s)"),
    (["sdo", "write", "0x6060:0", "i8", "3", "4"], EXIT_USAGE, "too many values"),
    (["pnu", "get", "964[0..9]"], EXIT_USAGE, "asks beyond them"),
    (["-T", "pn://", "pnu", "get", "930"], EXIT_USAGE, "needs a host"),
    (["-T", "can://socketcan/can0", "sdo", "read", "0x1000"], EXIT_USAGE, "can://INTERFACE/CHANNEL/NODE"),
    (["-T", "ecat-udp://gw/notanumber", "sdo", "read", "0x1000"], EXIT_USAGE, "STATION"),
    (["-T", "foo://bar", "pnu", "get", "930"], EXIT_USAGE, "known schemes: akd, can, ecat"),
    (["-T", "sim?drive=bogus", "pnu", "get", "930"], EXIT_USAGE, "drive=profidrive"),
    (["-T", "sim://a/b", "pnu", "get", "930"], EXIT_USAGE, "expected sim://NAME"),  # not drive 'a' unsaid
    (["-T", "sim://a.b", "pnu", "get", "930"], EXIT_USAGE, "letters, digits, - and _"),
    (["--profile", "nope", "pnu", "get", "930"], EXIT_USAGE, "no profile 'nope'"),
    (["--config", "/nonexistent/akd.toml", "pnu", "get", "930"], EXIT_USAGE, "does not exist"),
    (["pnu", "frobnicate"], EXIT_USAGE, "No such command"),
    (["--timeout", "-1", "pnu", "get", "930"], EXIT_USAGE, "--timeout"),
]


@pytest.mark.parametrize("argv,code,words", BAD_INPUTS, ids=[" ".join(a) for a, _, _ in BAD_INPUTS])
def test_bad_input_is_one_line_with_documented_exit_code(akd_inproc, argv: list[str], code: int, words: str) -> None:
    got, out, err = akd_inproc(*argv)
    assert got == code, (got, out, err)
    assert words in err, err
    assert "Traceback" not in err


def test_bad_input_through_subprocess(akd) -> None:
    code, out, err = akd("-T", "foo://bar", "pnu", "get", "930")
    assert code == EXIT_USAGE
    line = one_line_error(err)
    assert "unknown target scheme 'foo'" in line and "sim" in line
    code, out, err = akd("--json", "pnu", "get", "9999")
    assert code == EXIT_DRIVE
    assert json.loads(out)["parameters"][0]["error"]["code"] == 0


def test_json_errors_are_a_json_document_on_stdout(akd_inproc) -> None:
    code, out, err = akd_inproc("--json", "sdo", "read", "0x9999:1", "u32")
    assert code == EXIT_DRIVE
    error = json.loads(out)["error"]
    assert error["kind"] == "sdo-abort" and error["code"] == 0x06020000 and error["target"] == "sim"
    assert error["exit_code"] == EXIT_DRIVE
    assert "0x06020000" in one_line_error(err)
    code, out, _ = akd_inproc("--json", "-T", "foo://x", "pnu", "get", "930")
    assert code == EXIT_USAGE and json.loads(out)["error"]["kind"] == "usage"


def test_bad_config_file(akd_inproc, tmp_path: Path) -> None:
    config = tmp_path / "bad.toml"
    config.write_text("[profiles.x\ntarget=1\n")
    code, _, err = akd_inproc("--config", str(config), "pnu", "get", "930")
    assert code == EXIT_USAGE and "bad.toml" in err
    config.write_text('[profiles.x]\ntarget = 5\n')
    code, _, err = akd_inproc("--config", str(config), "--profile", "x", "pnu", "get", "930")
    assert code == EXIT_USAGE and "profiles.x.target has the wrong type" in err


def test_corrupt_sim_state_is_reported_and_recoverable(akd, isolated_env: Path) -> None:
    assert akd("pnu", "set", "930=2")[0] == EXIT_OK
    state = isolated_env / "sim-default.json"
    state.write_text('{"version": 1, "pnus": {"930": "garbage"')
    code, out, err = akd("pnu", "get", "930")
    assert code == EXIT_USAGE
    line = one_line_error(err)
    assert "corrupt" in line and "akdctl sim reset" in line
    code, _, err = akd("sim", "reset")
    assert code == EXIT_OK, err
    code, out, _ = akd("--json", "pnu", "get", "930")
    assert code == EXIT_OK and json.loads(out)["parameters"][0]["values"] == [1]


def test_state_file_is_never_half_written(isolated_env: Path) -> None:
    """Saves go through a temporary file and a rename: no temp files remain, the file always parses."""
    from akdctl.sim.drive import SimDrive

    drive = SimDrive("default")
    for value in range(5):
        with drive.transaction() as model:
            model.set_stored_pnu(1004, [value])
    assert json.loads((isolated_env / "sim-default.json").read_text())["pnus"]["1004"] == [4]
    assert not [p for p in isolated_env.iterdir() if p.suffix == ".tmp"]


def test_two_processes_share_one_drive_safely(isolated_env: Path) -> None:
    """Concurrent writers (threads here, each its own SimDrive) never lose an update."""
    import threading

    from akdctl.sim.drive import SimDrive

    def bump() -> None:
        drive = SimDrive("default")
        for _ in range(20):
            with drive.transaction() as model:
                value = model.stored_pnu(1005)[0]
                model.set_stored_pnu(1005, [value + 1])

    with SimDrive("default").transaction() as model:
        model.set_stored_pnu(1005, [0])
    threads = [threading.Thread(target=bump) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    with SimDrive("default").transaction() as model:
        assert model.stored_pnu(1005) == [80]


# ---------------------------------------------------------------------------- exit codes 3, 5, 130 via fake links
class _FakeTransport(Transport):
    """A transport whose parameter channel runs a scripted link (registered in-process for one test); every other
    capability keeps the base class's neutral declaration (transport/base.py), as a real transport's does."""

    scheme = "fake"
    reply: bytes | Exception = b""

    def open(self) -> None:
        from akdctl.links import RecordLink

        reply = type(self).reply

        class Link(RecordLink):
            def exchange(self, request: bytes) -> bytes:
                if isinstance(reply, BaseException):
                    raise reply
                return reply

        self.record_link = Link()

    def close(self) -> None:
        pass


@pytest.fixture
def fake_scheme(monkeypatch: pytest.MonkeyPatch):
    from akdctl.transport import registry

    spec = registry.TransportSpec("fake", __name__, "_FakeTransport", "test", "fake", "parameters")
    monkeypatch.setitem(registry.BUILTIN, "fake", spec)
    return _FakeTransport


@pytest.mark.parametrize("reply,words", [
    (bytes.fromhex("01 01 00"), "malformed"),            # truncated header
    (bytes.fromhex("7f 01 00 01 42 01 00 02"), "reference"),  # wrong request reference
    (bytes.fromhex("01 01 00 02 42 01 00 02"), "parameter"),  # two results for one parameter
])
def test_truncated_or_inconsistent_bmp_reply_is_exit_3(akd_inproc, fake_scheme, reply: bytes, words: str) -> None:
    fake_scheme.reply = reply
    code, _, err = akd_inproc("-T", "fake", "pnu", "get", "930")
    assert code == EXIT_COMM, err
    assert words in one_line_error(err).lower()


def test_silent_drive_is_exit_3(akd_inproc, fake_scheme) -> None:
    from akdctl.errors import NoAnswer

    fake_scheme.reply = NoAnswer("no answer from fake drive within 0.1 s")
    code, _, err = akd_inproc("-T", "fake", "--timeout", "0.1", "pnu", "get", "930")
    assert code == EXIT_COMM and "no answer" in err


def test_ctrl_c_is_exit_130(akd_inproc, fake_scheme) -> None:
    fake_scheme.reply = KeyboardInterrupt()
    code, _, err = akd_inproc("-T", "fake", "pnu", "get", "930")
    assert code == EXIT_INTERRUPTED and "interrupted" in err


def test_verify_mismatch_is_exit_5(akd_inproc, fake_scheme) -> None:
    # change accepted (6-byte positive response, SPEC-NOTES 3), then the read-back returns 1 instead of 2
    replies = iter([bytes.fromhex("01 02 00 01 00 00"), bytes.fromhex("02 01 00 01 42 01 00 01")])

    class Scripted(Exception):
        pass

    from akdctl.links import RecordLink

    original_open = _FakeTransport.open

    def open_scripted(self) -> None:
        class Link(RecordLink):
            def exchange(self, request: bytes) -> bytes:
                return next(replies)

        self.record_link = Link()

    _FakeTransport.open = open_scripted  # type: ignore[method-assign]
    try:
        code, _, err = akd_inproc("-T", "fake", "--yes", "pnu", "set", "--verify", "930=2")
    finally:
        _FakeTransport.open = original_open  # type: ignore[method-assign]
    assert code == EXIT_CHECK, err
    assert "read-back differs" in err


def test_internal_errors_do_not_show_tracebacks_without_debug(akd_inproc, fake_scheme) -> None:
    fake_scheme.reply = RuntimeError("boom")
    code, _, err = akd_inproc("-T", "fake", "pnu", "get", "930")
    assert code == 70 and "internal error" in err and "Traceback" not in err
    with pytest.raises(RuntimeError):
        akd_inproc("--debug", "-T", "fake", "pnu", "get", "930")
