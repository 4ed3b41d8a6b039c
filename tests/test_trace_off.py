"""Issue 29 item 1: tracing costs nothing when it is off, on CAN, CIP, the AKD ASCII channel and Modbus TCP.

Structure, not timing (no test asserts a timing): with an inactive tracer no transport calls the trace hook or
builds a note, a meta dict or an address tuple for a frame; with an active one every transport reports its frames
(the same requests, so each test can fail both ways). The CIP client also sets no socket timeout per request (each
``settimeout`` is a system call) and names a request only when a message needs the name; the client fast paths of
the codecs (``enip.pack_ucmm``/``ucmm_reply_message``, ``coe.pack_upload_initiate``/``expedited_upload_value``) are
held equal to the general encoders and decoders.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.connection import Connection
from akdctl.protocol import cip, coe, enip
from akdctl.sim.drive import SimDrive
from akdctl.transport.base import LinkOptions
from akdctl.transport.registry import parse_target
from akdctl.transport.trace import Tracer

REQUESTS = 20


class CountingTracer(Tracer):
    """A tracer that counts the calls of its hook (``frame``), whether or not it is active."""

    def __init__(self, active: bool) -> None:
        super().__init__(enabled=False, record=active)
        self.calls = 0

    def frame(self, *args: object, **kwargs: object) -> None:  # type: ignore[override]
        self.calls += 1
        super().frame(*args, **kwargs)  # type: ignore[arg-type]


@pytest.fixture
def drive(tmp_path: Path) -> SimDrive:
    return SimDrive("default", tmp_path)


def _connection(url: str, tracer: Tracer) -> Connection:
    return Connection(parse_target(url), LinkOptions(timeout=3.0, retries=0, tracer=tracer))


# ---------------------------------------------------------------- CAN
@pytest.fixture
def can_channel(drive: SimDrive) -> Iterator[str]:
    from akdctl.sim.face_can import CanFace, parse_spec

    channel = f"akd-{uuid.uuid4().hex[:10]}"
    face = CanFace(drive, parse_spec(f"virtual:{channel}:3"))
    face.start()
    try:
        yield channel
    finally:
        face.stop()


def test_can_frames_build_nothing_with_tracing_off(can_channel: str, monkeypatch: pytest.MonkeyPatch) -> None:
    from akdctl.transport import canopen_bus

    def refuse(*args: object, **kwargs: object) -> object:
        raise AssertionError("a frame note or meta dict was built with tracing off")

    monkeypatch.setattr(canopen_bus, "frame_note", refuse)
    monkeypatch.setattr(canopen_bus, "frame_meta", refuse)
    quiet = CountingTracer(active=False)
    conn = _connection(f"can://virtual/{can_channel}/3", quiet)
    try:
        for _ in range(REQUESTS):
            assert conn.objects().upload(0x1018, 1) == (0x6A).to_bytes(4, "little")
        assert len(conn.objects().upload(0x100A, 0)) > 4  # segmented too
    finally:
        conn.close()
    assert quiet.calls == 0


def test_can_frames_are_traced_when_on(can_channel: str) -> None:
    loud = CountingTracer(active=True)
    conn = _connection(f"can://virtual/{can_channel}/3", loud)
    try:
        conn.objects().upload(0x1018, 1)
    finally:
        conn.close()
    sdo = [(r.direction, r.meta["can_id"]) for r in loud.records if r.meta.get("can_id") in (0x603, 0x583)]
    assert sdo == [("tx", 0x603), ("rx", 0x583)]


# ---------------------------------------------------------------- CIP
@pytest.fixture
def eip_port(drive: SimDrive) -> Iterator[int]:
    from akdctl.sim import face_ethernetip

    face = face_ethernetip.from_options(drive, ethernetip="127.0.0.1:0", eip_io_port=0)
    assert face is not None
    face.start()
    try:
        yield face.port
    finally:
        face.stop()


class CountingSocket:
    """The session's socket, counting the calls that set its timeout (``settimeout``; ``setsockopt``, by which the
    client bounds a blocking socket's waits on Linux)."""

    def __init__(self, sock: object) -> None:
        self._sock = sock
        self.timeouts = 0

    def settimeout(self, value: float | None) -> None:
        self.timeouts += 1
        self._sock.settimeout(value)  # type: ignore[attr-defined]

    def setsockopt(self, *args: object) -> None:
        self.timeouts += 1
        self._sock.setsockopt(*args)  # type: ignore[attr-defined]

    def __getattr__(self, name: str) -> object:
        return getattr(self._sock, name)


def test_cip_requests_build_nothing_and_set_no_timeout_with_tracing_off(
        eip_port: int, monkeypatch: pytest.MonkeyPatch) -> None:
    from akdctl.transport import ethernetip

    named: list[object] = []
    real_name = ethernetip._name
    monkeypatch.setattr(ethernetip, "_name", lambda what: named.append(what) or real_name(what))
    quiet = CountingTracer(active=False)
    conn = _connection(f"eip://127.0.0.1:{eip_port}", quiet)
    try:
        attributes = conn.cip()
        attributes.get(cip.IDENTITY, 1, 1)  # the first request may set the timeout the deadline asks for
        session = conn.transport().message_link
        assert isinstance(session, ethernetip.EnipSession)
        counting = CountingSocket(session.sock)
        session.sock = counting  # type: ignore[assignment]
        for _ in range(REQUESTS):
            assert len(attributes.get(cip.IDENTITY, 1, 1)) == 2
        session.sock = counting._sock  # type: ignore[assignment]
    finally:
        conn.close()
    assert quiet.calls == 0
    assert named == []  # no "Get_Attribute_Single 0x01/1/1" string per request
    # One deadline per request; the socket's timeout is set only when the deadline moved by more than the
    # slack (a request stalled that long by the scheduler): the old client set it three times per request.
    assert counting.timeouts <= 4


def test_cip_frames_are_traced_when_on(eip_port: int) -> None:
    loud = CountingTracer(active=True)
    conn = _connection(f"eip://127.0.0.1:{eip_port}", loud)
    try:
        conn.cip().get(cip.IDENTITY, 1, 1)
    finally:
        conn.close()
    notes = [(r.direction, r.note) for r in loud.records if r.layer == "enip"]
    assert ("tx", "Get_Attribute_Single 0x01/1/1") in notes and ("rx", "Get_Attribute_Single 0x01/1/1") in notes


# ---------------------------------------------------------------- AKD ASCII channel
@pytest.fixture
def ascii_port(drive: SimDrive) -> Iterator[int]:
    from akdctl.sim import face_akd

    face = face_akd.from_options(drive, akd="127.0.0.1:0")
    assert face is not None
    face.start()
    try:
        yield face.port
    finally:
        face.stop()


def _ascii_commands(port: int, tracer: Tracer, monkeypatch: pytest.MonkeyPatch | None) -> None:
    from akdctl.transport import akd_ascii

    if monkeypatch is not None:
        def refuse(*args: object, **kwargs: object) -> None:
            raise AssertionError("an ASCII frame was traced with tracing off")

        monkeypatch.setattr(akd_ascii.AsciiLink, "_trace", refuse)
    conn = _connection(f"akd://127.0.0.1:{port}", tracer)
    try:
        for _ in range(5):
            assert "[" in conn.commands().command("VL.KP")
    finally:
        conn.close()


def test_ascii_commands_trace_nothing_with_tracing_off(ascii_port: int, monkeypatch: pytest.MonkeyPatch) -> None:
    quiet = CountingTracer(active=False)
    _ascii_commands(ascii_port, quiet, monkeypatch)
    assert quiet.calls == 0


def test_ascii_commands_are_traced_when_on(ascii_port: int) -> None:
    loud = CountingTracer(active=True)
    _ascii_commands(ascii_port, loud, None)
    assert {r.direction for r in loud.records if r.layer == "akd"} == {"tx", "rx"}


# ---------------------------------------------------------------- Modbus TCP
@pytest.fixture
def modbus_port(drive: SimDrive) -> Iterator[int]:
    pytest.importorskip("pymodbus")
    from akdctl.sim import face_modbus

    face = face_modbus.from_options(drive, modbus="127.0.0.1:0")
    assert face is not None
    face.start()
    try:
        yield face.port
    finally:
        face.stop()


def _modbus_reads(port: int, tracer: Tracer) -> None:
    conn = _connection(f"mb://127.0.0.1:{port}", tracer)
    try:
        for _ in range(5):
            assert len(conn.registers().read_registers(872, 2)) == 2  # VL.KP
    finally:
        conn.close()


def test_modbus_reads_trace_nothing_with_tracing_off(modbus_port: int) -> None:
    quiet = CountingTracer(active=False)
    _modbus_reads(modbus_port, quiet)
    assert quiet.calls == 0


def test_modbus_reads_are_traced_when_on(modbus_port: int) -> None:
    loud = CountingTracer(active=True)
    _modbus_reads(modbus_port, loud)
    assert {r.direction for r in loud.records if r.layer == "mb"} == {"tx", "rx"}


# ---------------------------------------------------------------- the codecs' client fast paths
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFFFFFF)


@given(u32, st.integers(0, (1 << 64) - 1), st.binary(max_size=300))
def test_ucmm_packet_equals_the_general_encoder(session: int, context: int, message: bytes) -> None:
    general = enip.Packet(enip.SEND_RR_DATA, enip.unconnected(message).encode(), session, 0,
                          context.to_bytes(8, "little")).encode()
    assert enip.pack_ucmm(session, context, message) == general
    head = enip.unpack_header(general)
    decoded = enip.decode_header(general)
    assert head == (decoded.command, decoded.length, decoded.session, decoded.status,
                    int.from_bytes(decoded.context, "little"), decoded.options)
    assert enip.ucmm_reply_message(general[enip.HEADER_SIZE:]) == message


@given(st.lists(st.builds(enip.Item, st.sampled_from([0x0000, 0x00B2, 0x00A1, 0x8000]), st.binary(max_size=20)),
                max_size=4), u16)
def test_ucmm_reply_message_agrees_with_the_general_decoder(items: list[enip.Item], timeout: int) -> None:
    data = enip.RRData(tuple(items), timeout).encode()
    try:
        expected: bytes | type[Exception] = enip.unconnected_message(enip.RRData.decode(data))
    except enip.CodecError:
        expected = enip.CodecError
    if expected is enip.CodecError:
        with pytest.raises(enip.CodecError):
            enip.ucmm_reply_message(data)
    else:
        assert enip.ucmm_reply_message(data) == expected


@given(u16, st.integers(0, 0xFF), st.one_of(st.none(), st.integers(0, 0xFF)))
def test_attribute_path_equals_the_general_encoder(class_id: int, instance: int, attribute: int | None) -> None:
    assert cip.attribute_path(class_id, instance, attribute) == cip.Path(class_id, instance, attribute).encode()


@given(u16, st.integers(0, 0xFF))
def test_upload_initiate_equals_the_general_encoder(index: int, subindex: int) -> None:
    assert coe.pack_upload_initiate(index, subindex) == coe.encode_sdo(coe.SdoUploadInitiate(index, subindex))


@given(st.binary(min_size=8, max_size=8), u16, st.integers(0, 0xFF))
def test_expedited_value_agrees_with_the_general_decoder(payload: bytes, index: int, subindex: int) -> None:
    value = coe.expedited_upload_value(payload, index, subindex)
    try:
        message = coe.decode_sdo(payload, from_server=True)
    except coe.CoeError:
        assert value is None
        return
    fits = (isinstance(message, coe.SdoUploadResponse) and message.expedited and message.index == index
            and message.subindex == subindex)
    assert value == (message.data if fits else None)  # type: ignore[union-attr]


@given(st.binary(min_size=4, max_size=4), u16, st.integers(0, 0xFF))
def test_expedited_value_reads_what_the_server_packs(raw: bytes, index: int, subindex: int) -> None:
    for size in range(1, 5):
        payload = coe.pack_expedited_upload_response(index, subindex, raw[:size])
        assert coe.expedited_upload_value(payload, index, subindex) == raw[:size]
