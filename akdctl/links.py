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

import time
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from typing import Literal

    from akdctl.protocol import cip, enip
    from akdctl.protocol.gateway_sdo import UploadFrames


class Deadline:
    """The end of one request's wait: every attempt, repeat and segment of the request fits before it.

    Why one object handed down instead of a timeout per wait: a wait per layer multiplies (three attempts
    of two seconds were six seconds at ``--timeout 2``); one end time is shared by everyone who waits for
    the same request, and each attempt takes its share of what is left.
    """

    __slots__ = ("at", "total", "attempts", "probe")

    def __init__(self, total: float, attempts: int = 1, probe: bool = False) -> None:
        # conditionals, not max(): this runs once per request on every hot path
        total = total if total.__class__ is float else float(total)
        self.total = total = total if total > 0.0 else 0.0
        attempts = attempts if attempts.__class__ is int else int(attempts)
        self.attempts = attempts if attempts > 1 else 1
        self.probe = probe  # the command has no time left: this request only checks whether the drive is back
        self.at = time.monotonic() + total

    def remaining(self) -> float:
        """Seconds left (0 once passed)."""
        left = self.at - time.monotonic()
        return left if left > 0.0 else 0.0

    def expired(self) -> bool:
        return time.monotonic() >= self.at

    def share(self, attempts_left: int) -> float:
        """How long one of ``attempts_left`` remaining attempts may wait: an equal part of what is left."""
        return self.remaining() / max(1, attempts_left)

    def describe(self) -> str:
        """"1 s (3 attempts of 0.33 s)": what a request that got no answer did, for its message."""
        if self.probe:
            return (f"{self.total:g} s (the command had already waited its whole timeout for this drive: "
                    "later requests only check whether it is back)")
        if self.attempts == 1:
            return f"{self.total:g} s"
        return f"{self.total:g} s ({self.attempts} attempts of {self.total / self.attempts:.2g} s)"


class _Request:
    """``with budget.request() as deadline``: one request's deadline, and the Budget's count afterwards.

    A class rather than a generator context manager: it runs once per request on every hot path.
    """

    __slots__ = ("budget", "attempts", "deadline", "outer", "at")

    def __init__(self, budget: "Budget", attempts: int | None, at: float | None = None) -> None:
        self.budget = budget
        self.attempts = attempts
        self.outer = False
        self.at = at

    def __enter__(self) -> Deadline:
        budget = self.budget
        current = budget._current
        if current is not None:
            return current  # nested: the outer request's deadline
        self.outer = True
        left = budget.timeout - budget.silent
        probe = left < budget.timeout * PROBE
        deadline = Deadline(budget.timeout * PROBE if probe else left,
                            budget.attempts if self.attempts is None else self.attempts, probe)
        if self.at is not None:
            deadline.at = self.at   # a request begun on the fast path (Budget.lone): its end time stays
        budget._current = self.deadline = deadline
        return deadline

    def __exit__(self, kind: object, exc: BaseException | None, tb: object) -> None:
        if not self.outer:
            return
        budget = self.budget
        budget._current = None
        if exc is not None and unanswered(exc):
            budget.silent = min(budget.timeout, budget.silent + self.deadline.total)  # all its time went in vain
        else:
            budget.silent = 0.0


_monotonic = time.monotonic

#: The share of ``timeout`` a request waits once the command has waited all of it for a silent drive.
PROBE = 0.1


class Budget:
    """How long a command waits for its drive: ``--timeout`` and ``--retries``, carried by the Connection.

    * ``timeout`` bounds each request's total wait -- one SDO transfer with all its segments and repeats,
      one PROFIdrive batch with both of its RPCs -- not each single wait;
    * ``retries`` is how often a request that got no answer is sent again within that bound, where the
      protocol makes the repeat harmless (reads; PNIO calls the device recognises by their sequence number);
    * the command as a whole waits about ``timeout`` for a drive that does not answer: the time of
      requests that ended unanswered is added up (an answer clears it), a request gets only what is left,
      and once nothing is left each later request is still sent -- a stop must go out -- but waits only
      a tenth of ``timeout`` (:data:`PROBE`), enough for a drive that is back to answer and clear the count.

    Nested requests (a channel's request carried by a transport that also waits) share the outer deadline.
    Links and channels import this module only, so both layers read one rule.
    """

    def __init__(self, timeout: float = 2.0, retries: int = 2) -> None:
        if not timeout > 0:
            raise ValueError(f"timeout must be positive (got {timeout})")
        self.timeout = float(timeout)
        self.retries = max(0, int(retries))
        self.silent = 0.0  # seconds spent in requests that ended without an answer, since the last answer
        self._current: Deadline | None = None

    @property
    def attempts(self) -> int:
        return self.retries + 1

    def request(self, attempts: int | None = None, at: float | None = None) -> "_Request":
        """The deadline of one request, as a context manager (``attempts`` defaults to ``retries + 1``).
        ``at``: the end time :meth:`lone` gave a request that has begun on the fast path and now needs its
        Deadline (more receives, or an error to word and count): the same request, the same end."""
        return _Request(self, attempts, at)

    def lone(self) -> float | None:
        """The end time (``time.monotonic()`` seconds) of a single-attempt request that starts now, when the
        Deadline object is not needed for it: no request encloses it and no unanswered time is counted, so the
        request gets the whole ``timeout`` and an answer leaves the count as it is (at 0). ``None`` otherwise:
        then the request takes :meth:`request`. A request begun here that needs more than one receive, or
        fails, continues in ``with budget.request(1, at=...)``, which counts it as any other request.

        Why: a TCP client's request/response costs a few microseconds of CPU; a context manager and two objects
        per request were a third of it (issue 29's ASCII row).
        """
        if self._current is None and not self.silent:
            return _monotonic() + self.timeout
        return None

    def left(self) -> float:
        """What a request started now would get (the rest of ``timeout``, or the probe share)."""
        return max(self.timeout - self.silent, self.timeout * PROBE)

    @property
    def exhausted(self) -> bool:
        """True once the command has waited ``timeout`` for a drive that did not answer."""
        return self.silent >= self.timeout


def unanswered(exc: BaseException) -> bool:
    """Whether an error means the drive did not answer at all: an ``akdctl.errors`` error of kind
    ``timeout``, or one that says so itself (``exc.unanswered``, set on an unknown outcome)."""
    flag = getattr(exc, "unanswered", None)
    return bool(flag) if flag is not None else getattr(exc, "kind", None) == "timeout"


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
    #: A capture sink's hint about the wire (the simulator's links: there is none), or None.
    trace_meta: dict[str, str] | None = None

    @abstractmethod
    def exchange(self, request: bytes) -> bytes: ...


class MailboxLink(ABC):
    """Carries EtherCAT mailbox frames (6-byte mailbox header + payload)."""

    mailbox_size: int = 512
    #: The address field the SDO client writes into each mailbox header (the gateway's station; 0 on a bus).
    mailbox_address: int = 0
    #: Shown after each traced frame.
    trace_note: str = ""
    #: A capture sink's hint about the wire (the simulator's links: there is none), or None.
    trace_meta: dict[str, str] | None = None
    #: True when the transport's own wire trace already shows every mailbox byte for byte (an ETG.8200
    #: datagram is the mailbox behind a 2-byte header), so the Connection does not trace it twice.
    traced_on_wire: ClassVar[bool] = False

    @abstractmethod
    def send(self, mailbox: bytes) -> None: ...

    @abstractmethod
    def receive(self, timeout: float) -> bytes | None:
        """Next mailbox from the slave, or ``None`` if nothing came in ``timeout`` s."""

    #: True when the link sends whole pre-encoded frames (:meth:`upload_frames`, :meth:`quick_request`,
    #: :meth:`frame_mailbox`: the ETG.8200 gateway's datagrams), so the SDO client's poll skips the layer-by-layer
    #: encoding and decoding (issue 29). False: the client uses :meth:`send` and :meth:`receive` only.
    quick_frames: ClassVar[bool] = False

    def upload_frames(self, index: int, subindex: int) -> "UploadFrames":
        """The pre-encoded frames of an upload of ``index:subindex`` (only where :attr:`quick_frames`)."""
        raise NotImplementedError

    def quick_request(self, frame: bytes, at: float, wait: float) -> "bytes | None | Literal[False]":
        """Send a whole frame and return the first frame that arrives before the monotonic time ``at`` (about now +
        ``wait``) as it came (None: none did); False when the link cannot take the quick way now (then nothing was
        sent). Only where :attr:`quick_frames`; failures raise as :meth:`send` and :meth:`receive` raise."""
        return False

    def frame_mailbox(self, frame: bytes) -> bytes | None:
        """The mailbox in a frame :meth:`quick_request` returned, judged as :meth:`receive` judges what it reads
        (None: a frame :meth:`receive` would have read past)."""
        raise NotImplementedError


class MessageLink(ABC):
    """Carries one CIP explicit message (EtherNet/IP unconnected messaging) and returns the CIP reply.

    ``req`` is a :class:`akdctl.protocol.cip.Request`; the reply a :class:`akdctl.protocol.cip.Response`
    whatever its general status (the channel turns a refusal into words). Link failures raise
    :class:`akdctl.errors.CommError` subclasses. The transport traces its own wire frames (TCP segments
    for ``--pcap``), so the Connection does not wrap this link.
    """

    @abstractmethod
    def request(self, req: "cip.Request", extra_items: "tuple[enip.Item, ...]" = ()) -> "cip.Response": ...


class CanopenSdoClient(Record):
    """A ``canopen.RemoteNode`` whose SDO client the CANopen adapter channel drives.

    ``reader``: the bus's :class:`akdctl.io.can_reader.BusReader` when the transport reads the bus with one (the
    channel then waits for its answers through it, reading the bus itself); None: answers come from the library's
    receive thread."""

    __slots__ = ("node", "where", "block", "reader")

    def __init__(self, node: Any, where: str, block: bool = False, reader: Any = None) -> None:
        self.node = node
        self.where = where
        self.block = block
        self.reader = reader


class SoemSdoClient(Record):
    """A pysoem slave whose ``sdo_read``/``sdo_write`` the SOEM adapter channel drives."""

    __slots__ = ("slave", "where")

    def __init__(self, slave: Any, where: str) -> None:
        self.slave = slave
        self.where = where


NativeSdoClient = CanopenSdoClient | SoemSdoClient


class CommandLink(ABC):
    """The AKD's own ASCII command channel (the service port's "Telnet", ``akd://``): one command line in,
    the drive's reply text out -- without the echo of the line and without the ``-->`` prompt.

    A reply that begins with ``Error:`` raises :class:`akdctl.errors.DriveError` (a subclass naming the drive's
    text); link failures raise :class:`akdctl.errors.CommError` subclasses; every wait is bounded by the
    command's timeout. Issue 24.
    """

    @abstractmethod
    def command(self, line: str) -> str: ...


class RegisterLink(ABC):
    """Modbus holding registers (``mb://``): read and write 16-bit registers by address (issue 24).

    Refusals (Modbus exception responses) raise :class:`akdctl.errors.DriveError` subclasses, link failures
    :class:`akdctl.errors.CommError` subclasses.
    """

    @abstractmethod
    def read_registers(self, address: int, count: int) -> list[int]: ...

    @abstractmethod
    def write_registers(self, address: int, values: list[int]) -> None: ...

__all__ = ["Budget", "Deadline", "RecordLink", "MailboxLink", "MessageLink", "CanopenSdoClient", "SoemSdoClient", "NativeSdoClient",
           "CommandLink", "RegisterLink"]
