"""PnuServer: request bytes in, the response bytes an AKD / PROFIdrive parameter manager would give."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.protocol.errors import CodecError
from akdctl.protocol.bmp import (
    ATTR_DESCRIPTION,
    ID_ARRAY,
    ID_READ_ONLY,
    REQ_CHANGE,
    REQ_READ,
    Format,
    ParameterAddress,
    ParameterDescription,
    ParameterFailure,
    ParameterRequest,
    ParameterValue,
    decode_description,
    decode_request,
    decode_response,
    encode_request,
)
from akdctl.sim.pnu_server import PnuAccessError, PnuServer, RecordRefused, convert_value, header_refusal
from tests.pnu_model import failing_reader


class FakeAccess:
    """A few PNUs: plain words, a read-only word, a dword with limits, arrays, 64-bit values."""

    def __init__(self) -> None:
        self.data: dict[int, tuple[int, list, bool, bool]] = {   # pnu -> (type, values, array, read only)
            930: (Format.UINT16, [1], False, False),
            964: (Format.UINT16, [0x1A, 0x5, 0x0201, 2012, 0x1503, 1], True, True),
            947: (Format.UINT16, [0] * 64, True, False),
            1000: (Format.INT32, [0], False, False),
            2000: (Format.DWORD, list(range(100)), True, False),
            3000: (Format.UINT64, [0] * 40, True, False),
        }
        self.writes: list[tuple[int, int, ParameterValue]] = []

    def _entry(self, pnu: int) -> tuple[int, list, bool, bool]:
        if pnu not in self.data:
            raise PnuAccessError(0x00)
        return self.data[pnu]

    def pnu_read(self, pnu: int, subindex: int, count: int) -> ParameterValue:
        fmt, values, array, _ = self._entry(pnu)
        if not array and (subindex or count != 1):
            raise PnuAccessError(0x04)
        if subindex + count > len(values):
            raise PnuAccessError(0x03, subindex + count - 1)
        return ParameterValue(fmt, tuple(values[subindex:subindex + count]))

    def pnu_write(self, pnu: int, subindex: int, value: ParameterValue) -> None:
        fmt, values, array, read_only = self._entry(pnu)
        if read_only:
            raise PnuAccessError(0x01, subindex)
        value = convert_value(value, fmt)
        if subindex + value.count > len(values):
            raise PnuAccessError(0x03, subindex + value.count - 1)
        if pnu == 1000 and not -1000 <= value.values[0] <= 1000:
            raise PnuAccessError(0x02, subindex)
        values[subindex:subindex + value.count] = value.values
        self.writes.append((pnu, subindex, value))

    def pnu_describe(self, pnu: int) -> ParameterDescription:
        fmt, values, array, read_only = self._entry(pnu)
        identifier = fmt | (ID_ARRAY if array else 0) | (ID_READ_ONLY if read_only else 0)
        return ParameterDescription(identifier, len(values) if array else 0, name=f"PNU{pnu}")


@pytest.fixture
def access() -> FakeAccess:
    return FakeAccess()


@pytest.fixture
def server(access: FakeAccess) -> PnuServer:
    return PnuServer(access)


def ask(server: PnuServer, request: ParameterRequest):
    return decode_response(server.handle(encode_request(request)), request)


# --- seed vectors ----------------------------------------------------------------------------------------------


def test_seed_operation_mode_change(server: PnuServer, access: FakeAccess) -> None:
    # 000/004 "Example for writing the operation mode", SPEC-NOTES 1-3.
    reply = server.handle(bytes.fromhex("05 02 00 01 10 01 03 A2 00 00 42 01 00 02"))
    assert reply == bytes.fromhex("05 02 00 01 00 00")
    assert access.data[930][1] == [2]


def test_seed_request_with_004_attribute_typo_is_refused(server: PnuServer, access: FakeAccess) -> None:
    # SPEC-NOTES 2: attribute 0x0A is not "value".
    reply = server.handle(bytes.fromhex("05 02 00 01 0A 01 03 A2 00 00 42 01 00 02"))
    assert reply == bytes.fromhex("05 82 00 01 44 01 00 16")
    assert access.data[930][1] == [1]


# --- reads -----------------------------------------------------------------------------------------------------


def test_single_and_multi_parameter_read(server: PnuServer) -> None:
    reply = server.handle(bytes.fromhex("07 01 00 02 10 01 03A2 0000 10 03 03C4 0001"))
    assert reply == bytes.fromhex("07 01 00 02 06 01 0001 06 03 0005 0201 07DC")


def test_read_mixing_values_and_errors_is_negative(server: PnuServer) -> None:
    response = ask(server, ParameterRequest(8, REQ_READ, 0, (
        ParameterAddress(930), ParameterAddress(1), ParameterAddress(964, 5, 2), ParameterAddress(930, 1))))
    assert response.response_id == 0x81
    assert response.results == (ParameterValue.of(Format.UINT16, 1), ParameterFailure(0x00),
                                ParameterFailure(0x03, 6), ParameterFailure(0x04))


@pytest.mark.parametrize("address_hex", [
    "30 01 03A2 0000",    # text attribute: the AKD supports value and description only
    "00 01 03A2 0000",    # reserved attribute
    "10 00 03A2 0000",    # no elements
    "10 EB 03A2 0000",    # 235 elements
    "10 01 03A2 FFFF",    # subindex 0xFFFF
    "10 01 0000 0000",    # PNU 0
])
def test_impermissible_addresses(server: PnuServer, address_hex: str) -> None:
    reply = server.handle(bytes.fromhex("01 01 00 01" + address_hex))
    assert reply == bytes.fromhex("01 81 00 01 44 01 0016")


def test_value_too_long_for_one_response(server: PnuServer) -> None:
    # 100 dwords = 400 bytes: that parameter is refused, its neighbour still answered.
    response = ask(server, ParameterRequest(2, REQ_READ, 0, (ParameterAddress(2000, 0, 100), ParameterAddress(930))))
    assert response.results == (ParameterFailure(0x15), ParameterValue.of(Format.UINT16, 1))


def test_whole_response_too_long(server: PnuServer) -> None:
    # three blocks of 50 dwords (202 bytes each) do not fit one 240-byte response
    request = ParameterRequest(3, REQ_READ, 0, (ParameterAddress(2000, 0, 50),) * 3)
    reply = server.handle(encode_request(request))
    assert reply == bytes.fromhex("03 81 00 03" + "44 01 0015" * 3)


# --- descriptions ----------------------------------------------------------------------------------------------


def test_description_complete(server: PnuServer) -> None:
    response = ask(server, ParameterRequest(4, REQ_READ, 0, (ParameterAddress(964, 0, 1, ATTR_DESCRIPTION),)))
    value = response.results[0]
    assert value.format == Format.OCTET_STRING and value.count == 46
    description = decode_description(value.values[0])
    assert description.name == "PNU964" and description.is_array and description.read_only
    assert description.elements == 6 and description.data_type == Format.UINT16


def test_description_elements_and_errors(server: PnuServer) -> None:
    response = ask(server, ParameterRequest(4, REQ_READ, 0, (
        ParameterAddress(964, 2, 1, ATTR_DESCRIPTION), ParameterAddress(964, 13, 1, ATTR_DESCRIPTION),
        ParameterAddress(964, 2, 2, ATTR_DESCRIPTION), ParameterAddress(5, 0, 1, ATTR_DESCRIPTION))))
    assert response.results == (ParameterValue.of(Format.UINT16, 6), ParameterFailure(0x03, 13),
                                ParameterFailure(0x16), ParameterFailure(0x00))


def test_description_cannot_be_changed(server: PnuServer) -> None:
    reply = server.handle(bytes.fromhex("05 02 00 01 20 01 03A2 0006 42 01 0002"))
    assert reply == bytes.fromhex("05 82 00 01 44 02 0007 0006")


# --- changes ---------------------------------------------------------------------------------------------------


def test_multi_parameter_change_with_a_faulty_parameter(server: PnuServer, access: FakeAccess) -> None:
    request = ParameterRequest(6, REQ_CHANGE, 0, (
        ParameterAddress(930), ParameterAddress(1000), ParameterAddress(964), ParameterAddress(947, 2, 2)),
        (ParameterValue.of(Format.WORD, 3), ParameterValue.of(Format.DWORD, 5000),
         ParameterValue.of(Format.WORD, 1), ParameterValue.of(Format.WORD, 7, 8)))
    reply = server.handle(encode_request(request))
    # accepted ones are listed as format 0x40 (zero), refused ones as 0x44 with the subindex as additional info
    assert reply == bytes.fromhex("06 82 00 04 4000 44 02 0002 0000 44 02 0001 0000 4000")
    assert access.data[930][1] == [3] and access.data[947][1][2:4] == [7, 8]
    assert access.data[1000][1] == [0]


def test_multi_parameter_change_all_ok(server: PnuServer, access: FakeAccess) -> None:
    request = ParameterRequest(6, REQ_CHANGE, 0, (ParameterAddress(930), ParameterAddress(1000)),
                               (ParameterValue.of(Format.WORD, 3), ParameterValue.of(Format.DWORD, 0xFFFFFFFF)))
    assert server.handle(encode_request(request)) == bytes.fromhex("06 02 00 02 0000 0000")
    assert access.data[1000][1] == [-1]   # DWORD bits into an Integer32 parameter


def test_change_with_wrong_data_type(server: PnuServer) -> None:
    reply = server.handle(bytes.fromhex("05 02 00 01 10 01 03A2 0000 03 01 0002"))  # Integer16 into Unsigned16
    assert reply == bytes.fromhex("05 82 00 01 44 01 0005")


@pytest.mark.parametrize("block, error", [
    ("40 00", 0x17),          # zero format carries no value
    ("44 01 0000", 0x17),     # error format is no value
])
def test_change_with_unusable_value_block(server: PnuServer, block: str, error: int) -> None:
    reply = server.handle(bytes.fromhex("05 02 00 01 10 01 03A2 0000 " + block))
    assert reply == bytes.fromhex(f"05 82 00 01 44 01 00{error:02X}")


def test_change_value_count_inconsistent(server: PnuServer) -> None:
    reply = server.handle(bytes.fromhex("05 02 00 01 10 02 03B3 0000 42 01 0002"))
    assert reply == bytes.fromhex("05 82 00 01 44 01 0018")


# --- whole-request refusals ------------------------------------------------------------------------------------


@pytest.mark.parametrize("request_hex, reply_hex", [
    ("05 01 00 00", "05 81 00 01 44 01 0016"),                             # no parameters
    ("05 01 00 28" + "10 01 03A2 0000" * 39, "05 81 00 01 44 01 0022"),    # 40 parameters
    ("05 01 07 02 10 01 03A2 0000 10 01 03A2 0000", "05 81 07 02 44 01 0019 44 01 0019"),  # no axis 7
    ("05 01 00 02 10 01 03A2 0000 10 01", "05 81 00 02 44 01 0016 44 01 0016"),  # addresses cut short
    ("05 01 00 01 10 01 03A2 0000 42 01", "05 81 00 01 44 01 0018"),       # values in a read request
    ("05 02 00 01 10 01 03A2 0000 42 01 00", "05 82 00 01 44 01 0018"),    # value cut short
    ("05 02 00 01 10 01 03A2 0000 42 01 0002 0000", "05 82 00 01 44 01 0018"),  # trailing bytes
    ("05 02 00 01 10 01 03A2 0000 99 01 0002", "05 82 00 01 44 01 0017"),  # unknown format
])
def test_whole_request_refusals(server: PnuServer, access: FakeAccess, request_hex: str, reply_hex: str) -> None:
    assert server.handle(bytes.fromhex(request_hex)) == bytes.fromhex(reply_hex)
    assert access.writes == []


@pytest.mark.parametrize("request_hex, code1", [
    ("", 0xB1),                                         # nothing at all: shorter than the header
    ("05 01", 0xB1),                                    # header cut short
    ("05 01 00 01" + "00" * 240, 0xB1),                 # longer than 240 bytes
    ("00 01 00 01 10 01 03A2 0000", 0xB7),              # request reference 0x00 is reserved (000 3.5)
    ("05 03 00 01 10 01 03A2 0000", 0xB7),              # unknown request ID
    ("05 00 00 01 10 01 03A2 0000", 0xB7),
])
def test_header_refusals_are_record_layer_refusals(server: PnuServer, access: FakeAccess, request_hex: str,
                                                   code1: int) -> None:
    """docs/fidelity.md F1: no response, the record write fails (PDRV V4.2 table 169)."""
    with pytest.raises(RecordRefused) as info:
        server.handle(bytes.fromhex(request_hex))
    assert info.value.code1 == code1
    assert access.writes == []


def test_broken_change_writes_nothing(server: PnuServer, access: FakeAccess) -> None:
    # the first block is fine, the second is cut short: no parameter may be written
    raw = bytes.fromhex("05 02 00 02 10 01 03A2 0000 10 01 03E8 0000 42 01 0002 43 01 0000")
    assert server.handle(raw) == bytes.fromhex("05 82 00 02 44 01 0018 44 01 0018")
    assert access.writes == [] and access.data[930][1] == [1]


def test_configurable_axes(access: FakeAccess) -> None:
    server = PnuServer(access, axes=(0, 1))
    assert server.handle(bytes.fromhex("05 01 01 01 10 01 03A2 0000")) == bytes.fromhex("05 01 01 01 06 01 0001")


# --- a broken model still gets an answer -----------------------------------------------------------------------


class BrokenAccess(FakeAccess):
    def pnu_read(self, pnu: int, subindex: int, count: int) -> ParameterValue:
        if pnu == 1:
            raise RuntimeError("model bug")
        if pnu == 2:
            return ParameterValue.of(Format.WORD, 1, 2)       # wrong number of values
        if pnu == 3:
            return ParameterValue.of(Format.WORD, 1 << 20)    # does not fit a word
        return super().pnu_read(pnu, subindex, count)


def test_model_bugs_become_operating_state_errors() -> None:
    server = PnuServer(BrokenAccess())
    response = ask(server, ParameterRequest(1, REQ_READ, 0, tuple(ParameterAddress(p) for p in (1, 2, 3, 930))))
    assert response.results == (ParameterFailure(0x11),) * 3 + (ParameterValue.of(Format.UINT16, 1),)
    assert server.last_exception is not None


# --- format conversion helper ----------------------------------------------------------------------------------


def test_convert_value() -> None:
    assert convert_value(ParameterValue.of(Format.WORD, 0xFFFE), Format.INT16) == ParameterValue.of(Format.INT16, -2)
    assert convert_value(ParameterValue.of(Format.INT16, -2), Format.WORD) == ParameterValue.of(Format.WORD, 0xFFFE)
    assert convert_value(ParameterValue.of(Format.UINT16, 5), Format.UINT16) == ParameterValue.of(Format.UINT16, 5)
    with pytest.raises(PnuAccessError) as info:
        convert_value(ParameterValue.of(Format.UINT16, 5), Format.INT16)
    assert info.value.error == 0x05
    with pytest.raises(PnuAccessError):
        convert_value(ParameterValue.of(Format.WORD, 5), Format.INT32)


# --- property: every answer is a well-formed response ----------------------------------------------------------


@settings(max_examples=600)
@given(st.one_of(
    st.binary(max_size=250),
    st.tuples(st.sampled_from([1, 2, 3]), st.integers(0, 3), st.binary(max_size=40)).map(
        lambda t: bytes([9, t[0], 0, t[1]]) + t[2]),
))
def test_every_reply_decodes(data: bytes) -> None:
    server = PnuServer(FakeAccess())
    if header_refusal(data) is not None:
        with pytest.raises(RecordRefused):      # refused by the record layer: no response at all
            server.handle(data)
        return
    reply = server.handle(data)
    response = decode_response(reply)           # never raises: the server only emits valid responses
    assert response.reference != 0 and response.response_id in (0x01, 0x02, 0x81, 0x82)  # the manual's IDs only
    try:
        request = decode_request(data)
    except CodecError:
        return
    decode_response(reply, request)             # and a decodable request gets a matching response
    assert response.reference == request.reference


# --- the read path over the drive model's raw access ------------------------------------------------------------


class _ObjectsOnly:
    """A DriveModel seen through the ParameterAccess protocol alone (no ``pnu_read_raw``): the general path."""

    def __init__(self, model: object) -> None:
        self.pnu_read = model.pnu_read  # type: ignore[attr-defined]
        self.pnu_write = model.pnu_write  # type: ignore[attr-defined]
        self.pnu_describe = model.pnu_describe  # type: ignore[attr-defined]


def _read_requests(seed: int, count: int) -> list[bytes]:
    """Seeded read requests over the catalogue's PNUs: arrays, odd sub-indices and counts, descriptions, texts,
    unknown PNUs, up to 39 parameters (some too long for one response)."""
    import random

    from akdctl.catalog import pnus as pnu_catalog

    rng = random.Random(seed)
    known = sorted(pnu_catalog.pnu_table())
    out = []
    for _ in range(count):
        n = rng.choice([1, 1, 1, 2, 5, 39])
        blocks = bytes([rng.randint(1, 255), REQ_READ, 0, n])
        for _ in range(n):
            pnu = rng.choice(known) if rng.random() < 0.9 else rng.choice([0, 1, 999, 65535])
            info = pnu_catalog.lookup(pnu)
            length = info.length if info else 1
            sub = rng.randrange(length) if rng.random() < 0.9 else rng.choice([length, 0xFFFF, 300])
            elements = rng.randint(1, max(1, length - sub)) if rng.random() < 0.9 else rng.choice([0, 235, length + 1])
            attribute = rng.choice([0x10] * 8 + [0x20, 0x30])
            blocks += bytes([attribute, elements & 0xFF]) + pnu.to_bytes(2, "big") + sub.to_bytes(2, "big")
        out.append(blocks)
    return out


@pytest.mark.parametrize("seed", [1, 2])
def test_reads_through_the_raw_access_answer_what_the_general_path_answers(seed: int) -> None:
    """``PnuServer`` packs a read over ``DriveModel.pnu_read_raw`` straight into bytes; the same requests through
    the objects-only protocol (ParameterValue, encode_response) give the same bytes."""
    from akdctl.sim.model import DriveModel

    raw_model, general_model = DriveModel(), DriveModel()
    raw, general = PnuServer(raw_model, raw_reads=True), PnuServer(_ObjectsOnly(general_model))
    for request in _read_requests(seed, 400):
        assert raw.handle(request) == general.handle(request), request.hex(" ")


def _outcome(server: PnuServer, request: bytes) -> bytes | tuple[str, int]:
    try:
        return server.handle(request)
    except RecordRefused as refused:
        return ("refused", refused.code1)


@pytest.mark.parametrize("seed", [3, 4])
def test_planned_reads_answer_what_the_general_path_answers(seed: int) -> None:
    """A one-parameter read is planned the first time (``PnuServer._plan``) and answered from the plan after it:
    repeated with other references (0 included: refused), its answers stay those of the general path, while the
    drive model changes between them."""
    import random

    from akdctl.sim.model import DriveModel

    rng = random.Random(seed)
    raw_model, general_model = DriveModel(), DriveModel()
    raw, general = PnuServer(raw_model, raw_reads=True), PnuServer(_ObjectsOnly(general_model))
    singles = [r for r in _read_requests(seed, 800) if r[3] == 1]
    planned = 0
    for request in singles * 3:
        request = bytes([rng.choice([0, 1, 77, 255])]) + request[1:]
        planned += request[1:] in raw._plans
        assert _outcome(raw, request) == _outcome(general, request), request.hex(" ")
        if rng.random() < 0.05:  # the drive changes: the next reads answer the new value
            word = rng.choice([0x0400, 0x0406, 0x040E])
            change = bytes([1, 2, 0, 1, 0x10, 1, 0, 1, 0, 0, 0x42, 1]) + word.to_bytes(2, "big")
            assert raw.handle(change) == general.handle(change)
    assert planned > 500


@pytest.mark.parametrize("failure", ["refused", "bug", "wrong count", "wrong format", "too big"])
def test_a_planned_read_the_model_fails_is_refused_as_the_general_path_refuses_it(failure: str) -> None:
    """Once planned, a read whose model answer fails (an access error, a bug, a wrong number of values, a format
    the raw way cannot pack, a value that does not fit) gets the refusal the general path gives."""
    from akdctl.sim.model import DriveModel

    reader = failing_reader(failure)
    request = bytes.fromhex("05 01 00 01 10 01 03 A2 00 00")  # PNU 930
    replies, errors = [], []
    for planned in (True, False):  # the plan's way, and the raw way it stands for (_read_single)
        model = DriveModel()
        server = PnuServer(model, raw_reads=True)
        server.handle(request)  # planned
        assert request[1:] in server._plans
        if not planned:
            server._plans.clear()
        info, fmt, mask, _read, array = model._pnu_shape(930)
        model._pnu_shapes[930] = (info, 0x02 if failure == "wrong format" else fmt, (1 << 64) - 1 if failure ==
                                  "too big" else mask, reader, array)
        replies.append(server.handle(request))
        errors.append(repr(server.last_exception))
    assert replies[0] == replies[1] and errors[0] == errors[1]
    assert replies[0][1] == 0x81  # refused
