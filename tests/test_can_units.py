"""CANopen transport pieces that need no bus: target syntax, --can syntax, slcan lines, error translation."""

from __future__ import annotations

import can
import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.cli.can import parse_nodes
from akdctl.errors import CommError, UsageError
from akdctl.sim.can_pdo import PdoConfig, pack, predefined_cob_id, unpack
from akdctl.sim.can_sdo import crc16
from akdctl.sim.face_can import parse_spec
from akdctl.sim.slcan_device import format_frame, parse_frame
from akdctl.transport import canopen_bus
from akdctl.transport.canopen_bus import BusConfig, bus_config, frame_note, open_bus
from akdctl.transport.registry import parse_target


def cfg(text: str) -> BusConfig:
    return bus_config(parse_target(text))


def test_target_basic_and_typed_options() -> None:
    c = cfg("can://socketcan/can0/5?bitrate=250000&fd=true&data_bitrate=2000000&receive_own_messages=false")
    assert (c.interface, c.channel, c.node, c.use_config, c.block) == ("socketcan", "can0", 5, False, False)
    assert c.kwargs == {"bitrate": 250000, "fd": True, "data_bitrate": 2000000, "receive_own_messages": False}


def test_target_device_path_ipv4_and_block() -> None:
    assert cfg("can://slcan//dev/ttyACM0/1").channel == "/dev/ttyACM0"
    assert cfg("can://slcan/%2Fdev%2FttyUSB0@115200/2").channel == "/dev/ttyUSB0@115200"
    c = cfg("can://udp_multicast/239.74.163.2/1?port=43114&block=1")
    assert (c.channel, c.kwargs, c.block) == ("239.74.163.2", {"port": 43114}, True)
    assert cfg("can://udp_multicast/ff15:7079:7468:6f6e:6465:6d6f:6d63:6173/3").channel.startswith("ff15:")


def test_target_config_interface() -> None:
    c = cfg("can://config/-/4?context=bench")
    assert (c.interface, c.channel, c.use_config, c.context, c.node) == (None, None, True, "bench", 4)
    assert cfg("can://default/7").node == 7


@pytest.mark.parametrize("text", [
    "can://socketcan/can0/0", "can://socketcan/can0/128", "can://socketcan/can0", "can://socketcan/can0/x",
    "can://socketcan/-/1", "can://socketcan/can0/1?block=maybe", "can://socketcan/can0/1?context=x",
])
def test_target_errors_are_usage_errors(text: str) -> None:
    with pytest.raises(UsageError):
        bus_config(parse_target(text))


def test_open_bus_unknown_interface_is_usage_error() -> None:
    with pytest.raises(UsageError, match="unknown python-can interface 'nosuch'"):
        open_bus(BusConfig("nosuch", "x"))


@pytest.mark.parametrize("exc, kind", [
    (can.CanInterfaceNotImplementedError("pcanbasic library not found"), CommError),
    (can.CanInitializationError("no such device"), CommError),
    (OSError(19, "No such device"), CommError),
    (ImportError("No module named 'vendor'"), CommError),
    (ValueError("Invalid bitrate"), UsageError),
    (TypeError("unexpected keyword"), UsageError),
])
def test_open_bus_translates_failures(monkeypatch: pytest.MonkeyPatch, exc: Exception, kind: type) -> None:
    def boom(*args: object, **kwargs: object) -> None:
        raise exc

    monkeypatch.setattr(can, "Bus", boom)
    with pytest.raises(kind) as info:
        open_bus(BusConfig("pcan", "PCAN_USBBUS1"))
    assert "\n" not in info.value.message and "pcan PCAN_USBBUS1" in info.value.message


def test_open_bus_passes_options_and_ignores_config_files(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: dict[str, object] = {}

    def fake(**kwargs: object) -> str:
        seen.update(kwargs)
        return "bus"

    monkeypatch.setattr(can, "Bus", fake)
    assert open_bus(cfg("can://kvaser/0/1?bitrate=125000")) == "bus"
    assert seen == {"interface": "kvaser", "channel": "0", "ignore_config": True, "bitrate": 125000}
    seen.clear()
    open_bus(cfg("can://config/-/1?context=bench"))
    assert seen == {"channel": None, "config_context": "bench"}


def test_config_interface_reads_python_can_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    """INTERFACE 'config' honours python-can's own configuration (CAN_INTERFACE/CAN_CHANNEL)."""
    monkeypatch.setenv("CAN_INTERFACE", "virtual")
    monkeypatch.setenv("CAN_CHANNEL", "akd-config-test")
    bus = open_bus(cfg("can://config/-/1"))
    try:
        assert bus.channel_info.endswith("akd-config-test")
    finally:
        bus.shutdown()


def test_frame_note_names_services() -> None:
    assert frame_note(0x601) == "id 0x601 SDO rx node 1"
    assert frame_note(0x705) == "id 0x705 heartbeat node 5"
    assert frame_note(0x080) == "id 0x080 SYNC node 0"
    assert frame_note(0) == "id 0x000 NMT"


@pytest.mark.parametrize("text, expected", [
    ("udp_multicast:239.74.163.2:1", ("udp_multicast", "239.74.163.2", 1, {})),
    ("udp_multicast:239.74.163.2", ("udp_multicast", "239.74.163.2", 1, {})),
    ("udp_multicast:[ff15::1]:9?port=43200", ("udp_multicast", "ff15::1", 9, {"port": 43200})),
    ("socketcan:vcan0:127?bitrate=500000", ("socketcan", "vcan0", 127, {"bitrate": 500000})),
    ("slcan-pty:-:2", ("slcan-pty", None, 2, {})),
])
def test_can_spec(text: str, expected: tuple) -> None:
    spec = parse_spec(text)
    assert (spec.interface, spec.channel, spec.node, spec.kwargs) == expected


@pytest.mark.parametrize("text", ["udp_multicast", "x:", "udp_multicast:ff15::1:1", "virtual:a:0", "virtual:a:z",
                                  "virtual:[a:1", "virtual:a:1?=&&"])
def test_can_spec_errors(text: str) -> None:
    with pytest.raises(UsageError):
        parse_spec(text)


def test_parse_nodes() -> None:
    assert parse_nodes("1-3,7, 5") == [1, 2, 3, 5, 7]
    for bad in ("0-3", "5-2", "x", "", "1-200"):
        with pytest.raises(UsageError):
            parse_nodes(bad)


def test_slcan_lines_seed_vectors() -> None:
    msg = can.Message(arbitration_id=0x601, data=bytes.fromhex("4018100100000000"), is_extended_id=False)
    assert format_frame(msg) == b"t60184018100100000000\r"
    rtr = can.Message(arbitration_id=0x701, is_remote_frame=True, dlc=1, is_extended_id=False)
    assert format_frame(rtr) == b"r7011\r"
    ext = parse_frame(b"T1ABCDEF02A1B2")
    assert (ext.arbitration_id, ext.is_extended_id, bytes(ext.data)) == (0x1ABCDEF0, True, b"\xa1\xb2")


@given(can_id=st.integers(0, 0x7FF), data=st.binary(max_size=8), ext=st.booleans(), ext_id=st.integers(0, 0x1FFFFFFF))
def test_slcan_round_trip(can_id: int, data: bytes, ext: bool, ext_id: int) -> None:
    ident = ext_id if ext else can_id
    msg = can.Message(arbitration_id=ident, data=data, is_extended_id=ext)
    back = parse_frame(format_frame(msg)[:-1])
    assert (back.arbitration_id, back.is_extended_id, bytes(back.data)) == (ident, ext, data)


@given(st.binary(max_size=30))
def test_slcan_parse_fuzz_raises_only_value_error(line: bytes) -> None:
    try:
        parse_frame(b"t" + line)
    except (ValueError, IndexError, UnicodeDecodeError):
        pass


def test_crc16_matches_canopen_client() -> None:
    from canopen.sdo.base import CrcXmodem

    ref = CrcXmodem()
    ref.process(b"123456789")
    assert crc16(b"123456789") == ref.final() == 0x31C3


def test_predefined_cob_ids() -> None:
    assert predefined_cob_id(0x1800, 1, bytes(4), 5) == (0x185).to_bytes(4, "little")
    assert predefined_cob_id(0x1401, 1, (0x80000000).to_bytes(4, "little"), 5) == (0x80000305).to_bytes(4, "little")
    assert predefined_cob_id(0x1800, 1, (0x1FF).to_bytes(4, "little"), 5) == (0x1FF).to_bytes(4, "little")
    assert predefined_cob_id(0x1800, 2, bytes([1]), 5) == bytes([1])


class _Objects:
    def __init__(self) -> None:
        self.values = {(0x6040, 0): b"\x0f\x00", (0x6060, 0): b"\x01"}

    def object_read(self, index: int, sub: int) -> bytes:
        return self.values[(index, sub)]

    def object_write(self, index: int, sub: int, data: bytes) -> None:
        self.values[(index, sub)] = data


def test_pdo_pack_unpack_with_dummy_padding() -> None:
    model = _Objects()
    config = PdoConfig(1, 0x201, entries=[(0x6040, 0, 16), (0x0005, 0, 8), (0x6060, 0, 8)])
    assert pack(model, config) == b"\x0f\x00\x00\x01"
    assert unpack(model, config, b"\x06\x00\xff\x03")
    assert model.values[(0x6040, 0)] == b"\x06\x00" and model.values[(0x6060, 0)] == b"\x03"
    assert not unpack(model, config, b"\x06")  # too short: the node answers with EMCY 0x8210


def test_module_has_no_bus_at_import() -> None:
    assert canopen_bus.OWN_QUERY == {"block", "context"}
