"""The link contracts: what a transport hands up so a channel can be built over it.

Why a module of its own: a *link* is the seam between two layers. Transports
(below) implement it and only move bytes; channels (above) speak a protocol over
it (batching, reference checks, SDO segmentation, retries, written once). Neither
side imports the other: both import this module, which imports nothing of akdctl.
:class:`akdctl.connection.Connection` is the one place that pairs a transport's
links with channels and wraps each link in the tracer.

A transport offers any of:

* a :class:`RecordLink` -- PROFIdrive base-mode request bytes in, response bytes
  out (PROFINET record 47, the simulator) -> the PROFIdrive parameter channel;
* a :class:`MailboxLink` -- EtherCAT mailboxes (raw master, ETG.8200 gateway, the
  simulator) -> the CoE SDO channel;
* a :class:`MessageLink` -- CIP explicit messages (EtherNet/IP UCMM) -> the CIP
  attribute channel;
* a native SDO client a library already implements (:class:`CanopenSdoClient`,
  :class:`SoemSdoClient`) -> the adapter channel for that library.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar


class RecordLink(ABC):
    """Carries one PROFIdrive base-mode request to the parameter manager and
    returns its response bytes (PROFINET: write record 47 then read record 47).

    Raises :class:`akdctl.errors.CommError` subclasses on link failures and
    :class:`akdctl.errors.RecordError` on record-layer refusals. Links do not
    trace the request/response bytes: the Connection's traced wrapper does.
    """

    max_record: int = 240
    #: The PROFIdrive axis (drive object) the requests address (``pn://...?axis=N``).
    axis: int = 0
    #: Shown after each traced frame (which drive or record the bytes went to).
    trace_note: str = ""

    @abstractmethod
    def exchange(self, request: bytes) -> bytes: ...


class MailboxLink(ABC):
    """Carries EtherCAT mailbox frames (6-byte mailbox header + payload)."""

    mailbox_size: int = 512
    #: The address field the SDO client writes into each mailbox header (the gateway's station; 0 on a bus).
    mailbox_address: int = 0
    #: Shown after each traced frame.
    trace_note: str = ""
    #: True when the transport's own wire trace already shows every mailbox byte for byte (an ETG.8200
    #: datagram is the mailbox behind a 2-byte header), so the Connection does not trace it twice.
    traced_on_wire: ClassVar[bool] = False

    @abstractmethod
    def send(self, mailbox: bytes) -> None: ...

    @abstractmethod
    def receive(self, timeout: float) -> bytes | None:
        """Next mailbox from the slave, or ``None`` if nothing came in ``timeout`` s."""


class MessageLink(ABC):
    """Carries one CIP explicit message (EtherNet/IP unconnected messaging) and returns the CIP reply.

    ``req`` is a :class:`akdctl.protocol.cip.Request`; the reply a :class:`akdctl.protocol.cip.Response`
    whatever its general status (the channel turns a refusal into words). Link failures raise
    :class:`akdctl.errors.CommError` subclasses. The transport traces its own wire frames (TCP segments
    for ``--pcap``), so the Connection does not wrap this link.
    """

    @abstractmethod
    def request(self, req: Any, extra_items: tuple[Any, ...] = ()) -> Any: ...


@dataclass(frozen=True)
class CanopenSdoClient:
    """A ``canopen.RemoteNode`` whose SDO client the CANopen adapter channel drives."""

    node: Any
    where: str
    block: bool = False


@dataclass(frozen=True)
class SoemSdoClient:
    """A pysoem slave whose ``sdo_read``/``sdo_write`` the SOEM adapter channel drives."""

    slave: Any
    where: str


NativeSdoClient = CanopenSdoClient | SoemSdoClient

__all__ = ["RecordLink", "MailboxLink", "MessageLink", "CanopenSdoClient", "SoemSdoClient", "NativeSdoClient"]
