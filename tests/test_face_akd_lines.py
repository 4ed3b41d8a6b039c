"""The ASCII face's line handling (sim/face_akd.py, issue 29): however the bytes are cut into segments, the face
answers exactly the lines and prompts the reference's rules give (akd-ascii-channel.md 1-2: a line ends with CR,
LF or CRLF; Telnet commands are not text; an unfinished line longer than MAX_LINE is refused).

How: each step sends one segment over a real socket and reads back exactly what a plain statement of those rules
(``_expected``: a regular expression for the line ends, written here and not shared with the face) says the face
owes for it -- then nothing more. A step that the rules answer with nothing is followed by the next segment, so two
segments may reach the face as one; the steps are chosen so that this changes nothing the rules answer.
"""

from __future__ import annotations

import re
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from akdctl.sim import face_akd
from akdctl.sim.drive import SimDrive

_EOL = re.compile(rb"\r\n|\r|\n")


@pytest.fixture
def face(tmp_path: Path) -> Iterator[face_akd.AkdFace]:
    drive = SimDrive("default", tmp_path)
    face = face_akd.from_options(drive, akd="127.0.0.1:0")
    assert face is not None
    face.start()
    try:
        yield face
    finally:
        face.stop()


def _expected(face: face_akd.AkdFace, state: dict[str, Any], pending: list[bytes], data: bytes) -> bytes:
    """What the face owes for the segment ``data``: every line the segment ends, answered in order, then the
    refusal of an unfinished line grown past MAX_LINE (``pending[0]``: the unfinished line so far)."""
    buffer = pending[0] + face_akd.strip_telnet(data, state)
    out = b""
    while (match := _EOL.search(buffer)) is not None:
        line, buffer = buffer[:match.start()], buffer[match.end():]
        text = line.decode("latin-1").strip()
        reply = face.answer(text) if text else ""
        out += (reply.replace("\n", "\r\n") + "\r\n-->").encode("latin-1", "replace")
    if len(buffer) > face_akd.MAX_LINE:
        buffer = b""
        out += b"Error: the line is too long.\r\n-->"
    pending[0] = buffer
    return out


def _receive(sock: socket.socket, size: int) -> bytes:
    data = b""
    end = time.monotonic() + 5.0
    while len(data) < size:
        sock.settimeout(max(0.01, end - time.monotonic()))
        chunk = sock.recv(size - len(data))
        assert chunk, f"closed after {data!r}"
        data += chunk
    return data


LONG = b"X" * (face_akd.MAX_LINE + 10)

STEPS = {
    "crlf": [b"DRV.OPMODE\r\n"],
    "lf, cr, then the cr's lf on its own": [b"DRV.OPMODE\n", b"VL.KP\r", b"\n"],
    "a line in two segments": [b"DRV.OP", b"MODE\r\n"],
    "two lines in one segment": [b"DRV.OPMODE\r\nVL.KP\r\n"],
    "a line and the start of the next": [b"DRV.OPMODE\r\nVL.", b"KP\n"],
    "empty lines": [b"\r\n\r\n", b"\n"],
    "cr cr lf": [b"DRV.OPMODE\r\r\n"],
    "every kind of end in one segment": [b"DRV.OPMODE\nVL.KP\rNOPE.X\r\nDRV.OPMODE", b"\n"],
    "padded and lower case": [b"  drv.opmode \t\r\n"],
    "a telnet answer before the line": [b"\xff\xfc\x1fDRV.OPMODE\r\n"],
    "an iac cut by the segment boundary": [b"DRV.OP\xff", b"\xfc\x1fMODE\r\n"],
    "a subnegotiation across segments": [b"\xff\xfa\x1f\x00\x50", b"\x00\x18\xff\xf0DRV.OPMODE\r\n"],
    "an escaped 255 in a line": [b"DRV.\xff\xffX\r\n"],
    "latin-1 in a line": [b"DRV.\xb5\r\n"],
    "an unfinished line too long, then a line": [LONG, b"DRV.OPMODE\r\n"],
    "a long line ended at once": [LONG + b"\r\n"],
}


@pytest.mark.parametrize("steps", list(STEPS.values()), ids=list(STEPS))
def test_the_face_answers_the_lines_the_rules_give(face: face_akd.AkdFace, steps: list[bytes]) -> None:
    state: dict[str, Any] = {}
    pending = [b""]
    with socket.create_connection(("127.0.0.1", face.port), timeout=5) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        assert _receive(sock, 3) == bytes([255, 253, 31])   # the option offered on connect
        for data in steps:
            sock.sendall(data)
            owed = _expected(face, state, pending, data)
            assert _receive(sock, len(owed)) == owed, data
        sock.settimeout(0.2)
        with pytest.raises(TimeoutError):
            extra = sock.recv(4096)
            pytest.fail(f"more than the rules give: {extra!r}")
