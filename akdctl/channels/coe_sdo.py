"""CoeObjectChannel: an SDO client over any MailboxLink (raw EtherCAT, gateway, simulator).

Written once so every EtherCAT transport gets the same SDO behaviour:

* expedited transfers for 1..4 bytes, "normal" transfers (size + data in one
  mailbox) up to the mailbox size, segmented transfers beyond it;
* mailbox counter 1..7 wrapping; a reply is taken only if its CoE service,
  SDO command, index and subindex (and, for a segment, its toggle) fit the
  request, and :mod:`akdctl.channels.reply_filter` drops duplicates and, on a
  link that echoes counters, answers to other requests;
* every request waits within one :class:`~akdctl.links.Deadline` of the
  command's :class:`~akdctl.links.Budget` (``--timeout``, ``--retries``): an
  upload that got no answer is repeated whole (a segment cannot be repeated on
  its own: the server has already flipped its toggle) while time is left;
* **a download is sent once, never again**: when its answer is lost the
  channel aborts a segmented transfer, reads the object back and reports
  success only if it holds the value written; otherwise
  :class:`~akdctl.errors.UnknownOutcome` says the drive may or may not have
  applied it. A gateway cannot make a repeat harmless -- the master numbers
  mailboxes itself, so the slave cannot recognise our repeat by its counter --
  and a repeated controlword edge or command would act twice. On a link that
  does not echo counters, an answer to a later write to the same object could
  be the lost answer arriving late, so such writes are confirmed by reading
  back too;
* uploads are capped: the size the server declares, and at most
  :data:`MAX_UPLOAD` bytes whatever it declares (an endless segmented upload
  ends there with an abort sent to the server);
* emergencies arriving between replies are queued for :meth:`take_emergencies`;
* a reply whose CoE service reads 2 (request) instead of 3 is accepted with a
  warning: the AKD manual's own example shows one (SPEC-NOTES 15).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar

from akdctl.channels.base import MAX_UPLOAD, ObjectChannel, confirm_write, sdo_aborted, sdo_what
from akdctl.channels.reply_filter import ReplyFilter
from akdctl.errors import CommError, MalformedReply, NoAnswer
from akdctl.io.log import log
from akdctl.links import Budget, Deadline, MailboxLink
from akdctl.protocol import coe, mailbox as mbx
from akdctl.protocol.coe import CoeService
from akdctl.protocol.emcy import Emergency, decode_emcy
from akdctl.protocol.errors import CodecError

if TYPE_CHECKING:
    from akdctl.protocol import coe_info
    from akdctl.protocol.gateway_sdo import UploadFrames


T = TypeVar("T")

_SDO_REQUEST = int(CoeService.SDO_REQUEST)
_SDO_RESPONSE = int(CoeService.SDO_RESPONSE)
_EMERGENCY = int(CoeService.EMERGENCY)
#: Objects whose upload frames a channel keeps (upload): more than a poll or a monitor reads.
_FRAMES_KEPT = 256
_monotonic = time.monotonic


def _coe_sdo(request: coe.SdoMessage) -> bytes:
    """CoE data (header + SDO) of a client SDO request."""
    return coe.encode_coe(CoeService.SDO_REQUEST, coe.encode_sdo(request))


class _Silence(Exception):
    """Internal: no matching reply within the attempt's wait (the request may be repeated)."""


def _where(index: int, subindex: int) -> str:
    return f"0x{index:04X}:{subindex:02X}"


class CoeObjectChannel(ObjectChannel):
    """SDO upload/download and SDO information over EtherCAT mailboxes."""

    def __init__(
        self,
        link: MailboxLink,
        *,
        budget: Budget | None = None,
        timeout: float | None = None,
        retries: int = 2,
        station: int | None = None,
        strict_counter: bool = False,
        max_upload: int = MAX_UPLOAD,
    ) -> None:
        self.link = link
        self.budget = budget if budget is not None else Budget(2.0 if timeout is None else timeout, retries)
        self.station = link.mailbox_address if station is None else station
        self.max_upload = max_upload
        self.filter = ReplyFilter(strict=strict_counter)
        self.requests = 0
        self._counter = 0
        self._stale = False  # an earlier request went unanswered: its reply may still come in
        self._proven = False  # the last answer taken carried the request's own counter (an echoing link)
        self._doubtful: set[tuple[int, int]] = set()  # objects with a write that went unanswered
        self._want: tuple[type, int, int, str, int | None] = (coe.SdoUploadResponse, 0, 0, "upload", None)
        self._emergencies: list[Emergency] = []
        self._quick = link.quick_frames  # the poll's frames come pre-encoded from the link (upload)
        self._frames: dict[tuple[int, int], UploadFrames] = {}

    @property
    def timeout(self) -> float:
        return self.budget.timeout

    # --- ObjectChannel ----------------------------------------------------------------------

    def take_emergencies(self) -> list[Emergency]:
        out, self._emergencies = self._emergencies, []
        return out

    def upload(self, index: int, subindex: int) -> bytes:
        """The value of ``index:subindex``.

        The poll's usual case -- no request of this command outstanding or unanswered (``Budget.lone``), the
        answer the next mailbox, expedited -- is read in one pass: the request sent as :meth:`_exchange` sends it,
        one receive, the reply read by one codec call (``coe.expedited_upload_reply``) and taken by the same
        counter rules. Anything else (silence, a late, foreign or other reply) goes on as the general path's first
        attempt with the reply already received, within the same deadline. On a link of whole frames
        (``MailboxLink.quick_frames``: ``ecat-udp://``) the request is the frame the link's codec made once for this
        object and counter, and the reply is checked whole (``gateway_sdo.UploadFrames.answer``) before the same
        counter rules; a link that declines (tracing) gets the pass above."""
        at = None if self._stale else self.budget.lone()
        if at is None:
            return self._upload_request(index, subindex)
        if self._quick:
            # A link of whole pre-encoded frames (MailboxLink.quick_frames: the ETG.8200 gateway): the datagram of
            # this object and counter out, the first datagram in, checked whole by the codec (gateway_sdo), then
            # taken by the same counter rules. Anything else goes on as the general path's first attempt, from the
            # same counter, datagram and deadline; declined (tracing): the one pass below.
            frames = self._frames.get((index, subindex))
            if frames is None:
                frames = self._upload_frames(index, subindex)
            counter = self._counter + 1 if self._counter < 7 else 1
            budget = self.budget
            wait = budget.timeout / (budget.retries + 1)  # (Deadline.share of the request's first attempt)
            end = at - budget.timeout + wait
            try:
                data = self.link.quick_request(frames.requests[counter], end, wait)
            except CommError:
                self._counter = counter
                self.requests += 1
                self.filter.sent(counter)
                with budget.request(at=at):  # the link failed: counted by the Budget as any request's failure
                    raise
            if data is not False:
                self._counter = counter
                self.requests += 1
                if data is None:  # silence in the attempt's share
                    self.filter.sent(counter)
                    mailbox: bytes | None = b""
                else:
                    answer = frames.answer(data)
                    if answer is not None and _monotonic() <= end:
                        mine = self.filter.take(answer[2], answer[0], counter)  # (filter.sent(counter) in the call)
                        if mine is not None:
                            self._proven = mine
                            return answer[1]
                    else:
                        self.filter.sent(counter)
                    mailbox = self.link.frame_mailbox(data)  # as the link's receive judges it (None: read past)
                return self._upload_request(index, subindex, at, (counter, wait, end, _monotonic(), mailbox))
        request = coe.upload_request(index, subindex)
        self._want = (coe.SdoUploadResponse, index, subindex, "upload", None)
        try:
            counter = self._send_request(request)
            now = time.monotonic()
            wait = max(0.0, at - now) / self.budget.attempts  # (Deadline.share of the request's first attempt)
            end = now + wait
            raw = self.link.receive(wait)
        except CommError:
            with self.budget.request(at=at):  # the link failed: counted by the Budget as any request's failure
                raise
        if raw is not None:
            now = time.monotonic()
            reply = coe.expedited_upload_reply(raw, index, subindex) if now <= end else None
            if reply is not None:
                mine = self.filter.take(raw, reply[0])
                if mine is not None:
                    self._proven = mine
                    return reply[1]
        return self._upload_request(index, subindex, at, (counter, wait, end, now, raw or b""))

    def _upload_frames(self, index: int, subindex: int) -> UploadFrames:
        """The link's pre-encoded frames of an upload of ``index:subindex``, kept for the next poll of it (a few
        hundred objects at most: a command that reads more starts over)."""
        frames = self.link.upload_frames(index, subindex)
        if len(self._frames) >= _FRAMES_KEPT:
            self._frames.clear()
        self._frames[(index, subindex)] = frames
        return frames

    def _upload_request(self, index: int, subindex: int, at: float | None = None,
                        begun: tuple[int, float, float, float, bytes | None] | None = None) -> bytes:
        """An upload with all its attempts in one request's deadline; ``at``/``begun``: the one :meth:`upload`
        began (its end time; the first attempt's counter, wait, end, clock and the reply it received: b"" none
        came, None one came that the link reads past, so the attempt listens on)."""
        with self.budget.request(at=at) as deadline:
            data = self._upload_attempts(index, subindex, deadline, deadline.attempts, begun)
            if data is not None:
                return data
            raise NoAnswer(f"no answer to SDO upload of {_where(index, subindex)} within {deadline.describe()}",
                           details={"timeout": deadline.total, "attempts": deadline.attempts})

    def download(self, index: int, subindex: int, data: bytes) -> None:
        data = bytes(data)
        what = f"SDO download to {_where(index, subindex)}"
        with self.budget.request() as deadline:
            try:
                proven = self._download_once(index, subindex, data, deadline)
            except _Silence:
                self._doubtful.add((index, subindex))
                if len(data) > 4 and len(data) > self._normal_room:
                    self._abort(index, subindex, coe.ABORT_TIMEOUT)  # leave no half transfer in the server
                self._confirm(index, subindex, data, deadline, f"no answer to the {what} within {deadline.describe()}")
                return
            if not proven and (index, subindex) in self._doubtful:
                # An earlier write to this object went unanswered and this link does not echo counters: the
                # answer just taken may be that write's late answer. Only the object itself can tell.
                self._confirm(index, subindex, data, deadline,
                              f"the answer to the {what} may be the late answer to an earlier write")

    def object_list(self) -> list[int]:
        from akdctl.protocol import coe_info  # the SDO information service: loaded on first use

        reply = self._info(coe_info.OdListRequest(coe_info.LIST_ALL), coe_info.OdListResponse, "object list")
        return list(reply.indices)

    def object_description(self, index: int) -> coe_info.ObjectDescription:
        from akdctl.protocol import coe_info

        return self._info(coe_info.ObjectDescriptionRequest(index), coe_info.ObjectDescription, f"description of 0x{index:04X}")

    def entry_description(self, index: int, subindex: int) -> coe_info.EntryDescription:
        from akdctl.protocol import coe_info

        return self._info(
            coe_info.EntryDescriptionRequest(index, subindex), coe_info.EntryDescription, f"description of {_where(index, subindex)}"
        )

    # --- transfers --------------------------------------------------------------------------

    @property
    def _normal_room(self) -> int:
        """Data bytes an initiate mailbox carries after the size field."""
        return max(0, self.link.mailbox_size - mbx.HEADER_SIZE - coe.NORMAL_OVERHEAD)

    @property
    def _segment_room(self) -> int:
        return max(7, self.link.mailbox_size - mbx.HEADER_SIZE - coe.SEGMENT_OVERHEAD)

    def _repeat(self, once: Callable[[Deadline, int], T], what: str) -> T:
        """Run an idempotent request (an upload, an information request) until answered or out of time."""
        with self.budget.request() as deadline:
            attempts = deadline.attempts
            for attempt in range(attempts):
                try:
                    return once(deadline, attempts - attempt)
                except _Silence:
                    if attempt + 1 < attempts and not deadline.expired():
                        log.info("%s: no answer, repeating (%d/%d)", what, attempt + 2, attempts)
                    if deadline.expired():
                        break
            raise NoAnswer(f"no answer to {what} within {deadline.describe()}",
                           details={"timeout": deadline.total, "attempts": deadline.attempts})

    def _upload_once(self, index: int, subindex: int, deadline: Deadline, left: int,
                     begun: tuple[int, float, float, float, bytes | None] | None = None) -> bytes:
        self._want = (coe.SdoUploadResponse, index, subindex, "upload", None)  # (what _sdo does, one call less)
        if begun is None:
            first = self._exchange(coe.upload_request(index, subindex), self._accept_sdo, left, deadline)
        else:  # sent by upload(): its first reply (b"": none came) is judged here first
            counter, wait, end, now, raw = begun
            first = self._listen(counter, self._accept_sdo, wait, end, now, deadline, None, raw)
        if not isinstance(first, coe.SdoUploadResponse):
            raise MalformedReply(f"unexpected reply {first!r} to the SDO upload of {_where(index, subindex)}")
        if first.expedited or first.size is None:
            return first.data  # size not indicated: the initiate carries everything
        size = first.size
        if size > self.max_upload:
            self._abort(index, subindex, coe.ABORT_OUT_OF_MEMORY)
            raise MalformedReply(f"the drive announces {size} bytes for {_where(index, subindex)}, more than the "
                                 f"{self.max_upload} bytes akdctl accepts from one object (transfer aborted)")
        data = bytearray(first.data)
        toggle = 0
        last = True
        while len(data) < size:
            seg = self._sdo(_coe_sdo(coe.SdoUploadSegment(toggle)), coe.SdoUploadSegmentResponse, index, subindex,
                            "upload", deadline, left, toggle)
            assert isinstance(seg, coe.SdoUploadSegmentResponse)
            data += seg.data
            toggle ^= 1
            last = seg.last
            if last:
                break
        if len(data) != size:
            if not last:
                self._abort(index, subindex, coe.ABORT_LENGTH_MISMATCH)  # the server would go on sending
            raise MalformedReply(
                f"segmented upload of {_where(index, subindex)} delivered {len(data)} bytes, announced {size}"
                + ("" if last else " (transfer aborted)")
            )
        return bytes(data)

    def _download_once(self, index: int, subindex: int, data: bytes, deadline: Deadline) -> bool:
        """Send the write once; True when the answers were proven ours by their counter."""
        if 1 <= len(data) <= 4:
            request: coe.SdoMessage = coe.SdoDownloadInitiate(index, subindex, data, len(data), True)
            rest = b""
        else:
            room = self._normal_room
            request = coe.SdoDownloadInitiate(index, subindex, data[:room], len(data), False)
            rest = data[room:]
        # Each answer may take a share of the request's time: the rest is for reading the object back.
        self._sdo(_coe_sdo(request), coe.SdoDownloadResponse, index, subindex, "download", deadline, deadline.attempts)
        proven = self._proven
        toggle = 0
        room = self._segment_room
        while rest:
            chunk, rest = rest[:room], rest[room:]
            self._sdo(_coe_sdo(coe.SdoDownloadSegment(toggle, chunk, not rest)), coe.SdoDownloadSegmentResponse,
                      index, subindex, "download", deadline, deadline.attempts, toggle)
            proven = proven and self._proven
            toggle ^= 1
        return proven

    def _confirm(self, index: int, subindex: int, data: bytes, deadline: Deadline, why: str) -> None:
        """Confirm a write whose answer is missing or doubtful by reading the object back."""
        attempts = deadline.attempts - 1  # the first attempt was the write itself
        read = None if attempts < 1 or deadline.expired() else lambda: self._read_back(index, subindex, deadline,
                                                                                      attempts)
        confirm_write(why, data, read, {"index": index, "subindex": subindex})

    def _read_back(self, index: int, subindex: int, deadline: Deadline, attempts: int) -> bytes:
        data = self._upload_attempts(index, subindex, deadline, attempts)
        if data is None:
            raise NoAnswer(f"no answer to reading {_where(index, subindex)} back")
        return data

    def _upload_attempts(self, index: int, subindex: int, deadline: Deadline, attempts: int,
                         begun: tuple[int, float, float, float, bytes | None] | None = None) -> bytes | None:
        """Up to ``attempts`` uploads within ``deadline`` (an upload is safe to repeat); None if none was answered.
        ``begun``: the first attempt was sent by :meth:`upload` (:meth:`_upload_once`)."""
        for attempt in range(attempts):
            try:
                return self._upload_once(index, subindex, deadline, attempts - attempt, begun if not attempt else None)
            except _Silence:
                if deadline.expired():
                    break
                if attempt + 1 < attempts:
                    log.info("SDO upload of %s: no answer, repeating (%d/%d)", _where(index, subindex),
                             attempt + 2, attempts)
        return None

    def _abort(self, index: int, subindex: int, code: int) -> None:
        """Tell the server to drop its transfer state (CiA 301: the client aborts what it gives up)."""
        try:
            self._send(_coe_sdo(coe.SdoAbort(index, subindex, code)))
        except CommError as exc:
            log.debug("could not send the SDO abort: %s", exc)

    def _sdo(self, request: bytes, wanted: type, index: int, subindex: int, verb: str, deadline: Deadline,
             left: int, toggle: int | None = None) -> coe.SdoMessage:
        """Send one SDO request (its CoE data); return the matching server message (aborts raise)."""
        self._want = (wanted, index, subindex, verb, toggle)
        # (the checker joins the union's members to their base class when it infers T: the accept function's type)
        return self._exchange(request, self._accept_sdo, left, deadline)  # type: ignore[return-value]

    def _accept_sdo(self, service: int, payload: bytes, mine: bool) -> coe.SdoMessage | None:
        """The server message if this reply answers the SDO request in ``self._want``, else None."""
        if service != _SDO_RESPONSE and service != _SDO_REQUEST:
            return None
        try:
            msg = coe.decode_sdo(payload, from_server=True)
        except CodecError as exc:
            log.debug("ignoring an undecodable SDO reply: %s", exc)
            return None
        wanted, index, subindex, verb, toggle = self._want
        segment = toggle is not None
        if type(msg) is not wanted:
            if isinstance(msg, coe.SdoAbort) and (
                    (msg.index, msg.subindex) in ((index, subindex), (0, 0)) or segment or mine):
                raise sdo_aborted(msg.code, sdo_what(verb, index, subindex),
                                  details={"index": index, "subindex": subindex})
            return None
        if segment:
            if msg.toggle != toggle:  # type: ignore[union-attr]
                if mine:
                    raise MalformedReply(f"segment toggle {msg.toggle} (expected {toggle}) in the SDO {verb} "  # type: ignore[union-attr]
                                         f"of {_where(index, subindex)}")
                return None  # a duplicate of the previous segment's answer
        elif msg.index != index or msg.subindex != subindex:  # type: ignore[union-attr]
            return None
        if service == _SDO_REQUEST:
            log.warning(
                "SDO reply for %s carries CoE service 2 (request) instead of 3 (response); "
                "accepted as the AKD manual prints it",
                _where(index, subindex),
            )
        return msg

    # --- SDO information --------------------------------------------------------------------

    def _info(self, request: coe_info.SdoInfoMessage, expect: type[T], what: str) -> T:
        from akdctl.protocol import coe_info

        frame = coe_info.encode_sdo_info(coe_info.pack_info(request))
        data = coe.encode_coe(CoeService.SDO_INFO, frame)

        def once(deadline: Deadline, left: int) -> T:
            assembler = coe_info.InfoReassembler()
            result: list[coe_info.SdoInfo] = []

            def accept(service: int, payload: bytes, mine: bool) -> bool | None:
                if service != CoeService.SDO_INFO:
                    return None
                try:
                    part = coe_info.decode_sdo_info(payload)
                    done = assembler.add(part)
                except CodecError as exc:
                    raise MalformedReply(f"SDO information reply for the {what} does not decode: {exc}") from None
                if done is None:
                    return False  # more fragments follow: keep listening, the wait restarts
                result.append(done)
                return True

            self._exchange(data, accept, left, deadline, until=lambda value: value is True)
            try:
                message = coe_info.unpack_info(result[0])
            except CodecError as exc:
                raise MalformedReply(f"SDO information reply for the {what} does not decode: {exc}") from None
            if isinstance(message, coe_info.SdoInfoError):
                raise sdo_aborted(message.code, f"information request for the {what}")
            if not isinstance(message, expect):
                raise MalformedReply(f"unexpected SDO information reply {type(message).__name__} for the {what}")
            return message

        return self._repeat(once, f"SDO information request for the {what}")

    # --- mailbox exchange -------------------------------------------------------------------

    def _send(self, coe_data: bytes) -> int:
        counter = self._counter = self._counter + 1 if self._counter < 7 else 1  # 1..7 (mailbox.next_counter)
        self.requests += 1
        self.link.send(mbx.pack(mbx.MailboxType.COE, coe_data, self.station, counter))
        return counter

    def _drain(self) -> None:
        """Clear replies left over from an unanswered request (keep their emergencies)."""
        for _ in range(64):
            raw = self.link.receive(0)
            if raw is None:
                return
            self._classify(raw, check_errors=False)

    def _classify(self, raw: bytes, check_errors: bool = True) -> tuple[int, int, bytes] | None:
        """Handle what every reply shares: mailbox errors, emergencies, foreign types.

        Returns (counter, CoE service, payload) of a CoE reply worth matching, else None.
        """
        try:
            mtype, counter, _address, data = mbx.split(raw)
        except CodecError as exc:
            log.debug("ignoring an undecodable mailbox: %s", exc)
            return None
        if mtype == mbx.MailboxType.ERROR:
            if not check_errors or not self.filter.admit(raw, counter):
                return None
            try:
                reply = mbx.decode_error_reply(data)
            except CodecError as exc:
                raise MalformedReply(f"the drive sent a mailbox error reply that does not decode: {exc}") from None
            from akdctl.catalog.texts import mailbox_error_text  # here: the texts are read only for a refusal

            raise CommError(
                f"the drive refused the mailbox request: {mailbox_error_text(reply.code)} (mailbox error {reply.code})", code=reply.code
            )
        if mtype != mbx.MailboxType.COE or len(data) < coe.COE_HEADER_SIZE:
            log.debug("ignoring a mailbox of type %d", mtype)
            return None
        service = data[1] >> 4  # CoE header: number bits 0-8, service bits 12-15
        payload = data[coe.COE_HEADER_SIZE:]
        if service == _EMERGENCY:
            try:
                self._emergencies.append(decode_emcy(payload[: 8]))
            except CodecError as exc:
                log.warning("ignoring an emergency that does not decode: %s", exc)
            return None
        return counter, service, payload

    def _exchange(
        self,
        coe_data: bytes,
        accept: Callable[[int, bytes, bool], T | None],
        left: int,
        deadline: Deadline,
        until: Callable[[T], bool] | None = None,
    ) -> T:
        """Send once, then read until ``accept`` returns a value ``until`` approves.

        Waits for each reply at most this attempt's share of what is left of ``deadline`` (``left``: the
        attempts left, this one included), never past it; raises _Silence when none comes.
        """
        if self._stale:
            self._drain()
            self._stale = False
        counter = self._send_request(coe_data)
        now = time.monotonic()
        wait = max(0.0, deadline.at - now) / max(1, left)  # (Deadline.share, with the clock read once)
        return self._listen(counter, accept, wait, now + wait, now, deadline, until)

    def _send_request(self, coe_data: bytes) -> int:
        """Send a request; its counter, which the reply filter now judges replies against."""
        try:
            counter = self._send(coe_data)
        except NoAnswer as exc:
            # The link could not confirm the request went out (a raw frame lost on its way back): the
            # slave may have it, so listen for its answer as if it had; silence is judged as silence.
            log.info("sending the request was not confirmed (%s); listening for an answer anyway", exc)
            counter = self._counter
        self.filter.sent(counter)
        return counter

    def _listen(
        self,
        counter: int,
        accept: Callable[[int, bytes, bool], T | None],
        wait: float,
        end: float,
        now: float,
        deadline: Deadline,
        until: Callable[[T], bool] | None = None,
        pending: bytes | None = None,
    ) -> T:
        """Read replies to the request sent with ``counter`` until ``end`` (``now``: the clock when it was sent, or
        when ``pending`` came: a reply already received, judged first; b"" when that receive got nothing)."""
        remaining = end - now
        while True:
            if pending is not None:
                raw, pending = pending or None, None
            else:
                raw = self.link.receive(remaining)
                if raw is not None:
                    now = time.monotonic()
                    remaining = end - now
            if raw is None or remaining < 0:
                # Silence -- or only mailboxes that are not the answer until the wait ran out: a slave that keeps
                # presenting a foreign reply (SM1 in buffered mode, issue 23 item 12) must not hold us forever.
                self._stale = True
                self.filter.unanswered()
                raise _Silence()
            classified = self._classify(raw)
            if classified is None:
                continue
            got, service, payload = classified
            if not self.filter.admit(raw, got):
                log.debug("ignoring a duplicate or a late reply (mailbox counter %d, sent %d)", got, counter)
                continue
            mine = self.filter.mine(got)
            value = accept(service, payload, mine)
            if value is None:
                continue
            self.filter.accepted(raw, got)
            self._proven = mine
            if until is None or until(value):
                return value
            end = min(deadline.at, now + wait)  # a fragment arrived: wait for the next one
            remaining = max(0.0, end - now)

