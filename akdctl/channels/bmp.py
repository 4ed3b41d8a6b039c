"""A ParameterChannel over any RecordLink: PROFIdrive base-mode parameter access from the client side.

The link only moves one request block and returns one response block (PROFINET:
write record 47, read record 47; the simulator: an in-process call). Everything
a technician relies on lives here, once for all links:

* batching: parameters are packed into as few requests as the limits allow
  (39 parameters, 240 bytes for the request *and* the worst-case response; the
  rule is :mod:`akdctl.channels.batching`); an array too long for one block is
  read/written in element ranges and joined again; every address is checked
  once, on entry, before anything is sent;
* request references count 1..255 (never 0) and every response must carry the
  reference, axis and a response ID belonging to its request, with one result
  per parameter -- anything else is a :class:`~akdctl.errors.MalformedReply`
  naming what was wrong, because acting on someone else's answer is worse than
  failing;
* refusals are per parameter: a negative response (0x81/0x82/0x80) comes back
  as :class:`~akdctl.protocol.bmp.ParameterFailure` results, not raised.
"""

from __future__ import annotations

from collections.abc import Sequence

from akdctl.channels.base import ParameterChannel
from akdctl.channels.batching import (
    Batch,
    ElementSize,
    chunk_value,
    element_bytes,
    element_ranges,
    max_elements_per_block,
    merge_values,
    plan_batches,
    plan_reads,
    response_block_size,
)
from akdctl.errors import MalformedReply, ParameterRefused, UsageError
from akdctl.protocol.bmp import (
    ATTR_DESCRIPTION,
    ATTR_VALUE,
    DEFAULT_ELEMENT_SIZE,
    ERR_RESPONSE_TOO_LONG,
    HEADER_SIZE,
    MAX_BLOCK,
    REQ_CHANGE,
    REQ_READ,
    BmpError,
    Format,
    ParameterAddress,
    ParameterDescription,
    ParameterFailure,
    ParameterRequest,
    ParameterResult,
    ParameterValue,
    ReadTemplate,
    address_key,
    check_address,
    decode_description,
    decode_response,
    encode_request,
    encode_value_block,
    format_size,
    next_reference,
)
from akdctl.links import RecordLink

#: A read's plan: the batches (positions in the caller's list) and each batch's request template.
_Plan = tuple[list[Batch], list[ReadTemplate]]
#: Lists of addresses whose plan a channel keeps (a poll repeats a few; a session reading ever new ones starts over).
_MAX_PLANS = 64

#: Widest element any numeric format has: the retry size when a 4-byte estimate proved too small.
_WIDEST_ELEMENT = 8


def catalogue_element_size(address: ParameterAddress) -> int:
    """Bytes per element the drive answers with: the catalogue's type for known PNUs (the AKD
    sends U16 PNUs as words, SPEC-NOTES 5), else the 4-byte bound. A drive that answers wider
    than this is caught by the "response too long" retry in :meth:`BmpParameterChannel.read`."""
    if address.attribute != ATTR_VALUE:
        return DEFAULT_ELEMENT_SIZE
    size = _ELEMENT_SIZES.get(address.pnu)
    if size is None:
        from akdctl.catalog.pnus import lookup

        info = lookup(address.pnu)
        size = _ELEMENT_SIZES[address.pnu] = info.bits // 8 if info is not None else DEFAULT_ELEMENT_SIZE
    return size


_ELEMENT_SIZES: dict[int, int] = {}  # PNU -> bytes per element, looked up in the catalogue once


class BmpParameterChannel(ParameterChannel):
    """Batched, reference-checked parameter access over a :class:`RecordLink`.

    ``axis`` is the PROFIdrive axis (drive object) addressed; by default the
    link's. ``element_size`` bounds the bytes per
    element when sizing read responses (by default the catalogue's type, else 4
    bytes: AKD PNUs are at most 4 bytes, SPEC-NOTES 5); a request that still comes
    back "response too long" is retried with the widest element size.
    """

    def __init__(
        self,
        link: RecordLink,
        axis: int | None = None,
        *,
        reference_start: int = 1,
        element_size: ElementSize = catalogue_element_size,
    ) -> None:
        if not 1 <= reference_start <= 255:
            raise UsageError(f"request reference must be 1..255, not {reference_start}")
        axis = link.axis if axis is None else axis
        if not 0 <= axis <= 255:
            raise UsageError(f"axis must be 0..255, not {axis}")
        self.link = link
        self.axis = axis
        self.element_size = element_size
        self.requests = 0
        self._reference = reference_start
        #: The batches and request templates of each list of addresses read so far (``bmp.address_key``).
        self._plans: dict[tuple[tuple[int, int, int, int], ...], _Plan] = {}

    # -- public API ----------------------------------------------------------------------------------------------

    def read(self, addresses: Sequence[ParameterAddress]) -> list[ParameterResult]:  # type: ignore[override]
        """One result (value or failure) per address, in order, in as few round trips as the limits allow."""
        key = address_key(addresses)
        plan = self._plans.get(key) if key is not None else None
        wanted: Sequence[ParameterAddress]
        if plan is not None:  # this list of addresses was read before: its batches and requests are known
            wanted = addresses
            templates = plan[1]
            if len(templates) == 1 and len(addresses) == 1:
                results = self._read_request(templates[0])  # (one parameter: no request to halve)
            else:
                results = self._read_planned(plan, self.element_size)
        else:
            wanted = [self._checked_address(a) for a in addresses]
            results = self._read(wanted, self.element_size, key)
        for r in results:
            if r.__class__ is ParameterFailure:
                break
        else:
            return results
        # A per-parameter "response too long" means the 4-byte estimate was short: retry those in smaller ranges.
        retry = [i for i, (a, r) in enumerate(zip(wanted, results))
                 if _too_long(r) and a.attribute == ATTR_VALUE and a.count > 1
                 and (callable(self.element_size) or self.element_size < _WIDEST_ELEMENT)]
        if retry:
            again = self._read([wanted[i] for i in retry], _WIDEST_ELEMENT)
            for i, result in zip(retry, again):
                results[i] = result
        return results

    def write(self, items: Sequence[tuple[ParameterAddress, ParameterValue]]) -> list[ParameterFailure | None]:
        """Change every parameter (batched); ``None`` where the drive accepted the change."""
        pieces: list[tuple[ParameterAddress, ParameterValue]] = []
        owners: list[int] = []
        for i, (address, value) in enumerate(items):
            for piece in self._chunk_write(self._checked_address(address), value):
                pieces.append(piece)
                owners.append(i)
        addresses = [a for a, _ in pieces]
        values = [v for _, v in pieces]
        results: list[ParameterResult] = [None] * len(pieces)
        for batch in self._plan(addresses, values):
            got = self._exchange(REQ_CHANGE, [addresses[i] for i in batch], [values[i] for i in batch])
            for i, result in zip(batch, got):
                results[i] = result
        merged: list[ParameterFailure | None] = [None] * len(items)
        for owner, result in zip(owners, results):
            if isinstance(result, ParameterFailure) and merged[owner] is None:
                merged[owner] = result
        return merged

    def read_description(self, pnu: int) -> ParameterDescription:
        """The parameter's 46-byte description (attribute 0x20, subindex 0); refusals raise ParameterRefused."""
        result = self.read([ParameterAddress(pnu, 0, 1, ATTR_DESCRIPTION)])[0]
        if isinstance(result, ParameterFailure):
            from akdctl.catalog.texts import profidrive_failure_detail

            raise ParameterRefused(f"PNU {pnu}: description refused: "
                                   f"{profidrive_failure_detail(result.error, result.additional)}", code=result.error,
                                   details={"pnu": pnu, "error": result.error, "additional": result.additional})
        assert isinstance(result, ParameterValue)
        if result.format == Format.OCTET_STRING:
            raw = result.values[0]
        elif result.format == Format.BYTE:
            raw = bytes(int(v) for v in result.values)  # type: ignore[arg-type]
        else:
            raise MalformedReply(f"PNU {pnu}: description came as {result.format!r} data, not an octet string")
        try:
            return decode_description(raw)  # type: ignore[arg-type]
        except BmpError as exc:
            raise MalformedReply(f"PNU {pnu}: description does not decode: {exc}") from None

    # -- reading -------------------------------------------------------------------------------------------------

    def _read(self, addresses: list[ParameterAddress], element_size: ElementSize,
              key: tuple[tuple[int, int, int, int], ...] | None = None) -> list[ParameterResult]:
        sizes = [response_block_size(a, element_size) for a in addresses]  # once per parameter
        if all(HEADER_SIZE + size <= MAX_BLOCK for size in sizes):
            # the usual case, no parameter is cut: planned once per list of addresses (``key``)
            plan = self._plan_reads(addresses, sizes)
            if key is not None and element_size is self.element_size:
                if len(self._plans) >= _MAX_PLANS:
                    self._plans.clear()  # a long session reading ever new lists: start over
                self._plans[key] = plan
            return self._read_planned(plan, element_size)
        pieces: list[ParameterAddress] = []
        owners: list[int] = []
        for i, address in enumerate(addresses):
            for piece in self._chunk_read(address, element_size):
                pieces.append(piece)
                owners.append(i)
        results = self._read_batches(pieces, element_size)
        grouped: list[list[ParameterResult]] = [[] for _ in addresses]
        for owner, result in zip(owners, results):
            grouped[owner].append(result)
        return [parts[0] if len(parts) == 1 else self._merge(parts, addresses[i]) for i, parts in enumerate(grouped)]

    def _read_batches(self, addresses: list[ParameterAddress], element_size: ElementSize) -> list[ParameterResult]:
        """One result per address, in order, from the requests :func:`plan_reads` groups them into."""
        return self._read_planned(self._plan_reads(addresses, [response_block_size(a, element_size)
                                                               for a in addresses]), element_size)

    def _plan_reads(self, addresses: list[ParameterAddress], sizes: list[int]) -> _Plan:
        """The batches of a read and each batch's request template."""
        try:
            batches = plan_reads(sizes)
            return batches, [ReadTemplate(self.axis, tuple([addresses[i] for i in batch]), addresses_checked=True)
                             for batch in batches]
        except BmpError as exc:
            raise UsageError(f"cannot build a parameter request: {exc}") from None

    def _read_planned(self, plan: _Plan, element_size: ElementSize) -> list[ParameterResult]:
        """One result per address of a planned read, in the caller's order."""
        batches, templates = plan
        if len(batches) == 1:
            return self._read_one(templates[0], element_size)
        results: list[ParameterResult] = [None] * sum(len(batch) for batch in batches)
        for batch, template in zip(batches, templates):
            for i, result in zip(batch, self._read_one(template, element_size)):
                results[i] = result
        return results

    def _read_one(self, template: ReadTemplate, element_size: ElementSize) -> list[ParameterResult]:
        """One read request; one the drive refused whole as too long (our size estimate was short) is read
        again in halves."""
        got = self._read_request(template)
        asked = template.addresses
        if len(asked) > 1 and all(_too_long(r) for r in got):
            half = len(asked) // 2
            return (self._read_batches(list(asked[:half]), element_size)
                    + self._read_batches(list(asked[half:]), element_size))
        return got

    def _read_request(self, template: ReadTemplate) -> list[ParameterResult]:
        """One round trip of a read request built from its template; the usual answer is read by the template,
        anything else by :func:`decode_response` (which says what is wrong)."""
        self._reference = next_reference(reference := self._reference)
        raw = template.request(reference)
        self.requests += 1
        reply = self.link.exchange(raw)
        if reply.__class__ is not bytes:
            try:
                reply = bytes(reply)
            except TypeError:
                raise MalformedReply(f"parameter {_what(template.request_object(reference))}: the link returned "
                                     f"{type(reply).__name__}, not bytes") from None
        results = template.results(reply, reference)
        if results is not None:
            return results
        return self._decode(template.request_object(reference), raw, reply)

    @staticmethod
    def _chunk_read(address: ParameterAddress, element_size: ElementSize) -> list[ParameterAddress]:
        """Element ranges of ``address`` small enough for one response block."""
        if HEADER_SIZE + response_block_size(address, element_size) <= MAX_BLOCK:
            return [address]
        per = max_elements_per_block(element_bytes(address, element_size), change=False)
        return _ranges(address, per)

    @staticmethod
    def _merge(parts: list[ParameterResult], address: ParameterAddress) -> ParameterResult:
        for part in parts:
            if isinstance(part, ParameterFailure):
                return part
        try:
            return merge_values([p for p in parts if isinstance(p, ParameterValue)])
        except BmpError as exc:
            raise MalformedReply(f"{address}: {exc}") from None

    # -- writing -------------------------------------------------------------------------------------------------

    @staticmethod
    def _chunk_write(address: ParameterAddress, value: ParameterValue) -> list[tuple[ParameterAddress, ParameterValue]]:
        if not isinstance(value, ParameterValue):
            raise UsageError(f"{address}: not a parameter value: {value!r}")
        try:
            block = encode_value_block(value)
        except BmpError as exc:
            raise UsageError(f"{address}: cannot send this value: {exc}") from None
        if value.count != address.count:
            raise UsageError(f"{address}: {value.count} values for {address.count} elements")
        if HEADER_SIZE + 6 + len(block) <= MAX_BLOCK:
            return [(address, value)]
        per = max_elements_per_block(format_size(value.format), change=True)
        pieces = chunk_value(value, per)
        return list(zip(_ranges(address, per), pieces))

    # -- one round trip ------------------------------------------------------------------------------------------

    def _plan(self, addresses: list[ParameterAddress], values: list[ParameterValue] | None,
              element_size: ElementSize | None = None) -> list[Batch]:
        try:
            return plan_batches(addresses, values, element_size=element_size or self.element_size)
        except BmpError as exc:
            raise UsageError(f"cannot build a parameter request: {exc}") from None

    def _take_reference(self) -> int:
        reference = self._reference
        self._reference = next_reference(reference)
        return reference

    def _exchange(self, request_id: int, addresses: Sequence[ParameterAddress],
                  values: Sequence[ParameterValue] = ()) -> list[ParameterResult]:
        request = ParameterRequest(self._take_reference(), request_id, self.axis, tuple(addresses), tuple(values))
        try:
            raw = encode_request(request, addresses_checked=True)
        except BmpError as exc:
            raise UsageError(f"cannot build a parameter request: {exc}") from None
        self.requests += 1
        reply = self.link.exchange(raw)
        try:
            reply = bytes(reply)
        except TypeError:
            raise MalformedReply(f"parameter {_what(request)}: the link returned {type(reply).__name__}, "
                                 "not bytes") from None
        return self._decode(request, raw, reply)

    @staticmethod
    def _decode(request: ParameterRequest, raw: bytes, reply: bytes) -> list[ParameterResult]:
        try:
            response = decode_response(reply, request)
        except BmpError as exc:
            raise MalformedReply(
                f"malformed PROFIdrive parameter response ({_what(request)}): {exc}",
                details={"request": raw.hex(" "), "response": reply.hex(" ")},
            ) from None
        return list(response.results)

    def _checked_address(self, address: object) -> ParameterAddress:
        """The one check of an address on its way down (planning and encoding trust it)."""
        if not isinstance(address, ParameterAddress):
            raise UsageError(f"not a parameter address: {address!r}")
        try:
            return check_address(address)
        except BmpError as exc:
            raise UsageError(f"{address}: {exc}") from None


def _what(request: ParameterRequest) -> str:
    """"read 3 parameter(s), ref 7": a request named in a message (built only when one is needed)."""
    verb = "read" if request.request_id == REQ_READ else "change"
    return f"{verb} {len(request.addresses)} parameter(s), ref {request.reference}"


def _too_long(result: ParameterResult) -> bool:
    return isinstance(result, ParameterFailure) and result.error == ERR_RESPONSE_TOO_LONG


def _ranges(address: ParameterAddress, per: int) -> list[ParameterAddress]:
    try:
        return element_ranges(address, per)
    except BmpError as exc:
        raise UsageError(str(exc)) from None
