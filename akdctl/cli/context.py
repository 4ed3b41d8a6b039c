"""The invocation's shared state: global options, config, target, the one Connection.

The root command builds one :class:`AppContext`; subcommands reach it with
:func:`get_app`. It resolves the target and config profile from the command line,
then holds one :class:`~akdctl.connection.Connection` (``app.connection``) and
delegates the drive side to it; ``drive/`` and ``recipe/`` are handed that
Connection, never this context. Opening the transport is lazy (commands that need
no drive, such as ``fault explain``, never open one) and happens once per invocation.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import click

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel, ParameterChannel
    from akdctl.cli.output import Doc
    from akdctl.connection import Connection
    from akdctl.config import Profile
    from akdctl.drive.axis.base import Axis
    from akdctl.transport.base import LinkOptions, Transport
    from akdctl.transport.target import Target


class AppContext:
    """The root options (filled by the root callback and cli/parsing.py) and what they resolve to, built lazily.

    A plain class: it is created on every start, ``--help`` included, where a dataclass costs more to define
    than the root command spends."""

    def __init__(self, target_text: str | None = None, config_path: str | None = None,
                 profile_name: str | None = None, json: bool = False, timeout: float | None = None,
                 retries: int | None = None, yes: bool = False, verbose: int = 0, trace: bool = False,
                 debug: bool = False, pcap: str | None = None) -> None:
        self.target_text = target_text
        self.config_path = config_path
        self.profile_name = profile_name
        self.json = json
        self.timeout = timeout
        self.retries = retries
        self.yes = yes
        self.verbose = verbose
        self.trace = trace
        self.debug = debug
        self.pcap = pcap
        self._target: Target | None = None
        self._profile: Profile | None = None
        self._profile_loaded = False
        self._options: LinkOptions | None = None
        self._connection: Connection | None = None
        self._cleanups: list[Callable[[], None]] = []
        self._started = time.monotonic()

    # ---------------------------------------------------------------- resolution
    @property
    def profile(self) -> "Profile | None":
        if not self._profile_loaded:
            from akdctl.config import load_config, select_profile

            self._profile = select_profile(load_config(self.config_path), self.profile_name)
            self._profile_loaded = True
        return self._profile

    @property
    def target(self) -> "Target":
        if self._target is None:
            from akdctl.config import resolve_target_text
            from akdctl.transport.registry import parse_target

            text, source = resolve_target_text(self.target_text, self.profile)
            self._target = parse_target(text, source)
        return self._target

    @property
    def options(self) -> "LinkOptions":
        """Timeout, retries (one Budget for the command) and the session's one tracer (``--trace``/``--pcap``), closed last at exit."""
        if self._options is None:
            from akdctl.connection import open_tracer
            from akdctl.transport.base import LinkOptions

            timeout = self.timeout
            if timeout is None and self.profile is not None and self.profile.timeout is not None:
                timeout = self.profile.timeout
            tracer = open_tracer(enabled=self.trace, pcap=self.pcap, record=bool(self.verbose))
            self._cleanups.append(tracer.close)
            self._options = LinkOptions(timeout=timeout if timeout is not None else 2.0,
                                        retries=self.retries if self.retries is not None else 2, tracer=tracer,
                                        verbose=self.verbose)
        return self._options

    @property
    def connection(self) -> "Connection":
        """The invocation's Connection to its target (the transport opens on first use, closes at exit)."""
        if self._connection is None:
            from akdctl.connection import Connection

            options = self.options  # first: its tracer closes after the connection
            if self.verbose:
                from akdctl.cli.output import message
                from akdctl.cli.verbose import link_line

                message(link_line(self.target, options.timeout))
            self._connection = Connection(self.target, options, self.profile)
            self._cleanups.append(self._connection.close)
        return self._connection

    @property
    def drive_profile(self) -> str | None:
        return self.connection.drive_profile

    # ---------------------------------------------------------------- delegated to the Connection
    def transport(self) -> "Transport":
        return self.connection.transport()

    def parameters(self) -> "ParameterChannel":
        return self.connection.parameters()

    def objects(self) -> "ObjectChannel":
        return self.connection.objects()

    @property
    def has_parameters(self) -> bool:
        return self.connection.has_parameters

    @property
    def has_objects(self) -> bool:
        return self.connection.has_objects

    def axis(self) -> "Axis":
        return self.connection.axis()

    def close(self) -> None:
        """Close what the invocation opened (last opened first); with ``-v`` first say what it did (cli/verbose.py)."""
        if self.verbose:
            from akdctl.cli.output import message
            from akdctl.cli.verbose import summary_lines

            records = list(self._options.tracer.records) if self._options is not None else []
            for line in summary_lines(records, time.monotonic() - self._started, self.verbose,
                                      contacted=self._connection is not None):
                message(line)
        while self._cleanups:
            cleanup = self._cleanups.pop()
            with contextlib.suppress(Exception):
                cleanup()

    # ---------------------------------------------------------------- output
    def emit(self, data: Any, human: "Doc | str | Callable[[], Doc | str]") -> None:
        """Print a result: ``data`` as JSON with ``--json``, else the human rendering."""
        from akdctl.cli import output

        if self.json:
            output.emit_json(data)
        else:
            output.render(human() if callable(human) else human)


def get_app(ctx: click.Context | None = None) -> AppContext:
    ctx = ctx or click.get_current_context()
    app = ctx.find_object(AppContext)
    if app is None:  # a command invoked outside the root group (tests of single commands)
        app = ctx.ensure_object(AppContext)
    return app
