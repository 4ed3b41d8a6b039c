"""SdoServer: CoE mailbox bytes in, response mailbox bytes out, over an ObjectAccess.

This is the simulated AKD's mailbox handler. It answers exactly what a slave
answers, so every client path (expedited, normal, segmented, aborts, mailbox
errors, SDO information, emergencies) can be exercised without hardware, and
the same bytes can be served to an independent master (pysoem, a gateway).

Behaviour, following ETG.1000.6 and SOEM/the Beckhoff slave stack:

* the response echoes the request's mailbox counter and address;
* values of 1..4 bytes are uploaded expedited, larger ones "normal" (size +
  data in one mailbox) and segmented once they exceed the mailbox;
* downloads: expedited, normal, or normal + segments, with toggle checks
  (0x05030000) and length checks (0x06070012/13) before anything is written;
* unknown command specifiers (block transfer) abort with 0x05040001, complete
  access with 0x06010000 (the AKD's ESI does not declare it);
* FoE mailboxes (type 4) go to the drive's file store when the server was told
  the access object has one (``files=True``: it is a :class:`akdctl.sim.foe.FileAccess`
  as well; declared, not probed): the AKD names FoE as its firmware path;
* a mailbox of another protocol, or whose header/size is broken, gets a
  mailbox error reply (type 0) instead of an SDO answer;
* queued emergencies go out as CoE service-1 mailboxes ahead of the next reply.

It never raises on hostile input: whatever the access object raises becomes
an abort code, and undecodable bytes become mailbox error replies.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol, runtime_checkable

from akdctl.io.log import log
from akdctl.protocol import coe, mailbox as mbx
from akdctl.protocol.coe import CoeError, CoeService, plain_upload_initiate
from akdctl.protocol.emcy import Emergency, encode_emcy
from akdctl.protocol.errors import CodecError
from akdctl.protocol.record import Record
from akdctl.sim.errors import SdoAccessError  # noqa: F401  (re-exported: servers raise and catch it)
from akdctl.sim.memo import remember

if TYPE_CHECKING:
    from akdctl.protocol import coe_info


MAX_TRANSFER = 1 << 20  # larger announced downloads abort with "out of memory"
#: Plain upload requests whose plan :meth:`SdoServer.handle` keeps at once (a client polls a few objects, with
#: counters 1..7); more distinct ones start the memo over.
PLANS_KEPT = 1024



class ObjectAccess(Protocol):
    """What SdoServer needs from the drive model (docs/internals.md)."""

    def object_read(self, index: int, subindex: int) -> bytes:
        """Raw little-endian value; raises SdoAccessError(abort code)."""
        ...

    def object_write(self, index: int, subindex: int, data: bytes) -> None:
        """Store a raw value; raises SdoAccessError(abort code)."""
        ...


class EntryInfo(Record):
    """Description of one subindex for the SDO information service (a Record: no code generated at import)."""

    __slots__ = ("name", "data_type", "bit_length", "access")

    def __init__(self, name: str, data_type: int, bit_length: int, access: int) -> None:
        self.name = name
        self.data_type = data_type  # CANopen data type code (0x0007 UNSIGNED32 ...)
        self.bit_length = bit_length
        self.access = access  # ETG.1000.6 object access bits (0x07 read, 0x38 write, 0x40 RxPDO, 0x80 TxPDO)


class ObjectInfo(Record):
    """Description of one object (object code 7 VAR, 8 ARRAY, 9 RECORD)."""

    __slots__ = ("index", "name", "object_code", "data_type", "max_subindex", "entries")
    __hash__ = None  # type: ignore[assignment]  # holds a dict

    def __init__(self, index: int, name: str, object_code: int, data_type: int, max_subindex: int,
                 entries: dict[int, EntryInfo] | None = None) -> None:
        self.index = index
        self.name = name
        self.object_code = object_code
        self.data_type = data_type
        self.max_subindex = max_subindex
        self.entries: dict[int, EntryInfo] = {} if entries is None else entries


@runtime_checkable
class ObjectInfoAccess(Protocol):
    """Optional extension of ObjectAccess: the model can describe its dictionary."""

    def object_indices(self) -> Sequence[int]:
        """All object indices, ascending."""
        ...

    def object_info(self, index: int) -> ObjectInfo:
        """Describe one object; raises SdoAccessError(0x06020000) for unknown ones."""
        ...


class _Request(NamedTuple):
    """What a reply echoes of its request mailbox."""

    address: int
    counter: int


_UPLOAD_INITIATE = coe.UPLOAD_INITIATE_COMMAND

# Object access bits behind the SDO information list types 2..5.
_LIST_FILTER = {2: 0x0040, 3: 0x0080, 4: 0x0100, 5: 0x0200}


class _Download:
    """A segmented download in progress."""

    __slots__ = ("index", "subindex", "size", "buffer", "toggle")

    def __init__(self, index: int, subindex: int, size: int, buffer: bytearray, toggle: int = 0) -> None:
        self.index = index
        self.subindex = subindex
        self.size = size
        self.buffer = buffer
        self.toggle = toggle


class _Upload:
    """A segmented upload in progress."""

    __slots__ = ("index", "subindex", "remaining", "toggle")

    def __init__(self, index: int, subindex: int, remaining: bytes, toggle: int = 0) -> None:
        self.index = index
        self.subindex = subindex
        self.remaining = remaining
        self.toggle = toggle


class SdoServer:
    """The CoE side of one simulated slave; keeps the state of one segmented transfer."""

    def __init__(self, access: ObjectAccess, mailbox_size: int = 512, *, files: bool = False,
                 drive_model: bool = False) -> None:
        """``files``: the access objects this server is handed also store files (``foe_read``/``foe_write``,
        :class:`akdctl.sim.foe.FileAccess`), so FoE mailboxes are answered; otherwise they are refused.
        ``drive_model``: they are the drive's model (:class:`akdctl.sim.model.DriveModel`): the emergencies its
        fault component queued go out ahead of each answer, and a planned upload of a plain stored value is read
        by the model's ``object_read_parts`` (:meth:`handle`). Both declared, not probed."""
        if mailbox_size < 32:
            raise ValueError("mailbox_size must be at least 32 bytes")
        self.access = access
        self.files = files
        self.drive_model = drive_model
        # drive_model: the model last handed to this server, its fault component (a model's, once built, is kept
        # for the model's life) and the count of models seen (a plan's parts name the model they were read from by
        # that count: no plan keeps an old model alive)
        self._model: Any = None
        self._fault_queue: Any = None
        self._models_seen = 0
        self.mailbox_size = mailbox_size
        self._download: _Download | None = None
        self._upload: _Upload | None = None
        self._emergencies: list[Emergency] = []
        self._foe_server: object | None = None  # the FoE transfer in progress (built on the first FoE mailbox)
        self._emcy_counter = 0
        #: mailbox bytes -> the plan of a plain upload initiate (:meth:`_plan`)
        self._plans: dict[bytes, tuple[int, int, dict[int, tuple[bytes, bytes]], _Request, list[Any]]] = {}

    # --- public -----------------------------------------------------------------------------

    def queue_emergency(self, emergency: Emergency) -> None:
        """Deliver ``emergency`` (as a CoE service-1 mailbox) before the next response."""
        self._emergencies.append(emergency)

    def take_pending(self) -> list[bytes]:
        """Queued emergencies as mailboxes, for faces that can push without a request."""
        out: list[bytes] = []
        for emergency in self._emergencies:
            self._emcy_counter = mbx.next_counter(self._emcy_counter)
            data = coe.encode_coe(CoeService.EMERGENCY, encode_emcy(emergency))
            out.append(mbx.encode_mailbox(mbx.Mailbox(mbx.MailboxType.COE, data, counter=self._emcy_counter)))
        self._emergencies.clear()
        return out

    def handle(self, mailbox: bytes) -> list[bytes]:
        """Answer one request mailbox; returns the mailboxes the slave puts in SM1, in order.

        The poll's request, an upload initiate, is read once per distinct mailbox (``coe.plain_upload_initiate``)
        into a plan kept in :attr:`_plans` (:meth:`_plan` says why that is safe), and answered expedited by
        joining the value read from the model between the plan's two byte strings
        (``coe.expedited_upload_templates``); the same rules as :meth:`_upload_fast`, which answers it when the
        value is not expedited.

        With ``drive_model`` declared, the emergencies the drive queued since the last mailbox are taken first
        (outside the refusal below: what the fault component raises, a damaged state, reaches the caller), and the
        plan keeps what the model's ``object_read_parts`` says of its address, for that model and while its
        ``object_bindings_version`` stays (:meth:`_read_parts`): a plain stored value is then read from
        ``object_values`` itself, the rest through ``object_read``. The plan also keeps the expedited answer it gave
        from those parts with the value it joined: the same value object again (bytes: the same content) gets the
        same answer bytes; any other is joined anew. Only expedited answers are kept: a longer value's answer starts
        a transfer (:meth:`_upload_answer`), every time."""
        access = self.access
        model = self._model
        if self.drive_model:
            if access is not model:  # another model (the first, a reload): what was read of the last is forgotten
                self._fault_queue = access.faults  # type: ignore[attr-defined]
                self._model = model = access
                self._models_seen += 1
            if self._fault_queue.emergencies:  # the usual mailbox finds none and changes nothing
                self._emergencies += self._fault_queue.take_emergencies()
        try:
            try:
                plan = self._plans.get(mailbox)
            except (TypeError, ValueError):  # not hashable (a bytearray, a writable view): no plan kept for it
                plan = None
            if plan is None:
                plan = self._plan(mailbox)
            if plan is not None:
                index, subindex, templates, request, parts = plan
                self._download = self._upload = None
                # parts: [the model's number, its object_bindings_version, key, default, value, answer]
                # (_read_parts); the number is None until a drive model's read was planned, the key None for an
                # address object_read answers; value and answer: the last expedited answer given from the parts
                answer = None
                if parts[0] == self._models_seen and parts[1] == model.object_bindings_version \
                        and (key := parts[2]) is not None:
                    plain = True
                    value = model.object_values.get(key)
                    if value is None:
                        value = parts[3]
                    if value is parts[4]:  # the very bytes answered last (immutable, kept alive by the plan)
                        answer = parts[5]
                else:
                    plain = False
                    try:  # _read, inline: the poll's one call into the model
                        value = access.object_read(index, subindex)
                    except Exception as exc:  # noqa: BLE001 - every failure becomes an abort (_read_failed)
                        value = self._read_failed(index, subindex, exc)
                    else:
                        if self.drive_model and (parts[0] != self._models_seen
                                                 or parts[1] != model.object_bindings_version):
                            parts[:4] = self._models_seen, *self._read_parts(model, index, subindex)
                if answer is None:
                    cut = templates.get(len(value)) if value.__class__ is bytes else None  # None: not expedited
                    if cut is not None:
                        head, tail = cut
                        answer = head + value + tail if tail else head + value  # 4 bytes: no tail to join
                        if plain:
                            parts[4], parts[5] = value, answer
                    else:
                        if not isinstance(value, coe.SdoAbort):
                            value = bytes(value)
                        answer = self._upload_answer(request, index, subindex, value)
                replies = [answer]
            else:
                replies = self._handle(bytes(mailbox))
        except Exception:  # the simulator must never die on a request; log and refuse
            log.exception("SDO server failed on a mailbox request")
            replies = [self._error_reply(None, mbx.ERR_SYNTAX)]
        if not self._emergencies:
            return replies
        try:
            pending = self.take_pending()
        except CodecError:
            log.warning("dropped an emergency that cannot be encoded")
            self._emergencies.clear()
            pending = []
        return pending + replies

    def _plan(self, mailbox: bytes) -> tuple[int, int, dict[int, tuple[bytes, bytes]], _Request, list[Any]] | None:
        """What :meth:`handle` keeps of a plain upload initiate (None: another request, the general path answers):
        its index and subindex, the answer's templates and the request's address and counter.

        Why a memo by the mailbox's bytes: a client polls the same few objects, and reading the 16 bytes apart
        and packing the answer again was a measurable share of a served upload (issue 29). Everything the plan
        holds is read from those bytes alone, so the key covers it; the value is read from the model on every
        request. Its last item, the parts of a drive model's read (:meth:`_read_parts`) and the last answer given
        from them, is checked against the model at each use (:meth:`handle`). The memo is bounded
        (:data:`PLANS_KEPT`): many distinct requests start it over."""
        upload = plain_upload_initiate(mailbox)
        if upload is None:
            return None
        address, counter, index, subindex = upload
        plan = (index, subindex, coe.expedited_upload_templates(address, counter, index, subindex),
                _Request(address, counter), [None, -1, None, None, None, None])
        if mailbox.__class__ is bytes:
            remember(self._plans, mailbox, plan, PLANS_KEPT)
        return plan

    @staticmethod
    def _read_parts(model: Any, index: int, subindex: int) -> tuple[int, Any, Any]:
        """What a plan keeps of the drive model's ``object_read_parts``, after a read through ``object_read`` that
        did not fail: ``(object_bindings_version, key, default)``, key and default None when the address is not a
        plain stored value (a component binds it, or will once built).

        Why that key is complete: the model answers from its bindings (the version moves with each), static
        catalogue data and the stored value, which :meth:`handle` reads at each use; another model (a reload) is
        another number (:attr:`_models_seen`)."""
        version = model.object_bindings_version  # the read before this made whatever binding it builds
        read = model.object_read_parts(index, subindex)
        return (version, None, None) if read is None else (version, *read)

    # --- mailbox level ----------------------------------------------------------------------
    # A request is taken apart once (mailbox.split: type, counter, address, data) and every reply is packed
    # straight into bytes (mailbox.pack): channel and priority 0, the request's address and counter.

    def _error_reply(self, request: _Request | None, code: int) -> bytes:
        data = mbx.encode_error_reply(mbx.MailboxErrorReply(code))
        address, counter = (request.address, request.counter) if request else (0, 0)
        return mbx.pack(mbx.MailboxType.ERROR, data, address, counter)

    def _reply(self, request: _Request, service: int, payload: bytes) -> bytes:
        return mbx.pack(mbx.MailboxType.COE, coe.coe_header(service) + payload, request.address,
                        request.counter)

    def _handle(self, raw: bytes) -> list[bytes]:
        if len(raw) < mbx.HEADER_SIZE:
            return [self._error_reply(None, mbx.ERR_SIZE_TOO_SHORT)]
        try:
            mtype, counter, address, data = mbx.split(raw)
        except CodecError:
            return [self._error_reply(None, mbx.ERR_INVALID_SIZE)]
        request = _Request(address, counter)
        if mbx.HEADER_SIZE + len(data) > self.mailbox_size:
            return [self._error_reply(request, mbx.ERR_INVALID_SIZE)]
        if mtype == mbx.MailboxType.FOE and self.files:
            return self._foe(request, data)
        if mtype != mbx.MailboxType.COE:
            return [self._error_reply(request, mbx.ERR_UNSUPPORTED_PROTOCOL)]
        if raw[4] & 0x3F:  # the channel
            return [self._error_reply(request, mbx.ERR_INVALID_CHANNEL)]
        if len(data) < coe.COE_HEADER_SIZE:
            return [self._error_reply(request, mbx.ERR_SIZE_TOO_SHORT)]
        try:
            service, _number, payload = coe.decode_coe(data)
        except CoeError:
            return [self._error_reply(request, mbx.ERR_SERVICE_NOT_SUPPORTED)]
        if service == CoeService.SDO_REQUEST:
            if len(payload) < coe.SDO_SIZE:
                return [self._error_reply(request, mbx.ERR_SIZE_TOO_SHORT)]
            if payload[0] == _UPLOAD_INITIATE:  # the most frequent request: answered without message objects
                return [self._upload_fast(request, payload)]
            answer = self._sdo(payload)
            # ETG.1000.6: "Abort SDO Transfer" travels as CoE service 2 (SDO request), not 3; SOEM/pysoem
            # report an abort sent as a response as a malformed frame (found by the EtherCAT interop tests).
            service = CoeService.SDO_REQUEST if isinstance(answer, coe.SdoAbort) else CoeService.SDO_RESPONSE
            return [self._reply(request, service, coe.encode_sdo(answer))] if answer else []
        if service == CoeService.SDO_INFO:
            from akdctl.protocol import coe_info  # the SDO information service: loaded on first use

            return [self._reply(request, CoeService.SDO_INFO, coe_info.encode_sdo_info(f)) for f in self._info(payload)]
        return [self._error_reply(request, mbx.ERR_SERVICE_NOT_SUPPORTED)]

    def _upload_fast(self, request: _Request, payload: bytes) -> bytes:
        """An upload initiate without complete access (:meth:`_upload_initiate`'s rules), the expedited answer
        packed by the codec's fast path (``coe.pack_expedited_upload_response``, byte-equal to ``encode_sdo``)."""
        index, subindex = coe.sdo_address(payload)
        self._download = None
        self._upload = None
        return self._upload_answer(request, index, subindex, self._read(index, subindex))

    def _upload_answer(self, request: _Request, index: int, subindex: int, value: bytes | coe.SdoAbort) -> bytes:
        """The answer mailbox to an upload initiate whose value (or abort) was read."""
        if isinstance(value, bytes) and 1 <= len(value) <= 4:
            return self._reply(request, CoeService.SDO_RESPONSE,
                               coe.pack_expedited_upload_response(index, subindex, value))
        if isinstance(value, coe.SdoAbort):
            return self._reply(request, CoeService.SDO_REQUEST, coe.encode_sdo(value))
        answer = self._upload_normal(index, subindex, value)
        return self._reply(request, CoeService.SDO_RESPONSE, coe.encode_sdo(answer))

    # --- FoE --------------------------------------------------------------------------------

    def _foe(self, request: _Request, data: bytes) -> list[bytes]:
        """File access (mailbox type 4): the AKD's firmware path (docs/fidelity.md F10, :mod:`akdctl.sim.foe`)."""
        from akdctl.protocol import foe
        from akdctl.sim.foe import FoeServer

        try:
            frame = foe.decode_foe(data)
        except CodecError:
            return [self._error_reply(request, mbx.ERR_SIZE_TOO_SHORT)]
        if self._foe_server is None:
            self._foe_server = FoeServer()
        max_data = self.mailbox_size - mbx.HEADER_SIZE - foe.HEADER_SIZE
        reply = self._foe_server.handle(self.access, frame, max_data)  # type: ignore[arg-type]
        if reply is None:
            return []
        return [mbx.pack(mbx.MailboxType.FOE, foe.encode_foe(reply), request.address, request.counter)]

    # --- SDO --------------------------------------------------------------------------------

    def _abort(self, index: int, subindex: int, code: int) -> coe.SdoAbort:
        self._download = None
        self._upload = None
        return coe.SdoAbort(index, subindex, code)

    def _sdo(self, payload: bytes) -> coe.SdoMessage | None:
        try:
            msg = coe.decode_sdo(payload, from_server=False)
        except CoeError:
            index = payload[1] | payload[2] << 8
            return self._abort(index, payload[3], coe.ABORT_UNKNOWN_COMMAND)
        if isinstance(msg, coe.SdoAbort):
            self._download = None
            self._upload = None
            return None
        if isinstance(msg, coe.SdoUploadInitiate):
            return self._upload_initiate(msg)
        if isinstance(msg, coe.SdoUploadSegment):
            return self._upload_segment(msg)
        if isinstance(msg, coe.SdoDownloadInitiate):
            return self._download_initiate(msg)
        if isinstance(msg, coe.SdoDownloadSegment):
            return self._download_segment(msg)
        return self._abort(0, 0, coe.ABORT_UNKNOWN_COMMAND)  # pragma: no cover - decode covers all

    def _read(self, index: int, subindex: int) -> bytes | coe.SdoAbort:
        try:
            return bytes(self.access.object_read(index, subindex))
        except Exception as exc:  # noqa: BLE001 - every failure becomes an abort
            return self._read_failed(index, subindex, exc)

    def _read_failed(self, index: int, subindex: int, exc: Exception) -> coe.SdoAbort:
        """The abort a failed ``object_read`` answers with: the model's own code, else a general error (logged)."""
        if isinstance(exc, SdoAccessError):
            return self._abort(index, subindex, exc.code)
        log.error("object_read(0x%04X, %d) failed", index, subindex, exc_info=exc)
        return self._abort(index, subindex, coe.ABORT_GENERAL)

    def _write(self, index: int, subindex: int, data: bytes) -> coe.SdoAbort | None:
        try:
            self.access.object_write(index, subindex, bytes(data))
        except SdoAccessError as exc:
            return self._abort(index, subindex, exc.code)
        except Exception:
            log.exception("object_write(0x%04X, %d) failed", index, subindex)
            return self._abort(index, subindex, coe.ABORT_GENERAL)
        return None

    def _upload_initiate(self, msg: coe.SdoUploadInitiate) -> coe.SdoMessage:
        self._download = None
        self._upload = None
        if msg.complete_access:
            return self._abort(msg.index, msg.subindex, coe.ABORT_UNSUPPORTED_ACCESS)
        value = self._read(msg.index, msg.subindex)
        if isinstance(value, coe.SdoAbort):
            return value
        if 1 <= len(value) <= 4:
            return coe.SdoUploadResponse(msg.index, msg.subindex, value, len(value), True)
        return self._upload_normal(msg.index, msg.subindex, value)

    def _upload_normal(self, index: int, subindex: int, value: bytes) -> coe.SdoUploadResponse:
        """A value that is not expedited: size and as much data as the mailbox holds; the rest in segments."""
        room = self.mailbox_size - mbx.HEADER_SIZE - coe.NORMAL_OVERHEAD
        if len(value) > room:
            self._upload = _Upload(index, subindex, value[room:])
        return coe.SdoUploadResponse(index, subindex, value[:room], len(value), False)

    def _upload_segment(self, msg: coe.SdoUploadSegment) -> coe.SdoMessage:
        state = self._upload
        if state is None:
            return self._abort(0, 0, coe.ABORT_UNKNOWN_COMMAND)
        if msg.toggle != state.toggle:
            return self._abort(state.index, state.subindex, coe.ABORT_TOGGLE)
        room = self.mailbox_size - mbx.HEADER_SIZE - coe.SEGMENT_OVERHEAD
        chunk, state.remaining = state.remaining[:room], state.remaining[room:]
        last = not state.remaining
        reply = coe.SdoUploadSegmentResponse(state.toggle, chunk, last)
        state.toggle ^= 1
        if last:
            self._upload = None
        return reply

    def _download_initiate(self, msg: coe.SdoDownloadInitiate) -> coe.SdoMessage:
        self._download = None
        self._upload = None
        if msg.complete_access:
            return self._abort(msg.index, msg.subindex, coe.ABORT_UNSUPPORTED_ACCESS)
        if msg.expedited or msg.size is None or len(msg.data) >= msg.size:
            failed = self._write(msg.index, msg.subindex, msg.data)
            return failed or coe.SdoDownloadResponse(msg.index, msg.subindex)
        if msg.size > MAX_TRANSFER:
            return self._abort(msg.index, msg.subindex, coe.ABORT_OUT_OF_MEMORY)
        self._download = _Download(msg.index, msg.subindex, msg.size, bytearray(msg.data))
        return coe.SdoDownloadResponse(msg.index, msg.subindex)

    def _download_segment(self, msg: coe.SdoDownloadSegment) -> coe.SdoMessage:
        state = self._download
        if state is None:
            return self._abort(0, 0, coe.ABORT_UNKNOWN_COMMAND)
        if msg.toggle != state.toggle:
            return self._abort(state.index, state.subindex, coe.ABORT_TOGGLE)
        state.buffer += msg.data
        if len(state.buffer) > state.size:
            return self._abort(state.index, state.subindex, 0x06070012)
        if not msg.last:
            state.toggle ^= 1
            return coe.SdoDownloadSegmentResponse(msg.toggle)
        self._download = None
        if len(state.buffer) < state.size:
            return self._abort(state.index, state.subindex, 0x06070013)
        failed = self._write(state.index, state.subindex, bytes(state.buffer))
        return failed or coe.SdoDownloadSegmentResponse(msg.toggle)

    # --- SDO information --------------------------------------------------------------------

    def _info(self, payload: bytes) -> list[coe_info.SdoInfo]:
        from akdctl.protocol import coe_info

        try:
            frame = coe_info.decode_sdo_info(payload)
            request = coe_info.unpack_info(frame)
        except CoeError:
            return [coe_info.pack_info(coe_info.SdoInfoError(coe.ABORT_UNKNOWN_COMMAND))]
        access = self.access
        if not isinstance(access, ObjectInfoAccess):
            return [coe_info.pack_info(coe_info.SdoInfoError(0x08000023))]
        try:
            answer = self._info_answer(access, request)
        except SdoAccessError as exc:
            answer = coe_info.SdoInfoError(exc.code)
        except CodecError:
            answer = coe_info.SdoInfoError(coe.ABORT_GENERAL)
        except Exception:
            log.exception("SDO information request %r failed", request)
            answer = coe_info.SdoInfoError(coe.ABORT_GENERAL)
        room = self.mailbox_size - mbx.HEADER_SIZE - coe.COE_HEADER_SIZE - coe_info.SDO_INFO_HEADER_SIZE
        try:
            return coe_info.fragment_info(coe_info.pack_info(answer), room)
        except CodecError:
            return [coe_info.pack_info(coe_info.SdoInfoError(coe.ABORT_GENERAL))]

    def _info_answer(self, access: ObjectInfoAccess, request: coe_info.SdoInfoMessage) -> coe_info.SdoInfoMessage:
        from akdctl.protocol import coe_info

        if isinstance(request, coe_info.OdListRequest):
            indices = sorted(int(i) for i in access.object_indices())
            if request.list_type == 0:
                counts = [len(indices)] + [len(self._filtered(access, indices, t)) for t in (2, 3, 4, 5)]
                return coe_info.OdListResponse(0, tuple(counts))
            if request.list_type == coe_info.LIST_ALL:
                return coe_info.OdListResponse(1, tuple(indices))
            if request.list_type in _LIST_FILTER:
                return coe_info.OdListResponse(request.list_type, tuple(self._filtered(access, indices, request.list_type)))
            return coe_info.SdoInfoError(0x08000000)
        if isinstance(request, coe_info.ObjectDescriptionRequest):
            info = access.object_info(request.index)
            return coe_info.ObjectDescription(info.index, info.data_type, info.max_subindex, info.object_code, info.name)
        if isinstance(request, coe_info.EntryDescriptionRequest):
            info = access.object_info(request.index)
            entry = info.entries.get(request.subindex)
            if entry is None:
                raise SdoAccessError(coe.ABORT_NO_SUBINDEX)
            return coe_info.EntryDescription(
                request.index, request.subindex, 0, entry.data_type, entry.bit_length, entry.access, entry.name
            )
        # a response opcode sent to the slave
        return coe_info.SdoInfoError(coe.ABORT_UNKNOWN_COMMAND)

    @staticmethod
    def _filtered(access: ObjectInfoAccess, indices: list[int], list_type: int) -> list[int]:
        bit = _LIST_FILTER[list_type]
        out = []
        for index in indices:
            try:
                info = access.object_info(index)
            except SdoAccessError:
                continue
            if any(entry.access & bit for entry in info.entries.values()):
                out.append(index)
        return out
