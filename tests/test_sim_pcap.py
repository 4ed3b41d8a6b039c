"""Issue 14: ``--pcap`` on the ``sim`` target captures the simulator's frames (akdctl/transport/pcap.py SimWire).

The simulated drive has no wire, so the capture wraps the bytes it exchanged as a real link would carry them:
PROFIdrive blocks in PNIO record Write requests / Read responses over UDP, CoE mailboxes in EtherCAT FPWR/FPRD
datagrams. The payloads must be byte for byte the traced ones, and tshark (when installed) must decode them.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from akdctl.protocol import dcerpc, ethercat, pnio
from akdctl.transport.pcap import PcapWriter
from akdctl.transport.trace import Tracer


def _frames(path: Path) -> list[bytes]:
    import struct

    raw = path.read_bytes()
    out, at = [], 24
    while at < len(raw):
        _, _, incl, _ = struct.unpack("<IIII", raw[at:at + 16])
        out.append(raw[at + 16:at + 16 + incl])
        at += 16 + incl
    return out


def test_sim_records_become_pnio_and_ethercat_frames(tmp_path: Path) -> None:
    path = tmp_path / "sim.pcap"
    tracer, writer = Tracer(), PcapWriter(path)
    tracer.add_sink(writer.write, writer.close)
    request, answer = bytes.fromhex("0101000110010103a20000"), bytes.fromhex("0101000142010002")
    mailbox = bytes.fromhex("0a00000000000320400018100100000000")
    for direction, layer, data in (("tx", "bmp", request), ("rx", "bmp", answer), ("tx", "mailbox", mailbox),
                                   ("rx", "mailbox", mailbox)):
        tracer.frame(direction, layer, data, meta={"proto": "sim"})  # type: ignore[arg-type]
    tracer.close()
    assert writer.frames == 4 and writer.skipped == 0
    frames = _frames(path)
    write_req = dcerpc.decode_packet(frames[0][42:])
    assert write_req.header.opnum == pnio.OP_WRITE
    assert pnio.IODWriteReq.decode(pnio.decode_request_args(write_req.body)[1]).data == request
    read_res = dcerpc.decode_packet(frames[1][42:])
    status, blocks = pnio.decode_response_args(read_res.body)
    assert status.ok and pnio.IODReadRes.decode(blocks).data == answer
    for frame, cmd, ado in ((frames[2], ethercat.Cmd.FPWR, 0x1800), (frames[3], ethercat.Cmd.FPRD, 0x1C00)):
        _, _, datagrams = ethercat.decode_frame(frame)
        assert [(d.cmd, d.adp, d.ado, d.data) for d in datagrams] == [(cmd, 0x1001, ado, mailbox)]


def test_pcap_on_the_sim_target_is_not_empty(akd_inproc: Any, tmp_path: Path) -> None:
    path = tmp_path / "c.pcap"
    code, _, err = akd_inproc("--pcap", str(path), "pnu", "get", "930")
    assert code == 0, err
    assert len(_frames(path)) == 2
    code, _, err = akd_inproc("--pcap", str(path), "sdo", "read", "0x1018:1")
    assert code == 0, err
    assert len(_frames(path)) == 2 and _frames(path)[0][12:14] == b"\x88\xa4"


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark is not installed")
def test_tshark_decodes_the_sim_capture(akd_inproc: Any, tmp_path: Path) -> None:
    pn, ecat = tmp_path / "pn.pcap", tmp_path / "ecat.pcap"
    assert akd_inproc("--pcap", str(pn), "pnu", "get", "930", "964")[0] == 0
    assert akd_inproc("--pcap", str(ecat), "sdo", "read", "0x1018:1")[0] == 0
    text = subprocess.run(["tshark", "-r", str(pn)], capture_output=True, text=True, timeout=60).stdout
    assert "PROFIDrive Write Request" in text and "P930[0]" in text and "PROFIDrive Read Response" in text, text
    text = subprocess.run(["tshark", "-r", str(ecat)], capture_output=True, text=True, timeout=60).stdout
    assert "Idx=0x1018 Sub=1" in text and "FPRD" in text, text
