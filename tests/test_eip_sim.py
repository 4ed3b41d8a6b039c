"""The simulator's CIP objects in process (fast), and the face surviving arbitrary bytes on real sockets.

Error codes per the AKD EtherNet/IP manual [M-10] (reference/ethernetip.md 1.1); the I/O handshake
per seed 002 (SPEC-NOTES 24).
"""

from __future__ import annotations

import socket
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.protocol import akd_assembly as asm
from akdctl.protocol import cip, enip
from akdctl.sim.cip_device import CipDevice
from akdctl.sim.drive import SimDrive
from akdctl.sim.face_ethernetip import EthernetIpFace


@pytest.fixture
def device(tmp_path) -> CipDevice:
    return CipDevice(SimDrive("eip", tmp_path))


def ask(device: CipDevice, service: int, class_id: int, instance: int, attribute: int | None,
        data: bytes = b"") -> cip.Response:
    return cip.Response.decode(device.handle(cip.request(service, class_id, instance, attribute, data).encode()))


GET, SET = cip.GET_ATTRIBUTE_SINGLE, cip.SET_ATTRIBUTE_SINGLE


def test_parameter_object_attributes_and_akd_error_codes(device) -> None:
    assert ask(device, GET, 0x0F, 796, 1).data == struct.pack("<I", 65536)
    assert ask(device, GET, 0x0F, 797, 5).data == b"\xC8" and ask(device, GET, 0x0F, 797, 6).data == b"\x04"
    assert ask(device, GET, 0x0F, 205, 6).data == b"\x01"
    assert ask(device, SET, 0x0F, 796, 5, b"\xC8").status == 0x0E                  # not settable
    assert ask(device, GET, 0x0F, 796, 2).status == 0x14                           # attribute not supported
    assert ask(device, cip.GET_ATTRIBUTES_ALL, 0x0F, 796, None).status == 0x08     # service not supported
    assert ask(device, GET, 0x0F, 4242, 1).status == 0x16                          # object does not exist
    assert ask(device, GET, 0x26, 1, 1).status == 0x16                             # no Block Sequencer on an AKD
    assert ask(device, SET, 0x0F, 796, 1, struct.pack("<I", 0)).status == 0x09     # out of range
    assert ask(device, SET, 0x0F, 796, 1, b"\x01\x00").status == 0x13              # wrong length
    assert ask(device, SET, 0x0F, 796, 1, struct.pack("<I", 1000)).ok
    assert ask(device, GET, 0x25, 1, 4).data == struct.pack("<i", 1000)             # position units mirror POSUNIT


def test_home_move_command_runs_on_write_not_on_read(device) -> None:
    assert ask(device, GET, 0x0F, 205, 1).ok
    assert ask(device, SET, 0x0F, 205, 1, b"\x01").status == cip.DEVICE_STATE_CONFLICT   # disabled axis
    assert ask(device, SET, 0x25, 1, 17, b"\x01").ok
    assert ask(device, GET, 0x25, 1, 17).data == b"\x01"
    assert ask(device, SET, 0x0F, 205, 1, b"\x07").ok                       # any value 0..255 runs it
    with device.drive.transaction() as model:
        assert model.motion.axis.homed


def test_position_controller_load_handshake_moves_the_shared_axis(device) -> None:
    ask(device, SET, 0x25, 1, 17, b"\x01")
    ask(device, SET, 0x0F, 205, 1, b"\x01")
    assert ask(device, SET, 0x25, 1, 3, b"\x00").ok
    assert ask(device, SET, 0x25, 1, 6, struct.pack("<i", 65536)).ok
    assert ask(device, SET, 0x25, 1, 7, struct.pack("<i", 655360)).ok
    assert ask(device, SET, 0x25, 1, 11, b"\x01").ok
    assert ask(device, GET, 0x25, 1, 58).data == b"\x01"
    assert ask(device, SET, 0x25, 1, 11, b"\x00").ok and ask(device, GET, 0x25, 1, 58).data == b"\x00"
    with device.drive.transaction() as model:
        assert model.object_value(0x607A, 0) == 65536 and model.object_value(0x6061, 0) == 1
    assert ask(device, GET, 0x25, 1, 101).status == 0x14        # Set only
    assert ask(device, SET, 0x25, 1, 3, b"\x05").status == 0x09
    assert ask(device, SET, 0x25, 1, 58, b"\x01").status == 0x0E
    assert ask(device, GET, 0x25, 2, 3).status == 0x16
    assert ask(device, GET, 0x24, 1, 3).data == b"\x01"         # Supervisor axis number [I]


def _cycle(device: CipDevice, raw8: str) -> bytes:
    return device.io_cycle(bytes.fromhex(raw8) + bytes(56))


def test_io_handshake_seed_bytes_and_error_response(device) -> None:
    # not homed: the target position command is answered with response type 0x14 (SPEC-NOTES 24)
    assert _cycle(device, "80 00 21 20 E8 03 00 00")[:4] == bytes.fromhex("84 00 00 20")
    err = asm.Response.decode(_cycle(device, "81 00 21 20 E8 03 00 00")).error
    assert err is not None and (err.code, err.additional, err.echo_command, err.echo_response) == (0x10, 0xFF, 0x21, 0x20)
    assert _cycle(device, "80 00 21 20 E8 03 00 00")[:8] == bytes.fromhex("84 00 00 20 00 00 00 00")
    ask(device, SET, 0x0F, 205, 1, b"\x01")                      # home (current position)
    assert _cycle(device, "80 00 21 20 E8 03 00 00")[:8] == bytes.fromhex("84 00 00 20 00 00 00 00")
    loaded = asm.Response.decode(_cycle(device, "81 00 21 20 E8 03 00 00"))
    assert loaded.load_complete and loaded.response_type == 0
    assert not asm.Response.decode(_cycle(device, "80 00 21 20 E8 03 00 00")).load_complete
    bad = asm.Response.decode(_cycle(device, "81 00 3F 20 00 00 00 00"))      # command type 0x1F: not offered
    assert bad.error is not None and bad.error.code == 0x20 and bad.error.echo_command == 0x3F
    _cycle(device, "00 00 00 20 00 00 00 00")          # Enable dropped: ramp down, then power off (DISSOURCES bit 6)
    with device.drive.transaction() as model:
        motion = model.component("motion")
        assert motion.state != "enabled" or motion.stopping_to == "ready"


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=40))
def test_device_answers_any_message(tmp_path_factory, data: bytes) -> None:
    device = CipDevice(SimDrive("fuzz", tmp_path_factory.mktemp("fuzz")))
    reply = device.handle(data)
    assert cip.Response.decode(reply).service == ((data[0] & 0x7F) if data else 0)


def test_face_survives_garbage_and_keeps_serving(tmp_path) -> None:
    face = EthernetIpFace(SimDrive("face", tmp_path), "127.0.0.1", 0, io_port=0)
    face.start()
    try:
        cases = ((b"\x00" * 3, None),                      # truncated header: connection closed
                 (b"\xff" * 40, None),                     # announces 65535 bytes that never come: closed
                 (enip.Packet(0x1234, b"x").encode(), enip.STATUS_INVALID_COMMAND),
                 (enip.Packet(enip.SEND_RR_DATA, b"\x01\x02", session=7).encode(), enip.STATUS_INVALID_SESSION))
        for junk, status in cases:
            with socket.create_connection(("127.0.0.1", face.port), timeout=2) as sock:
                sock.sendall(junk)
                sock.shutdown(socket.SHUT_WR)
                sock.settimeout(2)
                reply = sock.recv(1000)
                if status is None:
                    assert reply == b""
                else:
                    assert enip.decode_header(reply).status == status
        with socket.create_connection(("127.0.0.1", face.port), timeout=2) as sock:
            sock.sendall(enip.Packet(enip.REGISTER_SESSION, enip.register_session_data()).encode())
            head = enip.decode_header(sock.recv(100))
            assert head.status == 0 and head.session
            msg = cip.request(GET, 1, 1, 7).encode()
            sock.sendall(enip.Packet(enip.SEND_RR_DATA, enip.RRData(
                (enip.Item(enip.ITEM_NULL), enip.Item(0x00B1, msg))).encode(), session=head.session).encode())
            head2 = enip.decode_header(sock.recv(100))
            assert head2.status == enip.STATUS_INCORRECT_DATA         # not a UCMM item pair: status, no crash
    finally:
        face.stop()
