"""The batching rule (channels/batching.py): 39 parameters and 240 bytes per request and response, first fit.

The example tests moved here from the codec's tests with the codec's batching (they assert the same
splits; :func:`spans` turns the position lists back into the slices they name). The property tests
check every plan against the limits, that nothing is lost or doubled, that changes keep their order,
and that first fit never needs more requests than filling in order.
"""

from __future__ import annotations

from collections.abc import Sequence

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.channels.batching import (
    Batch,
    chunk_value,
    merge_values,
    pack,
    plan_batches,
    read_cost,
    response_block_size,
)
from akdctl.channels.bmp import BmpParameterChannel
from akdctl.protocol.bmp import (
    ATTR_DESCRIPTION,
    ATTR_TEXT,
    ATTR_VALUE,
    HEADER_SIZE,
    MAX_BLOCK,
    MAX_PARAMETERS,
    REQ_CHANGE,
    REQ_READ,
    BmpError,
    Format,
    ParameterAddress,
    ParameterRequest,
    ParameterValue,
    decode_request,
    encode_request,
    next_reference,
    request_size,
)
from akdctl.sim.pnu_server import PnuServer
from tests.test_bmp_channel import FakeAccess, ServerLink


def spans(batches: Sequence[Batch]) -> list[tuple[int, int]]:
    """Position lists as (start, stop) slices; each batch must be a consecutive run."""
    out = []
    for batch in batches:
        assert batch == list(range(batch[0], batch[-1] + 1)), f"batch {batch} is not consecutive"
        out.append((batch[0], batch[-1] + 1))
    return out


def split_requests(addresses, values=None, *, reference_start=1, element_size=2):  # noqa: ANN001, ANN201
    """The requests :func:`plan_batches` makes of the parameters (references counting up, wrapping past 255):
    test-only since the channel builds its own (issue 22: the library copy was dead code)."""
    requests, reference = [], reference_start
    for batch in plan_batches(addresses, values, element_size=element_size):
        picked = tuple(addresses[i] for i in batch)
        if values is None:
            requests.append(ParameterRequest(reference, REQ_READ, 0, picked))
        else:
            requests.append(ParameterRequest(reference, REQ_CHANGE, 0, picked, tuple(values[i] for i in batch)))
        reference = next_reference(reference)
    return requests


# --- examples (moved from test_bmp_codec.py) --------------------------------------------------------------


def test_plan_batches_by_parameter_count() -> None:
    addresses = [ParameterAddress(p) for p in range(1, 101)]
    assert spans(plan_batches(addresses)) == [(0, 39), (39, 78), (78, 100)]
    requests = split_requests(addresses, reference_start=254)
    assert [r.reference for r in requests] == [254, 255, 1]
    for request in requests:
        encode_request(request)


def test_plan_batches_by_response_size() -> None:
    # 20 elements × 4 bytes = 82-byte response blocks: two fit (4 + 164), three do not (4 + 246).
    addresses = [ParameterAddress(947, 0, 20) for _ in range(5)]
    assert spans(plan_batches(addresses)) == [(0, 2), (2, 4), (4, 5)]
    assert spans(plan_batches(addresses, element_size=2)) == [(0, 5)]
    descriptions = [ParameterAddress(p, attribute=ATTR_DESCRIPTION) for p in range(1, 11)]
    assert spans(plan_batches(descriptions)) == [(0, 4), (4, 8), (8, 10)]   # 48 bytes each


def test_plan_batches_by_request_size() -> None:
    value = ParameterValue.of(Format.WORD, *range(50))       # block of 102 bytes + 6 address bytes
    addresses = [ParameterAddress(947, 0, 50)] * 3
    batches = plan_batches(addresses, [value] * 3)
    assert spans(batches) == [(0, 2), (2, 3)]
    for request in split_requests(addresses, [value] * 3):
        assert request_size(request) <= MAX_BLOCK
        assert len(encode_request(request)) == request_size(request)


def test_plan_batches_refuses_an_oversized_single_parameter() -> None:
    with pytest.raises(BmpError, match="alone"):
        plan_batches([ParameterAddress(947, 0, 100)])
    assert response_block_size(ParameterAddress(947, 0, 58)) == 234


def test_chunk_and_merge() -> None:
    value = ParameterValue.of(Format.WORD, *range(10))
    assert merge_values(chunk_value(value, 3)) == value
    text = ParameterValue.of(Format.VISIBLE_STRING, "ABCDEFG")
    assert [p.values[0] for p in chunk_value(text, 3)] == ["ABC", "DEF", "G"]
    assert merge_values(chunk_value(text, 3)) == text
    with pytest.raises(BmpError):
        merge_values([ParameterValue.of(Format.WORD, 1), ParameterValue.of(Format.DWORD, 2)])


# --- first fit ---------------------------------------------------------------------------------------------------


def test_first_fit_keeps_the_callers_order_when_it_saves_nothing() -> None:
    # responses 98, 98, 130, 130, 98 bytes: in order [98 98] [130] [130 98]; largest first needs 3 too
    addresses = [ParameterAddress(2000 + i, 0, n) for i, n in enumerate((24, 24, 32, 32, 24))]
    assert spans(plan_batches(addresses)) == [(0, 2), (2, 3), (3, 5)]


def test_first_fit_fills_a_gap_that_filling_in_order_leaves() -> None:
    # responses 130, 226, 130, 226, 42 bytes: in order every one needs its own request (5);
    # largest first: [226] [226] [130 42] [130] -> 4, results still in the caller's order
    mixed = [ParameterAddress(3000 + i, 0, n) for i, n in enumerate((32, 56, 32, 56, 10))]
    assert len(pack([read_cost(a) for a in mixed], keep_order=True)) == 5
    planned = plan_batches(mixed)
    assert planned == [[1], [3], [0, 4], [2]]


def test_changes_keep_the_callers_order() -> None:
    values = [ParameterValue.of(Format.WORD, *range(n)) for n in (50, 10, 50, 10, 50)]
    addresses = [ParameterAddress(980, 0, v.count) for v in values]
    batches = plan_batches(addresses, values)
    assert [i for b in batches for i in b] == list(range(5))


# --- properties --------------------------------------------------------------------------------------------------

_address = st.builds(
    ParameterAddress,
    pnu=st.integers(1, 0xFFFF),
    subindex=st.integers(0, 200),
    count=st.integers(1, 58),
    attribute=st.sampled_from([ATTR_VALUE, ATTR_VALUE, ATTR_VALUE, ATTR_DESCRIPTION, ATTR_TEXT]),
).filter(lambda a: a.attribute != ATTR_TEXT or a.count <= 14)
_element_size = st.sampled_from([1, 2, 4])


@settings(max_examples=200, deadline=None)
@given(addresses=st.lists(_address, max_size=150), element_size=_element_size)
def test_every_read_batch_fits_both_ways(addresses: list[ParameterAddress], element_size: int) -> None:
    batches = plan_batches(addresses, element_size=element_size)
    assert sorted(i for b in batches for i in b) == list(range(len(addresses)))   # nothing lost or doubled
    for batch in batches:
        assert batch == sorted(batch) and 1 <= len(batch) <= MAX_PARAMETERS
        request = encode_request(split_requests([addresses[i] for i in batch], element_size=element_size)[0])
        assert len(request) <= MAX_BLOCK
        assert HEADER_SIZE + sum(response_block_size(addresses[i], element_size) for i in batch) <= MAX_BLOCK
    in_order = pack([read_cost(a, element_size) for a in addresses], keep_order=True)
    assert len(batches) <= len(in_order)


_change = st.integers(1, 100).flatmap(lambda n: st.tuples(
    st.sampled_from([Format.BYTE, Format.WORD, Format.DWORD]), st.just(n)))


@settings(max_examples=200, deadline=None)
@given(changes=st.lists(_change, max_size=60))
def test_every_change_batch_fits_both_ways_in_order(changes: list[tuple[int, int]]) -> None:
    values = [ParameterValue(fmt, tuple(range(n))) for fmt, n in changes]
    addresses = [ParameterAddress(900 + i, 0, n) for i, (_, n) in enumerate(changes)]
    values_fit = [(a, v) for a, v in zip(addresses, values) if HEADER_SIZE + 6 + len(encode(v)) <= MAX_BLOCK]
    addresses, values = [a for a, _ in values_fit], [v for _, v in values_fit]
    batches = plan_batches(addresses, values)
    assert [i for b in batches for i in b] == list(range(len(addresses)))   # order kept
    for request in split_requests(addresses, values):
        assert 1 <= len(request.addresses) <= MAX_PARAMETERS
        assert len(encode_request(request)) <= MAX_BLOCK
        assert HEADER_SIZE + 6 * len(request.addresses) <= MAX_BLOCK   # the worst answer: an error block each


def encode(value: ParameterValue) -> bytes:
    from akdctl.protocol.bmp import encode_value_block

    return encode_value_block(value)


@settings(max_examples=60, deadline=None)
@given(picks=st.lists(st.one_of(st.integers(1, 100).map(lambda p: ParameterAddress(p)),
                                st.tuples(st.integers(0, 150), st.integers(1, 49)).map(
                                    lambda t: ParameterAddress(980, t[0], t[1])),
                                st.tuples(st.integers(0, 40), st.integers(1, 20)).map(
                                    lambda t: ParameterAddress(2000, t[0], t[1]))),
                      min_size=1, max_size=80))
def test_channel_results_come_back_in_the_order_asked(picks: list[ParameterAddress]) -> None:
    access = FakeAccess()
    link = ServerLink(PnuServer(access))
    channel = BmpParameterChannel(link)
    results = channel.read(picks)
    for address, result in zip(picks, results):
        assert isinstance(result, ParameterValue)
        _, stored, _ = access.params[address.pnu]
        assert list(result.values) == stored[address.subindex:address.subindex + address.count]
    assert len(results) == len(picks)
    for request, _ in link.log:
        assert len(decode_request(request).addresses) <= MAX_PARAMETERS
