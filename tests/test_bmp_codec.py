"""PROFIdrive base-mode parameter access codec: seed vectors first, then layouts, limits, round trips, fuzz."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from akdctl.catalog.texts import profidrive_error_phrase, profidrive_failure_detail
from akdctl.protocol.errors import CodecError
from akdctl.protocol.bmp import (
    ATTR_DESCRIPTION,
    ATTR_TEXT,
    ATTR_VALUE,
    DESCRIPTION_SIZE,
    ID_ARRAY,
    MAX_BLOCK,
    MAX_ELEMENTS,
    MAX_PARAMETERS,
    MAX_SUBINDEX,
    REQ_CHANGE,
    REQ_READ,
    RESP_CHANGE_NAK,
    RESP_CHANGE_OK,
    RESP_NOT_SUPPORTED,
    RESP_READ_NAK,
    RESP_READ_OK,
    BmpError,
    Format,
    ParameterAddress,
    ParameterDescription,
    ParameterFailure,
    ParameterRequest,
    ParameterResponse,
    ParameterValue,
    decode_description,
    decode_request,
    decode_response,
    description_element,
    encode_description,
    encode_request,
    encode_response,
    format_size,
    next_reference,
    request_size,
    to_signed,
    to_unsigned,
)

# --- seed vectors (000 3.5.2 / 004 3.6.2 "Example for writing the operation mode") ----------------------------

# SPEC-NOTES 1 (big-endian value 00 02) and 2 (attribute 0x10) applied to the seed request.
SEED_CHANGE = bytes.fromhex("05 02 00 01 10 01 03 A2 00 00 42 01 00 02")
SEED_CHANGE_OK = bytes.fromhex("05 02 00 01 00 00")


def seed_request() -> ParameterRequest:
    return ParameterRequest(5, REQ_CHANGE, 0, (ParameterAddress(930),), (ParameterValue.of(Format.WORD, 2),))


def test_seed_change_request_encodes_to_the_ruled_bytes() -> None:
    # SPEC-NOTES 1, 2
    assert encode_request(seed_request()) == SEED_CHANGE


def test_seed_change_request_decodes() -> None:
    request = decode_request(SEED_CHANGE)
    assert request == seed_request()
    assert request.addresses[0].pnu == 930 and request.values[0].value == 2


def test_seed_positive_change_response_six_bytes() -> None:
    # SPEC-NOTES 3: the seed's 6-byte form decodes and is what the encoder emits.
    response = decode_response(SEED_CHANGE_OK, seed_request())
    assert response == ParameterResponse(5, RESP_CHANGE_OK, 0, (None,))
    assert encode_response(response) == SEED_CHANGE_OK


def test_positive_change_response_header_only() -> None:
    # SPEC-NOTES 3: the standard's bare header is accepted too.
    response = decode_response(SEED_CHANGE_OK[:4], seed_request())
    assert response.results == (None,)
    assert encode_response(response, compact=True) == SEED_CHANGE_OK[:4]


def test_seed_000_little_endian_value_is_read_big_endian() -> None:
    # SPEC-NOTES 1: 000 prints the value as 02 00; big-endian reads that as 512, not 2.
    request = decode_request(SEED_CHANGE[:12] + b"\x02\x00")
    assert request.values[0].values == (0x0200,)


def test_seed_004_attribute_0a_is_rejected() -> None:
    # SPEC-NOTES 2: 004's attribute 0x0A is a typo; 0x0A is no attribute.
    with pytest.raises(BmpError, match="attribute"):
        decode_request(SEED_CHANGE[:4] + b"\x0A" + SEED_CHANGE[5:])


# --- layouts ---------------------------------------------------------------------------------------------------


def test_multi_parameter_read_request_layout() -> None:
    request = ParameterRequest(0x21, REQ_READ, 0, (ParameterAddress(930), ParameterAddress(947, 3, 8)))
    raw = encode_request(request)
    assert raw == bytes.fromhex("21 01 00 02  10 01 03A2 0000  10 08 03B3 0003")
    assert decode_request(raw) == request


def test_multi_parameter_read_response_with_array_and_padding() -> None:
    request = ParameterRequest(7, REQ_READ, 0, (
        ParameterAddress(930), ParameterAddress(947, 0, 3), ParameterAddress(1000, 0, 3)))
    raw = bytes.fromhex("07 01 00 03  42 01 0002  42 03 0001 0002 0003  41 03 0A0B0C 00")
    response = decode_response(raw, request)
    assert response.results == (
        ParameterValue.of(Format.WORD, 2),
        ParameterValue.of(Format.WORD, 1, 2, 3),
        ParameterValue.of(Format.BYTE, 10, 11, 12),
    )
    assert encode_response(response) == raw


def test_missing_pad_byte_tolerated_only_at_the_end() -> None:
    raw = bytes.fromhex("07 01 00 01  41 03 0A0B0C")
    assert decode_response(raw).results[0] == ParameterValue.of(Format.BYTE, 10, 11, 12)
    # in the middle, the next block would start at the pad byte: inconsistent
    with pytest.raises(BmpError):
        decode_response(bytes.fromhex("07 01 00 02  41 03 0A0B0C  42 01 0002"))


def test_typed_formats_decode_to_python_types() -> None:
    raw = bytes.fromhex("09 01 00 06"
                        "03 01 FFFE"            # INT16 -2
                        "08 01 3FC00000"        # FLOAT32 1.5
                        "09 03 414B44 00"       # VisibleString "AKD"
                        "0A 02 BEEF"            # OctetString
                        "01 02 0100"            # BOOLEAN
                        "37 01 FFFFFFFFFFFFFFFF")  # INT64 -1
    results = decode_response(raw).results
    assert results == (
        ParameterValue.of(Format.INT16, -2), ParameterValue.of(Format.FLOAT32, 1.5),
        ParameterValue.of(Format.VISIBLE_STRING, "AKD"), ParameterValue.of(Format.OCTET_STRING, b"\xbe\xef"),
        ParameterValue.of(Format.BOOLEAN, True, False), ParameterValue.of(Format.INT64, -1),
    )
    assert results[2].count == 3 and results[3].count == 2


def test_negative_read_response_with_and_without_additional_info() -> None:
    request = ParameterRequest(9, REQ_READ, 0, (ParameterAddress(930), ParameterAddress(1), ParameterAddress(947, 99)))
    raw = bytes.fromhex("09 81 00 03  42 01 0002  44 01 0000  44 02 0003 0063")
    response = decode_response(raw, request)
    assert response.negative
    assert response.results == (ParameterValue.of(Format.WORD, 2), ParameterFailure(0), ParameterFailure(3, 99))
    assert profidrive_error_phrase(response.results[1].error) == "impermissible parameter number"
    assert "subindex 99" in profidrive_failure_detail(response.results[2].error, response.results[2].additional)
    assert encode_response(response) == raw


def test_negative_change_response_lists_ok_parameters_as_zero() -> None:
    raw = bytes.fromhex("0A 82 00 02  40 00  44 02 0002 0000")
    response = decode_response(raw)
    assert response.results == (None, ParameterFailure(2, 0))
    assert encode_response(response) == raw


def test_not_supported_response() -> None:
    raw = bytes.fromhex("0B 80 00 01 44 01 0021")
    response = decode_response(raw, ParameterRequest(0x0B, REQ_READ, 0, (ParameterAddress(930),)))
    assert response.results == (ParameterFailure(0x21),)
    assert "service not supported" in profidrive_error_phrase(response.results[0].error)


def test_manufacturer_specific_error_text() -> None:
    assert profidrive_error_phrase(ParameterFailure(0x6A).error) == "manufacturer-specific PROFIdrive error 0x6A"


def test_single_error_for_multi_parameter_request_applies_to_all() -> None:
    request = ParameterRequest(3, REQ_READ, 0, tuple(ParameterAddress(p) for p in (930, 931, 932)))
    response = decode_response(bytes.fromhex("03 81 00 01 44 01 0019"), request)
    assert response.results == (ParameterFailure(0x19),) * 3


@pytest.mark.parametrize("raw, words", [
    ("04 01 00 01 42 01 0002", "reference 4 does not match request reference 3"),
    ("03 02 00 01 00 00", "does not answer a read"),
    ("03 01 01 01 42 01 0002", "axis 1"),
    ("03 01 00 02 42 01 0002 42 01 0003", "2 results for 1 parameters"),
    ("03 01 00 01 42 02 0002 0003", "asked for 1 values, got 2"),
])
def test_response_checked_against_request(raw: str, words: str) -> None:
    request = ParameterRequest(3, REQ_READ, 0, (ParameterAddress(930),))
    with pytest.raises(BmpError, match=words):
        decode_response(bytes.fromhex(raw), request)


def test_value_block_in_change_response_is_malformed() -> None:
    with pytest.raises(BmpError):
        decode_response(bytes.fromhex("05 02 00 01 42 01 0002"))


def test_signed_helpers() -> None:
    assert to_signed(0xFFFE, 16) == -2 and to_signed(0x7FFF, 16) == 0x7FFF
    assert to_unsigned(-2, 16) == 0xFFFE and to_signed(to_unsigned(-5, 32), 32) == -5
    assert format_size(Format.DWORD) == 4 and format_size(Format.UINT64) == 8 and format_size(Format.ZERO) == 0


# --- description -----------------------------------------------------------------------------------------------


def make_description() -> ParameterDescription:
    return ParameterDescription(
        identifier=Format.INT16 | ID_ARRAY, elements=8, standardisation_factor=0.5, variable_attribute=0x0102,
        name="FAULT NUMBERS", low_limit=ParameterDescription.limit_bytes(Format.INT16, -100),
        high_limit=ParameterDescription.limit_bytes(Format.INT16, 100), id_extension=0,
        normalisation_ref=0, normalisation_field=0x0F00,
    )


def test_description_block_layout() -> None:
    raw = encode_description(make_description())
    assert len(raw) == DESCRIPTION_SIZE == 46
    assert raw[0:2] == b"\x40\x03"                     # identifier: array of Integer16
    assert raw[2:4] == b"\x00\x08"                     # number of elements
    assert raw[4:8] == struct.pack(">f", 0.5)          # standardisation factor
    assert raw[8:10] == b"\x01\x02"                    # variable attribute
    assert raw[10:14] == b"\x00" * 4                   # reserved
    assert raw[14:30] == b"FAULT NUMBERS   "           # name, 16 characters
    assert raw[30:34] == b"\x00\x00\xff\x9c"           # low limit -100
    assert raw[34:38] == b"\x00\x00\x00\x64"           # high limit 100
    assert raw[44:46] == b"\x0f\x00"                   # normalisation field
    description = decode_description(raw)
    assert description == make_description()
    assert description.is_array and not description.read_only and description.data_type == Format.INT16
    assert description.limits() == (-100, 100)


def test_description_elements() -> None:
    d = make_description()
    assert description_element(d, 0) == ParameterValue(Format.OCTET_STRING, (encode_description(d),))
    assert description_element(d, 1) == ParameterValue.of(Format.V2, 0x4003)
    assert description_element(d, 2) == ParameterValue.of(Format.UINT16, 8)
    assert description_element(d, 3) == ParameterValue.of(Format.FLOAT32, 0.5)
    assert description_element(d, 6) == ParameterValue.of(Format.VISIBLE_STRING, "FAULT NUMBERS   ")
    with pytest.raises(BmpError):
        description_element(d, 13)


def test_description_rejects_bad_fields() -> None:
    with pytest.raises(BmpError):
        encode_description(ParameterDescription(Format.UINT16, name="X" * 17))
    with pytest.raises(BmpError):
        encode_description(ParameterDescription(0x10000))
    with pytest.raises(BmpError):
        decode_description(b"\x00" * 45)


# --- limits (SPEC-NOTES 4) -------------------------------------------------------------------------------------


@pytest.mark.parametrize("address", [
    ParameterAddress(0), ParameterAddress(0x10000), ParameterAddress(930, MAX_SUBINDEX + 1),
    ParameterAddress(930, 0, 0), ParameterAddress(930, 0, MAX_ELEMENTS + 1), ParameterAddress(930, attribute=0x40),
])
def test_address_limits_on_encode(address: ParameterAddress) -> None:
    with pytest.raises(BmpError):
        encode_request(ParameterRequest(1, REQ_READ, 0, (address,)))


def test_address_limits_at_the_edges_encode() -> None:
    for address in (ParameterAddress(1), ParameterAddress(0xFFFF, MAX_SUBINDEX, MAX_ELEMENTS)):
        encode_request(ParameterRequest(1, REQ_READ, 0, (address,)))


@pytest.mark.parametrize("patch, words", [
    (b"\x10\x01\x03\xa2\xff\xff", "subindex"),
    (b"\x10\x00\x03\xa2\x00\x00", "number of elements"),
    (b"\x10\xeb\x03\xa2\x00\x00", "number of elements"),
    (b"\x10\x01\x00\x00\x00\x00", "PNU"),
])
def test_address_limits_on_decode(patch: bytes, words: str) -> None:
    with pytest.raises(BmpError, match=words):
        decode_request(b"\x01\x01\x00\x01" + patch)


def test_parameter_count_limits() -> None:
    many = tuple(ParameterAddress(900 + i) for i in range(MAX_PARAMETERS))
    assert len(encode_request(ParameterRequest(1, REQ_READ, 0, many))) == 4 + 6 * 39
    with pytest.raises(BmpError):
        encode_request(ParameterRequest(1, REQ_READ, 0, many + (ParameterAddress(1),)))
    with pytest.raises(BmpError):
        encode_request(ParameterRequest(1, REQ_READ, 0, ()))
    with pytest.raises(BmpError, match="number of parameters"):
        decode_request(b"\x01\x01\x00\x28" + b"\x10\x01\x03\xa2\x00\x00" * 39)
    with pytest.raises(BmpError, match="number of parameters"):
        decode_request(b"\x01\x01\x00\x00")


def test_block_limit() -> None:
    big = ParameterValue.of(Format.DWORD, *range(58))  # 232 data bytes: 4 + 6 + 2 + 232 = 244 > 240
    with pytest.raises(BmpError, match="240"):
        encode_request(ParameterRequest(1, REQ_CHANGE, 0, (ParameterAddress(947, 0, 58),), (big,)))
    with pytest.raises(BmpError, match="240"):
        decode_response(b"\x01\x01\x00\x01\x41\xea" + bytes(234) + b"\x00")


def test_request_value_count_must_match_elements() -> None:
    with pytest.raises(BmpError):
        encode_request(ParameterRequest(1, REQ_CHANGE, 0, (ParameterAddress(930, 0, 2),),
                                        (ParameterValue.of(Format.WORD, 1),)))
    with pytest.raises(BmpError, match="number of elements"):
        decode_request(bytes.fromhex("01 02 00 01 10 02 03A2 0000 42 01 0002"))


@pytest.mark.parametrize("value", [
    ParameterValue.of(Format.WORD, 0x10000), ParameterValue.of(Format.INT8, 128), ParameterValue.of(Format.WORD, 1.5),
    ParameterValue.of(Format.FLOAT32, 1e60), ParameterValue.of(Format.VISIBLE_STRING, "\u20ac"),
    ParameterValue.of(Format.OCTET_STRING, "text"), ParameterValue.of(Format.ERROR, 1),
    ParameterValue.of(0x50, 1), ParameterValue.of(Format.BOOLEAN, 2),
])
def test_unencodable_values(value: ParameterValue) -> None:
    with pytest.raises(BmpError):
        encode_request(ParameterRequest(1, REQ_CHANGE, 0, (ParameterAddress(930, 0, max(value.count, 1)),), (value,)))


def test_next_reference_never_zero() -> None:
    assert next_reference(1) == 2 and next_reference(254) == 255 and next_reference(255) == 1


# --- property tests --------------------------------------------------------------------------------------------

_INT_RANGES = {
    Format.INT8: (-(2**7), 2**7 - 1), Format.INT16: (-(2**15), 2**15 - 1), Format.INT32: (-(2**31), 2**31 - 1),
    Format.INT64: (-(2**63), 2**63 - 1), Format.UINT8: (0, 2**8 - 1), Format.UINT16: (0, 2**16 - 1),
    Format.UINT32: (0, 2**32 - 1), Format.UINT64: (0, 2**64 - 1), Format.BYTE: (0, 255),
    Format.WORD: (0, 0xFFFF), Format.DWORD: (0, 0xFFFFFFFF), Format.N2: (-(2**15), 2**15 - 1),
    Format.V2: (0, 0xFFFF), Format.N4: (-(2**31), 2**31 - 1), Format.T4: (0, 2**32 - 1),
}


@st.composite
def parameter_values(draw: st.DrawFn) -> ParameterValue:
    kind = draw(st.sampled_from(["int", "f32", "f64", "bool", "vs", "os", "us", "raw"]))
    n = draw(st.integers(1, 4))
    if kind == "int":
        fmt = draw(st.sampled_from(sorted(_INT_RANGES)))
        low, high = _INT_RANGES[fmt]
        return ParameterValue(fmt, tuple(draw(st.lists(st.integers(low, high), min_size=n, max_size=n))))
    if kind == "f32":
        return ParameterValue(Format.FLOAT32, tuple(draw(st.lists(
            st.floats(width=32, allow_nan=False), min_size=n, max_size=n))))
    if kind == "f64":
        return ParameterValue(Format.FLOAT64, tuple(draw(st.lists(st.floats(allow_nan=False), min_size=n, max_size=n))))
    if kind == "bool":
        return ParameterValue(Format.BOOLEAN, tuple(draw(st.lists(st.booleans(), min_size=n, max_size=n))))
    if kind == "vs":
        return ParameterValue(Format.VISIBLE_STRING, (draw(st.text(st.characters(max_codepoint=255), min_size=1,
                                                                   max_size=17)),))
    if kind == "os":
        return ParameterValue(Format.OCTET_STRING, (draw(st.binary(min_size=1, max_size=17)),))
    if kind == "us":
        return ParameterValue(Format.UNICODE_STRING, (draw(st.text(min_size=1, max_size=8)),))
    fmt = draw(st.sampled_from([Format.TIME_OF_DAY, Format.BINARY_DATE, Format.TIME_DIFFERENCE_NO_DATE]))
    size = format_size(fmt)
    return ParameterValue(fmt, tuple(draw(st.lists(st.binary(min_size=size, max_size=size), min_size=n, max_size=n))))


addresses_st = st.builds(
    ParameterAddress, pnu=st.integers(1, 0xFFFF), subindex=st.integers(0, MAX_SUBINDEX),
    count=st.integers(1, MAX_ELEMENTS), attribute=st.sampled_from([ATTR_VALUE, ATTR_DESCRIPTION, ATTR_TEXT]))


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 255), st.integers(0, 255), st.lists(addresses_st, min_size=1, max_size=MAX_PARAMETERS))
def test_read_request_round_trip(reference: int, axis: int, addresses: list[ParameterAddress]) -> None:
    request = ParameterRequest(reference, REQ_READ, axis, tuple(addresses))
    assert decode_request(encode_request(request)) == request


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 255), st.lists(st.tuples(addresses_st, parameter_values()), min_size=1, max_size=6))
def test_change_request_round_trip(reference: int, items: list[tuple[ParameterAddress, ParameterValue]]) -> None:
    addresses = tuple(ParameterAddress(a.pnu, a.subindex, v.count, a.attribute) for a, v in items)
    request = ParameterRequest(reference, REQ_CHANGE, 0, addresses, tuple(v for _, v in items))
    assume(request_size(request) <= MAX_BLOCK)
    raw = encode_request(request)
    assert len(raw) % 2 == 0
    assert decode_request(raw) == request


results_st = st.one_of(
    parameter_values(),
    st.builds(ParameterFailure, st.integers(0, 0xFFFF), st.one_of(st.none(), st.integers(0, 0xFFFF))),
)


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 255), st.integers(0, 255), st.lists(results_st, min_size=1, max_size=8))
def test_read_response_round_trip(reference: int, axis: int, results: list) -> None:
    negative = any(isinstance(r, ParameterFailure) for r in results)
    response = ParameterResponse(reference, RESP_READ_NAK if negative else RESP_READ_OK, axis, tuple(results))
    try:
        raw = encode_response(response)
    except BmpError:
        assume(False)
    assert decode_response(raw) == response


@given(st.integers(0, 255), st.lists(st.one_of(st.none(), st.integers(0, 0xFFFF).map(ParameterFailure)),
                                     min_size=1, max_size=MAX_PARAMETERS))
def test_change_response_round_trip(reference: int, results: list) -> None:
    negative = any(r is not None for r in results)
    response = ParameterResponse(reference, RESP_CHANGE_NAK if negative else RESP_CHANGE_OK, 0, tuple(results))
    assert decode_response(encode_response(response)) == response


@given(st.builds(
    ParameterDescription, identifier=st.integers(0, 0xFFFF), elements=st.integers(0, 0xFFFF),
    standardisation_factor=st.floats(width=32, allow_nan=False),
    variable_attribute=st.integers(0, 0xFFFF),
    name=st.text(st.characters(min_codepoint=0x21, max_codepoint=255), max_size=16),
    low_limit=st.binary(min_size=4, max_size=4), high_limit=st.binary(min_size=4, max_size=4),
    id_extension=st.integers(0, 0xFFFF), normalisation_ref=st.integers(0, 0xFFFF),
    normalisation_field=st.integers(0, 0xFFFF)))
def test_description_round_trip(description: ParameterDescription) -> None:
    decoded = decode_description(encode_description(description))
    assert decoded == description or (math.isnan(decoded.standardisation_factor))


@settings(max_examples=1000)
@given(st.binary(max_size=260))
def test_fuzz_only_codec_errors(data: bytes) -> None:
    request = ParameterRequest(data[0] if data else 1, REQ_READ, 0, (ParameterAddress(930),))
    for decode in (decode_request, decode_response, decode_description, lambda d: decode_response(d, request)):
        try:
            decode(data)
        except CodecError:
            pass


@settings(max_examples=500)
@given(st.sampled_from([REQ_READ, REQ_CHANGE, RESP_CHANGE_NAK, RESP_NOT_SUPPORTED]), st.integers(1, 3),
       st.binary(max_size=60))
def test_fuzz_plausible_headers(kind: int, n: int, body: bytes) -> None:
    # Arbitrary bodies behind a valid-looking header reach the deeper decoding paths.
    data = bytes([1, kind, 0, n]) + body
    for decode in (decode_request, decode_response):
        try:
            decode(data)
        except CodecError:
            pass
