"""CanopenObjectChannel: the ObjectChannel over a ``canopen`` SDO client.

The canopen library already implements the CiA 301 SDO client (expedited,
segmented and block transfer, toggle bits, CRC), so this module only chooses
the transfer, translates the library's exceptions into akdctl's errors and
collects emergencies. One exception, for the request a poll makes again and
again: a normal upload is framed by akdctl's own SDO codec and takes its reply
straight from the node's SDO response COB-ID (``_on_reply`` into a C queue),
without canopen's stream and queue objects per request, and waits for it in the
transport's :class:`~akdctl.io.can_reader.BusReader`, which reads the bus in the
caller's thread meanwhile (no hand-over between threads per answer); downloads and
block transfers stay canopen's, with the receive thread reading for them. The library's errors become akdctl's:

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

import queue
import threading
import time
from typing import TYPE_CHECKING, TypeVar

from akdctl.channels.base import MAX_UPLOAD, ObjectChannel, confirm_write, sdo_aborted, sdo_what
from akdctl.errors import AkdError, CommError, MalformedReply, NoAnswer
from akdctl.links import Budget, Deadline
from akdctl.protocol import coe
from akdctl.protocol.emcy import Emergency
from akdctl.protocol.nmt import state_name

if TYPE_CHECKING:
    import canopen

    from akdctl.io.can_reader import BusReader

T = TypeVar("T")


class CanopenObjectChannel(ObjectChannel):
    """SDO upload/download on one ``canopen.RemoteNode``'s default SDO channel.

    Each transfer waits within one deadline of the command's :class:`~akdctl.links.Budget`:
    canopen's per-response timeout is set to an attempt's share of it before every call. An upload
    is repeated by canopen up to ``retries`` times; a **download is sent once** (canopen would send
    the same request again after a timeout, applying a write twice if only its answer was lost):
    a lost answer is confirmed by reading back (:func:`~akdctl.channels.base.confirm_write`).
    Uploads are read segment by segment and capped at the declared size and :data:`MAX_UPLOAD`.
    ``block`` selects SDO block transfer; if the node answers a block request with something
    else, the channel falls back to normal transfers for the rest of the session (CiA 301 lets
    a server decline block transfer).
    """

    def __init__(
        self,
        node: "canopen.RemoteNode",
        *,
        budget: Budget | None = None,
        timeout: float = 2.0,
        retries: int = 2,
        block: bool = False,
        where: str = "",
        max_upload: int = MAX_UPLOAD,
        reader: "BusReader | None" = None,
    ) -> None:
        self.node = node
        # Where a normal upload waits for its answer: with the transport's BusReader, reading the bus in this thread
        # (one wake-up per answer instead of three); else the receive thread hands the answer over.
        self._reader = reader
        self._wait = reader.wait if reader is not None else _handed_over
        self.sdo = node.sdo
        self.budget = budget if budget is not None else Budget(timeout, retries)
        self.block = block
        self.where = where or f"CANopen node {node.id}"
        self.max_upload = max_upload
        self.requests = 0
        self._emcy: list[Emergency] = []
        self._emcy_cond = threading.Condition()
        self._attached = True
        node.emcy.add_callback(self._on_emcy)
        # Normal uploads take their replies straight from the SDO response COB-ID into a C queue (no Python lock,
        # condition or queue object per reply, as canopen's ``SdoClient.responses`` needs): the channel's callback
        # stands in for ``sdo.on_response`` on the network and hands replies on to canopen's client whenever one of
        # canopen's own transfers (downloads, block transfers) is running instead.
        self._replies: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        self._taking = False  # an upload of ours waits for replies
        self._subscribed = False
        network = node.network
        if network is not None:
            try:
                network.unsubscribe(self.sdo.tx_cobid, self.sdo.on_response)
            except (KeyError, ValueError):
                pass
            network.subscribe(self.sdo.tx_cobid, self._on_reply)
            self._subscribed = True

    @property
    def timeout(self) -> float:
        return self.budget.timeout

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
        self._hand_back()
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
        """Stop collecting emergencies and give SDO replies back to canopen's client (the node object may outlive
        this channel)."""
        self._attached = False
        try:
            self.node.emcy.callbacks.remove(self._on_emcy)
        except ValueError:
            pass
        network = self.node.network
        if self._subscribed and network is not None:
            self._subscribed = False
            try:
                network.unsubscribe(self.sdo.tx_cobid, self._on_reply)
            except (KeyError, ValueError):
                pass
            network.subscribe(self.sdo.tx_cobid, self.sdo.on_response)

    def _on_reply(self, can_id: int, data: bytearray, timestamp: float) -> None:
        """The SDO response COB-ID's one subscriber (called by canopen's receive thread)."""
        if self._taking:
            self._replies.put(bytes(data))
        else:
            self.sdo.on_response(can_id, data, timestamp)

    # -- SDO --------------------------------------------------------------------------------------------------
    def upload(self, index: int, subindex: int) -> bytes:
        self.requests += 1
        with self.budget.request() as deadline:
            if self.block:
                self._pace(deadline, deadline.attempts)
                try:
                    return self._call(sdo_what("upload", index, subindex), deadline, self._read, index, subindex,
                                      True, deadline)
                except _BlockDeclined:
                    self.block = False
            return self._upload(index, subindex, deadline)

    def download(self, index: int, subindex: int, data: bytes) -> None:
        what = sdo_what("download", index, subindex)
        self.requests += 1
        data = bytes(data)
        with self.budget.request() as deadline:
            self._pace(deadline, 1, share=deadline.attempts)  # sent once; the rest of the time reads back
            try:
                if self.block:
                    try:
                        self._call(what, deadline, self._block_download, index, subindex, data)
                        return
                    except _BlockDeclined:
                        self.block = False
                self._call(what, deadline, self.sdo.download, index, subindex, data)
            except NoAnswer as exc:
                attempts = deadline.attempts - 1

                def read_back() -> bytes:
                    return self._upload(index, subindex, deadline, attempts)

                confirm_write(exc.message, data, None if attempts < 1 or deadline.expired() else read_back,
                              {"index": index, "subindex": subindex})

    def _hand_back(self) -> None:
        """Before a wait that relies on the receive thread (canopen's own transfers, emergencies): it reads now."""
        if self._reader is not None:
            self._reader.hand_back()

    def _pace(self, deadline: Deadline, tries: int, share: int | None = None) -> None:
        """canopen's per-response timeout and repeats for its next call (block transfers, downloads): a share of
        what is left. The receive thread reads for canopen's client."""
        self._hand_back()
        self.sdo.MAX_RETRIES = max(1, tries)
        self.sdo.RESPONSE_TIMEOUT = max(0.001, deadline.share(share or tries))

    def _upload(self, index: int, subindex: int, deadline: Deadline, tries: int | None = None) -> bytes:
        """A normal (expedited or segmented) upload, framed by our own SDO codec (:mod:`akdctl.protocol.coe`, the
        same CiA 301 frames CoE carries) and answered through :meth:`_on_reply`: no stream objects, one request
        for an expedited value. A reply that is not for this request (a late answer to an earlier one, another
        client's) is skipped and the wait goes on within the deadline; a wrong toggle bit aborts."""
        tries = deadline.attempts if tries is None else tries
        first = self._exchange(coe.pack_upload_initiate(index, subindex), deadline, tries, index, subindex, False)
        if isinstance(first, bytes):
            return first  # expedited: the value itself
        assert isinstance(first, coe.SdoUploadResponse)
        size = first.size
        if first.expedited:
            return first.data
        if size is not None and size > self.max_upload:
            self._abort(coe.ABORT_OUT_OF_MEMORY, index, subindex)
            raise MalformedReply(f"{self.where} announces {size} bytes for SDO {sdo_what('upload', index, subindex)}"
                                 f", more than the {self.max_upload} bytes akdctl accepts from one object "
                                 "(transfer aborted)")
        limit = self.max_upload if size is None else size
        data = bytearray()
        toggle = 0
        while True:
            if deadline.expired():
                self._abort(coe.ABORT_TIMEOUT, index, subindex)
                raise NoAnswer(f"SDO {sdo_what('upload', index, subindex)} from {self.where} did not finish "
                               f"within {deadline.describe()} (transfer aborted)")
            segment = self._exchange(coe.encode_sdo(coe.SdoUploadSegment(toggle)), deadline, tries, index, subindex,
                                     True)
            assert isinstance(segment, coe.SdoUploadSegmentResponse)
            if segment.toggle != toggle:
                self._abort(coe.ABORT_TOGGLE, index, subindex)
                raise MalformedReply(f"{self.where} answered SDO {sdo_what('upload', index, subindex)} with a "
                                     "segment of the wrong toggle bit (transfer aborted)")
            data += segment.data
            if len(data) > limit:
                self._abort(coe.ABORT_LENGTH_MISMATCH, index, subindex)
                raise MalformedReply(f"{self.where} sent more than the {limit} bytes "
                                     f"{'it announced' if size is not None else 'akdctl accepts'} for SDO "
                                     f"{sdo_what('upload', index, subindex)} (transfer aborted)")
            if segment.last:
                return bytes(data)
            toggle ^= 1

    def _exchange(self, request: bytes, deadline: Deadline, tries: int, index: int, subindex: int,
                  segment: bool) -> "bytes | coe.SdoMessage":
        """Send ``request`` (again after a silent share of the deadline, ``tries`` times in all) and return the
        first reply that fits it: the value of an expedited upload response for ``index:subindex`` as bytes, else
        the upload response (``segment`` False) or upload segment response (``segment`` True) decoded. Replies
        that do not fit are skipped until the deadline; an abort raises :class:`~akdctl.errors.SdoAborted`; after
        the last silent try the transfer is aborted (as canopen's client does) and :class:`NoAnswer` raised."""
        replies, wait = self._replies, self._wait
        while not replies.empty():  # answers that came after their own request's deadline
            replies.get_nowait()
        self._taking = True
        try:
            for left in range(max(1, tries), 0, -1):
                self._send(request, index, subindex)
                try:
                    reply = wait(replies, deadline.share(left))  # never below 0
                except queue.Empty:
                    continue
                except Exception as exc:  # reading the bus in this thread failed (python-can's error)
                    raise self._read_failed(exc, index, subindex) from None
                while True:
                    if not segment:
                        value = coe.expedited_upload_value(reply, index, subindex)
                        if value is not None:
                            return value
                    message = self._fitting(reply, index, subindex, segment)
                    if message is not None:
                        return message
                    if deadline.expired():
                        raise MalformedReply(f"{self.where} sent only replies that do not fit the request "
                                             f"(last: {reply.hex(' ')})")
                    try:
                        reply = wait(replies, deadline.remaining())
                    except queue.Empty:
                        raise self._silent(index, subindex, deadline) from None
                    except Exception as exc:
                        raise self._read_failed(exc, index, subindex) from None
        finally:
            self._taking = False
        self._abort(coe.ABORT_TIMEOUT, index, subindex)
        raise self._silent(index, subindex, deadline)

    def _fitting(self, reply: bytes, index: int, subindex: int, segment: bool) -> "coe.SdoMessage | None":
        """The decoded reply if it answers the request; None if it does not (skipped); an abort raises."""
        try:
            message = coe.decode_sdo(reply, from_server=True)
        except coe.CoeError:
            return None
        if isinstance(message, coe.SdoAbort):
            from canopen.sdo.exceptions import SdoAbortedError

            raise sdo_aborted(message.code, sdo_what("upload", index, subindex), where=self.where,
                              fallback=SdoAbortedError.CODES)
        if segment:
            return message if isinstance(message, coe.SdoUploadSegmentResponse) else None
        if isinstance(message, coe.SdoUploadResponse) and message.index == index and message.subindex == subindex:
            return message
        return None

    def _silent(self, index: int, subindex: int, deadline: Deadline) -> NoAnswer:
        return NoAnswer(f"no answer from {self.where} to SDO {sdo_what('upload', index, subindex)} within "
                        f"{deadline.describe()}{self._nmt_hint()}")

    def _read_failed(self, exc: Exception, index: int, subindex: int) -> Exception:
        """The akdctl error for a failure to read the bus while waiting for an answer; anything else unchanged."""
        error = _bus_error(exc, sdo_what("upload", index, subindex), self.where)
        return exc if error is None else error

    def _send(self, request: bytes, index: int, subindex: int) -> None:
        """One request frame on the SDO request COB-ID (canopen's ``send_request``: it repeats a send the bus
        refused, as a full transmit queue does); a bus failure becomes a CommError."""
        try:
            self.sdo.send_request(request)
        except Exception as exc:
            error = _bus_error(exc, sdo_what("upload", index, subindex), self.where)
            if error is None:
                raise
            raise error from None

    def _abort(self, code: int, index: int, subindex: int) -> None:
        self._send(coe.encode_sdo(coe.SdoAbort(index, subindex, code)), index, subindex)

    def _read(self, index: int, subindex: int, block: bool, deadline: Deadline) -> bytes:
        """One upload, segment by segment: never more than the declared size or ``max_upload``."""
        stream = self._open_block(index, subindex, "rb") if block else self.sdo.open(index, subindex, "rb",
                                                                                    buffering=0)
        with stream:
            size = stream.size
            if size is not None and size > self.max_upload:
                self.sdo.abort(0x05040005)  # out of memory
                raise MalformedReply(f"{self.where} announces {size} bytes for SDO {sdo_what('upload', index, subindex)}"
                                     f", more than the {self.max_upload} bytes akdctl accepts from one object "
                                     "(transfer aborted)")
            limit = self.max_upload if size is None else size
            data = bytearray()
            while True:
                chunk = stream.read(7)
                if not chunk:
                    break
                data += chunk
                if len(data) > limit:
                    self.sdo.abort(0x06070010)  # length does not match
                    raise MalformedReply(f"{self.where} sent more than the {limit} bytes "
                                         f"{'it announced' if size is not None else 'akdctl accepts'} for SDO "
                                         f"{sdo_what('upload', index, subindex)} (transfer aborted)")
                if deadline.expired():
                    self.sdo.abort(0x05040000)  # SDO protocol timed out
                    raise NoAnswer(f"SDO {sdo_what('upload', index, subindex)} from {self.where} did not finish "
                                   f"within {deadline.describe()} (transfer aborted)")
            return bytes(data)

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

    def _call(self, what: str, deadline: Deadline, func, *args):  # noqa: ANN001, ANN202
        """Run one canopen SDO call; every library failure becomes an akdctl error (the library's exception
        classes are imported only when one is raised)."""
        try:
            return func(*args)
        except AkdError:
            raise
        except Exception as exc:
            from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

            if isinstance(exc, SdoAbortedError):
                raise sdo_aborted(int(exc.code), what, where=self.where, fallback=SdoAbortedError.CODES) from None
            if isinstance(exc, SdoCommunicationError):
                text = str(exc)
                if "No SDO response" in text or "timed out" in text.lower():
                    raise NoAnswer(f"no answer from {self.where} to SDO {what} within {deadline.describe()}"
                                   f"{self._nmt_hint()}") from None
                raise MalformedReply(f"unexpected reply from {self.where} to SDO {what}: {text}") from None
            error = _bus_error(exc, what, self.where)
            if error is None:
                raise
            raise error from None

    def _nmt_hint(self) -> str:
        """What the node's heartbeat last said, when it explains the silence (a STOPPED node answers no SDO)."""
        nmt = getattr(self.node, "nmt", None)
        received = getattr(nmt, "_state_received", None)
        if nmt is None or received is None:
            return ""
        state = state_name(received)
        if state == "STOPPED":
            return ("; its heartbeat says NMT state STOPPED, in which a node answers no SDO "
                    "(akdctl can nmt preop brings it back)")
        return f"; its heartbeat says NMT state {state}"


def _handed_over(replies: "queue.SimpleQueue[T]", timeout: float) -> T:
    """Wait for an answer the receive thread hands over (no BusReader)."""
    return replies.get(timeout=timeout)


def _bus_error(exc: Exception, what: str, where: str) -> CommError | None:
    """The CommError for a python-can/canopen failure to use the bus; None for any other exception."""
    import can

    if isinstance(exc, can.CanError):
        return CommError(f"CAN bus error during SDO {what} on {where}: {exc}")
    if isinstance(exc, RuntimeError):  # canopen: "Not connected to CAN bus" / network gone
        return CommError(f"CAN bus not usable for SDO {what} on {where}: {exc}")
    return None


class _BlockDeclined(Exception):
    """The server answered a block initiate with something else: use normal transfers."""
