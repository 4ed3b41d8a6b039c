"""The simulator's CANopen node against akdctl's CANopen transport and against canopen's own client classes.

Everything runs in this process on python-can's ``virtual`` interface (one
channel per test), so these tests are fast; tests/test_can_e2e.py repeats the
important paths across processes.
"""

from __future__ import annotations

import json
import struct
import threading
import uuid
from collections.abc import Iterator

import canopen
import pytest

from akdctl.connection import Connection
from akdctl.errors import MalformedReply, NoAnswer, SdoAborted, UsageError
from akdctl.protocol.emcy import Emergency
from akdctl.sim.drive import SimDrive
from akdctl.sim.face_can import CanFace, parse_spec
from akdctl.transport.base import LinkOptions
from akdctl.transport.canopen_bus import NMT_COMMANDS, CanopenTransport
from akdctl.transport.registry import parse_target
from akdctl.transport.trace import Tracer
from tests.harness import wait_until

NODE = 3


@pytest.fixture
def channel() -> str:
    return f"akd-{uuid.uuid4().hex[:10]}"


@pytest.fixture
def face(channel: str) -> Iterator[CanFace]:
    face = CanFace(SimDrive(), parse_spec(f"virtual:{channel}:{NODE}"))
    face.start()
    yield face
    face.stop()


def _transport(channel: str, query: str = "", timeout: float = 1.0, node: int = NODE) -> Connection:
    """A Connection over the CAN transport (``.objects()`` the SDO channel, ``.transport()`` NMT and the bus)."""
    target = parse_target(f"can://virtual/{channel}/{node}{query}")
    conn = Connection.over(CanopenTransport(target, LinkOptions(timeout=timeout, retries=0, tracer=Tracer(enabled=False))))
    conn.transport()
    return conn


@pytest.fixture
def link(face: CanFace, channel: str) -> Iterator[Connection]:
    transport = _transport(channel)
    yield transport
    transport.close()


# ------------------------------------------------------------------ SDO through akdctl's channel
def test_expedited_identity(link: Connection) -> None:
    assert link.objects().upload(0x1018, 1) == (0x6A).to_bytes(4, "little")  # Kollmorgen vendor id (ESI)
    assert link.objects().upload(0x1000, 0) == (0x00020192).to_bytes(4, "little")


@pytest.mark.parametrize("block", [False, True])
@pytest.mark.parametrize("size", [1, 4, 5, 7, 8, 14, 20, 32])
def test_segmented_and_block_round_trip(face: CanFace, channel: str, block: bool, size: int) -> None:
    transport = _transport(channel, "?block=1" if block else "")
    try:
        value = bytes((65 + i % 26) for i in range(size))
        transport.objects().download(0x2032, 0, value)  # DRV.CUSTOMIDENTIFIER, STRING(32)
        assert transport.objects().upload(0x2032, 0) == value
        assert transport.objects().block is block  # the simulator accepts block transfers
    finally:
        transport.close()


def test_abort_translated_with_code_and_text(link: Connection) -> None:
    with pytest.raises(SdoAborted) as info:
        link.objects().upload(0x7777, 0)
    assert info.value.code == 0x06020000 and info.value.exit_code == 1
    assert "0x06020000" in info.value.message and "does not exist" in info.value.message
    with pytest.raises(SdoAborted) as info:
        link.objects().download(0x1018, 1, b"\0\0\0\0")
    assert info.value.code == 0x06010002  # read-only


def test_silent_node_is_no_answer(face: CanFace, channel: str) -> None:
    transport = _transport(channel, timeout=0.2, node=99)
    try:
        with pytest.raises(NoAnswer) as info:
            transport.objects().upload(0x1000, 0)
        assert info.value.exit_code == 3 and "node 99" in info.value.message
    finally:
        transport.close()


def test_trace_sees_every_frame(face: CanFace, channel: str) -> None:
    tracer = Tracer(enabled=False)
    transport = Connection.over(CanopenTransport(parse_target(f"can://virtual/{channel}/{NODE}"),
                                                 LinkOptions(timeout=1, retries=0, tracer=tracer)))
    try:
        transport.objects().upload(0x1018, 1)
    finally:
        transport.close()
    sdo = [(r.direction, r.meta["can_id"]) for r in tracer.records if r.meta.get("can_id") in (0x600 + NODE, 0x580 + NODE)]
    assert sdo == [("tx", 0x603), ("rx", 0x583)]


# ------------------------------------------------------------------ NMT, heartbeat, guarding
def test_nmt_states_by_guarding_and_heartbeat(face: CanFace, link: CanopenTransport) -> None:
    assert link.transport().nmt_state() == "PRE-OPERATIONAL"  # heartbeat is off (0x1017 = 0): node guarding answers
    link.transport().nmt("stop")
    assert link.transport().nmt_state(fresh=True) == "STOPPED"
    with pytest.raises(NoAnswer) as info:
        link.objects().upload(0x1018, 1)  # no SDO in STOPPED (CiA 301)
    assert "NMT state STOPPED" in info.value.message and "can nmt preop" in info.value.message  # issue 14
    link.transport().nmt("start")
    assert link.transport().nmt_state(fresh=True) == "OPERATIONAL"
    link.objects().download(0x1017, 0, struct.pack("<H", 50))  # heartbeat producer on
    beats: list[bytes] = []
    link.transport().network.subscribe(0x700 + NODE, lambda cid, data, ts: beats.append(bytes(data)))
    wait_until(lambda: len(beats) >= 2, "two heartbeats", timeout=3.0)
    assert beats[-1] == b"\x05"
    link.transport().nmt("reset-comm")
    assert link.transport().nmt_state(fresh=True) == "PRE-OPERATIONAL"
    wait_until(lambda: b"\x00" in beats, "the boot-up message", timeout=3.0)  # boot-up message


def test_scan_reports_identity(face: CanFace, link: CanopenTransport) -> None:
    found = link.transport().scan(range(1, 128), wait=0.3)
    assert [n.node for n in found] == [NODE]
    info = found[0]
    assert (info.vendor_id, info.device_type, info.state) == (0x6A, 0x00020192, "PRE-OPERATIONAL")


# ------------------------------------------------------------------ EMCY
def test_emergencies_reach_the_channel(face: CanFace, link: CanopenTransport, monkeypatch: pytest.MonkeyPatch) -> None:
    pending = [Emergency(0x4310, 0x09, b"\x01\x02\x03\x04\x05"), Emergency(0x0000, 0x00)]
    lock = threading.Lock()

    def take() -> list[Emergency]:
        with lock:
            out, pending[:] = list(pending), []
        return out

    monkeypatch.setattr(face.drive, "take_emergencies", take)
    got = link.objects().wait_emergencies(3.0)
    wait_until(lambda: len(got) + len(link.objects()._emcy) >= 2, "two emergencies", timeout=3.0)
    got += link.objects().take_emergencies()
    assert got == [Emergency(0x4310, 0x09, b"\x01\x02\x03\x04\x05"), Emergency(0, 0, bytes(5))]
    assert got[1].is_reset


# ------------------------------------------------------------------ PDOs
def test_pdos_follow_the_mapping(face: CanFace, link: CanopenTransport) -> None:
    tpdo: list[bytes] = []
    link.transport().network.subscribe(0x180 + NODE, lambda cid, data, ts: tpdo.append(bytes(data)))
    o = link.objects()
    assert o.upload(0x1800, 1) == (0x180 + NODE).to_bytes(4, "little")  # predefined connection set
    assert int.from_bytes(o.upload(0x1A00, 1), "little") == 0x60410010  # statusword in TPDO1
    o.download(0x1800, 2, bytes([1]))  # TPDO1 synchronous, every SYNC
    link.transport().nmt("start")
    assert link.transport().nmt_state(fresh=True) == "OPERATIONAL"
    tpdo.clear()
    for sent in range(1, 4):  # one SYNC at a time: each answered by its TPDO before the next goes out
        link.transport().network.send_message(0x080, b"")
        wait_until(lambda: len(tpdo) >= sent, f"TPDO {sent}", timeout=3.0)  # noqa: B023 - used at once
    assert all(len(p) == 2 for p in tpdo)
    # RPDO1 carries the controlword (0x1600:01 = 0x60400010)
    link.transport().network.send_message(0x200 + NODE, b"\x06\x00")
    wait_until(lambda: o.upload(0x6040, 0) == b"\x06\x00", "the RPDO to set the controlword", timeout=3.0)
    link.transport().network.send_message(0x200 + NODE, b"\x07")  # too short: EMCY 0x8210
    emcy = o.wait_emergencies(3.0)
    assert any(e.error_code == 0x8210 for e in emcy)


# ------------------------------------------------------------------ canopen's own classes as independent peers
def _od_from_catalogue(indices: list[int]) -> canopen.ObjectDictionary:
    """A canopen object dictionary for some AKD objects, typed from akdctl's catalogue."""
    from canopen.objectdictionary import ODRecord, ODVariable, datatypes as dt

    from akdctl.catalog import objects

    types = {"USINT": dt.UNSIGNED8, "SINT": dt.INTEGER8, "UINT": dt.UNSIGNED16, "INT": dt.INTEGER16,
             "UDINT": dt.UNSIGNED32, "DINT": dt.INTEGER32, "BOOL": dt.UNSIGNED8}
    od = canopen.ObjectDictionary()
    for index in indices:
        entries = objects.subentries(index)
        def var(e):  # noqa: ANN001, ANN202
            v = ODVariable(e.name, e.index, e.subindex)
            v.data_type = types.get(e.type.split("(")[0].upper(), dt.VISIBLE_STRING)
            v.access_type = {"ro": "ro", "wo": "wo"}.get(e.access, "rw")
            return v
        if len(entries) == 1 and entries[0].subindex == 0:
            od.add_object(var(entries[0]))
        else:
            record = ODRecord(objects.object_name(index) or f"0x{index:04X}", index)
            for e in entries:
                record.add_member(var(e))
            od.add_object(record)
    return od


def _peer_network(channel: str) -> canopen.Network:
    network = canopen.Network()
    network.connect(interface="virtual", channel=channel)
    return network


def test_canopen_sdo_client_as_peer(face: CanFace, channel: str) -> None:
    network = _peer_network(channel)
    try:
        node = network.add_node(NODE, canopen.ObjectDictionary())
        node.sdo.RESPONSE_TIMEOUT = 1.0
        assert node.sdo.upload(0x1018, 1) == b"\x6a\x00\x00\x00"
        node.sdo.download(0x2032, 0, b"peer-written-by-canopen")
        assert node.sdo.upload(0x2032, 0) == b"peer-written-by-canopen"
        with node.sdo.open(0x2032, 0, "wb", size=20, block_transfer=True) as fp:
            fp.write(b"block-by-canopen-lib")
        with node.sdo.open(0x2032, 0, "rb", block_transfer=True) as fp:
            assert fp.read() == b"block-by-canopen-lib"
        with pytest.raises(canopen.SdoAbortedError) as info:
            node.sdo.upload(0x7777, 0)
        assert info.value.code == 0x06020000
    finally:
        network.disconnect()


def test_canopen_base_node_402_as_peer(face: CanFace, channel: str) -> None:
    network = _peer_network(channel)
    indices = [0x1400, 0x1401, 0x1402, 0x1403, 0x1600, 0x1601, 0x1602, 0x1603,
               0x1800, 0x1801, 0x1802, 0x1803, 0x1A00, 0x1A01, 0x1A02, 0x1A03,
               0x6040, 0x6041, 0x6060, 0x6061]
    try:
        od = _od_from_catalogue(indices)
        node = canopen.BaseNode402(NODE, od)
        network.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 1.0
        node.nmt.state = "PRE-OPERATIONAL"
        node.setup_402_state_machine(read_pdos=True)  # reads the PDO configuration by SDO
        assert node.tpdo[1].cob_id == 0x180 + NODE and 0x6041 in node.tpdo_values
        assert 0x6040 in node.rpdo_pointers
        statusword = int.from_bytes(face.drive.object_read(0x6041, 0), "little")
        assert node.sdo[0x6041].raw == statusword
        assert node.state in canopen.profiles.p402.State402.SW_MASK
    finally:
        network.disconnect()


def test_malformed_block_reply_is_comm_error(link: CanopenTransport, monkeypatch: pytest.MonkeyPatch) -> None:
    """A canopen transfer (downloads and block transfers run on canopen's own client) that fails on a reply that
    does not fit is a malformed reply, not a crash."""
    from canopen.sdo.exceptions import SdoCommunicationError

    def broken(*args: object, **kwargs: object) -> bytes:
        raise SdoCommunicationError("Toggle bit mismatch")

    monkeypatch.setattr(link.objects().sdo, "request_response", broken)  # canopen's request path
    with pytest.raises(MalformedReply):
        link.objects().download(0x6060, 0, b"\x01")


def test_a_reply_that_is_not_for_the_request_is_skipped_and_the_upload_goes_on(link: CanopenTransport) -> None:
    """A late answer to an earlier request (another object) arrives first: it is not taken as this one's."""
    objects = link.objects()
    real = objects._send

    def late_first(request: bytes, index: int, subindex: int) -> None:
        # the stray reply waits in the queue ahead of the real answer to this request
        objects._replies.put(bytes([0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]))  # 0x1000:0, not 0x1018:1
        real(request, index, subindex)

    objects._send = late_first  # type: ignore[method-assign]
    try:
        assert objects.upload(0x1018, 1) == (0x6A).to_bytes(4, "little")
    finally:
        objects._send = real  # type: ignore[method-assign]


def test_a_segmented_upload_with_a_wrong_toggle_bit_is_aborted(link: CanopenTransport) -> None:
    objects = link.objects()
    real = objects._send
    sent: list[bytes] = []

    def wrong_toggle(request: bytes, index: int, subindex: int) -> None:
        sent.append(bytes(request))
        if request[0] & 0xE0 == 0x60:  # upload segment request: answered with the other toggle bit
            objects._replies.put(bytes([0x00 | (request[0] & 0x10) ^ 0x10]) + b"AKD-SIM")
            return
        real(request, index, subindex)

    objects._send = wrong_toggle  # type: ignore[method-assign]
    try:
        with pytest.raises(MalformedReply, match="wrong toggle bit"):
            objects.upload(0x100A, 0)  # software version: more than 4 bytes, segmented
    finally:
        objects._send = real  # type: ignore[method-assign]
    assert sent[-1][0] == 0x80 and int.from_bytes(sent[-1][4:], "little") == 0x05030000  # aborted: toggle bit


# ------------------------------------------------------------------ NMT as a write plan (drive/nmt.py)
def test_nmt_start_is_gated_the_others_are_not(face: CanFace, link: Connection) -> None:
    """NMT start makes the node act on the RPDOs a master sends (CiA 301: PDOs only in OPERATIONAL): consent;
    stop, preop and the resets only take process data away."""
    from akdctl.drive import nmt

    for command in nmt.EXPECTED_STATE:
        plan = nmt.plan(link, nmt.NmtRequest(command))
        assert [w.raw for w in plan.writes] == [bytes((NMT_COMMANDS[command], NODE))]
        assert bool(plan.needing_consent) == (command == "start"), command
    every = nmt.plan(link, nmt.NmtRequest("reset", 0))
    assert not every.verify and any("no node's new state is confirmed" in n for n in every.notes)
    with pytest.raises(UsageError, match="NODE 128 is outside"):
        nmt.plan(link, nmt.NmtRequest("stop", 128))
    assert link.transport().nmt_state(fresh=True) == "PRE-OPERATIONAL"  # planning sent nothing


def test_cli_nmt_start_asks_consent_and_dry_run_sends_nothing(face: CanFace, channel: str, akd_inproc) -> None:
    target = f"can://virtual/{channel}/{NODE}"
    code, out, err = akd_inproc("-T", target, "can", "nmt", "start", "--dry-run")
    assert code == 0 and "needs consent" in out and "RPDOs" in out, err
    code, out, err = akd_inproc("-T", target, "can", "nmt", "start")
    assert code == 4 and "refusing to write NMT start (node" in err and out == "", err
    code, out, err = akd_inproc("-T", target, "--json", "can", "nmt", "preop")  # never gated
    assert code == 0 and json.loads(out)["nmt_state"] == "PRE-OPERATIONAL", err
    code, out, err = akd_inproc("-T", target, "-y", "--json", "can", "nmt", "start")
    assert code == 0 and json.loads(out)["nmt_state"] == "OPERATIONAL", err
    code, out, err = akd_inproc("-T", target, "can", "nmt", "stop", "300")
    assert code == 2 and "NODE 300 is outside" in err
