"""The transport contract: one open connection to one drive, moving bytes.

A transport opens the link to the drive and offers what it carries as *links*
(:mod:`akdctl.links`): ``record_link`` (PROFIdrive request/response bytes),
``mailbox_link`` (EtherCAT mailboxes) and/or ``sdo_client`` (an SDO client a
library already implements: canopen, pysoem). It never builds a channel and never
traces the bytes of those links: :class:`akdctl.connection.Connection` builds the
channels over the links and wraps each link in the session's tracer. A transport
traces only the wire frames nobody else sees (DCE/RPC datagrams, EtherCAT frames,
gateway datagrams, CAN frames), to ``options.tracer``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, ClassVar

from akdctl.links import Budget
from akdctl.transport.trace import NULL_TRACER, Tracer

if TYPE_CHECKING:
    from akdctl.links import CommandLink, MailboxLink, MessageLink, NativeSdoClient, RecordLink, RegisterLink
    from akdctl.transport.ethercat_raw import ProcessDataCycle
    from akdctl.transport.target import Target


class LinkOptions:
    """Settings every transport honours.

    ``timeout`` bounds each request's total wait, repeats included (seconds); ``retries`` is how
    often a request may be repeated after no answer where the protocol makes a repeat harmless;
    ``budget`` is the one :class:`~akdctl.links.Budget` of the command built from both, shared by
    the Connection's channels and the transport; ``tracer`` receives the transport's wire frames
    (the Connection traces the links). (A plain class: a dataclass costs more to define at every start.)
    """

    __slots__ = ("timeout", "retries", "tracer", "verbose", "budget")

    def __init__(self, timeout: float = 2.0, retries: int = 2, tracer: Tracer | None = None, verbose: int = 0) -> None:
        self.timeout = timeout
        self.retries = retries
        self.tracer: Tracer = NULL_TRACER if tracer is None else tracer
        self.verbose = verbose
        self.budget = Budget(timeout, retries)

    def __repr__(self) -> str:
        return (f"LinkOptions(timeout={self.timeout!r}, retries={self.retries!r}, tracer={self.tracer!r}, "
                f"verbose={self.verbose!r})")

    def __eq__(self, other: object) -> bool:
        if other.__class__ is not self.__class__:
            return NotImplemented
        return ((self.timeout, self.retries, self.tracer, self.verbose, self.budget)
                == (other.timeout, other.retries, other.tracer, other.verbose, other.budget))  # type: ignore[attr-defined]

    __hash__ = None  # type: ignore[assignment]


class Transport(ABC):
    """One open connection to one drive.

    Subclasses set ``scheme`` and, in :meth:`open`, fill ``record_link``,
    ``mailbox_link``, ``message_link`` and/or ``sdo_client``. ``close`` must be safe
    to call twice and after a failed open. A transport holds no channel: the
    :class:`~akdctl.connection.Connection` builds them over these links.
    """

    scheme: ClassVar[str] = ""

    def __init__(self, target: "Target", options: LinkOptions) -> None:
        self.target = target
        self.options = options
        self.record_link: "RecordLink | None" = None
        self.mailbox_link: "MailboxLink | None" = None
        self.sdo_client: "NativeSdoClient | None" = None
        self.message_link: "MessageLink | None" = None
        #: The AKD's ASCII command channel (akd://) and Modbus registers (mb://), issue 24.
        self.command_link: "CommandLink | None" = None
        self.register_link: "RegisterLink | None" = None

    @abstractmethod
    def open(self) -> None: ...

    # ---------------------------------------------------------------- declared capabilities, neutral defaults
    # What only some transports can tell is declared here with the answer of a transport that cannot
    # (as python-can's BusABC declares ``state``), so nobody asks ``getattr(transport, ...)``: the
    # Connection reads these and hands them up; drive/ never sees a transport.

    @property
    def time_scale(self) -> float:
        """Seconds of the drive's time per wall-clock second: 1 for every real drive (the simulator
        under ``sim speed`` runs faster, and the axis polls faster with it)."""
        return 1.0

    def al_state(self) -> str | None:
        """The EtherCAT AL state as the slave reports it now ('PREOP', 'OP', 'SAFEOP+ERR'), or None
        where there is none or it is unknown (PROFINET, CANopen, EtherNet/IP)."""
        return None

    def read_im0(self) -> dict[str, object] | None:
        """The device's I&M0 record in JSON form where the network defines one (PROFINET), else None."""
        return None

    #: Whether this host is the bus master of cyclic process data with the target's slave (``ecat://``):
    #: :meth:`process_data` then gives the exchange. A class attribute, so it is known before the target opens.
    cyclic_master: ClassVar[bool] = False

    def process_data(self, rx_bytes: int, tx_bytes: int) -> "ProcessDataCycle | None":
        """The cyclic exchange of ``rx_bytes`` outputs and ``tx_bytes`` inputs with the slave, not yet configured;
        None where this host is no such master (:attr:`cyclic_master`)."""
        return None

    @abstractmethod
    def close(self) -> None: ...

    @property
    def display_name(self) -> str:
        """Human name of the target, shown with results (a transport may add what it resolved)."""
        return self.target.display
