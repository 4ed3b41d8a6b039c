"""The invocation's shared state: global options, config, target, open transport.

The root command builds one :class:`AppContext`; subcommands reach it with
:func:`get_app`. Opening the transport is lazy (commands that need no drive,
such as ``fault explain``, never open one) and happens once per invocation.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import click

from akdctl.errors import AkdError, UsageError

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel, ParameterChannel
    from akdctl.cli.output import Doc
    from akdctl.config import Profile
    from akdctl.transport.base import LinkOptions, Transport
    from akdctl.transport.target import Target


@dataclass
class AppContext:
    target_text: str | None = None
    config_path: str | None = None
    profile_name: str | None = None
    json: bool = False
    timeout: float | None = None
    yes: bool = False
    verbose: int = 0
    trace: bool = False
    debug: bool = False
    pcap: str | None = None
    _target: "Target | None" = None
    _profile: "Profile | None" = None
    _profile_loaded: bool = False
    _options: "LinkOptions | None" = None
    _transport: "Transport | None" = None
    _cleanups: list[Callable[[], None]] = field(default_factory=list)

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
        if self._options is None:
            from akdctl.transport.base import LinkOptions
            from akdctl.transport.trace import Tracer

            timeout = self.timeout
            if timeout is None and self.profile is not None and self.profile.timeout is not None:
                timeout = self.profile.timeout
            tracer = Tracer(enabled=self.trace)
            if self.pcap:
                from akdctl.transport.pcap import PcapWriter

                try:
                    writer = PcapWriter(self.pcap)
                except OSError as exc:
                    raise UsageError(f"cannot write capture file {self.pcap}: {exc.strerror}") from None
                tracer.add_sink(writer.write)
                self._cleanups.append(writer.close)
            self._options = LinkOptions(timeout=timeout if timeout is not None else 2.0, tracer=tracer,
                                        verbose=self.verbose)
        return self._options

    @property
    def drive_profile(self) -> str | None:
        """Which axis profile motion commands use: target ?drive=, else the config profile's ``drive``."""
        chosen = self.target.query.get("drive")
        if chosen is None and self.profile is not None:
            chosen = self.profile.drive
        return chosen

    # ---------------------------------------------------------------- transport
    def transport(self) -> "Transport":
        """The open transport of this invocation (opened on first use, closed at exit)."""
        if self._transport is None:
            from akdctl.transport.registry import transport_class

            target = self.target
            cls = transport_class(target)
            transport = cls(target, self.options)
            try:
                transport.open()
            except AkdError as exc:
                with contextlib.suppress(Exception):
                    transport.close()
                raise exc.with_target(target.display)
            self._transport = transport
            self._cleanups.append(transport.close)
        return self._transport

    @contextlib.contextmanager
    def open_transport(self) -> Iterator["Transport"]:
        yield self.transport()

    def parameters(self) -> "ParameterChannel":
        transport = self.transport()
        if transport.parameters is None:
            raise UsageError(
                f"target {self.target.display} offers no PROFIdrive parameter channel (PNUs); use 'sdo' commands "
                "or a sim/pn:// target"
            )
        return transport.parameters

    def objects(self) -> "ObjectChannel":
        transport = self.transport()
        if transport.objects is None:
            raise UsageError(
                f"target {self.target.display} offers no object channel (SDO); use 'pnu' commands or a "
                "sim/ecat/can target"
            )
        return transport.objects

    def close(self) -> None:
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
