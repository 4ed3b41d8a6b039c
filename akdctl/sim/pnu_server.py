"""The drive side of PROFIdrive base-mode parameter access: request bytes in, response bytes out.

:class:`PnuServer` answers like the AKD's parameter manager (PROFINET manual 3.6,
PROFIdrive V4.1): it mirrors reference and axis, checks the request in the order
a device does, and asks a :class:`ParameterAccess` (the drive model) for values.
Front ends (the simulated record link, the PNIO RPC face) hand it the bytes of
record 47 and send back what it returns; the only exception it raises is
:class:`RecordRefused`, for a request the record layer itself refuses (below).

How a request is refused:

=====================================================  ===================================================
request                                                answer
=====================================================  ===================================================
shorter than the 4-byte header, or longer than 240     no response: the record write is refused,
                                                       Error_Code_1 ``0xB1`` write length error
request reference 0x00 (reserved, manual 3.5), or      no response: the record write is refused,
request ID neither 0x01 nor 0x02                       Error_Code_1 ``0xB7`` (error in the request header)
number of parameters 0                                 ``0x16``
number of parameters above 39                          ``0x22`` too many parameters
axis other than the served ones (AKD: 0)               ``0x19`` axis/DO nonexistent
parameter addresses cut short                          ``0x16``
change: value block with an unknown format             ``0x17`` illegal format, whole
change: value blocks cut short / extra bytes;          ``0x18`` number of values inconsistent, whole
read: any bytes after the addresses
attribute not 0x10/0x20 (AKD has no texts), elements   ``0x16`` for that parameter
0 or > 234, subindex 0xFFFF, PNU 0
change: format 0x40/0x44 or 0x00                       ``0x17`` for that parameter
change: number of values ≠ number of elements          ``0x18`` for that parameter
change of a description                                ``0x07`` (additional info: subindex)
description element beyond 12                          ``0x03`` faulty subindex (additional info: subindex)
value larger than 234 bytes                            ``0x15`` response too long for that parameter
whole response larger than 240 bytes                   ``0x15`` for every parameter
the model raises :class:`PnuAccessError`               its error value and additional info
the model fails otherwise (a bug)                      ``0x11`` request cannot be executed for that
                                                       parameter (exception kept in ``last_exception``)
=====================================================  ===================================================

"Whole" errors answer every parameter with the same error block (header number of
parameters mirrored when it is 1..39, else 1), so a strict client decodes them.

Why some requests get no response at all: a response mirrors the request
reference and answers with one of the response IDs the manual lists (0x01, 0x02,
0x81, 0x82; manual 3.5 record data table). A request whose reference is the
reserved 0x00, or whose request ID is neither 0x01 nor 0x02, leaves nothing valid
to answer with, so the PROFIdrive profile refuses it one layer down: the write of
record 47 fails with Error_Code_1 0xB7, "write with an error in the base-mode
request header" (PDRV V4.2 table 169, ``reference/profidrive_reference.md``); a
record too short for the header or longer than 240 bytes fails with 0xB1 (write
length error). :meth:`PnuServer.handle` raises :class:`RecordRefused` for those,
and the record layer in front of it (the simulated record link, the PNIO face)
turns it into the record-layer refusal. SPEC-NOTES style ruling: docs/fidelity.md F1.

Multi-parameter changes are applied in order, one by one, as PROFIdrive devices do:
a refused parameter does not undo the accepted ones; the response is then 0x82
with format 0x40 for the accepted parameters and 0x44 for the refused ones.
A structurally broken change request writes nothing.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Collection
from typing import Any, Protocol

from akdctl.sim.errors import PnuAccessError, RecordRefused  # noqa: F401  (re-exported: servers raise and catch them)
from akdctl.protocol.bmp import (
    ADDRESS_SIZE,
    ATTR_DESCRIPTION,
    ATTR_VALUE,
    DESCRIPTION_ELEMENTS,
    ERR_ADDRESS,
    ERR_AXIS,
    ERR_DATA_TYPE,
    ERR_DESCRIPTION_READ_ONLY,
    ERR_FORMAT,
    ERR_OPERATING_STATE,
    ERR_RESPONSE_TOO_LONG,
    ERR_SUBINDEX,
    ERR_TOO_MANY,
    ERR_VALUE_COUNT,
    HEADER_SIZE,
    MAX_BLOCK,
    MAX_ELEMENTS,
    MAX_PARAMETERS,
    MAX_SUBINDEX,
    REQ_CHANGE,
    REQ_READ,
    RESP_CHANGE_NAK,
    RESP_CHANGE_OK,
    RESP_READ_OK,
    BmpError,
    Format,
    ParameterAddress,
    ParameterDescription,
    ParameterFailure,
    ParameterResponse,
    ParameterResult,
    ParameterValue,
    decode_address,
    decode_value_block,
    description_element,
    encode_response,
    encode_value_block,
    first_read_address,
    format_size,
    iter_read_addresses,
    pack_failure_block,
    pack_read_response,
    raw_block_layout,
    one_read_response_packer,
    raw_batch_response_layout,
    raw_batch_value_positions,
    raw_read_response_layout,
    to_signed,
    to_unsigned,
)



class ParameterAccess(Protocol):
    """What :class:`PnuServer` needs from a drive model (``DriveModel`` implements it)."""

    def pnu_read(self, pnu: int, subindex: int, count: int) -> ParameterValue:
        """``count`` elements from ``subindex``; raises :class:`PnuAccessError`."""
        ...

    def pnu_write(self, pnu: int, subindex: int, value: ParameterValue) -> None:
        """Store the elements of ``value`` from ``subindex`` on; raises :class:`PnuAccessError`."""
        ...

    def pnu_describe(self, pnu: int) -> ParameterDescription:
        """The parameter's description; raises :class:`PnuAccessError` (0x00 for an unknown PNU)."""
        ...


# (bits, signed) of the integer formats, for format conversion on write.
_INTEGERS: dict[int, tuple[int, bool]] = {
    Format.INT8: (8, True), Format.INT16: (16, True), Format.INT32: (32, True), Format.INT64: (64, True),
    Format.UINT8: (8, False), Format.UINT16: (16, False), Format.UINT32: (32, False), Format.UINT64: (64, False),
    Format.BYTE: (8, False), Format.WORD: (16, False), Format.DWORD: (32, False),
    Format.N2: (16, True), Format.X2: (16, True), Format.E2: (16, True),
    Format.V2: (16, False), Format.L2: (16, False), Format.R2: (16, False), Format.T2: (16, False),
    Format.D2: (16, False), Format.N4: (32, True), Format.X4: (32, True), Format.C4: (32, True),
    Format.T4: (32, False),
}
_UNTYPED = frozenset({Format.BYTE, Format.WORD, Format.DWORD})
_FORMATS = frozenset(int(f) for f in Format)


def convert_value(value: ParameterValue, data_type: int) -> ParameterValue:
    """Bring a written value into the parameter's data type, or refuse with 0x05 (incorrect data type).

    PROFIdrive lets a client write a parameter in its own format or as Byte/Word/
    DWord of the same width (the AKD documents only those three, SPEC-NOTES 5); a
    model declared with Byte/Word/DWord likewise accepts a typed integer of its
    width. Bits are kept, signedness follows ``data_type``.
    """
    if value.format == data_type:
        return value
    source, target = _INTEGERS.get(value.format), _INTEGERS.get(data_type)
    if (source is not None and target is not None and source[0] == target[0]
            and (value.format in _UNTYPED or data_type in _UNTYPED)):
        bits, signed = target
        converted = tuple(to_signed(int(v), bits) if signed else to_unsigned(int(v), bits)  # type: ignore[arg-type]
                          for v in value.values)
        return ParameterValue(data_type, converted)
    raise PnuAccessError(ERR_DATA_TYPE, message=f"format 0x{value.format:02X} cannot be written to a parameter "
                                                f"of type 0x{data_type:02X}")


class _WholeRequest(Exception):
    """A refusal of the entire request (header or structure), answered with one error for every parameter."""

    def __init__(self, error: int) -> None:
        super().__init__(error)
        self.error = error


#: PDRV V4.2 table 169 Error_Code_1 of a refused record write (``reference/profidrive_reference.md``).
EC1_WRITE_LENGTH = 0xB1  # the record is shorter than the request header or longer than 240 bytes
EC1_HEADER = 0xB7  # "invalid range": an error in the base-mode request header


def header_refusal(request: bytes) -> int | None:
    """The record-layer Error_Code_1 for a request no base-mode response can answer, else None."""
    if not HEADER_SIZE <= len(request) <= MAX_BLOCK:
        return EC1_WRITE_LENGTH
    if request[0] == 0x00 or request[1] not in (REQ_READ, REQ_CHANGE):
        return EC1_HEADER
    return None


def raw_value_address(attribute: int, count: int, pnu: int, subindex: int) -> bool:
    """Whether the model's raw access answers this read address (a value of 1..MAX_ELEMENTS elements of a PNU
    other than 0, within the subindex range); every other address takes the general path (:meth:`PnuServer.
    _read_one`), which refuses or describes it. The one rule for the unplanned, single, planned and batch reads."""
    return attribute == ATTR_VALUE and 1 <= count <= MAX_ELEMENTS and pnu != 0 and subindex <= MAX_SUBINDEX


_ONE_READ_SIZE = HEADER_SIZE + ADDRESS_SIZE  # a read request of one parameter
_PLANS = 256  # one-parameter read plans a server keeps (request shapes; a poll has a few)
_BATCHES = 64  # batch read plans a server keeps (request shapes of two or more parameters)


class _BatchPlan:
    """A read request of several parameters resolved once (:meth:`PnuServer._plan_batch`), by its bytes after the
    reference: for each parameter, what answers it -- the model's getter of its values (``DriveModel.
    pnu_value_getter``), the refusal the catalogue gives it (an unknown PNU, a subindex out of range: fixed), or
    the general path (descriptions, texts, malformed addresses) -- and, when every one is a getter whose values
    fit, the whole positive response as one pack. The values are read at every request; the plan holds while the
    server's model is ``model`` and its bindings' version is ``version``."""

    __slots__ = ("model", "version", "steps", "reads", "pack", "arguments")

    def __init__(self, model: Any, version: int, steps: list[tuple[Any, bytes | None, int, tuple[int, int, int, int]]],
                 layout: tuple[Any, list[Any]] | None, positions: list[int]) -> None:
        self.model = model
        self.version = version
        #: per parameter: (getter or None, fixed block or None, format, (attribute, count, PNU, subindex))
        self.steps = steps
        #: the one-pack way (every step a getter): per parameter (getter, first argument, end argument)
        self.reads = [(get, at, at + address[1]) for (get, _b, _f, address), at in zip(steps, positions)]
        self.pack, self.arguments = layout if layout is not None else (None, [])


class PnuServer:
    """Answers base-mode parameter requests over a :class:`ParameterAccess`."""

    def __init__(self, access: ParameterAccess, *, axes: Collection[int] = (0,), raw_reads: bool = False) -> None:
        """``raw_reads``: the access objects this server is handed also answer ``pnu_read_raw`` (DriveModel's
        (format, unsigned values) without objects) and ``pnu_read_parts``, and reads take that fast path;
        declared, not probed."""
        self.access = access
        self.raw_reads = raw_reads
        self.axes = frozenset(axes)
        self.last_exception: BaseException | None = None
        # The one-parameter value reads seen, by the request's bytes after the reference: [PNU, subindex, count,
        # format, response layout, model, bindings' version, reader, mask, axis, fixed bytes, quick], the checks of the
        # request and its address passed once (_plan); the layout is bmp.raw_read_response_layout's for the format
        # the model last answered -- for a computed element's read, bmp.one_read_response_packer's pack and its fixed
        # bytes; the model, version, reader and mask are the model's parts of such a read (_plan_parts), taken again
        # when another model (a reload) or a new binding serves it; last, those parts with the pack and its bytes as
        # one tuple when there is a pack (handle's quick way: one unpack, not eight lookups in the list), else None.
        # The value is read each time.
        self._plans: dict[bytes, list[Any]] = {}
        # The reads of several parameters seen, by the request's bytes after the reference (_BatchPlan, _plan_batch)
        self._batches: dict[bytes, _BatchPlan] = {}

    # -- entry point -----------------------------------------------------------------------------------------

    def handle(self, request: bytes) -> bytes:
        """Response bytes for ``request``; raises only :class:`RecordRefused` (module docstring)."""
        data = request
        if data.__class__ is not bytes:  # the usual bytes: not a call to copy them (nor one to ask their type)
            data = bytes(data)
        plan = self._plans.get(data[1:])
        if plan is not None and (reference := data[0]):
            try:
                quick = plan[11]
                if quick is not None:
                    model, version, read, mask, pack, fixed = quick
                    if self.access is model and model.pnu_bindings_version == version:
                        # the poll's request: a computed element read by the parts the plan holds for this model
                        # (DriveModel.pnu_read_raw's steps, inline), packed by bmp.one_read_response_packer's pack
                        try:
                            values = read(0, 1)
                            value = values[0] & mask if len(values) == 1 else None
                        except Exception as exc:  # noqa: BLE001 - refused as _read_raw refuses it
                            return self._read_planned(data, plan[0], plan[1], plan[2], exc)
                        if value is not None:
                            try:
                                return pack(reference, fixed, value)  # type: ignore[no-any-return]
                            except struct.error:
                                pass  # _raw_block says so
                        return self._read_computed(data, plan, values, value)
                return self._read_plan(data, plan)
            except Exception as exc:  # noqa: BLE001 - as the unplanned read below: a bug still gets an answer
                self.last_exception = exc
                return self._refuse(data, ERR_OPERATING_STATE)
        if len(data) == _ONE_READ_SIZE and data[1] == REQ_READ and data[3] == 1 and data[0] and data[2] in self.axes:
            # one parameter read, the poll's request: the checks header_refusal and _handle make of it, passed
            try:
                if self.raw_reads:
                    self._plan(data)
                return self._read_single(data)
            except _WholeRequest as refusal:
                return self._refuse(data, refusal.error)
            except Exception as exc:  # noqa: BLE001 - as below
                self.last_exception = exc
                return self._refuse(data, ERR_OPERATING_STATE)
        if self._batches and data[0]:
            batch = self._batches.get(data[1:])
            if batch is not None:  # a read of several parameters seen before: its checks passed on the same bytes
                try:
                    if batch.model is self.access and batch.model.pnu_bindings_version == batch.version:
                        return self._read_batch(data, batch)
                    return self._read_all(data, data[3])  # planned again for the model now served
                except _WholeRequest as refusal:
                    return self._refuse(data, refusal.error)
                except Exception as exc:  # noqa: BLE001 - as below
                    self.last_exception = exc
                    return self._refuse(data, ERR_OPERATING_STATE)
        code1 = header_refusal(data)
        if code1 is not None:
            what = "length" if code1 == EC1_WRITE_LENGTH else "header"
            raise RecordRefused(code1, f"base-mode request {what} refused (Error_Code_1 0x{code1:02X})")
        try:
            return self._handle(data)
        except _WholeRequest as refusal:
            return self._refuse(data, refusal.error)
        except Exception as exc:  # noqa: BLE001 - a model bug must still produce an answer, as a device would
            self.last_exception = exc
            return self._refuse(data, ERR_OPERATING_STATE)

    def _read_computed(self, data: bytes, plan: list[Any], values: Any, value: int | None) -> bytes:
        """A planned computed element's read that :meth:`handle` did not pack itself (the reader gave other than one
        value, the plan has no packer, or the value does not fit it): answered by :meth:`_read_planned`."""
        if value is None:
            try:
                values = [v & plan[8] for v in values]
            except Exception as exc:  # noqa: BLE001 - refused as _read_raw refuses it
                return self._read_planned(data, plan[0], plan[1], plan[2], exc)
        else:
            values = [value]
        return self._read_planned(data, plan[0], plan[1], plan[2], (plan[3], values))

    def _read_plan(self, data: bytes, plan: list[Any]) -> bytes:
        """A planned read whose parts are not (or no longer) this model's, or that has none: the parts taken again
        (:meth:`_plan_parts`), then read as a computed element or through ``pnu_read_raw``, whose format's layout
        the plan keeps."""
        pnu, subindex, count, planned_format, layout, model, version, read, mask, _axis, fixed, _quick = plan
        access = self.access
        if access is not model or (read is not None and model.pnu_bindings_version != version):
            read = self._plan_parts(plan, access)
            planned_format, layout, mask, fixed = plan[3], plan[4], plan[8], plan[10]
        if read is not None:  # DriveModel.pnu_read_raw's steps for a computed element, inline
            try:
                values = read(0, 1)
                value = values[0] & mask if len(values) == 1 else None
            except Exception as exc:  # noqa: BLE001 - refused as _read_raw refuses it
                return self._read_planned(data, pnu, subindex, count, exc)
            if value is not None and layout is not None:  # here: the plan's one_read_response_packer
                try:
                    return layout(data[0], fixed, value)  # type: ignore[no-any-return]
                except struct.error:
                    pass  # _raw_block says so
            return self._read_computed(data, plan, values, value)
        try:
            fmt, values = access.pnu_read_raw(pnu, subindex, count)  # type: ignore[attr-defined]
        except Exception as exc:  # noqa: BLE001 - refused as _read_raw refuses it
            return self._read_planned(data, pnu, subindex, count, exc)
        if fmt != planned_format:  # the first read of the plan (or a model answering another format)
            layout = raw_read_response_layout(fmt, count)
            plan[3], plan[4] = fmt, layout
        if layout is not None and len(values) == count:
            try:
                return layout.pack(data[0], RESP_READ_OK, data[2], 1, fmt, count, *values)  # type: ignore[no-any-return]
            except struct.error:
                pass  # _raw_block says so
        return self._read_planned(data, pnu, subindex, count, (fmt, values))

    @staticmethod
    def _refuse(data: bytes, error: int) -> bytes:
        """One error block for every parameter of the request (see the module table); the header is valid."""
        ref, rid, axis, n = data[0], data[1], data[2], data[3]
        response_id = rid | 0x80
        count = n if 1 <= n <= MAX_PARAMETERS else 1
        block = bytes((Format.ERROR, 1, error >> 8 & 0xFF, error & 0xFF))
        return bytes((ref, response_id, axis, count)) + block * count

    def _handle(self, data: bytes) -> bytes:
        reference, request_id, axis, n = data[0], data[1], data[2], data[3]  # header_refusal checked them
        if n == 0:
            raise _WholeRequest(ERR_ADDRESS)
        if n > MAX_PARAMETERS:
            raise _WholeRequest(ERR_TOO_MANY)
        if axis not in self.axes:
            raise _WholeRequest(ERR_AXIS)
        offset = HEADER_SIZE + ADDRESS_SIZE * n
        if len(data) < offset:
            raise _WholeRequest(ERR_ADDRESS)
        if request_id == REQ_READ:
            if offset != len(data):
                raise _WholeRequest(ERR_VALUE_COUNT)
            return self._read_all(data, n)
        addresses = [decode_address(data, HEADER_SIZE + ADDRESS_SIZE * i) for i in range(n)]
        blocks = self._value_blocks(data, offset, n)
        results = [self._change_one(a, b) for a, b in zip(addresses, blocks)]
        negative = any(r is not None for r in results)
        response_id = RESP_CHANGE_NAK if negative else RESP_CHANGE_OK
        try:
            return encode_response(ParameterResponse(reference, response_id, axis, tuple(results)))
        except BmpError:  # every block was validated alone: only the total size can be wrong
            raise _WholeRequest(ERR_RESPONSE_TOO_LONG) from None

    def _read_all(self, data: bytes, n: int) -> bytes:
        """A read response: each parameter's value block (or error block) packed as it is read.

        Why bytes and not ``encode_response``: a read is the request every poll makes, and each parameter was
        checked alone already; packing once costs less than building, validating and encoding result objects.
        The blocks are those ``encode_value_block`` / ``encode_response`` write (tests/test_pnu_server.py).
        """
        if self.raw_reads and n > 1:
            plan = self._plan_batch(data, n)
            if plan is not None:
                return self._read_batch(data, plan)
        return self._read_each(data, n)

    def _read_each(self, data: bytes, n: int) -> bytes:
        """:meth:`_read_all` parameter by parameter, unplanned (the general path a batch plan stands for)."""
        raw: Callable[[int, int, int], tuple[int, list[int]]] | None = (
            self.access.pnu_read_raw if self.raw_reads else None)  # type: ignore[attr-defined]
        blocks = []
        for attribute, count, pnu, subindex in iter_read_addresses(data, n):
            if raw is not None and raw_value_address(attribute, count, pnu, subindex):
                blocks.append(self._read_raw(raw, pnu, subindex, count))
            else:
                blocks.append(self._general_block(attribute, count, pnu, subindex))
        return _response(data, blocks)

    def _plan_batch(self, data: bytes, n: int) -> _BatchPlan | None:
        """The plan of a checked read request of ``n`` parameters (:class:`_BatchPlan`), remembered by its bytes after
        the reference; None (and nothing remembered) when the model fails otherwise than with a refusal while it is
        taken (a damaged component: :meth:`_read_each` answers, as it always did)."""
        from akdctl.sim.memo import remember

        access = self.access
        for _attempt in range(3):  # a first access may build a lazy component, which binds PNUs: take it again
            version = access.pnu_bindings_version  # type: ignore[attr-defined]
            steps: list[tuple[Any, bytes | None, int, tuple[int, int, int, int]]] = []
            for address in iter_read_addresses(data, n):
                attribute, count, pnu, subindex = address
                if not raw_value_address(attribute, count, pnu, subindex):
                    steps.append((None, None, 0, address))  # the general path (_read_one) answers it
                    continue
                try:
                    fmt, get = access.pnu_value_getter(pnu, subindex, count)  # type: ignore[attr-defined]
                except PnuAccessError as exc:  # the catalogue's refusal of this address
                    steps.append((None, pack_failure_block(exc.error, exc.additional), 0, address))
                    continue
                except Exception:  # noqa: BLE001 - not a fixed refusal: nothing to plan
                    return None
                steps.append((get, None, fmt, address))
            if access.pnu_bindings_version == version:  # type: ignore[attr-defined]
                break
        else:
            return None
        shapes = [(fmt, address[1]) for _get, _block, fmt, address in steps]
        every = all(get is not None for get, _block, _fmt, _address in steps)
        layout = raw_batch_response_layout(shapes, data[2]) if every else None
        plan = _BatchPlan(access, version, steps, layout, raw_batch_value_positions(shapes))
        return remember(self._batches, data[1:], plan, _BATCHES)

    def _read_batch(self, data: bytes, plan: _BatchPlan) -> bytes:
        """The response to a planned read of several parameters: each value read now, packed at once when every
        parameter answers its values and they fit; else block by block as :meth:`_read_each` answers."""
        got: list[Any] = []
        pack = plan.pack
        if pack is not None:
            arguments = plan.arguments.copy()
            append = got.append
            for get, at, end in plan.reads:
                try:
                    values = get()
                except Exception as exc:  # noqa: BLE001 - refused block by block, as _read_raw refuses it
                    append(exc)
                    break
                append(values)
                if len(values) != end - at:
                    break
                arguments[at:end] = values
            else:
                arguments[0] = data[0]
                try:
                    return pack(*arguments)  # type: ignore[no-any-return]
                except struct.error:
                    pass  # a value that does not fit: _raw_block says so for its parameter
        blocks = []
        done = len(got)
        for i, (get, block, fmt, address) in enumerate(plan.steps):
            if get is not None:
                if i < done:
                    outcome = got[i]
                else:
                    try:
                        outcome = get()
                    except Exception as exc:  # noqa: BLE001 - as _read_raw
                        outcome = exc
                if isinstance(outcome, Exception):
                    block = self._raw_failure(outcome)
                else:
                    block = self._raw_block(address[2], address[1], fmt, outcome)
            elif block is None:
                block = self._general_block(*address)
            blocks.append(block)
        return _response(data, blocks)

    def _read_single(self, data: bytes) -> bytes:
        """:meth:`_read_all` of a one-parameter read, its raw path without the loop."""
        attribute, count, pnu, subindex = first_read_address(data)
        if not (self.raw_reads and raw_value_address(attribute, count, pnu, subindex)):
            return self._read_all(data, 1)
        raw = self.access.pnu_read_raw  # type: ignore[attr-defined]
        return _response(data, [self._read_raw(raw, pnu, subindex, count)])

    def _plan(self, data: bytes) -> None:
        """Remember a one-parameter read of a value (the request checked by :meth:`handle`) whose address
        :meth:`_read_single` takes the raw way: its next requests go to :meth:`_read_planned` at once."""
        attribute, count, pnu, subindex = first_read_address(data)
        if raw_value_address(attribute, count, pnu, subindex):
            plans = self._plans
            if len(plans) >= _PLANS:
                plans.clear()  # a client walking every address: start over rather than grow
            # the format and layout: at the first planned read; the model's parts for it: _plan_parts
            plans[data[1:]] = [pnu, subindex, count, -1, None, None, -1, None, 0, data[2], b"", None]

    @staticmethod
    def _plan_parts(plan: list[Any], access: Any) -> Any:
        """Take a plan's read parts from ``access`` (``DriveModel.pnu_read_parts``: format, mask and the reader of a
        computed element) and the bindings' version they hold for; the reader, or None when the read is not of that
        kind (or the access has no parts to give): then :meth:`handle` reads through ``pnu_read_raw`` as before."""
        try:
            parts = access.pnu_read_parts(plan[0], plan[1], plan[2])
            version = access.pnu_bindings_version
        except Exception:  # noqa: BLE001 - pnu_read_raw says the same on the read itself
            parts, version = None, -1
        plan[5], plan[6] = access, version
        if parts is None:
            plan[3], plan[4], plan[7] = -1, None, None  # pnu_read_raw's way: its first read takes the layout again
            plan[11] = None
            return None
        fmt, mask, read = parts
        packer = one_read_response_packer(fmt, plan[9])
        plan[3], plan[7], plan[8] = fmt, read, mask
        plan[4], plan[10] = packer if packer is not None else (None, b"")
        # what handle's quick way reads: the parts with the model and version they hold for, and the packer
        plan[11] = None if packer is None else (access, version, read, mask, plan[4], plan[10])
        return read

    def _read_planned(self, data: bytes, pnu: int, subindex: int, count: int,
                      read: tuple[int, list[int]] | Exception) -> bytes:
        """The response to a planned read (:meth:`handle` packs the usual one itself) from what the model's raw
        access returned or raised: as :meth:`_read_single` answers it, refusals included."""
        block = self._raw_failure(read) if isinstance(read, Exception) else self._raw_block(pnu, count, *read)
        return _response(data, [block])

    def _raw_failure(self, exc: Exception) -> bytes:
        if isinstance(exc, PnuAccessError):
            return pack_failure_block(exc.error, exc.additional)
        self.last_exception = exc  # a model bug refuses this parameter only
        return pack_failure_block(ERR_OPERATING_STATE)

    def _general_block(self, attribute: int, count: int, pnu: int, subindex: int) -> bytes:
        """The block the general path answers an address with (a description, a text, a refusal)."""
        return self._block(self._read_one(ParameterAddress(pnu, subindex, count, attribute)))

    def _read_raw(self, raw: Callable[[int, int, int], tuple[int, list[int]]], pnu: int, subindex: int,
                  count: int) -> bytes:
        """One value read through the model's raw access, as its value block."""
        try:
            fmt, values = raw(pnu, subindex, count)
        except Exception as exc:  # noqa: BLE001 - PnuAccessError, or a model bug: refuses this parameter only
            return self._raw_failure(exc)
        return self._raw_block(pnu, count, fmt, values)

    def _raw_block(self, pnu: int, count: int, fmt: int, values: list[int]) -> bytes:
        """The value block of what the model's raw access returned, or the refusal of a reply it cannot be."""
        block = raw_block_layout(fmt, count)
        if block is None or len(values) != count:
            self.last_exception = ValueError(f"pnu_read_raw({pnu}) returned format {fmt} with {len(values)} values "
                                             f"for {count} elements")
            return pack_failure_block(ERR_OPERATING_STATE)
        if block.size > MAX_BLOCK - HEADER_SIZE:
            return pack_failure_block(ERR_RESPONSE_TOO_LONG)
        try:
            return block.pack(fmt, count, *values)
        except struct.error as exc:
            self.last_exception = exc
            return pack_failure_block(ERR_OPERATING_STATE)

    @staticmethod
    def _block(result: ParameterResult) -> bytes:
        if isinstance(result, ParameterFailure):
            return pack_failure_block(result.error, result.additional)
        assert isinstance(result, ParameterValue)  # _read_one answers a value or a failure
        return b"\x40\x00" if result.format == Format.ZERO else encode_value_block(result)

    # -- parsing -------------------------------------------------------------------------------------------------

    @staticmethod
    def _value_blocks(data: bytes, offset: int, n: int) -> list[ParameterResult]:
        """All value blocks of a change request, or a whole-request refusal if they do not parse."""
        blocks: list[ParameterResult] = []
        for _ in range(n):
            if offset + 2 > len(data):
                raise _WholeRequest(ERR_VALUE_COUNT)
            fmt = data[offset]
            if fmt != 0 and fmt not in _FORMATS:
                raise _WholeRequest(ERR_FORMAT)
            try:
                block, offset = decode_value_block(data, offset)
            except BmpError:
                raise _WholeRequest(ERR_VALUE_COUNT) from None
            blocks.append(block)
        if offset != len(data):
            raise _WholeRequest(ERR_VALUE_COUNT)
        return blocks

    @staticmethod
    def _address_error(address: ParameterAddress) -> ParameterFailure | None:
        if (address.attribute not in (ATTR_VALUE, ATTR_DESCRIPTION) or not 1 <= address.count <= MAX_ELEMENTS
                or address.subindex > MAX_SUBINDEX or address.pnu == 0):
            return ParameterFailure(ERR_ADDRESS)
        return None

    # -- one parameter -------------------------------------------------------------------------------------------

    def _read_one(self, address: ParameterAddress) -> ParameterResult:
        failure = self._address_error(address)
        if failure is not None:
            return failure
        try:
            if address.attribute == ATTR_DESCRIPTION:
                return self._describe_one(address)
            value = self.access.pnu_read(address.pnu, address.subindex, address.count)
        except PnuAccessError as exc:
            return ParameterFailure(exc.error, exc.additional)
        except Exception as exc:  # noqa: BLE001 - a model bug refuses this parameter only
            self.last_exception = exc
            return ParameterFailure(ERR_OPERATING_STATE)
        return self._checked(value, address)

    def _describe_one(self, address: ParameterAddress) -> ParameterResult:
        if address.subindex != 0 and address.count != 1:
            return ParameterFailure(ERR_ADDRESS)
        description = self.access.pnu_describe(address.pnu)
        if address.subindex != 0 and address.subindex not in DESCRIPTION_ELEMENTS:
            return ParameterFailure(ERR_SUBINDEX, address.subindex)
        try:
            return description_element(description, address.subindex)
        except BmpError as exc:
            self.last_exception = exc
            return ParameterFailure(ERR_OPERATING_STATE)

    def _checked(self, value: object, address: ParameterAddress) -> ParameterResult:
        """A model's answer, validated so one bad value cannot break the whole response."""
        if not isinstance(value, ParameterValue):
            self.last_exception = TypeError(f"pnu_read({address.pnu}) returned {value!r}")
            return ParameterFailure(ERR_OPERATING_STATE)
        try:
            if value.count * format_size(value.format) > MAX_BLOCK - HEADER_SIZE - 2:
                return ParameterFailure(ERR_RESPONSE_TOO_LONG)
            encode_value_block(value)
        except BmpError as exc:
            self.last_exception = exc
            return ParameterFailure(ERR_OPERATING_STATE)
        if value.count != address.count:
            self.last_exception = ValueError(f"pnu_read({address.pnu}) returned {value.count} values "
                                             f"for {address.count} elements")
            return ParameterFailure(ERR_OPERATING_STATE)
        return value

    def _change_one(self, address: ParameterAddress, block: ParameterResult) -> ParameterFailure | None:
        failure = self._address_error(address)
        if failure is not None:
            return failure
        try:
            if address.attribute == ATTR_DESCRIPTION:
                self.access.pnu_describe(address.pnu)  # an unknown PNU says so first
                return ParameterFailure(ERR_DESCRIPTION_READ_ONLY, address.subindex)
            if not isinstance(block, ParameterValue):
                return ParameterFailure(ERR_FORMAT)
            if block.count != address.count:
                return ParameterFailure(ERR_VALUE_COUNT)
            self.access.pnu_write(address.pnu, address.subindex, block)
        except PnuAccessError as exc:
            return ParameterFailure(exc.error, exc.additional)
        except Exception as exc:  # noqa: BLE001 - a model bug refuses this parameter only
            self.last_exception = exc
            return ParameterFailure(ERR_OPERATING_STATE)
        return None


def _response(data: bytes, blocks: list[bytes]) -> bytes:
    """The read response of ``blocks`` (negative when one is an error block); a whole request refused when it
    would not fit a record (every read path's last step)."""
    out = pack_read_response(data, blocks, any(block[0] == Format.ERROR for block in blocks))
    if len(out) > MAX_BLOCK:
        raise _WholeRequest(ERR_RESPONSE_TOO_LONG)
    return out
