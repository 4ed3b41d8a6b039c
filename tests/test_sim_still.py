"""The drive model's clock at rest (``DriveModel.advance``): once every ticking component declares itself still
(``Component.still``), an advance moves only the clock until the revision moves. These tests show values read while
something runs still see time pass, and that a model taking the O(1) way ends in exactly the state of one that
steps every time, whatever happens in between (motion started and stopped, faults, watchdog)."""

from __future__ import annotations

import random
import struct

from akdctl.profiles import statusword as sw
from akdctl.profiles import units
from akdctl.protocol import bmp
from akdctl.sim.model import DriveModel
from akdctl.sim.pnu_server import PnuServer
from tests.pnu_model import pnu_write


def _read(model: DriveModel, pnu: int) -> int:
    request = bmp.ParameterRequest(1, bmp.REQ_READ, 0, (bmp.ParameterAddress(pnu, 0, 1),))
    response = bmp.decode_response(PnuServer(model, raw_reads=True).handle(bmp.encode_request(request)), request)
    return int(response.results[0].values[0])  # type: ignore[union-attr]


def _jog(model: DriveModel, rpm: float) -> None:
    for word in sw.S7_ENABLE_SEQUENCE:
        pnu_write(model, 1, word)
    pnu_write(model, 1004, units.rpm_to_x(rpm, 15))
    pnu_write(model, 1, 0x040F | sw.STW1_JOG1)


def test_a_resting_drive_moves_only_its_clock() -> None:
    model = DriveModel()
    model.advance(0.5)
    assert model._still_at == model.revision  # proven still after one step
    state = model.to_state()
    model.advance(2.0)
    assert model.clock == state["clock"] + 2.0
    assert {k: v for k, v in model.to_state().items() if k != "clock"} == {k: v for k, v in state.items()
                                                                          if k != "clock"}


def test_values_read_while_the_axis_moves_see_time_pass() -> None:
    model = DriveModel()
    model.advance(0.5)
    assert model._still_at == model.revision
    _jog(model, 600)  # a write: the revision moves, the next advance steps
    positions = []
    for _ in range(4):
        model.advance(0.2)
        positions.append(_read(model, 28))
        assert model._still_at != model.revision  # never declared still while moving
    assert len(set(positions)) == 4
    assert _read(model, 6) == units.rpm_to_x(600, 15)


def test_a_fault_raised_at_rest_gets_its_reaction_at_the_next_advance() -> None:
    model = DriveModel()
    _jog(model, 300)
    model.advance(1.0)
    pnu_write(model, 1, 0x040F)  # jog off: the axis ramps to rest
    model.advance(5.0)
    model.advance(0.1)
    assert model._still_at == model.revision and model.motion.standstill
    model.faults.raise_fault("F501")
    assert model._still_at != model.revision
    model.advance(0.1)
    assert _read(model, 2) & sw.ZSW1_FAULT


def test_the_o1_way_ends_where_stepping_every_time_ends() -> None:
    """Two models, one of them never allowed the O(1) way, get the same random requests and advances: their whole
    persisted state is equal after every advance (the watchdog included: no request for seconds while moving)."""
    rng = random.Random(29)
    fast, slow = DriveModel(), DriveModel()
    slow._stills = [lambda: False]
    shortcuts = 0
    for step in range(300):
        action, rpm = rng.random(), rng.choice([60, 600, -300])
        for model in (fast, slow):
            if action < 0.05:
                _jog(model, rpm)
            elif action < 0.1:
                pnu_write(model, 1, 0x040F)
            elif action < 0.12:
                model.faults.raise_fault("F501")
            elif action < 0.15:
                pnu_write(model, 1, 0x04F6)  # acknowledge edge
            elif action < 0.3:
                _read(model, 28)
            elif action < 0.35:
                model.object_write(0x6040, 0, struct.pack("<H", 0x0006))
        shortcuts += fast._still_at == fast.revision
        dt = rng.choice([0.001, 0.05, 0.3, 2.5])
        fast.advance(dt)
        slow.advance(dt)
        assert fast.to_state() == slow.to_state(), step
    assert shortcuts > 50
