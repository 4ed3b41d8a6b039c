"""protocol/foe.py: FoE frames (ETG.1000.6) round-trip, and malformed bytes raise the one codec error."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.protocol import foe
from akdctl.protocol.errors import CodecError


def test_write_request_bytes() -> None:
    # opcode 2, reserved, password 0 (u32 LE), then the name without terminator
    assert foe.encode_foe(foe.write_request("fw.bin")) == bytes.fromhex("02 00 00000000") + b"fw.bin"
    assert foe.encode_foe(foe.ack(3)) == bytes.fromhex("04 00 03000000")


@given(st.sampled_from(sorted(foe.OPCODES)), st.integers(0, 0xFFFFFFFF), st.binary(max_size=600))
def test_round_trip(opcode: int, value: int, data: bytes) -> None:
    frame = foe.FoeFrame(opcode, value, data)
    assert foe.decode_foe(foe.encode_foe(frame)) == frame


@given(st.binary(max_size=12))
def test_malformed_raises_codec_error(data: bytes) -> None:
    try:
        frame = foe.decode_foe(data)
    except CodecError:
        return
    assert frame.opcode in range(1, 7) and len(data) >= foe.HEADER_SIZE


def test_bad_values_refused() -> None:
    with pytest.raises(foe.FoeError):
        foe.encode_foe(foe.FoeFrame(9, 0))
    with pytest.raises(foe.FoeError):
        foe.encode_foe(foe.FoeFrame(foe.FoeOpcode.ACK, -1))
