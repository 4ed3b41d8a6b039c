"""The client's read template equals the general PROFIdrive codec (issue 29, item 2).

``bmp.ReadTemplate`` encodes a read once and patches the reference: its request must be byte-equal to
``encode_request``. Its reading of the answer must give exactly ``decode_response(data, request).results`` for the
answers it takes, and leave every other answer (None) to ``decode_response``, which words what is wrong.
``address_key`` accepts exactly the addresses ``check_address`` accepts (plain ints). The channel's plan per list of
addresses gives the same results and the same requests as planning anew.
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.channels.bmp import BmpParameterChannel
from akdctl.links import RecordLink
from akdctl.protocol import bmp
from akdctl.protocol.bmp import ParameterAddress, ParameterFailure, ParameterValue

addresses = st.builds(ParameterAddress, pnu=st.integers(1, 0xFFFF), subindex=st.integers(0, 20),
                      count=st.integers(1, 4), attribute=st.sampled_from(bmp.ATTRIBUTES))


def _answer(address: ParameterAddress, draw: st.DrawFn) -> bmp.ParameterResult:
    if draw(st.booleans()):
        return ParameterFailure(draw(st.integers(0, 0x30)), draw(st.none() | st.integers(0, 0xFFFF)))
    count = address.count if draw(st.integers(0, 9)) else draw(st.integers(1, 5))  # now and then a wrong count
    fmt = draw(st.sampled_from([bmp.Format.WORD, bmp.Format.BYTE, bmp.Format.DWORD, bmp.Format.INT8]))
    bits = {bmp.Format.WORD: 16, bmp.Format.BYTE: 8, bmp.Format.DWORD: 32, bmp.Format.INT8: 8}[fmt]
    low = -(1 << (bits - 1)) if fmt == bmp.Format.INT8 else 0
    high = (1 << (bits - 1)) - 1 if fmt == bmp.Format.INT8 else (1 << bits) - 1
    return ParameterValue(fmt, tuple(draw(st.lists(st.integers(low, high), min_size=count, max_size=count))))


@settings(max_examples=300, deadline=None)
@given(asked=st.lists(addresses, min_size=1, max_size=8), axis=st.integers(0, 255), reference=st.integers(1, 255),
       data=st.data())
def test_template_equals_the_general_codec(asked: list[ParameterAddress], axis: int, reference: int,
                                           data: st.DataObject) -> None:
    template = bmp.ReadTemplate(axis, tuple(asked))
    request = bmp.ParameterRequest(reference, bmp.REQ_READ, axis, tuple(asked))
    assert template.request(reference) == bmp.encode_request(request)
    assert template.request_object(reference) == request
    results = tuple(_answer(a, data.draw) for a in asked)
    negative = any(isinstance(r, ParameterFailure) for r in results)
    reply = bytearray(bmp.encode_response(bmp.ParameterResponse(
        data.draw(st.sampled_from([reference, reference % 255 + 1])) if data.draw(st.booleans()) else reference,
        bmp.RESP_READ_NAK if negative else bmp.RESP_READ_OK, axis, results)))
    learnt = template.results(bytes(reply), reference)  # a valid answer first: the template learns its layout
    if learnt is not None:
        assert learnt == list(bmp.decode_response(bytes(reply), request).results)
        assert template.results(bytes(reply), reference) == learnt  # and reads it again by that layout
    for at, value in data.draw(st.lists(st.tuples(st.integers(0, 40), st.integers(0, 255)), max_size=2)):
        if at < len(reply):
            reply[at] = value
    if data.draw(st.integers(0, 5)) == 0 and len(reply) > 4:
        del reply[-1]
    fast = template.results(bytes(reply), reference)
    try:
        general: list[bmp.ParameterResult] | None = list(bmp.decode_response(bytes(reply), request).results)
    except bmp.BmpError:
        general = None
    if fast is not None:
        assert fast == general
    if not data.draw(st.integers(0, 3)):  # the learnt layout against another answer of the same size
        other = bytearray(reply)
        if len(other) > 5:
            other[4] = data.draw(st.sampled_from([bmp.Format.WORD, bmp.Format.BYTE, bmp.Format.ERROR, 0x09, 0x0A]))
        fast = template.results(bytes(other), reference)
        try:
            general = list(bmp.decode_response(bytes(other), request).results)
        except bmp.BmpError:
            general = None
        if fast is not None:
            assert fast == general


@settings(max_examples=200, deadline=None)
@given(pnu=st.one_of(st.integers(-2, 0x10001), st.booleans(), st.floats(0, 10), st.just("930")),
       subindex=st.one_of(st.integers(-1, 0xFFFF), st.just(1.0)), count=st.one_of(st.integers(0, 235), st.just(True)),
       attribute=st.one_of(st.sampled_from([*bmp.ATTRIBUTES, 0, 0x11]), st.just(16.0)))
def test_address_key_accepts_exactly_what_check_address_accepts(pnu: object, subindex: object, count: object,
                                                                attribute: object) -> None:
    address = ParameterAddress(pnu, subindex, count, attribute)  # type: ignore[arg-type]
    key = bmp.address_key([address])
    plain = all(type(v) is int for v in (pnu, subindex, count, attribute))
    try:
        bmp.check_address(address)
        accepted = plain
    except bmp.BmpError:
        accepted = False
    assert (key is not None) == accepted
    if key is not None:
        assert key == ((pnu, subindex, count, attribute),)


class _Recorder(RecordLink):
    """Answers every read with words counting up, and records the requests."""

    def __init__(self) -> None:
        self.sent: list[bytes] = []

    def exchange(self, request: bytes) -> bytes:
        self.sent.append(request)
        parsed = bmp.decode_request(request)
        results = tuple(ParameterValue(bmp.Format.WORD, tuple(range(a.count))) for a in parsed.addresses)
        return bmp.encode_response(bmp.ParameterResponse(parsed.reference, bmp.RESP_READ_OK, parsed.axis, results))


def test_a_planned_read_sends_what_a_new_plan_sends() -> None:
    asked = [ParameterAddress(p, 0, 1 + p % 3) for p in range(900, 950)]  # two requests
    planned, fresh = _Recorder(), _Recorder()
    channel = BmpParameterChannel(planned, element_size=2)
    for _ in range(3):
        reference = channel._reference
        first = channel.read(asked)
        again = BmpParameterChannel(fresh, element_size=2, reference_start=reference).read(asked)
        assert first == again
    assert planned.sent == fresh.sent and len(planned.sent) == 6
    assert len(channel._plans) == 1


def test_a_repeated_answer_reads_as_the_codec_reads_it_and_any_changed_byte_is_read_anew() -> None:
    """ReadTemplate keeps the last answer's results for an answer whose bytes after the reference are all the same
    (a poll of a value that did not change): those results must be decode_response's, in a new list each time, and
    an answer that differs in any byte - a changed value, a failure, another format - must be read anew."""
    asked = (ParameterAddress(930), ParameterAddress(964, 0, 2))
    template = bmp.ReadTemplate(0, asked)

    def answer(reference: int, first: int, second: bmp.ParameterResult) -> bytes:
        request = bmp.ParameterRequest(reference, bmp.REQ_READ, 0, asked)
        return bmp.encode_response(bmp.ParameterResponse(
            reference, bmp.RESP_READ_NAK if isinstance(second, ParameterFailure) else bmp.RESP_READ_OK, 0,
            (ParameterValue(bmp.Format.WORD, (first,)), second))), request

    seen = []
    for reference, first, second in [(1, 7, ParameterValue(bmp.Format.WORD, (1, 2))),
                                     (2, 7, ParameterValue(bmp.Format.WORD, (1, 2))),   # the same answer again
                                     (3, 8, ParameterValue(bmp.Format.WORD, (1, 2))),   # the value changed
                                     (4, 8, ParameterValue(bmp.Format.WORD, (1, 3))),   # the last byte changed
                                     (5, 8, ParameterFailure(0x14, 0)),                  # refused now
                                     (6, 8, ParameterFailure(0x14, 0)),
                                     (7, 8, ParameterValue(bmp.Format.DWORD, (1, 3))),  # another format
                                     (8, 8, ParameterValue(bmp.Format.WORD, (1, 3)))]:
        data, request = answer(reference, first, second)
        got = template.results(data, reference)
        assert got == list(bmp.decode_response(data, request).results)
        assert got[0].values == (first,) and got[1] == second
        assert template.results(data, reference % 255 + 1) is None  # another reference is never taken
        if seen:
            assert got is not seen[-1]  # a new list each time: a caller may change it
        seen.append(got)
    seen[1].append("changed by a caller")  # what a caller does to its list does not reach the next answer
    data, request = answer(9, 8, ParameterValue(bmp.Format.WORD, (1, 3)))
    assert template.results(data, 9) == list(bmp.decode_response(data, request).results)
