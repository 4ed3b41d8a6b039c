"""``SimDrive._serve``'s straight line (the lock kept, the held model trusted) against the general transaction
(``_serve_general``: ``_begin``/``_commit``): the same answers to the same base-mode requests -- reads, accepted
and refused writes, whole-request refusals, record-layer refusals -- and the same saved state afterwards."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from akdctl.sim.drive import SimDrive
from akdctl.sim.errors import RecordRefused


def _requests() -> list[bytes]:
    read_930 = bytes.fromhex("01 01 00 01 10 01 03 A2 00 00")
    out = []
    for reference, value in enumerate((2, 1, 0, 7, 2), start=1):  # 7: out of range, refused by the model
        out.append(bytes([reference]) + read_930[1:])
        out.append(bytes([reference, 0x02, 0, 1, 0x10, 1, 0x03, 0xA2, 0, 0, 0x06, 1]) + value.to_bytes(2, "big"))
        out.append(bytes([reference]) + read_930[1:])
    out += [
        bytes.fromhex("09 01 00 01 10 02 03 C4 00 00"),  # PNU 964[0..1]
        bytes.fromhex("0A 01 00 01 10 01 30 39 00 00"),  # unknown PNU 12345
        bytes.fromhex("0B 01 05 01 10 01 03 A2 00 00"),  # axis 5: whole-request refusal
        bytes.fromhex("00 01 00 01 10 01 03 A2 00 00"),  # reference 0: the record write is refused (0xB7)
        bytes.fromhex("0C 01 00"),                       # too short: refused (0xB1)
    ]
    return out


def _answer(drive: SimDrive, request: bytes) -> Any:
    try:
        return drive.handle_bmp(request)
    except RecordRefused as exc:
        return ("refused", exc.code1)


def _persisted(directory: Path) -> dict[str, Any]:
    drive = SimDrive("default", directory)
    try:
        state = drive.snapshot()
    finally:
        drive.close()
    state.pop("sim", None)
    motion = state.get("components", {}).get("motion", {})
    for name in ("clock", "since_access"):  # wall time passes differently in the two drives
        state.pop(name, None)
        motion.pop(name, None)
    return state


def test_a_served_drive_answers_as_a_drive_that_takes_the_general_way(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    kept, plain = SimDrive("default", tmp_path / "kept"), SimDrive("default", tmp_path / "plain")
    kept.serve_faces()
    generals: list[str] = []
    general = SimDrive._serve_general

    def counted(self: SimDrive, *args: Any) -> Any:
        generals.append("kept" if self is kept else "plain")
        return general(self, *args)

    monkeypatch.setattr(SimDrive, "_serve_general", counted)
    try:
        answers = [(_answer(kept, r), _answer(plain, r)) for r in _requests()]
    finally:
        kept.close()
        plain.close()
    for request, (fast, slow) in zip(_requests(), answers):
        assert fast == slow, request.hex()
    assert generals.count("plain") == len(answers)  # a drive that does not keep its lock: always the general way
    assert generals.count("kept") < 3  # the served drive: the straight line once it holds the lock
    assert any(isinstance(a, bytes) and a[1] == 0x82 for a, _ in answers)  # a refused write was among them
    assert _persisted(tmp_path / "kept") == _persisted(tmp_path / "plain")
