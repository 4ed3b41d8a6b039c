"""Issue 23.19: ``--pcap`` on a CAN target captures the CAN frames (LINKTYPE_CAN_SOCKETCAN) and tshark decodes
the CANopen SDOs, as on every other transport. Before, the file held a pcap header and no frame."""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from akdctl.transport.pcap import LINKTYPE_CAN_SOCKETCAN, can_frame
from tests.harness import SimServer

NODE = 5


def test_a_socketcan_frame_is_id_big_endian_length_and_eight_bytes() -> None:
    assert can_frame(0x605, b"\x40\x18\x10\x01") == bytes.fromhex("00000605 04000000 40181001 00000000")
    assert can_frame(0x18FF0001, b"", extended=True, remote=True)[:5] == bytes.fromhex("d8ff0001 00")


@pytest.mark.slow
def test_pcap_on_a_can_target_holds_the_sdo_frames_tshark_decodes(akd, tmp_path: Path) -> None:
    link, capture = tmp_path / "slcan-tty", tmp_path / "can.pcap"
    with SimServer("--can", f"slcan-pty:{link}:{NODE}"):
        result = akd("-T", f"can://slcan/{link}/{NODE}?sleep_after_open=0", "--pcap", str(capture),
                     "sdo", "read", "0x1018:1", timeout=60)
    assert result.returncode == 0, result.stderr
    data = capture.read_bytes()
    assert struct.unpack_from("<I", data, 20)[0] == LINKTYPE_CAN_SOCKETCAN
    assert len(data) >= 24 + 2 * (16 + 16), "no CAN frame captured"
    tshark = shutil.which("tshark")
    if tshark is None:
        if os.environ.get("CI") == "true":
            pytest.fail("tshark is missing in CI (.ci/run installs it)")
        pytest.skip("tshark is not installed (apt-get install tshark); CI runs this part")
    fields = subprocess.run([tshark, "-r", str(capture), "-d", "can.subdissector,canopen", "-T", "fields",
                             "-e", "can.id", "-e", "canopen.sdo.main_idx", "-e", "canopen.sdo.sub_idx"],
                            capture_output=True, text=True, timeout=60)
    assert fields.returncode == 0, fields.stderr
    rows = [line.split("\t") for line in fields.stdout.splitlines() if line.strip()]
    assert ["1541", "0x1018", "0x01"] in rows  # 0x600 + node: the request
    assert ["1413", "0x1018", "0x01"] in rows  # 0x580 + node: the answer
