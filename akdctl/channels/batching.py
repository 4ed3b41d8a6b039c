"""The batching rule: which parameters share one PROFIdrive request.

Why here and not in the codec: ``protocol/bmp.py`` only turns blocks into
bytes and back; how many parameters to put into one round trip is a policy of
the client, so it lives beside the channel that uses it (and ``drive/`` code
that wants few round trips simply hands the channel all it needs in one call).

The limits (SPEC-NOTES 4): at most 39 parameters per request, and at most 240
bytes for the request block *and* for the response block it will bring back.
A read is sized by the worst-case response (:func:`response_block_size`); a
change by its value blocks, its response by an error block per parameter.

The rule (:func:`plan_batches`): **first fit, largest first** -- each parameter
goes into the first request that still has room for it under all three limits.
Reads may be packed in any order (results come back in the caller's order);
changes keep the caller's order, because the drive applies them in the order
they arrive (units before values, counts after entries). When first fit saves
no request, the parameters are packed in the caller's order, so a trace reads
as asked and no plan ever uses more round trips than filling in order.

A parameter too long for one block is cut into element ranges first
(:func:`element_ranges`, :func:`chunk_value`) and joined again after the read
(:func:`merge_values`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

from akdctl.protocol.bmp import (
    ADDRESS_SIZE,
    ATTR_DESCRIPTION,
    ATTR_TEXT,
    DEFAULT_ELEMENT_SIZE,
    DESCRIPTION_OFFSETS,
    DESCRIPTION_SIZE,
    HEADER_SIZE,
    MAX_BLOCK,
    MAX_ELEMENTS,
    MAX_PARAMETERS,
    MAX_SUBINDEX,
    STRING_FORMATS,
    BmpError,
    Format,
    ParameterAddress,
    ParameterValue,
    encode_value_block,
    format_name,
)

#: Bytes per element of a value read: a fixed bound, or a function of the address (e.g. the catalogue's type).
ElementSize = int | Callable[[ParameterAddress], int]

#: A batch: the positions (in the caller's list) of the parameters that travel in one request, ascending.
Batch = list[int]

_TEXT_SIZE = 16  # a text element (attribute 0x30) is a VisibleString16
_ERROR_BLOCK = 6  # format, count, error value, additional info: the largest answer to a change


def _pad(n: int) -> int:
    return n + (n & 1)


def response_block_size(address: ParameterAddress, element_size: ElementSize = DEFAULT_ELEMENT_SIZE) -> int:
    """Worst-case bytes of the response block answering ``address``.

    Value reads: ``count × element_size`` (the caller's bound on the parameter's
    format; AKD PNUs are at most 4 bytes, SPEC-NOTES 5). Descriptions: 46 bytes for
    the whole block, the element's size otherwise. Texts: 16 characters per element.
    Never less than an error block with additional info (6 bytes).
    """
    if address.attribute == ATTR_DESCRIPTION:
        start, end = DESCRIPTION_OFFSETS.get(address.subindex, (0, _TEXT_SIZE))
        data = DESCRIPTION_SIZE if address.subindex == 0 else end - start
    elif address.attribute == ATTR_TEXT:
        data = _TEXT_SIZE * address.count
    else:
        data = element_bytes(address, element_size) * address.count
    return max(_ERROR_BLOCK, 2 + _pad(data))


def element_bytes(address: ParameterAddress, element_size: ElementSize) -> int:
    """Bytes per element of ``address`` under ``element_size`` (texts: 16 characters)."""
    if address.attribute == ATTR_TEXT:
        return _TEXT_SIZE
    return element_size(address) if callable(element_size) else element_size


class Cost(NamedTuple):
    """What one parameter adds to a request block and to the response block that answers it
    (a named tuple: one is made per parameter of every request)."""

    request: int
    response: int


def read_cost(address: ParameterAddress, element_size: ElementSize = DEFAULT_ELEMENT_SIZE) -> Cost:
    return Cost(ADDRESS_SIZE, response_block_size(address, element_size))


def change_cost(value: ParameterValue) -> Cost:
    """A change carries its address and value block; the drive answers at most an error block."""
    return Cost(ADDRESS_SIZE + len(encode_value_block(value)), _ERROR_BLOCK)


def pack(costs: Sequence[Cost], *, keep_order: bool = False) -> list[Batch]:
    """The batching rule (module docstring) over costs already known to fit a block each.

    ``keep_order``: the batches, read one after another, give the parameters in the
    caller's order (changes); otherwise first fit, largest response first, when that
    saves a request.
    """
    in_order = _first_fit(range(len(costs)), costs, only_last=True)
    if keep_order or len(in_order) <= 1:
        return in_order
    largest_first = sorted(range(len(costs)), key=lambda i: costs[i].response, reverse=True)
    packed = _first_fit(largest_first, costs, only_last=False)
    return [sorted(batch) for batch in packed] if len(packed) < len(in_order) else in_order


def _first_fit(order: Sequence[int] | range, costs: Sequence[Cost], *, only_last: bool) -> list[Batch]:
    """Each position into the first open batch with room under the three limits; one pass over ``order``.

    ``only_last`` (filling in order) looks at the open batch only: linear. Otherwise each parameter is
    tried against every open batch, at most (parameters / 39 + 1) of them.
    """
    batches: list[Batch] = []
    req_used: list[int] = []
    resp_used: list[int] = []
    for i in order:
        request, response = costs[i]
        n = len(batches)
        for b in (range(n - 1, n) if only_last and n else range(n)):
            if (len(batches[b]) < MAX_PARAMETERS and req_used[b] + request <= MAX_BLOCK
                    and resp_used[b] + response <= MAX_BLOCK):
                batches[b].append(i)
                req_used[b] += request
                resp_used[b] += response
                break
        else:
            batches.append([i])
            req_used.append(HEADER_SIZE + request)
            resp_used.append(HEADER_SIZE + response)
    return batches


def plan_batches(
    addresses: Sequence[ParameterAddress],
    values: Sequence[ParameterValue] | None = None,
    *,
    element_size: ElementSize = DEFAULT_ELEMENT_SIZE,
) -> list[Batch]:
    """Reads (``values is None``) or changes of ``addresses``, grouped into requests by :func:`pack`.

    The addresses must already be valid (the channel checks each once, on entry).
    Raises :class:`BmpError` if one parameter alone cannot fit a block (the caller
    must cut its elements into ranges first).
    """
    if values is not None and len(values) != len(addresses):
        raise BmpError(f"{len(addresses)} parameters but {len(values)} values")
    costs = ([read_cost(a, element_size) for a in addresses] if values is None
             else [change_cost(v) for v in values])
    for i, (address, cost) in enumerate(zip(addresses, costs)):
        if HEADER_SIZE + cost.request > MAX_BLOCK or HEADER_SIZE + cost.response > MAX_BLOCK:
            raise BmpError(f"parameter {i + 1} ({address}) alone does not fit a {MAX_BLOCK}-byte block")
    return pack(costs, keep_order=values is not None)


def plan_reads(response_sizes: Sequence[int]) -> list[Batch]:
    """:func:`plan_batches` for reads whose worst-case response blocks the caller already sized
    (:func:`response_block_size`), so each parameter's size is worked out once per request."""
    for i, size in enumerate(response_sizes):
        if HEADER_SIZE + size > MAX_BLOCK:
            raise BmpError(f"parameter {i + 1} alone does not fit a {MAX_BLOCK}-byte block")
    return pack([Cost(ADDRESS_SIZE, size) for size in response_sizes])


# --- one parameter larger than a block ---------------------------------------------------------------------------


def max_elements_per_block(size: int, *, change: bool) -> int:
    """How many elements of ``size`` bytes one parameter may move in one request/response."""
    room = MAX_BLOCK - HEADER_SIZE - 2 - (ADDRESS_SIZE if change else 0)
    return max(1, min(MAX_ELEMENTS, room // max(1, size)))


def element_ranges(address: ParameterAddress, per: int) -> list[ParameterAddress]:
    """Consecutive element ranges of at most ``per`` elements covering ``address``."""
    out = []
    for offset in range(0, address.count, per):
        subindex = address.subindex + offset
        if subindex > MAX_SUBINDEX:
            raise BmpError(f"{address}: elements beyond subindex {MAX_SUBINDEX} cannot be addressed")
        out.append(ParameterAddress(address.pnu, subindex, min(per, address.count - offset), address.attribute))
    return out


def chunk_value(value: ParameterValue, limit: int) -> list[ParameterValue]:
    """Split a value into pieces of at most ``limit`` wire elements (strings split by character)."""
    if value.format in STRING_FORMATS:
        item = value.values[0]
        assert isinstance(item, (str, bytes)), "a string format holds one str or bytes"
        if value.format == Format.UNICODE_STRING and isinstance(item, str):
            units = item.encode("utf-16-be", "surrogatepass")
            return [ParameterValue(value.format, (units[i:i + 2 * limit].decode("utf-16-be", "surrogatepass"),))
                    for i in range(0, len(units), 2 * limit)]
        return [ParameterValue(value.format, (item[i:i + limit],)) for i in range(0, len(item), limit)]
    return [ParameterValue(value.format, value.values[i:i + limit]) for i in range(0, len(value.values), limit)]


def merge_values(pieces: Sequence[ParameterValue]) -> ParameterValue:
    """Join the values of consecutive element ranges read separately (inverse of :func:`chunk_value`)."""
    if not pieces:
        raise BmpError("nothing to merge")
    fmt = pieces[0].format
    if any(p.format != fmt for p in pieces):
        raise BmpError("parts of one parameter came back in different formats: "
                       + ", ".join(format_name(p.format) for p in pieces))
    if fmt in STRING_FORMATS:
        first = pieces[0].values[0]
        joined = (b"" if isinstance(first, bytes) else "").join(p.values[0] for p in pieces)  # type: ignore[misc]
        return ParameterValue(fmt, (joined,))
    return ParameterValue(fmt, tuple(v for p in pieces for v in p.values))
