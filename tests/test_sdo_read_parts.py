"""The SDO server's plan of a plain stored value's read (``DriveModel.object_read_parts``, ``SdoServer._read_parts``,
issue 29) against the read it stands for (``object_read``, and the server's general path): the same answers for
the addresses a client polls (plain, bound, lazy, write-only, unknown, long), and a plan that follows the model it
reads -- a value written, a new binding of the index, a lazy component built, another model handed to the server (a
reload), the axis moving while time passes -- and takes the drive's queued emergencies ahead of its answer."""

from __future__ import annotations

import pytest

from akdctl.catalog import objects as object_catalog
from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.protocol import coe
from akdctl.protocol import mailbox as mbx
from akdctl.protocol.coe import CoeService
from akdctl.sim import model as model_module
from akdctl.sim.drive import factory_model
from akdctl.sim.errors import SdoAccessError
from akdctl.sim.model import DriveModel
from akdctl.sim.sdo_server import SdoServer
from tests.pnu_model import pnu_write


def _model() -> DriveModel:
    model = factory_model("parts")
    model.object_write(0x2032, 0, b"x" * 1500)  # DRV.CUSTOMIDENTIFIER: longer than one mailbox (segmented)
    model.set_stored_object(0x2033, 0, b"AKD-x")  # a string of 5 bytes (normal upload)
    return model


def _upload(index: int, subindex: int, counter: int = 3) -> bytes:
    return mbx.pack(mbx.MailboxType.COE, coe.upload_request(index, subindex), 1001, counter)


def _general(model: DriveModel, request: bytes) -> list[bytes]:
    """The same request through a server without plans: the general decoder path (``_handle``), reading through
    ``object_read``."""
    server = SdoServer(model)
    return server._handle(request)


def _answer(server: SdoServer, model: DriveModel, request: bytes) -> list[bytes]:
    server.access = model
    return server.handle(request)


def _read(model: DriveModel, index: int, subindex: int) -> bytes | int:
    try:
        return model.object_read(index, subindex)
    except SdoAccessError as exc:
        return exc.code


def _parts(server: SdoServer, request: bytes) -> list[object]:
    return server._plans[request][4]


def test_parts_read_what_object_read_reads_for_every_catalogued_address() -> None:
    model = _model()
    model.motion.axis  # noqa: B018 - a part built later binds its objects (bind_object_later), as a served drive's
    planned = 0
    for index, subindex in [*sorted(object_catalog.entries()), (0x7FFF, 0), (0x1018, 9), (0x0002, 0)]:
        parts = model.object_read_parts(index, subindex)
        if parts is None:
            continue
        planned += 1
        assert index not in model._object_bindings and index not in model_module.LAZY_OBJECTS \
            and index not in model._object_builders, hex(index)
        key, default = parts
        assert key == (index, subindex)
        assert _read(model, index, subindex) == model.object_values.get(key, default), (hex(index), subindex)
    assert planned > 100  # the identity, the stored parameters: most of the dictionary is plain


ADDRESSES = [
    (0x1018, 1), (0x1018, 4), (0x1018, 0), (0x1000, 0), (0x6041, 0), (0x6064, 0), (0x6081, 0), (0x2033, 0),
    (0x1008, 0), (0x2032, 0), (0x1001, 0), (0x1003, 1), (0x1C12, 0), (0x1018, 9), (0x7FFF, 0), (0x0002, 0),
    (0x1026, 1), (0x60B1, 0),
]


@pytest.mark.parametrize(("index", "subindex"), ADDRESSES)
def test_a_planned_upload_answers_as_the_general_path(index: int, subindex: int) -> None:
    """Two drives in the same state: one served by a drive-model server (planned, then read from its parts), the
    other by the general path; the same answers on every round, counters 1..7 (a plan per mailbox)."""
    fast_model, general_model = _model(), _model()
    fast = SdoServer(fast_model, drive_model=True)
    for _round in range(3):
        for counter in range(1, 8):
            request = _upload(index, subindex, counter)
            assert _answer(fast, fast_model, request) == _general(general_model, request), (hex(index), subindex)
            fast._upload = None  # a segmented answer's transfer is not continued here (both would alike)


def test_a_write_shows_at_once() -> None:
    model = _model()
    server = SdoServer(model, drive_model=True)
    request = _upload(0x6081, 0)  # profile velocity: a stored parameter, plain
    for _ in range(3):
        _answer(server, model, request)
    assert _parts(server, request)[2] == (0x6081, 0)  # answered from the parts now
    model.object_write(0x6081, 0, (4321).to_bytes(4, "little"))
    assert _answer(server, model, request) == _general(model, request)
    assert _answer(server, model, request)[0][-4:] == (4321).to_bytes(4, "little")
    model.object_values.pop((0x6081, 0))  # back to the catalogue's default
    assert _answer(server, model, request) == _general(model, request)


def test_a_new_binding_of_the_index_is_followed() -> None:
    model = _model()
    server = SdoServer(model, drive_model=True)
    request = _upload(0x1018, 1)
    for _ in range(3):
        assert _answer(server, model, request) == _general(model, request)
    assert _parts(server, request)[2] == (0x1018, 1)
    model.bind_object(0x1018, read=lambda sub: b"\x01\x02\x03\x04")
    assert _answer(server, model, request)[0][-4:] == b"\x01\x02\x03\x04"
    assert _answer(server, model, request) == _general(model, request)
    assert _parts(server, request)[2] is None  # bound: object_read answers from now on
    model.bind_object(0x1018, read=lambda sub: b"\x05\x06\x07\x08")
    assert _answer(server, model, request)[0][-4:] == b"\x05\x06\x07\x08"


def test_a_binding_made_later_by_a_part_is_followed() -> None:
    """bind_object_later (a part of a component built on first use) moves the version too."""
    model = _model()
    server = SdoServer(model, drive_model=True)
    request = _upload(0x1018, 2)
    for _ in range(3):
        _answer(server, model, request)
    before = model.object_bindings_version
    model.bind_object_later(0x1018, lambda: model.bind_object(0x1018, read=lambda sub: b"\x0A\x0B\x0C\x0D"))
    assert model.object_bindings_version != before
    assert _answer(server, model, request)[0][-4:] == b"\x0A\x0B\x0C\x0D"
    assert _answer(server, model, request) == _general(model, request)


def test_a_lazy_component_is_built_and_read_through_object_read() -> None:
    model = _model()
    server = SdoServer(model, drive_model=True)
    request = _upload(0x1001, 0)  # the error register: the fault component's, built on first use
    assert "faults" not in model._built
    for _ in range(3):
        assert _answer(server, model, request) == _general(model, request)
    assert "faults" in model._built and _parts(server, request)[2] is None
    model.faults.raise_fault("F501")
    model.faults.take_emergencies()
    assert _answer(server, model, request) == _general(model, request)
    assert _answer(server, model, request)[0][-4] != 0  # the register shows the fault


def test_another_model_handed_to_the_server_is_read() -> None:
    """A served drive hands its server the model of each transaction: after a reload (another process saved) it is
    another object, whose stored value the plan must read."""
    first, second = _model(), _model()
    second.object_write(0x6081, 0, (777).to_bytes(4, "little"))
    server = SdoServer(first, drive_model=True)
    request = _upload(0x6081, 0)
    for _ in range(3):
        assert _answer(server, first, request) == _general(first, request)
    assert _answer(server, second, request)[0][-4:] == (777).to_bytes(4, "little")
    assert _answer(server, first, request) == _general(first, request)
    assert _answer(server, first, request) != _answer(server, second, request)


def test_uploads_while_the_axis_moves_see_time_pass() -> None:
    model = _model()
    server = SdoServer(model, drive_model=True)
    position, identity = _upload(0x6064, 0), _upload(0x1018, 1)
    for _ in range(3):
        _answer(server, model, position)
        _answer(server, model, identity)
    for word in sw.S7_ENABLE_SEQUENCE:
        pnu_write(model, 1, word)
    pnu_write(model, 1004, units.rpm_to_x(600, 15))
    pnu_write(model, 1, 0x040F | sw.STW1_JOG1)  # jog: the axis moves
    seen = []
    for _ in range(4):
        model.advance(0.2)
        reply = _answer(server, model, position)
        assert reply == _general(model, position)
        assert _answer(server, model, identity) == _general(model, identity)
        seen.append(reply[0][-4:])
    assert len(set(seen)) == 4


def _services(replies: list[bytes]) -> list[int]:
    return [coe.decode_coe(mbx.split(reply)[3])[0] for reply in replies]


def test_queued_emergencies_go_out_ahead_of_the_answer_once() -> None:
    first, second = _model(), _model()
    server = SdoServer(first, drive_model=True)
    request = _upload(0x1018, 1)
    assert _services(_answer(server, first, request)) == [CoeService.SDO_RESPONSE]
    first.faults.raise_fault("F501")
    replies = _answer(server, first, request)
    assert _services(replies) == [CoeService.EMERGENCY, CoeService.SDO_RESPONSE]
    assert replies[1:] == _general(first, request)
    assert _services(_answer(server, first, request)) == [CoeService.SDO_RESPONSE]  # delivered once
    second.faults.raise_fault("F501")  # another model: its own fault component
    assert _services(_answer(server, second, request)) == [CoeService.EMERGENCY, CoeService.SDO_RESPONSE]
    assert _services(_answer(server, first, request)) == [CoeService.SDO_RESPONSE]


def test_a_plan_keeps_no_old_model_alive() -> None:
    """After a reload the server holds the new model only: a plan names the model it read by number, so a state of
    many megabytes is not kept once replaced (the plans of requests no longer sent included)."""
    import gc
    import weakref

    first = _model()
    server = SdoServer(first, drive_model=True)
    for counter in range(1, 8):
        _answer(server, first, _upload(0x6081, 0, counter))
        _answer(server, first, _upload(0x1018, 1, counter))
    gone = weakref.ref(first)
    second = _model()
    assert _answer(server, second, _upload(0x1018, 1)) == _general(second, _upload(0x1018, 1))
    del first
    gc.collect()
    assert gone() is None


def test_the_kept_answer_follows_the_value() -> None:
    """A plan keeps the expedited answer it gave with the value object it joined: a value written since (another
    object, equal or not) is joined anew, the factory default again after the stored one is removed."""
    model = _model()
    server = SdoServer(model, drive_model=True)
    request = _upload(0x6081, 0)
    first = [_answer(server, model, request) for _ in range(3)]
    assert first[0] == first[2] == _general(model, request)
    assert _parts(server, request)[5] == first[0][0]  # kept
    for value in (5, 6, 6, 0):  # 6 twice: equal content, another object
        model.object_write(0x6081, 0, value.to_bytes(4, "little"))
        for _ in range(2):
            reply = _answer(server, model, request)
            assert reply == _general(model, request) and reply[0][-4:] == value.to_bytes(4, "little")
    model.object_values.pop((0x6081, 0))
    assert _answer(server, model, request) == _general(model, request) == first[0]


def test_a_long_plain_value_starts_its_transfer_on_every_upload() -> None:
    """Only expedited answers are kept: a plain value longer than 4 bytes is answered by the general packing, which
    starts the segmented transfer each time (the next segment request continues it as on the general path)."""
    model, general_model = _model(), _model()
    fast, general = SdoServer(model, drive_model=True), SdoServer(general_model)
    request = _upload(0x2032, 0)  # 1500 bytes: segmented
    for _ in range(3):
        assert _answer(fast, model, request) == general.handle(request)
        assert fast._upload is not None and general._upload is not None
        segment = mbx.pack(mbx.MailboxType.COE, coe.encode_coe(CoeService.SDO_REQUEST,
                                                              coe.encode_sdo(coe.SdoUploadSegment(0))), 1001, 4)
        assert _answer(fast, model, segment) == general.handle(segment)
