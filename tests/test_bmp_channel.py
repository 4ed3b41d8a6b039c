"""BmpParameterChannel against PnuServer through an in-memory RecordLink: batching, references, malformed replies."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from akdctl.channels.bmp import BmpParameterChannel
from akdctl.errors import MalformedReply, NoAnswer, ParameterRefused, UsageError
from akdctl.protocol.bmp import (
    ID_ARRAY,
    MAX_BLOCK,
    MAX_PARAMETERS,
    Format,
    ParameterAddress,
    ParameterDescription,
    ParameterFailure,
    ParameterValue,
    decode_request,
)
from akdctl.sim.pnu_server import PnuAccessError, PnuServer, convert_value
from akdctl.links import RecordLink
from akdctl.transport.trace import TracedRecordLink, Tracer


class FakeAccess:
    """PNUs 1..100 hold their own number (Unsigned32); a few arrays, a 64-bit array, a read-only word."""

    def __init__(self) -> None:
        self.params: dict[int, tuple[int, list, bool]] = {p: (Format.UINT32, [p], False) for p in range(1, 101)}
        self.params[947] = (Format.UINT16, list(range(300, 364)), True)
        self.params[980] = (Format.UINT16, list(range(200)), True)
        self.params[2000] = (Format.UINT32, list(range(60)), True)
        self.params[3000] = (Format.UINT64, [2**40 + i for i in range(40)], True)
        self.params[964] = (Format.UINT16, [0x1A, 5, 0x0201, 2012, 0x1503, 1], True)
        self.params[4000] = (Format.VISIBLE_STRING, [" " * 200], True)

    def pnu_read(self, pnu: int, subindex: int, count: int) -> ParameterValue:
        if pnu not in self.params:
            raise PnuAccessError(0)
        fmt, values, array = self.params[pnu]
        if fmt == Format.VISIBLE_STRING:
            text = values[0]
            if subindex + count > len(text):
                raise PnuAccessError(3, subindex)
            return ParameterValue(fmt, (text[subindex:subindex + count],))
        if not array and (subindex or count != 1):
            raise PnuAccessError(4)
        if subindex + count > len(values):
            raise PnuAccessError(3, subindex)
        return ParameterValue(fmt, tuple(values[subindex:subindex + count]))

    def pnu_write(self, pnu: int, subindex: int, value: ParameterValue) -> None:
        if pnu not in self.params:
            raise PnuAccessError(0)
        fmt, values, _ = self.params[pnu]
        if pnu == 964:
            raise PnuAccessError(1, subindex)
        if fmt == Format.VISIBLE_STRING:
            text = values[0]
            values[0] = text[:subindex] + value.values[0] + text[subindex + value.count:]
            return
        value = convert_value(value, fmt)
        values[subindex:subindex + value.count] = value.values

    def pnu_describe(self, pnu: int) -> ParameterDescription:
        if pnu not in self.params:
            raise PnuAccessError(0)
        fmt, values, array = self.params[pnu]
        return ParameterDescription(fmt | (ID_ARRAY if array else 0), len(values) if array else 0,
                                    name=f"P{pnu}", high_limit=b"\x00\x00\x03\xe8")


class ServerLink(RecordLink):
    """In-memory RecordLink: hands every request to a PnuServer; ``mangle`` may tamper with the reply."""

    def __init__(self, server: PnuServer, mangle: Callable[[bytes, bytes], bytes] | None = None) -> None:
        self.server = server
        self.mangle = mangle
        self.log: list[tuple[bytes, bytes]] = []

    def exchange(self, request: bytes) -> bytes:
        assert len(request) <= MAX_BLOCK
        reply = self.server.handle(request)
        assert len(reply) <= MAX_BLOCK
        if self.mangle is not None:
            reply = self.mangle(request, reply)
        self.log.append((request, reply))
        return reply


@pytest.fixture
def access() -> FakeAccess:
    return FakeAccess()


@pytest.fixture
def link(access: FakeAccess) -> ServerLink:
    return ServerLink(PnuServer(access))


@pytest.fixture
def channel(link: ServerLink) -> BmpParameterChannel:
    return BmpParameterChannel(link)


def channel_with(access: FakeAccess, mangle: Callable[[bytes, bytes], bytes]) -> BmpParameterChannel:
    return BmpParameterChannel(ServerLink(PnuServer(access), mangle))


# --- batching --------------------------------------------------------------------------------------------------


def test_reading_100_pnus_takes_three_round_trips(channel: BmpParameterChannel, link: ServerLink) -> None:
    results = channel.read([ParameterAddress(p) for p in range(1, 101)])
    assert channel.requests == math.ceil(100 / MAX_PARAMETERS) == 3
    assert [r.value for r in results] == list(range(1, 101))
    assert [decode_request(req).addresses[0].pnu for req, _ in link.log] == [1, 40, 79]


def test_writing_100_pnus_is_bound_by_the_request_size(channel: BmpParameterChannel, access: FakeAccess) -> None:
    # a dword change costs 6 address + 6 value bytes: 19 fit one 240-byte request (4 + 19 × 12 = 232)
    items = [(ParameterAddress(p), ParameterValue.of(Format.DWORD, 1000 + p)) for p in range(1, 101)]
    assert channel.write(items) == [None] * 100
    assert channel.requests == math.ceil(100 / 19) == 6
    assert access.params[77][1] == [1077]


def test_change_batches_fill_to_the_byte_limit(channel: BmpParameterChannel) -> None:
    # 19 dword changes fit one request, the 20th opens a second one
    items = [(ParameterAddress(p), ParameterValue.of(Format.DWORD, p)) for p in range(1, 21)]
    channel.write(items[:19])
    assert channel.requests == 1
    channel.write(items)
    assert channel.requests == 3


def test_response_size_splits_at_240_bytes(channel: BmpParameterChannel, link: ServerLink) -> None:
    # six reads of 20 dwords: 82-byte response blocks, two per response
    results = channel.read([ParameterAddress(2000, 10 * i, 20) for i in range(3)] * 2)
    assert channel.requests == 3
    assert results[1].values == tuple(range(10, 30))
    assert all(len(req) <= MAX_BLOCK and len(rep) <= MAX_BLOCK for req, rep in link.log)


def test_request_size_splits_at_240_bytes(channel: BmpParameterChannel, access: FakeAccess) -> None:
    # three changes of 50 words (102-byte blocks + 6-byte addresses): two fit one request
    items = [(ParameterAddress(980, 50 * i, 50), ParameterValue.of(Format.WORD, *range(50 * i, 50 * i + 50)))
             for i in range(3)]
    items = [(a, ParameterValue(v.format, tuple(x + 1000 for x in v.values))) for a, v in items]
    assert channel.write(items) == [None] * 3
    assert channel.requests == 2
    assert access.params[980][1][:150] == list(range(1000, 1150))


def test_long_array_read_in_ranges_and_joined(link: ServerLink) -> None:
    channel = BmpParameterChannel(link, element_size=4)  # the generic bound, whatever the catalogue says
    result = channel.read([ParameterAddress(980, 0, 200)])[0]
    assert result == ParameterValue(Format.UINT16, tuple(range(200)))
    assert channel.requests == 4          # 58 elements per response at 4 bytes per element


def test_catalogue_element_sizes_pack_word_arrays_tighter(channel: BmpParameterChannel) -> None:
    """By default the channel sizes PNU 980 (U16 in the catalogue) at 2 bytes per element (SPEC-NOTES 5)."""
    result = channel.read([ParameterAddress(980, 0, 200)])[0]
    assert result == ParameterValue(Format.UINT16, tuple(range(200)))
    assert channel.requests == 2          # 117 elements per response at 2 bytes per element


def test_long_array_write_in_ranges(channel: BmpParameterChannel, access: FakeAccess) -> None:
    value = ParameterValue.of(Format.WORD, *range(500, 700))
    assert channel.write([(ParameterAddress(980, 0, 200), value)]) == [None]
    assert channel.requests == 2          # 114 words per request
    assert access.params[980][1] == list(range(500, 700))


def test_long_string_read_and_write(channel: BmpParameterChannel, access: FakeAccess) -> None:
    text = "".join(chr(65 + i % 26) for i in range(200))
    assert channel.write([(ParameterAddress(4000, 0, 200), ParameterValue.of(Format.VISIBLE_STRING, text))]) == [None]
    assert access.params[4000][1][0] == text
    assert channel.read([ParameterAddress(4000, 0, 200)])[0] == ParameterValue.of(Format.VISIBLE_STRING, text)


def test_64_bit_values_retried_smaller(channel: BmpParameterChannel, access: FakeAccess) -> None:
    # 40 × 8 bytes is too long for one response; the drive says 0x15 and the channel re-reads in ranges
    result = channel.read([ParameterAddress(3000, 0, 40), ParameterAddress(1)])
    assert result[0] == ParameterValue(Format.UINT64, tuple(access.params[3000][1]))
    assert result[1].value == 1


def test_whole_request_too_long_is_halved(channel: BmpParameterChannel, access: FakeAccess) -> None:
    # five reads of 10 × 8 bytes fit the 4-byte estimate but not the response: refused as a whole, then halved
    results = channel.read([ParameterAddress(3000, 8 * i, 8) for i in range(5)])
    assert [r.values for r in results] == [tuple(access.params[3000][1][8 * i:8 * i + 8]) for i in range(5)]


# --- references ------------------------------------------------------------------------------------------------


def test_references_count_up_and_skip_zero(access: FakeAccess) -> None:
    link = ServerLink(PnuServer(access))
    channel = BmpParameterChannel(link, reference_start=254)
    for _ in range(3):
        channel.read([ParameterAddress(1)])
    assert [req[0] for req, _ in link.log] == [254, 255, 1]
    with pytest.raises(UsageError):
        BmpParameterChannel(link, reference_start=0)


def test_wrong_reference_is_malformed(access: FakeAccess) -> None:
    channel = channel_with(access, lambda req, rep: bytes([rep[0] ^ 1]) + rep[1:])
    with pytest.raises(MalformedReply, match="reference"):
        channel.read([ParameterAddress(1)])


def test_truncated_reply_is_malformed(access: FakeAccess) -> None:
    channel = channel_with(access, lambda req, rep: rep[:-1] if len(rep) > 6 else rep[:3])
    with pytest.raises(MalformedReply) as info:
        channel.read([ParameterAddress(947, 0, 3)])
    assert "announces 3 values (6 bytes) but only 5 follow" in str(info.value)
    assert info.value.exit_code == 3


def test_empty_reply_is_malformed(access: FakeAccess) -> None:
    with pytest.raises(MalformedReply, match="header"):
        channel_with(access, lambda req, rep: b"").read([ParameterAddress(1)])


def test_response_id_of_another_service_is_malformed(access: FakeAccess) -> None:
    channel = channel_with(access, lambda req, rep: rep[:1] + b"\x02" + rep[2:4] + b"\x00\x00")
    with pytest.raises(MalformedReply, match="does not answer a read"):
        channel.read([ParameterAddress(1)])


def test_result_count_mismatch_is_malformed(access: FakeAccess) -> None:
    channel = channel_with(access, lambda req, rep: rep[:3] + b"\x01" + rep[4:10])
    with pytest.raises(MalformedReply, match="1 results for 2 parameters"):
        channel.read([ParameterAddress(1), ParameterAddress(2)])


# --- refusals are results --------------------------------------------------------------------------------------


def test_negative_read_gives_per_parameter_failures(channel: BmpParameterChannel) -> None:
    results = channel.read([ParameterAddress(1), ParameterAddress(555), ParameterAddress(947, 70)])
    assert results[0].value == 1
    assert results[1] == ParameterFailure(0)
    assert results[2] == ParameterFailure(3, 70)


def test_whole_request_refusal_applies_to_every_parameter(access: FakeAccess) -> None:
    channel = BmpParameterChannel(ServerLink(PnuServer(access)), axis=3)
    assert channel.read([ParameterAddress(1), ParameterAddress(2)]) == [ParameterFailure(0x19)] * 2


def test_single_error_for_many_is_applied_to_all(access: FakeAccess) -> None:
    # Devices that answer a header error with one error block (the Siemens reference does) are understood.
    channel = channel_with(access, lambda req, rep: bytes([req[0], 0x81, 0, 1, 0x44, 1, 0, 0x23]))
    assert channel.read([ParameterAddress(1), ParameterAddress(2)]) == [ParameterFailure(0x23)] * 2


def test_negative_change_gives_per_parameter_failures(channel: BmpParameterChannel, access: FakeAccess) -> None:
    results = channel.write([(ParameterAddress(964), ParameterValue.of(Format.WORD, 1)),
                             (ParameterAddress(5), ParameterValue.of(Format.DWORD, 55)),
                             (ParameterAddress(5), ParameterValue.of(Format.INT16, 1))])
    assert results == [ParameterFailure(1, 0), None, ParameterFailure(5)]
    assert access.params[5][1] == [55]


def test_header_only_positive_change_accepted(access: FakeAccess) -> None:
    # SPEC-NOTES 3: the 4-byte form of a positive change response
    channel = channel_with(access, lambda req, rep: rep[:4])
    assert channel.write([(ParameterAddress(5), ParameterValue.of(Format.DWORD, 9))]) == [None]


# --- description, usage errors, link errors, tracing -----------------------------------------------------------


def test_describe(channel: BmpParameterChannel) -> None:
    description = channel.read_description(947)
    assert description.name == "P947" and description.is_array and description.elements == 64
    assert description.data_type == Format.UINT16 and description.limits() == (0, 1000)
    with pytest.raises(ParameterRefused) as info:
        channel.read_description(555)
    assert info.value.code == 0 and "impermissible parameter number" in str(info.value)


@pytest.mark.parametrize("address", [ParameterAddress(0), ParameterAddress(1, 0xFFFF), ParameterAddress(1, 0, 0)])
def test_invalid_addresses_are_usage_errors(channel: BmpParameterChannel, address: ParameterAddress) -> None:
    with pytest.raises(UsageError):
        channel.read([address])
    assert channel.requests == 0


def test_value_count_mismatch_is_a_usage_error(channel: BmpParameterChannel) -> None:
    with pytest.raises(UsageError, match="2 values for 1 elements"):
        channel.write([(ParameterAddress(1), ParameterValue.of(Format.DWORD, 1, 2))])
    with pytest.raises(UsageError):
        channel.write([(ParameterAddress(1), ParameterValue.of(Format.WORD, 1 << 20))])


def test_link_errors_pass_through() -> None:
    class SilentLink(RecordLink):
        def exchange(self, request: bytes) -> bytes:
            raise NoAnswer("no answer from the drive within 2.0 s")

    channel = BmpParameterChannel(SilentLink())
    with pytest.raises(NoAnswer):
        channel.read([ParameterAddress(1)])
    assert channel.requests == 1


def test_tracer_records_bmp_frames(link: ServerLink) -> None:
    tracer = Tracer()
    BmpParameterChannel(TracedRecordLink(link, tracer)).read([ParameterAddress(1)])
    assert [(r.direction, r.layer) for r in tracer.records] == [("tx", "bmp"), ("rx", "bmp")]
    assert tracer.records[0].data == link.log[0][0]


def test_empty_read_sends_nothing(channel: BmpParameterChannel) -> None:
    assert channel.read([]) == [] and channel.write([]) == [] and channel.requests == 0
