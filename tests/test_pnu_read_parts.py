"""The PNU server's plan of a computed element's read (``DriveModel.pnu_read_parts``, ``PnuServer._plan_parts``,
issue 29) against the read it stands for (``pnu_read_raw``, the general path): the same values for every catalogued
PNU, and a plan that follows the model it reads -- a new binding of the PNU, another model handed to the server (a
reload), state changed between reads."""

from __future__ import annotations

import pytest

from akdctl.catalog import pnus as pnu_catalog
from akdctl.sim.errors import PnuAccessError
from akdctl.sim.model import DriveModel
from akdctl.sim.pnu_server import PnuServer

READ_930 = bytes.fromhex("05 01 00 01 10 01 03 A2 00 00")


def _raw(model: DriveModel, pnu: int) -> object:
    try:
        return model.pnu_read_raw(pnu, 0, 1)
    except PnuAccessError as exc:
        return ("refused", exc.error, exc.additional)


def test_parts_read_what_pnu_read_raw_reads_for_every_pnu() -> None:
    model = DriveModel()
    planned = 0
    for pnu in [*sorted(pnu_catalog.pnu_table()), 0, 999, 65535]:
        try:
            parts = model.pnu_read_parts(pnu, 0, 1)
        except PnuAccessError as exc:
            assert _raw(model, pnu) == ("refused", exc.error, exc.additional)
            continue
        assert model.pnu_read_parts(pnu, 1, 1) is None and model.pnu_read_parts(pnu, 0, 2) is None
        if parts is None:
            continue
        planned += 1
        fmt, mask, read = parts
        values = read(0, 1)
        assert len(values) == 1 and _raw(model, pnu) == (fmt, [values[0] & mask]), pnu
    assert planned >= 5  # the words and actual values a poll reads (STW1, ZSW1, 930, ...) are computed


def _answer(server: PnuServer, model: DriveModel, request: bytes) -> bytes:
    server.access = model
    return server.handle(request)


def _general(model: DriveModel, request: bytes) -> bytes:
    """The same request through a server without plans (each read the raw way, ``_read_single``)."""
    server = PnuServer(model, raw_reads=True)
    server.handle(request)
    server._plans.clear()
    return server.handle(request)  # and once more unplanned: the plan-free answer


def test_a_plan_follows_a_new_binding_of_its_pnu() -> None:
    model = DriveModel()
    server = PnuServer(model, raw_reads=True)
    for _ in range(3):  # planned, then answered from the plan's parts
        assert _answer(server, model, READ_930) == _general(model, READ_930)
    assert server._plans[READ_930[1:]][7] is not None  # the parts were taken
    model.bind_pnu(930, read=lambda sub, count: [7])
    assert _answer(server, model, READ_930) == _general(model, READ_930)
    assert _answer(server, model, READ_930)[-1] == 7
    model.bind_pnu(930, read=lambda sub, count: [3])
    assert _answer(server, model, READ_930)[-1] == 3


def test_a_plan_follows_the_model_it_is_handed() -> None:
    """A served drive hands its server the model of each transaction: after a reload (another process saved) it is
    another object, whose reader the plan must use."""
    first, second = DriveModel(), DriveModel()
    second.bind_pnu(930, read=lambda sub, count: [9])
    server = PnuServer(first, raw_reads=True)
    for _ in range(3):
        assert _answer(server, first, READ_930) == _general(first, READ_930)
    assert _answer(server, second, READ_930)[-1] == 9
    assert _answer(server, first, READ_930) == _general(first, READ_930)


@pytest.mark.parametrize("mode", [1, 2, 3])
def test_a_plan_reads_the_current_state(mode: int) -> None:
    """The value is read on every request: a write of the operating mode between two reads is seen by the next."""
    model = DriveModel()
    server = PnuServer(model, raw_reads=True)
    before = [_answer(server, model, READ_930) for _ in range(3)]
    change = bytes([6, 2, 0, 1, 0x10, 1, 0x03, 0xA2, 0, 0, 0x04, 1]) + mode.to_bytes(2, "big")  # PNU 930 := mode
    reply = _answer(server, model, change)
    after = _answer(server, model, READ_930)
    assert after == _general(model, READ_930)
    if reply[1] == 0x02:  # accepted: the next read says so
        assert int.from_bytes(after[-2:], "big") == mode
    assert before[0] == before[-1]


def test_a_reader_that_fails_is_refused_as_the_raw_read_refuses_it() -> None:
    model = DriveModel()
    server = PnuServer(model, raw_reads=True)
    for _ in range(3):
        _answer(server, model, READ_930)

    def failing(sub: int, count: int) -> list[int]:
        raise PnuAccessError(0x14, 7)

    model.bind_pnu(930, read=failing)
    assert _answer(server, model, READ_930) == _general(model, READ_930)
    assert _answer(server, model, READ_930)[1] == 0x81


def test_one_read_response_packer_writes_the_layouts_bytes() -> None:
    """bmp.one_read_response_packer (the planned read's pack) writes raw_read_response_layout's bytes for every format
    it packs, every axis and reference, and refuses the same values (struct.error)."""
    import struct

    from akdctl.protocol import bmp

    checked = 0
    for fmt in range(256):
        layout = bmp.raw_read_response_layout(fmt, 1)
        for axis in (0, 1, 255):
            packer = bmp.one_read_response_packer(fmt, axis)
            assert (packer is None) == (layout is None)
            if packer is None or layout is None:
                continue
            pack, fixed = packer
            for reference in (1, 0x7F, 255):
                for value in (0, 1, 0x7F, 0xFF, 0x100, 0xFFFF, 0x10000, 0xFFFFFFFF, 1 << 32, -1):
                    try:
                        expected: bytes | type = layout.pack(reference, bmp.RESP_READ_OK, axis, 1, fmt, 1, value)
                    except struct.error:
                        expected = struct.error
                    try:
                        got: bytes | type = pack(reference, fixed, value)
                    except struct.error:
                        got = struct.error
                    assert got == expected
                    checked += 1
    assert checked > 100
