"""``akdctl shell``: the CLI's commands typed at a prompt, over ONE open connection.

Why: every ``akdctl`` run opens its link again (about 2 s on an slcan adapter, a PROFINET connect, the owner lock
taken and released). A technician commissioning one drive for an hour wants the link kept. The shell is not a
second parser: each line is split like a shell would (``shlex``) and handed to the same click tree with the same
root options the shell was started with, so every command, option, consent prompt and error is the CLI's own
(the gate and :func:`akdctl.cli.consent.require_consent` are reached exactly as from the command line).

What differs from one run per command, and why:

* one :class:`ShellApp` (an :class:`~akdctl.cli.context.AppContext`) lives for the session; its Connection and
  tracer are closed when the shell ends; what a command adds (the axis owner lock) is released when the command
  ends, so another process may take the axis between two commands, as between two CLI runs;
* a lost link (any communication error) closes the connection; the next command opens it again;
* Ctrl-C during a command is the CLI's Ctrl-C (a motion stops, exit 130 reported) and the prompt comes back;
  Ctrl-C at the prompt clears the line; Ctrl-D or ``exit`` ends the shell;
* the target, timeout, retries, trace and pcap belong to the session (one link): a line naming other ones is
  refused; ``-y`` is per line only (the shell refuses a session-wide one: consent is per command);
* with ``--json`` (for scripts driving the shell through a pipe) every command prints exactly one JSON line
  ``{"line": N, "command": [...], "exit_code": C, "result": ...}`` and no prompt is shown;
* history (readline) is kept in ``$AKDCTL_STATE_DIR/shell_history``; Tab completes commands, options, PNU numbers
  and names, object addresses (and AKD parameter names where the catalogue has them).
"""

from __future__ import annotations

import contextlib
import io
import shlex
import sys
import time
from collections.abc import Callable
from typing import Any

import click

from akdctl.cli.context import AppContext, get_app
from akdctl.errors import (
    EXIT_USAGE,
    AkdError,
    CommError,
    InternalError,
    Interrupted,
    UsageError,
)

HISTORY_FILE = "shell_history"
HISTORY_LENGTH = 1000
#: Root options that name the session's one link: they may not change between lines.
SESSION_FIELDS = ("target_text", "config_path", "profile_name", "timeout", "retries", "trace", "pcap")


class ShellApp(AppContext):
    """The session's context: what the link needs lives for the session, what a command takes ends with it."""

    def __init__(self, base: AppContext) -> None:
        super().__init__(base.target_text, base.config_path, base.profile_name, base.json, base.timeout,
                         base.retries, False, base.verbose, base.trace, base.debug, base.pcap)
        self.session = {name: getattr(base, name) for name in SESSION_FIELDS}
        self.session_json = base.json
        self.session_verbose = base.verbose
        self.session_debug = base.debug
        self._session_cleanups: list[Callable[[], None]] = []

    def _check_session(self) -> None:
        changed = [name for name, value in self.session.items() if getattr(self, name) != value]
        if changed:
            names = ", ".join(n.replace("_text", "").replace("_", "-") for n in changed)
            for name, value in self.session.items():
                setattr(self, name, value)
            raise UsageError(f"the shell keeps one link: {names} cannot change inside it (start another "
                             "'akdctl shell' with the options you want)")

    def _adopt_last_cleanup(self) -> None:
        if self._cleanups:
            self._session_cleanups.append(self._cleanups.pop())

    @property
    def target(self) -> Any:
        self._check_session()
        return super().target

    @property
    def options(self) -> Any:
        self._check_session()
        fresh = self._options is None
        options = super().options
        if fresh:
            self._adopt_last_cleanup()  # the tracer lives for the session
        return options

    @property
    def connection(self) -> Any:
        self._check_session()
        fresh = self._connection is None
        connection = super().connection
        if fresh:
            self._adopt_last_cleanup()  # closed when the link is lost or the shell ends
        return connection

    def close(self) -> None:
        """The end of one command: release what it took (owner lock), keep the link."""
        super().close()
        if self._connection is not None:
            self._connection.release_axis()
        self.yes = False

    def drop_connection(self) -> None:
        """Forget a lost link (closing what is left of it); the next command opens a new one."""
        connection, self._connection = self._connection, None
        if connection is not None:
            with contextlib.suppress(Exception):
                connection.close()
            self._session_cleanups = [c for c in self._session_cleanups
                                      if getattr(c, "__self__", None) is not connection]

    def end(self) -> None:
        """The end of the session: close the link and the tracer."""
        self.drop_connection()
        while self._session_cleanups:
            with contextlib.suppress(Exception):
                self._session_cleanups.pop()()


def _root_args(app: ShellApp) -> list[str]:
    """The session's root options as they are given again before every line."""
    args: list[str] = []
    for option, value in (("--target", app.session["target_text"]), ("--config", app.session["config_path"]),
                          ("--profile", app.session["profile_name"]), ("--pcap", app.session["pcap"])):
        if value is not None:
            args += [option, str(value)]
    for option, value in (("--timeout", app.session["timeout"]), ("--retries", app.session["retries"])):
        if value is not None:
            args += [option, repr(value) if isinstance(value, float) else str(value)]
    if app.session["trace"]:
        args.append("--trace")
    if app.session_json:
        args.append("--json")
    if app.session_verbose:
        args.append("-" + "v" * app.session_verbose)
    if app.session_debug:
        args.append("--debug")
    return args


def run_line(app: ShellApp, words: list[str]) -> int:
    """One command through the CLI's own tree and error style; the exit code it would have had."""
    from akdctl.cli.main import (
        _click_hint,
        _from_click,
        _json_wanted,
        _print_error,
        cli,
    )

    args = _root_args(app) + words
    app._started = time.monotonic()  # -v: this command's time and frames, not the session's
    if app._options is not None:
        app._options.tracer.records.clear()
    error: AkdError | None = None
    hint: list[str] = []
    code = 0
    interrupted = False
    try:
        with cli.make_context("akdctl", list(args), obj=app) as ctx:
            cli.invoke(ctx)
    except click.exceptions.Exit as exc:
        code = exc.exit_code
    except click.exceptions.Abort:
        error = Interrupted("aborted")
    except click.exceptions.NoArgsIsHelpError as exc:
        exc.show()
        code = EXIT_USAGE
    except click.ClickException as exc:
        error, hint = _from_click(exc), _click_hint(exc) if isinstance(exc, click.UsageError) else []
    except AkdError as exc:
        error = exc
    except KeyboardInterrupt:
        error, interrupted = Interrupted("interrupted"), True
    except Exception as exc:  # noqa: BLE001 - a bug: one line, the shell goes on
        if app.debug:
            import traceback

            traceback.print_exc()
        error = InternalError(f"internal error: {type(exc).__name__}: {exc} (run with --debug for a traceback)")
    if error is not None:
        _print_error(app, error, json_wanted=_json_wanted(app, args), hint=hint)
        code = error.exit_code
        if isinstance(error, CommError) or interrupted:
            lost = app._connection is not None
            app.drop_connection()
            if lost and isinstance(error, CommError):
                from akdctl.cli.output import message

                message("akdctl: the link to the drive was closed after this error; the next command opens it again")
    return code


def run_json_line(app: ShellApp, number: int, words: list[str]) -> int:
    """:func:`run_line` with its stdout gathered into one JSON line (the scripted shell's one output)."""
    import json

    from akdctl.cli.output import emit_json_line

    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = run_line(app, words)
    text = buffer.getvalue()
    documents: list[Any] = []
    decoder = json.JSONDecoder()
    position = 0
    try:
        while position < len(text.rstrip()):
            while text[position].isspace():
                position += 1
            document, position = decoder.raw_decode(text, position)
            documents.append(document)
        result: Any = documents[0] if len(documents) == 1 else documents
    except (ValueError, IndexError):
        result = {"text": text}
    emit_json_line({"line": number, "command": words, "exit_code": code, "result": result})
    return code


# ---------------------------------------------------------------------------- completion
def _walk(words: list[str]) -> tuple[click.Command, list[str]]:
    """The deepest command the words name, and its path."""
    from akdctl.cli.main import cli

    ctx = click.Context(cli)
    command: click.Command = cli
    path: list[str] = []
    for word in words:
        if isinstance(command, click.Group) and not word.startswith("-"):
            sub = command.get_command(ctx, word)
            if sub is not None:
                command = sub
                path.append(word)
                continue
        if isinstance(command, click.Group):
            continue
        break
    return command, path


def _value_words(path: list[str]) -> list[str]:
    """Values worth completing for a command: PNUs for ``pnu``, object addresses for ``sdo``, AKD parameter names
    where the catalogue has them (``akdctl.catalog.akd_params``, when present)."""
    words: list[str] = []
    if path[:1] == ["pnu"]:
        from akdctl.catalog.pnus import pnu_table

        for number, info in pnu_table().items():
            words += [str(number), str(info.name)]
    elif path[:1] == ["sdo"]:
        from akdctl.catalog import objects as catalog

        words += [f"0x{index:04X}:{sub}" for index, sub in catalog.entries()]
    elif path == ["fault", "explain"]:
        from akdctl.catalog.faults import faults

        words += [f.code for f in faults() if f.code]
    elif path == ["sim", "set"]:
        from akdctl.cli.sim_set import SETTINGS

        words += [f"{name}=" for name in SETTINGS]
    if path[:1] in (["param"], ["params"], ["cmd"], ["eip"], ["sdo"]):
        import importlib.util

        if importlib.util.find_spec("akdctl.catalog.akd_params") is not None:
            import importlib

            module = importlib.import_module("akdctl.catalog.akd_params")
            names = getattr(module, "names", None)
            if callable(names):
                words += [str(n) for n in names()]
    return words


def candidates(line: str, text: str) -> list[str]:
    """What Tab offers for ``text``, the word being typed at the end of ``line``."""
    from akdctl.cli.main import cli

    try:
        words = shlex.split(line[: len(line) - len(text)])
    except ValueError:
        return []
    command, path = _walk(words)
    if not path:
        pool = [*cli.list_commands(click.Context(cli)), "exit", "help"]
    elif text.startswith("-"):
        pool = [opt for param in [*command.params, *cli.params] if isinstance(param, click.Option)
                for opt in param.opts if opt.startswith("--") or len(opt) == 2]
    elif isinstance(command, click.Group):
        pool = list(command.list_commands(click.Context(command)))
    else:
        pool = _value_words(path)
    return sorted({word for word in pool if word.startswith(text)})


def _readline_setup() -> Callable[[], None]:
    """History and completion on a terminal; returns what saves the history at the end."""
    try:
        import readline
    except ImportError:  # a Python without readline: the shell works, without history
        return lambda: None
    from akdctl.sim.drive import state_dir

    path = state_dir() / HISTORY_FILE
    with contextlib.suppress(OSError):
        readline.read_history_file(path)
    readline.set_history_length(HISTORY_LENGTH)
    matches: list[str] = []

    def complete(text: str, state: int) -> str | None:
        nonlocal matches
        if state == 0:
            try:
                matches = candidates(readline.get_line_buffer()[: readline.get_endidx()], text)
            except Exception:  # noqa: BLE001 - a completion must never end the shell
                matches = []
        return matches[state] if state < len(matches) else None

    readline.set_completer(complete)
    readline.set_completer_delims(" \t\n\"'")
    readline.parse_and_bind("tab: complete")

    def save() -> None:
        with contextlib.suppress(OSError):
            path.parent.mkdir(parents=True, exist_ok=True)
            readline.write_history_file(path)

    return save


# ---------------------------------------------------------------------------- the command
@click.command()
def shell() -> None:
    """Type akdctl commands at a prompt over one open connection (history, Tab completion).

    Every line is an akdctl command line without 'akdctl' (e.g. 'status',
    'pnu get 930', '-y jog 60 --for 2s'): the same options, consent prompts and
    errors as the CLI. The target, timeout and trace are the shell's (given before
    'shell'); -y is given per line. Ctrl-C stops a running motion and returns to the
    prompt; a lost link is reported and opened again by the next command; 'exit' or
    Ctrl-D ends. With --json and a pipe, each command prints one JSON line
    {line, command, exit_code, result}. Through a pipe the exit code is the last
    command's; at a terminal it is 0.

    \b
    Examples:
      akdctl shell
      akdctl -T ecat-udp://10.0.0.5/1001 shell
      printf 'status\\npnu get 930\\n' | akdctl --json shell
    """
    base = get_app()
    if base.yes:
        raise UsageError("-y is given per command inside the shell (consent belongs to each command), not to the shell")
    app = ShellApp(base)
    verbose, base.verbose = base.verbose, 0  # -v speaks per command; after one, the shell has nothing to add
    interactive = sys.stdin.isatty()
    save_history = _readline_setup() if interactive else (lambda: None)
    last = 0
    number = 0
    from akdctl.cli.output import inert, message

    if interactive and not app.json:
        message(f"akdctl shell on {inert(app.target.display)}: akdctl commands without 'akdctl'; "
                "Tab completes, 'exit' or Ctrl-D ends")
    try:
        while True:
            try:
                line = input(f"akdctl {app.target.display}> ") if interactive else sys.stdin.readline()
            except EOFError:
                break
            except KeyboardInterrupt:
                sys.stderr.write("^C\n")
                continue
            except OSError as exc:  # stdin closed under us or not readable at all
                raise UsageError(f"cannot read commands from standard input: {exc}") from None
            if not interactive and not line:
                break
            try:
                words = shlex.split(line, comments=True)
            except ValueError as exc:
                error = UsageError(f"cannot split the line: {exc}")
                message(f"akdctl: error: {error.message}")
                last = EXIT_USAGE
                if app.session_json:  # a script still gets its one line for this command
                    from akdctl.cli.output import emit_json_line

                    number += 1
                    emit_json_line({"line": number, "command": line.rstrip("\n"), "exit_code": last,
                                    "result": {"error": error.to_json()}})
                continue
            if not words:
                continue
            if words[0] in ("exit", "quit"):
                break
            if words[0] == "help":
                words = [*words[1:], "--help"]
            if words[0] == "shell":
                message("akdctl: error: already in the shell")
                last = EXIT_USAGE
                continue
            number += 1
            last = run_json_line(app, number, words) if app.session_json else run_line(app, words)
            sys.stdout.flush()
    finally:
        save_history()
        app.end()
        if number == 0:
            base.verbose = verbose  # no command ran: -v ends as every command's does
    if last and not interactive:
        raise click.exceptions.Exit(last)
