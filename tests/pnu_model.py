"""What tests of the simulated drive's PNU server do to a model, one copy each: the failing reader the planned reads
are held to the general path with (test_pnu_server, test_pnu_batch_plan), and a write through the server as a
client makes it (test_sim_still, test_sdo_read_parts)."""

from __future__ import annotations

from collections.abc import Callable

from akdctl.protocol import bmp
from akdctl.sim.errors import PnuAccessError
from akdctl.sim.model import DriveModel
from akdctl.sim.pnu_server import PnuServer


def failing_reader(failure: str) -> Callable[[int, int], list[int]]:
    """A component's PNU reader that fails as ``failure`` says: an access error, a bug, a wrong number of values,
    a value that does not fit (``"wrong format"`` and ``"fine"`` answer one small value: the caller binds the
    format)."""

    def reader(sub: int, count: int) -> list[int]:
        if failure == "refused":
            raise PnuAccessError(0x14, 7)
        if failure == "bug":
            raise RuntimeError("model bug")
        if failure == "wrong count":
            return [1, 2]
        return [1 << 40] if failure == "too big" else [3]

    return reader


def pnu_write(model: DriveModel, pnu: int, value: int) -> None:
    """Write ``value`` to element 0 of ``pnu`` through a PNU server on ``model`` (a PROFIdrive change request, as a
    client sends it); the drive must accept it."""
    info = model.pnu_info(pnu)
    request = bmp.ParameterRequest(1, bmp.REQ_CHANGE, 0, (bmp.ParameterAddress(pnu, 0, 1),),
                                   (bmp.ParameterValue(info.wire_format, (value & ((1 << info.bits) - 1),)),))
    response = bmp.decode_response(PnuServer(model, raw_reads=True).handle(bmp.encode_request(request)), request)
    assert not response.negative, response
