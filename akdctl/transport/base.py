"""The transport contract: what every link to a drive offers.

A transport is opened for one CLI invocation (or one recipe run) and offers
one or both *channels*:

* a parameter channel (PROFIdrive base-mode parameter access, PNUs), and
* an object channel (CoE / CANopen SDO, index:subindex).

Transports that carry raw protocol bytes expose a *link* (:class:`RecordLink`
for BMP request/response bytes, :class:`MailboxLink` for EtherCAT mailboxes);
the generic channel implementations in :mod:`akdctl.channels` turn a link into a
channel, so batching, reference checking and SDO segmentation are written once.
A transport whose library already speaks SDO (CANopen via ``canopen``)
implements :class:`akdctl.channels.base.ObjectChannel` directly.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

from akdctl.transport.trace import NULL_TRACER, Tracer

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel, ParameterChannel
    from akdctl.transport.target import Target


@dataclass
class LinkOptions:
    """Settings every transport honours.

    ``timeout`` bounds every single wait (seconds); ``retries`` is how often a
    request may be repeated after a timeout where the protocol allows it.
    """

    timeout: float = 2.0
    retries: int = 2
    tracer: Tracer = field(default_factory=lambda: NULL_TRACER)
    verbose: int = 0


class RecordLink(ABC):
    """Carries one PROFIdrive base-mode request to the parameter manager and
    returns its response bytes (PROFINET: write record 47 then read record 47).

    Raises :class:`akdctl.errors.CommError` subclasses on link failures and
    :class:`akdctl.errors.RecordError` on record-layer refusals.
    """

    max_record: int = 240

    @abstractmethod
    def exchange(self, request: bytes) -> bytes: ...


class MailboxLink(ABC):
    """Carries EtherCAT mailbox frames (6-byte mailbox header + payload)."""

    mailbox_size: int = 512

    @abstractmethod
    def send(self, mailbox: bytes) -> None: ...

    @abstractmethod
    def receive(self, timeout: float) -> bytes | None:
        """Next mailbox from the slave, or ``None`` if nothing came in ``timeout`` s."""


class Transport(ABC):
    """One open connection to one drive.

    Subclasses set ``scheme`` and fill ``parameters`` and/or ``objects`` in
    :meth:`open`. ``close`` must be safe to call twice and after a failed open.
    """

    scheme: ClassVar[str] = ""

    def __init__(self, target: "Target", options: LinkOptions) -> None:
        self.target = target
        self.options = options
        self.parameters: "ParameterChannel | None" = None
        self.objects: "ObjectChannel | None" = None

    @abstractmethod
    def open(self) -> None: ...

    @abstractmethod
    def close(self) -> None: ...

    def __enter__(self) -> "Transport":
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def describe(self) -> str:
        """Human name of the target, shown with every result."""
        return self.target.display
