"""CanopenObjectChannel: the ObjectChannel over a ``canopen`` SDO client.

The canopen library already implements the CiA 301 SDO client (expedited,
segmented and block transfer, toggle bits, CRC), so this module only chooses
the transfer, translates the library's exceptions into akdctl's errors and
collects emergencies:

* ``canopen.SdoAbortedError`` -> :class:`~akdctl.errors.SdoAborted` through
  :func:`~akdctl.channels.base.sdo_aborted`, worded by the catalogue and, for codes
  it lacks, by canopen's own table (exit 1);
* ``canopen.SdoCommunicationError`` (no answer, or an answer that does not
  fit) -> :class:`~akdctl.errors.NoAnswer` / :class:`~akdctl.errors.MalformedReply`
  (exit 3);
* ``can.CanError`` while sending -> :class:`~akdctl.errors.CommError`.

EMCY frames (COB-ID 0x80 + node) arrive through the node's
``canopen.emcy.EmcyConsumer`` and are queued as
:class:`akdctl.protocol.emcy.Emergency` for :meth:`take_emergencies`.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

from akdctl.channels.base import ObjectChannel, sdo_aborted, sdo_what
from akdctl.errors import CommError, MalformedReply, NoAnswer
from akdctl.protocol.emcy import Emergency

if TYPE_CHECKING:
    import canopen


class CanopenObjectChannel(ObjectChannel):
    """SDO upload/download on one ``canopen.RemoteNode``'s default SDO channel.

    ``timeout`` bounds each wait for a server response; ``retries`` is how often
    canopen repeats a request that got no answer.  ``block`` selects SDO block
    transfer; if the node answers a block request with something else, the
    channel falls back to normal transfers for the rest of the session (CiA 301
    lets a server decline block transfer).
    """

    def __init__(
        self,
        node: "canopen.RemoteNode",
        *,
        timeout: float = 2.0,
        retries: int = 2,
        block: bool = False,
        where: str = "",
    ) -> None:
        self.node = node
        self.sdo = node.sdo
        self.sdo.RESPONSE_TIMEOUT = timeout
        self.tries = self.sdo.MAX_RETRIES = max(1, retries + 1)
        self.timeout = timeout
        self.block = block
        self.where = where or f"CANopen node {node.id}"
        self.requests = 0
        self._emcy: list[Emergency] = []
        self._emcy_cond = threading.Condition()
        self._attached = True
        node.emcy.add_callback(self._on_emcy)

    # -- emergencies -------------------------------------------------------------------------------------------
    def _on_emcy(self, entry: "canopen.emcy.EmcyError") -> None:
        if not self._attached:
            return
        emcy = Emergency(int(entry.code), int(entry.register), bytes(entry.data)[:5].ljust(5, b"\0"))
        with self._emcy_cond:
            self._emcy.append(emcy)
            self._emcy_cond.notify_all()

    def take_emergencies(self) -> list[Emergency]:
        with self._emcy_cond:
            taken, self._emcy = self._emcy, []
        return taken

    def wait_emergencies(self, timeout: float) -> list[Emergency]:
        """Wait up to ``timeout`` s for at least one emergency, then drain the queue."""
        deadline = time.monotonic() + timeout
        with self._emcy_cond:
            while not self._emcy:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._emcy_cond.wait(left)
        return self.take_emergencies()

    def close(self) -> None:
        self.detach()

    def detach(self) -> None:
        """Stop collecting emergencies (the node object may outlive this channel)."""
        self._attached = False
        try:
            self.node.emcy.callbacks.remove(self._on_emcy)
        except ValueError:
            pass

    # -- SDO --------------------------------------------------------------------------------------------------
    def upload(self, index: int, subindex: int) -> bytes:
        what = sdo_what("upload", index, subindex)
        self.requests += 1
        if self.block:
            try:
                return self._call(what, self._block_upload, index, subindex)
            except _BlockDeclined:
                self.block = False
        return self._call(what, self.sdo.upload, index, subindex)

    def download(self, index: int, subindex: int, data: bytes) -> None:
        what = sdo_what("download", index, subindex)
        self.requests += 1
        data = bytes(data)
        if self.block:
            try:
                self._call(what, self._block_download, index, subindex, data)
                return
            except _BlockDeclined:
                self.block = False
        self._call(what, self.sdo.download, index, subindex, data)

    def _block_upload(self, index: int, subindex: int) -> bytes:
        stream = self._open_block(index, subindex, "rb")
        with stream:
            return bytes(stream.read())

    def _block_download(self, index: int, subindex: int, data: bytes) -> None:
        stream = self._open_block(index, subindex, "wb", size=len(data))
        with stream:
            view = memoryview(data)
            while view:
                sent = stream.write(view[:7])
                if not sent:
                    raise MalformedReply(f"SDO block download of {len(data)} bytes to {self.where} stalled")
                view = view[sent:]

    def _open_block(self, index: int, subindex: int, mode: str, size: int | None = None):  # noqa: ANN202
        from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

        try:
            return self.sdo.open(index, subindex, mode, buffering=0, size=size, block_transfer=True)
        except SdoAbortedError as exc:
            if exc.code == 0x05040001:  # "command specifier not valid": the server has no block transfer
                raise _BlockDeclined() from None
            raise
        except SdoCommunicationError as exc:
            if "Unexpected response" in str(exc):
                raise _BlockDeclined() from None
            raise

    def _call(self, what: str, func, *args):  # noqa: ANN001, ANN202
        """Run one canopen SDO call; every library failure becomes an akdctl error."""
        import can
        from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

        try:
            return func(*args)
        except SdoAbortedError as exc:
            raise sdo_aborted(int(exc.code), what, where=self.where, fallback=SdoAbortedError.CODES) from None
        except SdoCommunicationError as exc:
            text = str(exc)
            if "No SDO response" in text or "timed out" in text.lower():
                raise NoAnswer(f"no answer from {self.where} to SDO {what} ({self.tries} tries of {self.timeout:g} s)") from None
            raise MalformedReply(f"unexpected reply from {self.where} to SDO {what}: {text}") from None
        except can.CanError as exc:
            raise CommError(f"CAN bus error during SDO {what} on {self.where}: {exc}") from None
        except RuntimeError as exc:  # canopen: "Not connected to CAN bus" / network gone
            raise CommError(f"CAN bus not usable for SDO {what} on {self.where}: {exc}") from None


class _BlockDeclined(Exception):
    """The server answered a block initiate with something else: use normal transfers."""
