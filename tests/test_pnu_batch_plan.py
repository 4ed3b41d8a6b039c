"""The PNU server's plan of a read of several parameters (``PnuServer._plan_batch``, ``DriveModel.pnu_value_getter``,
``bmp.raw_batch_response_layout``, issue 29) against the reads it stands for: the getters read what ``pnu_read_raw``
reads, and a planned batch answers byte for byte what the general path (ParameterValue objects, ``encode_response``)
answers -- repeated with other references, refused PNUs and out-of-range subindices among the parameters, values
written between reads, the axis moving, a new binding, another model handed to the server, and every way a model's
answer can fail."""

from __future__ import annotations

import random
import struct

import pytest

from akdctl.catalog import pnus as pnu_catalog
from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.protocol import bmp
from akdctl.sim.errors import PnuAccessError
from akdctl.sim.model import DriveModel
from akdctl.sim.pnu_server import PnuServer, RecordRefused
from tests.pnu_model import failing_reader


class _ObjectsOnly:
    """A DriveModel seen through the ParameterAccess protocol alone (no raw reads, no plans): the general path."""

    def __init__(self, model: DriveModel) -> None:
        self.pnu_read = model.pnu_read
        self.pnu_write = model.pnu_write
        self.pnu_describe = model.pnu_describe


def _outcome(call: object) -> object:
    try:
        return call()  # type: ignore[operator]
    except PnuAccessError as exc:
        return ("refused", exc.error, exc.additional)
    except RecordRefused as exc:
        return ("record refused", exc.code1)


def _read_request(reference: int, addresses: list[tuple[int, int, int, int]]) -> bytes:
    """A read request of (attribute, count, PNU, subindex) addresses, as the wire has them."""
    return bytes((reference, bmp.REQ_READ, 0, len(addresses))) + b"".join(
        struct.pack(">BBHH", attribute, count & 0xFF, pnu, subindex) for attribute, count, pnu, subindex in addresses)


def _write_request(pnu: int, value: int, fmt: int = 0x42) -> bytes:
    return bytes((1, bmp.REQ_CHANGE, 0, 1, 0x10, 1)) + struct.pack(">HH", pnu, 0) + bytes((fmt, 1)) + \
        value.to_bytes(2 if fmt == 0x42 else 4, "big")


def test_getters_read_what_pnu_read_raw_reads_for_every_address() -> None:
    model = DriveModel()
    checked = 0
    for pnu in [*sorted(pnu_catalog.pnu_table()), 0, 999, 65535]:
        info = pnu_catalog.lookup(pnu)
        length = info.length if info else 1
        for subindex, count in {(0, 1), (1, 1), (0, 2), (0, length), (length - 1, 1), (length, 1), (0, length + 1)}:
            if count < 1 or subindex < 0:
                continue
            try:
                fmt, get = model.pnu_value_getter(pnu, subindex, count)
            except PnuAccessError as exc:
                assert _outcome(lambda: model.pnu_read_raw(pnu, subindex, count)) == \
                    ("refused", exc.error, exc.additional), (pnu, subindex, count)
                continue
            checked += 1
            assert (fmt, list(get())) == model.pnu_read_raw(pnu, subindex, count), (pnu, subindex, count)
    assert checked > 60


def test_a_getter_reads_the_value_stored_after_it_was_taken() -> None:
    model = DriveModel()
    _fmt, get = model.pnu_value_getter(1006, 0, 1)  # Jog Acc: a stored value, its default until written
    assert list(get()) == [1000]
    model.set_stored_pnu(1006, [1234])
    assert list(get()) == [1234] == model.pnu_read_raw(1006, 0, 1)[1]
    _fmt, element = model.pnu_value_getter(964, 2, 2)  # an array's elements
    model.set_stored_pnu(964, [7, 8], 2)
    assert list(element()) == [7, 8] == model.pnu_read_raw(964, 2, 2)[1]


def _batch_requests(seed: int, count: int) -> list[bytes]:
    """Seeded reads of 2..39 parameters: mostly plain values a poll reads, with arrays, odd subindices and counts,
    descriptions, texts, unknown PNUs and PNU 0 among them (some too long for one response)."""
    rng = random.Random(seed)
    known = sorted(pnu_catalog.pnu_table())
    out = []
    for _ in range(count):
        n = rng.choice([2, 3, 5, 12, 39])
        addresses = []
        for _ in range(n):
            pnu = rng.choice(known) if rng.random() < 0.9 else rng.choice([0, 999, 65535])
            info = pnu_catalog.lookup(pnu)
            length = info.length if info else 1
            plain = rng.random() < 0.7
            sub = 0 if plain else (rng.randrange(length) if rng.random() < 0.8 else rng.choice([length, 0xFFFF]))
            elements = 1 if plain else (rng.randint(1, max(1, length - sub)) if rng.random() < 0.8
                                        else rng.choice([0, 235, length + 1]))
            attribute = 0x10 if plain else rng.choice([0x10] * 6 + [0x20, 0x30])
            addresses.append((attribute, elements, pnu, sub))
        out.append(_read_request(1, addresses))
    return out


def _jog(server: PnuServer, general: PnuServer, rpm: float) -> None:
    for request in [*(_write_request(1, word) for word in sw.S7_ENABLE_SEQUENCE),
                    _write_request(1004, units.rpm_to_x(rpm, 15) & 0xFFFF), _write_request(1, 0x040F | sw.STW1_JOG1)]:
        assert server.handle(request) == general.handle(request)


@pytest.mark.parametrize("seed", [5, 6])
def test_planned_batches_answer_what_the_general_path_answers(seed: int) -> None:
    """Each batch is planned at its first read and answered from the plan after it (other references, 0 refused
    at the record layer), while values are written and the axis moves between the reads."""
    rng = random.Random(seed)
    planned_model, general_model = DriveModel(), DriveModel()
    planned, general = PnuServer(planned_model, raw_reads=True), PnuServer(_ObjectsOnly(general_model))
    requests = _batch_requests(seed, 50)  # within the memo (_BATCHES)
    from_plan = 0
    for round_ in range(3):
        if round_ == 1:
            _jog(planned, general, 600)  # the axis moves: positions, velocities and words change from read to read
        for request in requests:
            request = bytes([rng.choice([0, 1, 77, 255])]) + request[1:]
            from_plan += request[1:] in planned._batches
            assert _outcome(lambda: planned.handle(request)) == _outcome(lambda: general.handle(request)), \
                request.hex(" ")
            if rng.random() < 0.1:  # a stored value written: the next reads answer it
                change = _write_request(1006, rng.randrange(1, 5000))
                assert planned.handle(change) == general.handle(change)
            if rng.random() < 0.3:
                dt = rng.choice([0.001, 0.05, 0.3])
                planned_model.advance(dt)
                general_model.advance(dt)
    assert from_plan > 80
    assert planned_model.to_state() == general_model.to_state()


_POLL = [(0x10, 1, pnu, 0) for pnu in (2, 28, 6, 930, 1006, 1002)] + [(0x10, 3, 964, 1), (0x10, 1, 999, 0),
                                                                      (0x10, 1, 930, 1), (0x20, 1, 930, 2)]


def _values(reply: bytes) -> list[object]:
    request = bmp.decode_request(_read_request(reply[0], _POLL))
    return list(bmp.decode_response(reply, request).results)


def test_a_planned_batch_reads_values_that_change_with_motion_and_writes() -> None:
    model, twin = DriveModel(), DriveModel()
    server, general = PnuServer(model, raw_reads=True), PnuServer(_ObjectsOnly(twin))
    request = _read_request(9, _POLL)
    first = server.handle(request)
    assert request[1:] in server._batches and first == general.handle(request)
    assert first[1] == bmp.RESP_READ_NAK  # PNU 999 unknown, 930[1] out of range: refused, the rest answered
    _jog(server, general, 900)
    positions = set()
    for _ in range(4):
        model.advance(0.1)
        twin.advance(0.1)
        reply = server.handle(request)
        assert reply == general.handle(request)
        positions.add(_values(reply)[1])
    assert len(positions) == 4  # XIST_A read anew each time
    assert server.handle(_write_request(1006, 4321)) == general.handle(_write_request(1006, 4321))
    assert _values(server.handle(request))[4] == bmp.ParameterValue(0x42, (4321,))


def test_a_batch_plan_follows_a_new_binding_and_another_model() -> None:
    model = DriveModel()
    server = PnuServer(model, raw_reads=True)
    request = _read_request(3, [(0x10, 1, 930, 0), (0x10, 1, 1006, 0)])
    assert _values_of(server.handle(request)) == [1, 1000]
    model.bind_pnu(930, read=lambda sub, count: [2])  # the version moves: the plan is taken again
    assert _values_of(server.handle(request)) == [2, 1000]
    other = DriveModel()
    other.set_stored_pnu(1006, [77])
    server.access = other  # a reload: another model served
    assert _values_of(server.handle(request)) == [1, 77]
    assert server._batches[request[1:]].model is other


def _values_of(reply: bytes) -> list[int]:
    return [struct.unpack_from(">H", reply, 6 + 4 * i)[0] for i in range(reply[3])]


@pytest.mark.parametrize("failure", ["refused", "bug", "wrong count", "wrong format", "too big", "fine"])
def test_a_planned_batch_the_model_fails_is_refused_as_the_general_path_refuses_it(failure: str) -> None:
    """A parameter whose model answer fails (an access error, a bug, a wrong number of values, a format the raw way
    cannot pack, a value that does not fit) gets the refusal the unplanned read gives it; the others their values."""

    reader = failing_reader(failure)

    request = _read_request(5, [(0x10, 1, 1006, 0), (0x10, 1, 930, 0), (0x10, 1, 2, 0)])
    replies, errors = [], []
    for planned in (True, False):
        model = DriveModel()
        server = PnuServer(model, raw_reads=True)
        info, fmt, mask, _read, array = model._pnu_shape(930)
        model._pnu_shapes[930] = (info, 0x02 if failure == "wrong format" else fmt, (1 << 64) - 1 if failure ==
                                  "too big" else mask, reader, array)
        if planned:
            server.handle(request)  # planned
            assert request[1:] in server._batches
            replies.append(server.handle(request))
        else:
            replies.append(server._read_each(request, 3))
        errors.append(repr(server.last_exception))
    assert replies[0] == replies[1] and errors[0] == errors[1]
    assert (replies[0][1] == bmp.RESP_READ_OK) == (failure == "fine")


def test_a_served_drive_answers_a_planned_batch_with_what_another_process_saved(isolated_env: object) -> None:
    """``sim serve``'s drive (lock kept between requests) plans the batch once; a write saved by another process
    makes it load a new model, and the next batch read answers from that model, not from the plan's."""
    from akdctl.sim.drive import SimDrive

    served, cli = SimDrive("default"), SimDrive("default")
    served.serve_faces()
    request = _read_request(4, [(0x10, 1, 930, 0), (0x10, 1, 1006, 0), (0x10, 1, 1002, 0)])
    try:
        for _ in range(3):
            assert _values_of(served.handle_bmp(request)) == [1, 1000, 16]
        planned = served._pnu_server._batches[request[1:]]
        cli.handle_bmp(_write_request(1006, 2500))
        cli.handle_bmp(_write_request(930, 2))
        assert _values_of(served.handle_bmp(request)) == [2, 2500, 16]
        assert served._pnu_server._batches[request[1:]].model is not planned.model  # taken again for the new model
        served.handle_bmp(_write_request(1002, 20))  # a write through the served drive itself
        assert _values_of(served.handle_bmp(request)) == [2, 2500, 20]
        assert _values_of(cli.handle_bmp(request)) == [2, 2500, 20]
    finally:
        served.close()
        cli.close()
