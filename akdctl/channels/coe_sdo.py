"""CoeObjectChannel: an SDO client over any MailboxLink (raw EtherCAT, gateway, simulator).

Written once so every EtherCAT transport gets the same SDO behaviour:

* expedited transfers for 1..4 bytes, "normal" transfers (size + data in one
  mailbox) up to the mailbox size, segmented transfers beyond it;
* mailbox counter 1..7 wrapping; replies are matched on CoE service, SDO
  command, index and subindex, not on the counter, because mailbox gateways
  rewrite it (``strict_counter=True`` additionally drops replies whose counter
  differs, for links that echo it faithfully);
* emergencies arriving between replies are queued for :meth:`take_emergencies`;
* a reply whose CoE service reads 2 (request) instead of 3 is accepted with a
  warning: the AKD manual's own example shows one (SPEC-NOTES 15);
* a lost reply repeats the whole transfer (a segment cannot be repeated on its
  own: the server has already flipped its toggle), at most ``retries`` times,
  then :class:`akdctl.errors.NoAnswer`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

from akdctl.channels.base import ObjectChannel, sdo_aborted, sdo_what
from akdctl.catalog.texts import mailbox_error_text
from akdctl.errors import CommError, MalformedReply, NoAnswer, UsageError
from akdctl.io.log import log
from akdctl.links import MailboxLink
from akdctl.protocol import coe, mailbox as mbx
from akdctl.protocol.coe import CoeService
from akdctl.protocol.emcy import Emergency, decode_emcy
from akdctl.protocol.errors import CodecError


T = TypeVar("T")


class _Silence(Exception):
    """Internal: no matching reply within the timeout (the transfer may be repeated)."""


def _where(index: int, subindex: int) -> str:
    return f"0x{index:04X}:{subindex:02X}"


class CoeObjectChannel(ObjectChannel):
    """SDO upload/download and SDO information over EtherCAT mailboxes."""

    def __init__(
        self,
        link: MailboxLink,
        *,
        timeout: float,
        retries: int = 2,
        station: int | None = None,
        strict_counter: bool = False,
    ) -> None:
        if timeout <= 0:
            raise UsageError(f"timeout must be positive (got {timeout})")
        self.link = link
        self.timeout = float(timeout)
        self.retries = max(0, int(retries))
        self.station = link.mailbox_address if station is None else station
        self.strict_counter = strict_counter
        self.requests = 0
        self._counter = 0
        self._emergencies: list[Emergency] = []

    # --- ObjectChannel ----------------------------------------------------------------------

    def take_emergencies(self) -> list[Emergency]:
        out, self._emergencies = self._emergencies, []
        return out

    def upload(self, index: int, subindex: int) -> bytes:
        return self._repeat(lambda: self._upload_once(index, subindex), f"SDO upload of {_where(index, subindex)}")

    def download(self, index: int, subindex: int, data: bytes) -> None:
        data = bytes(data)
        self._repeat(lambda: self._download_once(index, subindex, data), f"SDO download to {_where(index, subindex)}")

    def object_list(self) -> list[int]:
        reply = self._info(coe.OdListRequest(coe.LIST_ALL), coe.OdListResponse, "object list")
        return list(reply.indices)

    def object_description(self, index: int) -> coe.ObjectDescription:
        return self._info(coe.ObjectDescriptionRequest(index), coe.ObjectDescription, f"description of 0x{index:04X}")

    def entry_description(self, index: int, subindex: int) -> coe.EntryDescription:
        return self._info(
            coe.EntryDescriptionRequest(index, subindex), coe.EntryDescription, f"description of {_where(index, subindex)}"
        )

    # --- transfers --------------------------------------------------------------------------

    @property
    def _normal_room(self) -> int:
        """Data bytes an initiate mailbox carries after the size field."""
        return max(0, self.link.mailbox_size - mbx.HEADER_SIZE - coe.NORMAL_OVERHEAD)

    @property
    def _segment_room(self) -> int:
        return max(7, self.link.mailbox_size - mbx.HEADER_SIZE - coe.SEGMENT_OVERHEAD)

    def _repeat(self, once: Callable[[], T], what: str) -> T:
        attempts = self.retries + 1
        for attempt in range(1, attempts + 1):
            try:
                return once()
            except _Silence:
                if attempt < attempts:
                    log.info("%s: no answer within %.3g s, repeating (%d/%d)", what, self.timeout, attempt, attempts)
        raise NoAnswer(
            f"no answer to {what} within {self.timeout:g} s ({attempts} attempt{'s' if attempts > 1 else ''})",
            details={"timeout": self.timeout, "attempts": attempts},
        )

    def _upload_once(self, index: int, subindex: int) -> bytes:
        first = self._sdo(coe.SdoUploadInitiate(index, subindex), index, subindex, "upload")
        if not isinstance(first, coe.SdoUploadResponse) or (first.index, first.subindex) != (index, subindex):
            raise MalformedReply(f"unexpected reply {first!r} to the SDO upload of {_where(index, subindex)}")
        if first.expedited:
            return first.data
        if first.size is None:
            return first.data  # size not indicated: the initiate carries everything
        data = bytearray(first.data)
        toggle = 0
        while len(data) < first.size:
            seg = self._sdo(coe.SdoUploadSegment(toggle), index, subindex, "upload")
            if not isinstance(seg, coe.SdoUploadSegmentResponse):
                raise MalformedReply(f"unexpected reply {seg!r} in the segmented upload of {_where(index, subindex)}")
            if seg.toggle != toggle:
                raise MalformedReply(f"segment toggle {seg.toggle} (expected {toggle}) uploading {_where(index, subindex)}")
            data += seg.data
            toggle ^= 1
            if seg.last:
                break
        if len(data) != first.size:
            raise MalformedReply(
                f"segmented upload of {_where(index, subindex)} delivered {len(data)} bytes, announced {first.size}"
            )
        return bytes(data)

    def _download_once(self, index: int, subindex: int, data: bytes) -> None:
        if 1 <= len(data) <= 4:
            request: coe.SdoMessage = coe.SdoDownloadInitiate(index, subindex, data, len(data), True)
            rest = b""
        else:
            room = self._normal_room
            request = coe.SdoDownloadInitiate(index, subindex, data[:room], len(data), False)
            rest = data[room:]
        reply = self._sdo(request, index, subindex, "download")
        if not isinstance(reply, coe.SdoDownloadResponse) or (reply.index, reply.subindex) != (index, subindex):
            raise MalformedReply(f"unexpected reply {reply!r} to the SDO download to {_where(index, subindex)}")
        toggle = 0
        room = self._segment_room
        while rest:
            chunk, rest = rest[:room], rest[room:]
            seg = self._sdo(coe.SdoDownloadSegment(toggle, chunk, not rest), index, subindex, "download")
            if not isinstance(seg, coe.SdoDownloadSegmentResponse) or seg.toggle != toggle:
                raise MalformedReply(f"unexpected reply {seg!r} in the segmented download to {_where(index, subindex)}")
            toggle ^= 1

    def _sdo(self, request: coe.SdoMessage, index: int, subindex: int, verb: str) -> coe.SdoMessage:
        """Send one SDO request; return the matching server message (aborts raise)."""
        segment = isinstance(request, (coe.SdoUploadSegment, coe.SdoDownloadSegment))
        if segment:
            wanted: tuple[type, ...] = (
                (coe.SdoUploadSegmentResponse,) if isinstance(request, coe.SdoUploadSegment)
                else (coe.SdoDownloadSegmentResponse,)
            )
        elif isinstance(request, coe.SdoUploadInitiate):
            wanted = (coe.SdoUploadResponse,)
        else:
            wanted = (coe.SdoDownloadResponse,)

        def accept(service: int, payload: bytes) -> coe.SdoMessage | None:
            if service not in (CoeService.SDO_RESPONSE, CoeService.SDO_REQUEST):
                return None
            try:
                msg = coe.decode_sdo(payload, from_server=True)
            except CodecError as exc:
                log.debug("ignoring an undecodable SDO reply: %s", exc)
                return None
            if isinstance(msg, coe.SdoAbort):
                if (msg.index, msg.subindex) in ((index, subindex), (0, 0)) or segment:
                    raise sdo_aborted(msg.code, sdo_what(verb, index, subindex),
                                      details={"index": index, "subindex": subindex})
                return None
            if not isinstance(msg, wanted):
                return None
            if not segment and (getattr(msg, "index", index), getattr(msg, "subindex", subindex)) != (index, subindex):
                return None
            if service == CoeService.SDO_REQUEST:
                log.warning(
                    "SDO reply for %s carries CoE service 2 (request) instead of 3 (response); "
                    "accepted as the AKD manual prints it",
                    _where(index, subindex),
                )
            return msg

        return self._exchange(coe.encode_coe(CoeService.SDO_REQUEST, coe.encode_sdo(request)), accept)

    # --- SDO information --------------------------------------------------------------------

    def _info(self, request: coe.SdoInfoMessage, expect: type[T], what: str) -> T:
        frame = coe.encode_sdo_info(coe.pack_info(request))
        data = coe.encode_coe(CoeService.SDO_INFO, frame)

        def once() -> T:
            assembler = coe.InfoReassembler()
            result: list[coe.SdoInfo] = []

            def accept(service: int, payload: bytes) -> bool | None:
                if service != CoeService.SDO_INFO:
                    return None
                try:
                    part = coe.decode_sdo_info(payload)
                    done = assembler.add(part)
                except CodecError as exc:
                    raise MalformedReply(f"SDO information reply for the {what} does not decode: {exc}") from None
                if done is None:
                    return False  # more fragments follow: keep listening, the timer restarts
                result.append(done)
                return True

            self._exchange(data, accept, until=lambda value: value is True)
            try:
                message = coe.unpack_info(result[0])
            except CodecError as exc:
                raise MalformedReply(f"SDO information reply for the {what} does not decode: {exc}") from None
            if isinstance(message, coe.SdoInfoError):
                raise sdo_aborted(message.code, f"information request for the {what}")
            if not isinstance(message, expect):
                raise MalformedReply(f"unexpected SDO information reply {type(message).__name__} for the {what}")
            return message

        return self._repeat(once, f"SDO information request for the {what}")

    # --- mailbox exchange -------------------------------------------------------------------

    def _send(self, coe_data: bytes) -> int:
        self._counter = mbx.next_counter(self._counter)
        frame = mbx.encode_mailbox(mbx.Mailbox(mbx.MailboxType.COE, coe_data, address=self.station, counter=self._counter))
        self.link.send(frame)
        self.requests += 1
        return self._counter

    def _drain(self) -> None:
        """Clear replies left over from an earlier, timed-out attempt (keep their emergencies)."""
        for _ in range(64):
            raw = self.link.receive(0)
            if raw is None:
                return
            self._classify(raw, counter=None)

    def _classify(self, raw: bytes, counter: int | None) -> tuple[int, bytes] | None:
        """Handle what every reply shares: mailbox errors, emergencies, foreign types."""
        try:
            frame = mbx.decode_mailbox(raw)
        except CodecError as exc:
            log.debug("ignoring an undecodable mailbox: %s", exc)
            return None
        if frame.type == mbx.MailboxType.ERROR:
            if counter is None:
                return None
            try:
                reply = mbx.decode_error_reply(frame.data)
            except CodecError as exc:
                raise MalformedReply(f"the drive sent a mailbox error reply that does not decode: {exc}") from None
            raise CommError(
                f"the drive refused the mailbox request: {mailbox_error_text(reply.code)} (mailbox error {reply.code})", code=reply.code
            )
        if frame.type != mbx.MailboxType.COE:
            log.debug("ignoring a mailbox of type %d", frame.type)
            return None
        try:
            service, _number, payload = coe.decode_coe(frame.data)
        except CodecError as exc:
            log.debug("ignoring a CoE mailbox that does not decode: %s", exc)
            return None
        if service == CoeService.EMERGENCY:
            try:
                self._emergencies.append(decode_emcy(payload[: 8]))
            except CodecError as exc:
                log.warning("ignoring an emergency that does not decode: %s", exc)
            return None
        if counter is not None and self.strict_counter and frame.counter not in (0, counter):
            log.debug("ignoring a reply with mailbox counter %d (sent %d)", frame.counter, counter)
            return None
        return service, payload

    def _exchange(
        self,
        coe_data: bytes,
        accept: Callable[[int, bytes], T | None],
        until: Callable[[T], bool] = lambda value: True,
    ) -> T:
        """Send once, then read until ``accept`` returns a value ``until`` approves.

        Raises _Silence when the timeout passes without one.
        """
        self._drain()
        counter = self._send(coe_data)
        deadline = time.monotonic() + self.timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise _Silence()
            raw = self.link.receive(remaining)
            if raw is None:
                raise _Silence()
            classified = self._classify(raw, counter)
            if classified is None:
                continue
            value = accept(*classified)
            if value is None:
                continue
            if until(value):
                return value
            deadline = time.monotonic() + self.timeout  # a fragment arrived: wait for the next one
