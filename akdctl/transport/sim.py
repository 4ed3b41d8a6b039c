"""The ``sim`` transport: the built-in simulated AKD, in process, over real codecs.

The simulator is never a shortcut around the wire formats: the parameter
channel sends PROFIdrive base-mode request bytes to the simulated parameter
manager, and the object channel sends EtherCAT CoE mailboxes to the simulated
SDO server, exactly as the PROFINET and EtherCAT transports do. ``--trace``
shows those bytes.
"""

from __future__ import annotations

from collections import deque

from akdctl.channels.base import ObjectChannel
from akdctl.sim.drive import SimDrive
from akdctl.transport.base import LinkOptions, MailboxLink, RecordLink, Transport
from akdctl.transport.target import Target


class SimRecordLink(RecordLink):
    """BMP request bytes in, BMP response bytes out, via the simulated parameter manager."""

    def __init__(self, drive: SimDrive, options: LinkOptions) -> None:
        self.drive = drive
        self.options = options

    def exchange(self, request: bytes) -> bytes:
        tracer = self.options.tracer
        tracer.frame("tx", "bmp", request, note=f"sim:{self.drive.name}")
        response = self.drive.handle_bmp(request)
        tracer.frame("rx", "bmp", response, note=f"sim:{self.drive.name}")
        return response


class SimMailboxLink(MailboxLink):
    """EtherCAT mailboxes to and from the simulated SDO server."""

    mailbox_size = 512

    def __init__(self, drive: SimDrive, options: LinkOptions) -> None:
        self.drive = drive
        self.options = options
        self._pending: deque[bytes] = deque()

    def send(self, mailbox: bytes) -> None:
        self.options.tracer.frame("tx", "mailbox", mailbox, note=f"sim:{self.drive.name}")
        self._pending.extend(self.drive.handle_mailbox(mailbox))

    def receive(self, timeout: float) -> bytes | None:
        if not self._pending:
            return None
        reply = self._pending.popleft()
        self.options.tracer.frame("rx", "mailbox", reply, note=f"sim:{self.drive.name}")
        return reply


class _LazyCoeChannel(ObjectChannel):
    """The CoE SDO client, built on first use so PNU-only commands never import the CoE codecs."""

    def __init__(self, link: SimMailboxLink, options: LinkOptions) -> None:
        self._link = link
        self._options = options
        self._channel: ObjectChannel | None = None

    @property
    def channel(self) -> ObjectChannel:
        if self._channel is None:
            from akdctl.channels.coe_sdo import CoeObjectChannel

            self._channel = CoeObjectChannel(self._link, timeout=self._options.timeout, retries=self._options.retries)
        return self._channel

    @property
    def requests(self) -> int:  # type: ignore[override]
        return self._channel.requests if self._channel is not None else 0

    def upload(self, index: int, subindex: int) -> bytes:
        return self.channel.upload(index, subindex)

    def download(self, index: int, subindex: int, data: bytes) -> None:
        self.channel.download(index, subindex, data)

    def take_emergencies(self) -> list:  # type: ignore[type-arg]
        return self.channel.take_emergencies()

    def object_list(self) -> list[int]:
        return self.channel.object_list()

    def __getattr__(self, name: str) -> object:
        return getattr(self.channel, name)


class SimTransport(Transport):
    """``sim`` / ``sim://NAME``: a persisted simulated AKD offering both channels."""

    scheme = "sim"

    def __init__(self, target: Target, options: LinkOptions) -> None:
        super().__init__(target, options)
        self.drive = SimDrive(target.host or "default")
        self.drive_profile = target.query.get("drive")

    def open(self) -> None:
        from akdctl.channels.bmp import BmpParameterChannel

        self.record_link = SimRecordLink(self.drive, self.options)
        self.mailbox_link = SimMailboxLink(self.drive, self.options)
        self.parameters = BmpParameterChannel(self.record_link)
        self.objects = _LazyCoeChannel(self.mailbox_link, self.options)

    def close(self) -> None:
        self.parameters = None
        self.objects = None

    def al_state(self) -> str | None:
        """The simulated drive's EtherCAT AL state (its ``pdo`` component), so commands whose rules
        depend on it (PDO mapping only in PRE-OP) can check before writing; None if unknown."""
        with self.drive.transaction() as model:
            return str(model.pdo.al_state)
