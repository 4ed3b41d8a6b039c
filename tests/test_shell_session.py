"""Issue 28 item 1: ``akdctl shell``, driven as a technician would: through a pseudo-terminal (prompt, Tab
completion, history, Ctrl-C during a jog, a drive that vanishes mid-session) and through a pipe (``--json`` lines).

The consent parity test holds the shell to the CLI: the same line gets the same exit code and the same refusal.
"""

from __future__ import annotations

import json
import os
import re
import select
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest

from akdctl.cli.shell import candidates
from tests.harness import ROOT, SimServer, _argv, akdctl_env, run_akdctl, wait_until

pytestmark = pytest.mark.slow
PROMPT = re.compile(r"akdctl \S+> $")
ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|\x1b[()][A-Z0-9]|\x07")


class PtyShell:
    """``akdctl ARGS shell`` on a pseudo-terminal: type lines, read the screen up to the next prompt."""

    def __init__(self, *args: str, env: dict[str, str] | None = None) -> None:
        import fcntl
        import pty
        import struct
        import termios

        self.master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 160, 0, 0))
        full = akdctl_env({"TERM": "dumb", "COLUMNS": "160", **(env or {})})
        # SIGINT at its default, as a terminal's foreground job has it: a runner started in the background
        # (``cmd &`` in a script, nohup) ignores SIGINT, every child inherits that, and the shell's Python then
        # leaves Ctrl-C ignored too (so the prompt test saw no prompt, and its "exit" joined the uncancelled line).
        self.proc = subprocess.Popen(_argv([*args, "shell"], None), stdin=slave, stdout=slave, stderr=slave, env=full,
                                     cwd=ROOT, close_fds=True, start_new_session=True,
                                     preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        os.close(slave)
        self.screen = ""
        self.closed = False

    def read_until(self, predicate: Any, timeout: float = 30.0) -> str:
        """Everything the terminal showed until ``predicate(text)`` holds (text since the last call)."""
        start = len(self.screen)
        deadline = time.monotonic() + timeout
        while True:
            text = ANSI.sub("", self.screen[start:]).replace("\r", "")
            if predicate(text):
                return text
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out; the terminal showed:\n{text}")
            ready, _, _ = select.select([self.master], [], [], 0.1)
            if ready:
                try:
                    data = os.read(self.master, 65536)
                except OSError:
                    data = b""
                if not data:
                    raise AssertionError(f"the shell ended; the terminal showed:\n{text}")
                self.screen += data.decode("utf-8", "replace")

    def prompt(self, timeout: float = 30.0) -> str:
        return self.read_until(lambda t: PROMPT.search(t) is not None, timeout)

    def type(self, text: str) -> None:
        os.write(self.master, text.encode())

    def run(self, line: str, timeout: float = 30.0) -> str:
        self.type(line + "\n")
        return self.prompt(timeout)

    def close(self) -> int:
        if self.closed:
            return self.proc.wait()
        self.closed = True
        try:
            self.type("exit\n")
            return self.proc.wait(timeout=20)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
            os.close(self.master)


def _moving() -> bool:
    from akdctl.sim.drive import SimDrive

    with SimDrive("default").transaction() as model:
        return not model.component("motion").standstill


@pytest.fixture
def cia402_shell() -> Any:
    shell = PtyShell("-T", "sim?drive=cia402")
    try:
        shell.prompt()
        yield shell
    finally:
        shell.close()


def test_commands_completion_and_history(cia402_shell: PtyShell, isolated_env: Path) -> None:
    out = cia402_shell.run("status")
    assert "axis status (sim?drive=cia402)" in out and "switch on disabled" in out
    out = cia402_shell.run("pnu get 930 --json")
    assert json.loads(out[out.index("{"): out.rindex("}") + 1])["parameters"][0]["pnu"] == 930
    out = cia402_shell.run("bogus")
    assert "akdctl: error: No such command 'bogus'." in out
    cia402_shell.type("pnu ge\t")  # Tab completes the subcommand
    cia402_shell.read_until(lambda t: "pnu get" in t)
    cia402_shell.type(" 93\t\t")  # two Tabs list the PNUs starting with 93
    cia402_shell.read_until(lambda t: "930" in t)
    cia402_shell.type("\x15")  # Ctrl-U: drop the line
    cia402_shell.run("")
    assert cia402_shell.close() == 0
    history = (isolated_env / "shell_history").read_text()
    assert "pnu get 930 --json" in history and "status" in history


def test_completion_candidates() -> None:
    assert "diagnose" in candidates("di", "di") and "exit" in candidates("", "")
    assert candidates("pnu g", "g") == ["get"]
    assert "--json" in candidates("status --j", "--j") and "--watch" in candidates("status --w", "--w")
    assert "930" in candidates("pnu get 93", "93") and "ZSW1" in candidates("pnu get ZS", "ZS")
    assert "0x6041:0" in candidates("sdo read 0x6041", "0x6041")
    assert "F501" in candidates("fault explain F50", "F50") and candidates("sim set hw", "hw") == ["hw-enable="]


def test_ctrl_c_during_a_jog_stops_the_axis_and_returns_the_prompt(cia402_shell: PtyShell) -> None:
    cia402_shell.type("-y jog 300 --for 30\n")
    # the jog is running: seen on the drive, not assumed after a sleep (on a loaded machine 2 s were not always
    # enough for the shell to read the line and start it; a Ctrl-C before the jog interrupts nothing)
    wait_until(_moving, "the jog to start", timeout=30)
    os.killpg(cia402_shell.proc.pid, signal.SIGINT)  # Ctrl-C: the terminal signals the foreground group
    out = cia402_shell.prompt(timeout=30)
    assert "interrupted" in out
    out = cia402_shell.run("status")
    assert re.search(r"velocity\s+0\.00 rpm", out) and re.search(r"standstill\s+yes", out), out
    out = cia402_shell.run("sdo read 0x6041")  # the session goes on over its link
    assert "Statusword" in out


def test_ctrl_c_at_the_prompt_clears_the_line(cia402_shell: PtyShell) -> None:
    cia402_shell.type("pnu get 93")   # Ctrl-C once the line shows, as a person would
    cia402_shell.read_until(lambda text: "pnu get 93" in text)
    time.sleep(0.3)
    os.killpg(cia402_shell.proc.pid, signal.SIGINT)
    cia402_shell.prompt()
    out = cia402_shell.run("info")
    assert "error" not in out.lower()


def test_a_vanished_drive_is_reported_and_reopened(tmp_path: Path) -> None:
    server = SimServer("--profinet", "127.0.0.1:0")
    server.start()
    port = server.port
    shell = PtyShell("-T", f"pn://127.0.0.1:{port}", "--timeout", "0.5")
    try:
        shell.prompt()
        assert "PNU values" in shell.run("pnu get 930")
        server.stop()
        out = shell.run("pnu get 930")
        assert "akdctl: error:" in out and "opens it again" in out
        server = SimServer("--profinet", f"127.0.0.1:{port}")
        server.start()
        out = shell.run("pnu get 930")
        assert "PNU values" in out and "error" not in out
    finally:
        server.stop()
        assert shell.close() == 0


@pytest.mark.parametrize("line", [["jog", "60", "--for", "0.5"], ["enable"], ["sdo", "write", "0x6040", "15"],
                                  ["pnu", "set", "1=1151"]])
def test_consent_parity_with_the_cli(line: list[str]) -> None:
    """No terminal, no -y: the CLI refuses (exit 4) and so does the same line in the shell; with -y both run."""
    target = ["-T", "sim?drive=cia402"] if line[0] != "pnu" else []
    cli = run_akdctl(*target, *line)
    piped = run_akdctl(*target, "--json", "shell", input=" ".join(line) + "\n")
    (document,) = [json.loads(x) for x in piped.stdout.splitlines()]
    assert cli.code == 4 and document["exit_code"] == cli.code == piped.code
    assert document["result"]["error"]["kind"] == "safety"
    assert "refusing" in cli.stderr and cli.stderr.split("refusing")[1][:40] in piped.stderr
    run_akdctl("sim", "reset")


def test_json_lines_through_a_pipe() -> None:
    script = "status\npnu get 930\n# a comment\n\nsdo read 0x6041 --json\n-T other status\nbogus\n-y enable\n"
    result = run_akdctl("-T", "sim?drive=cia402", "--json", "shell", input=script)
    documents = [json.loads(line) for line in result.stdout.splitlines()]
    assert [d["line"] for d in documents] == [1, 2, 3, 4, 5, 6]
    assert [d["exit_code"] for d in documents] == [0, 0, 0, 2, 2, 0]
    assert documents[0]["result"]["status"]["state"] == "switch on disabled"
    assert documents[3]["result"]["error"]["message"].startswith("the shell keeps one link")
    assert documents[5]["result"]["status"]["enabled"] is True
    assert result.code == 0


def test_shell_refuses_session_wide_consent_and_nesting() -> None:
    result = run_akdctl("-y", "shell", input="status\n")
    assert result.code == 2 and "per command" in result.stderr
    result = run_akdctl("shell", input="shell\nstatus --json\n")
    assert "already in the shell" in result.stderr and json.loads(result.stdout)["status"]


def test_consent_prompt_at_the_terminal_and_the_owner_lock_between_commands(cia402_shell: PtyShell) -> None:
    cia402_shell.type("enable\n")
    cia402_shell.read_until(lambda t: "Proceed?" in t)
    cia402_shell.type("n\n")
    out = cia402_shell.prompt()
    assert "not confirmed" in out
    cia402_shell.type("enable\n")
    cia402_shell.read_until(lambda t: "Proceed?" in t)
    cia402_shell.type("y\n")
    out = cia402_shell.prompt()
    assert "drive enabled" in out
    # Between two commands the shell holds no axis: another process may take it, as between two CLI runs
    # (``enable`` takes the owner lock; ``disable`` never waits for it, so it alone would prove nothing).
    other = run_akdctl("-T", "sim?drive=cia402", "-y", "enable")
    assert other.code == 0, other.stderr
    other = run_akdctl("-T", "sim?drive=cia402", "-y", "disable")
    assert other.code == 0, other.stderr
    assert "switch on disabled" in cia402_shell.run("status")


def test_hostile_lines_get_one_line_each() -> None:
    script = 'pnu get "930\n\x1b[31m\nstatus --count 0\n' + "x" * 5000 + "\n"
    result = run_akdctl("--json", "shell", input=script)
    documents = [json.loads(line) for line in result.stdout.splitlines()]
    assert [d["exit_code"] for d in documents] == [2, 2, 2, 2] and result.code == 2
    assert "No closing quotation" in documents[0]["result"]["error"]["message"]
    assert "\x1b" not in result.stderr and "Traceback" not in result.stderr
