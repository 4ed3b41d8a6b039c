"""The ``sim`` transport: the built-in simulated AKD, in process, over real codecs.

The simulator is never a shortcut around the wire formats: the record link
carries PROFIdrive base-mode request bytes to the simulated parameter manager,
and the mailbox link carries EtherCAT CoE mailboxes to the simulated SDO server,
exactly as the PROFINET and EtherCAT transports do. ``--trace`` shows those
bytes (the Connection traces both links).
"""

from __future__ import annotations

from collections import deque

from akdctl.links import MailboxLink, RecordLink
from akdctl.sim.drive import SimDrive
from akdctl.transport.base import LinkOptions, Transport
from akdctl.transport.target import Target


class SimRecordLink(RecordLink):
    """BMP request bytes in, BMP response bytes out, via the simulated parameter manager."""

    trace_meta = {"proto": "sim"}  # no wire: --pcap wraps the blocks as a PROFINET device would carry them

    def __init__(self, drive: SimDrive) -> None:
        self.drive = drive
        self.trace_note = f"sim:{drive.name}"

    def exchange(self, request: bytes) -> bytes:
        from akdctl.sim.errors import RecordRefused

        try:
            return self.drive.handle_bmp(request)
        except RecordRefused as exc:  # the record write itself is refused, as over pn:// (docs/fidelity.md F1)
            from akdctl.catalog.texts import pnio_status_text
            from akdctl.errors import RecordError
            from akdctl.protocol import pnio

            status = pnio.rw_error(True, exc.code1)
            raise RecordError(f"sim:{self.drive.name}: write record 47 refused: {pnio_status_text(*status.encode())}",
                              code=status.value) from None


class SimMailboxLink(MailboxLink):
    """EtherCAT mailboxes to and from the simulated SDO server."""

    mailbox_size = 512
    trace_meta = {"proto": "sim"}  # no wire: --pcap wraps the mailboxes as an EtherCAT master would carry them

    def __init__(self, drive: SimDrive) -> None:
        self.drive = drive
        self.trace_note = f"sim:{drive.name}"
        self._pending: deque[bytes] = deque()

    def send(self, mailbox: bytes) -> None:
        self._pending.extend(self.drive.handle_mailbox(mailbox))

    def receive(self, timeout: float) -> bytes | None:
        return self._pending.popleft() if self._pending else None


class SimTransport(Transport):
    """``sim`` / ``sim://NAME``: a persisted simulated AKD offering a record link and a mailbox link."""

    scheme = "sim"

    def __init__(self, target: Target, options: LinkOptions) -> None:
        super().__init__(target, options)
        self.drive = SimDrive(target.host or "default")

    def open(self) -> None:
        self.record_link = SimRecordLink(self.drive)
        self.mailbox_link = SimMailboxLink(self.drive)

    def close(self) -> None:
        self.record_link = None
        self.mailbox_link = None

    @property
    def time_scale(self) -> float:
        """Seconds of the drive's virtual time per wall second (``sim speed``) as of its last transaction: the
        axis' waits poll that much faster (drive/polling.py). Transports of real drives have no such attribute."""
        meta = getattr(self.drive, "meta", None)
        return float(meta.get("time_scale", 1.0)) if isinstance(meta, dict) else 1.0

    def al_state(self) -> str | None:
        """The simulated drive's EtherCAT AL state (its ``pdo`` component), so commands whose rules
        depend on it (PDO mapping only in PRE-OP) can check before writing; None if unknown."""
        with self.drive.transaction() as model:
            return str(model.pdo.al_state)
