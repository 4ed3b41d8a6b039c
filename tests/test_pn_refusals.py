"""Issue 23.16: refused PROFINET Connects (AR slots full) are reported one line per cause, repeats counted.

Before, every refused Connect wrote a long warning naming every holder: a client retrying in a loop filled the
face's stderr (853 KB in 4 minutes).
"""

from __future__ import annotations

import socket
import uuid
from pathlib import Path

import pytest

from akdctl.sim import face_profinet
from akdctl.sim.drive import SimDrive
from akdctl.sim.refusals import RefusalReport


def _connect(port: int, station: bytes) -> bool:
    """One PNIO Connect on the wire; True when the device accepted it (the AR is then held, never released)."""
    from akdctl.protocol import dcerpc, pnio

    req = pnio.ARBlockReq(pnio.AR_TYPE_IOSAR, uuid.uuid4(), 1, b"\x02\x00\x00\x00\x00\x01", pnio.object_uuid(0, 0, 0),
                          pnio.DEVICE_ACCESS_PROPERTIES, 1000, station)
    head = dcerpc.RpcHeader(ptype=dcerpc.PT_REQUEST, object_uuid=pnio.object_uuid(0x100, 1),
                            interface_uuid=pnio.DEVICE_INTERFACE, activity_uuid=uuid.uuid4(), sequence=0,
                            opnum=pnio.OP_CONNECT, flags1=dcerpc.FLAG_IDEMPOTENT)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(2)
        sock.sendto(dcerpc.encode_packet(head, pnio.encode_request_args(req.encode())), ("127.0.0.1", port))
        reply = dcerpc.decode_packet(sock.recv(4096))
    return bool(pnio.decode_response_args(reply.body, reply.header.little_endian)[0].ok)


def test_repeated_refusals_are_one_line_then_a_count(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    face = face_profinet.from_options(SimDrive("default", tmp_path), profinet="127.0.0.1:0", pn_ars=1)
    assert face is not None
    face.start()
    try:
        assert _connect(face.port, b"holder")
        refused = [_connect(face.port, b"retrying-tool") for _ in range(40)]
    finally:
        face.stop()
    assert not any(refused)
    lines = [line for line in capsys.readouterr().err.splitlines() if "profinet" in line]
    assert len(lines) == 2, lines  # the first refusal in full, then the count when the face stops
    assert "out of AR resources (1 held: AR" in lines[0] and "of holder at 127.0.0.1" in lines[0]
    assert lines[1].endswith("39 more Connect(s) refused (out of AR resources) since the last report")


def test_the_report_counts_per_cause_and_prints_again_after_its_interval() -> None:
    out: list[str] = []
    report = RefusalReport("profinet", interval=0.0, write=out.append)
    assert report.refused("out of AR resources", "first") and report.refused("out of AR resources", "second")
    slow = RefusalReport("profinet", interval=3600, write=out.append)
    assert slow.refused("a", "x") and not slow.refused("a", "x") and slow.refused("b", "y")
    slow.flush()
    assert out == ["akdctl: warning: profinet: first", "akdctl: warning: profinet: second",
                   "akdctl: warning: profinet: x", "akdctl: warning: profinet: y",
                   "akdctl: warning: profinet: 1 more Connect(s) refused (a) since the last report"]
