"""The simulated AKD against the PROFINET manuals (issue 16 items 1-6): each test quotes the statement it checks.

Manuals (``/work/shared/seeds``): ``000`` AKD PROFINET Communication (Oct 2011), ``004`` AKD PROFINET RT
Communication (edition B), ``003`` AKD PROFINET RT Kommunikation (German, later). Rulings of our own are
docs/fidelity.md F1..; SPEC-NOTES numbers are named where a test relies on one.
"""

from __future__ import annotations

import json

import pytest

from akdctl.errors import RecordError
from akdctl.protocol import pnio
from akdctl.sim.drive import SimDrive
from akdctl.sim.face_profinet import ProfinetFace
from akdctl.transport.base import LinkOptions
from akdctl.transport.profinet import PnioRecordLink, ProfinetTransport
from akdctl.transport.sim import SimRecordLink
from akdctl.transport.target import split_target
from akdctl.transport.trace import Tracer

READ_930 = bytes.fromhex("05 01 00 01 10 01 03 A2 00 00")


# ---------------------------------------------------------------------------------------------------- item 4
def test_bmp_reserved_reference_and_unknown_request_id_are_refused_by_the_record_layer() -> None:
    """``000`` 3.5 "Record data fields": "Request reference Unsigned8 0x00 reserved, 0x01 – 0xFF"; "Request ID
    0x01 Request parameter, 0x02 Change parameter"; "Response ID 0x01, 0x02, 0x81, 0x82" - nothing else.
    ``reference/profidrive_reference.md`` (PDRV V4.2 table 169): Error_Code_1 "0xB7 invalid range (error in
    base-mode request header)". docs/fidelity.md F1: such a request gets no response; the write fails with 0xB7.
    """
    link = SimRecordLink(SimDrive("f1"))
    assert link.exchange(READ_930)[:2] == b"\x05\x01"                    # a valid request is answered
    for request in (b"\x00" + READ_930[1:], READ_930[:1] + b"\x03" + READ_930[2:]):
        with pytest.raises(RecordError) as info:
            link.exchange(request)
        assert info.value.code == pnio.rw_error(True, 0xB7).value       # DF 80 B7 00
        assert "invalid range" in info.value.message


def test_bmp_header_refusal_over_the_pnio_face() -> None:
    """The same rule on the wire: the PNIO face answers the record write with PNIOStatus DF 80 B7 00."""
    face = ProfinetFace(SimDrive("f1-face"), "127.0.0.1", 0)
    face.start()
    transport = ProfinetTransport(split_target(f"pn://127.0.0.1:{face.port}"),
                                  LinkOptions(timeout=1.0, retries=2, tracer=Tracer()))
    try:
        transport.connect()
        link = PnioRecordLink(transport)
        assert link.exchange(READ_930)[:2] == b"\x05\x01"
        with pytest.raises(RecordError) as info:
            link.exchange(b"\x00" + READ_930[1:])
        assert "B7" in info.value.message and info.value.code == pnio.rw_error(True, 0xB7).value
        assert link.exchange(READ_930)[:2] == b"\x05\x01"                # the channel still works afterwards
    finally:
        transport.close()
        face.stop()
