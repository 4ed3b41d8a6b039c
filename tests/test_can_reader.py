"""The caller that waits for an SDO answer reads the bus itself (akdctl.io.can_reader.BusReader): same answers as
when canopen's receive thread hands them over, and nothing another listener needs is lost or held back for good.

Over python-can's ``virtual`` bus (in-process, real python-can frames): the simulated node (``CanFace``), or a
scripted node on a bus of its own that answers every SDO request with an emergency and a heartbeat first, so they
arrive while the caller reads.
"""

from __future__ import annotations

import queue
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

can = pytest.importorskip("can")
pytest.importorskip("canopen")

from akdctl.channels.canopen_sdo import CanopenObjectChannel  # noqa: E402
from akdctl.errors import AkdError, CommError  # noqa: E402
from akdctl.links import Budget  # noqa: E402
from akdctl.sim.drive import SimDrive  # noqa: E402
from akdctl.transport.base import LinkOptions  # noqa: E402
from akdctl.transport.canopen_bus import CanopenTransport  # noqa: E402
from akdctl.transport.registry import parse_target  # noqa: E402
from tests.harness import wait_until  # noqa: E402

NODE = 3
#: Expedited, segmented (device name, firmware version), an object and a subindex the node does not have.
REQUESTS = [(0x1018, 1), (0x1018, 2), (0x1008, 0), (0x100A, 0), (0x1000, 0), (0x5FFF, 0), (0x1018, 0x40)]


@pytest.fixture
def channel_name(tmp_path: Path) -> Iterator[str]:
    """A virtual bus with the simulated drive on it as node 3."""
    from akdctl.sim.face_can import CanFace, parse_spec

    name = f"akd-{uuid.uuid4().hex[:10]}"
    face = CanFace(SimDrive("default", tmp_path), parse_spec(f"virtual:{name}:{NODE}"))
    face.start()
    try:
        yield name
    finally:
        face.stop()


def _transport(name: str, node: int = NODE, timeout: float = 2.0) -> CanopenTransport:
    transport = CanopenTransport(parse_target(f"can://virtual/{name}/{node}"), LinkOptions(timeout=timeout, retries=0))
    transport.open()
    return transport


def _outcome(channel: CanopenObjectChannel, index: int, subindex: int) -> tuple[str, object]:
    try:
        return "value", channel.upload(index, subindex)
    except AkdError as exc:
        return type(exc).__name__, exc.message


def _channel(transport: CanopenTransport, fast: bool, timeout: float = 2.0) -> CanopenObjectChannel:
    client = transport.sdo_client
    assert client is not None
    return CanopenObjectChannel(client.node, budget=Budget(timeout, 0), where=client.where,
                                reader=client.reader if fast else None)


class _Threads:
    """A listener that notes which thread handed each SDO answer on (the caller's: the caller read it)."""

    def __init__(self, can_id: int) -> None:
        self.can_id = can_id
        self.readers: list[str] = []

    def __call__(self, msg: Any) -> None:
        if msg.arbitration_id == self.can_id:
            self.readers.append(threading.current_thread().name)


def test_answers_and_errors_are_those_of_the_handed_over_path(channel_name: str) -> None:
    transport = _transport(channel_name)
    try:
        assert transport.network is not None
        seen = _Threads(0x580 + NODE)
        transport.sdo_client.reader.add_listener(seen)
        fast = _channel(transport, fast=True)
        read_here = [_outcome(fast, index, sub) for index, sub in REQUESTS]
        fast.detach()
        assert threading.current_thread().name in seen.readers  # the fast path ran (the first call may be handed over)
        seen.readers.clear()
        general = _channel(transport, fast=False)
        handed_over = [_outcome(general, index, sub) for index, sub in REQUESTS]
        general.detach()
        assert seen.readers and threading.current_thread().name not in seen.readers  # the receive thread's
    finally:
        transport.close()
    assert read_here == handed_over
    kinds = [kind for kind, _ in read_here]
    assert kinds[:5] == ["value"] * 5 and kinds[5:] == ["SdoAborted", "SdoAborted"]


def test_silence_is_the_same_no_answer(channel_name: str) -> None:
    transport = _transport(channel_name, node=9, timeout=0.3)  # nobody is node 9
    try:
        fast = _channel(transport, fast=True, timeout=0.3)
        here = _outcome(fast, 0x1018, 1)
        fast.detach()
        general = _channel(transport, fast=False, timeout=0.3)
        handed = _outcome(general, 0x1018, 1)
        general.detach()
    finally:
        transport.close()
    assert here == handed
    assert here[0] == "NoAnswer" and "no answer from CANopen node 9" in str(here[1])


class _ScriptedNode:
    """Node 5 on its own bus: every SDO upload request gets an EMCY, a heartbeat (pre-operational) and then the
    expedited answer 0x12345678 -- the emergency and the heartbeat arrive while the client waits for the answer."""

    def __init__(self, name: str, node: int = 5) -> None:
        self.node = node
        self.bus = can.Bus(interface="virtual", channel=name)
        self.stopped = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stopped.is_set():
            msg = self.bus.recv(0.05)
            if msg is None or msg.arbitration_id != 0x600 + self.node or msg.data[0] != 0x40:
                continue
            index, sub = msg.data[1:3], msg.data[3]
            self.emcy(0x8110)
            self.bus.send(can.Message(arbitration_id=0x700 + self.node, data=b"\x7f", is_extended_id=False))
            self.bus.send(can.Message(arbitration_id=0x580 + self.node, is_extended_id=False,
                                      data=bytes([0x43, *index, sub]) + (0x12345678).to_bytes(4, "little")))

    def emcy(self, code: int) -> None:
        self.bus.send(can.Message(arbitration_id=0x80 + self.node, is_extended_id=False,
                                  data=code.to_bytes(2, "little") + b"\x11\x00\x00\x00\x00\x00"))

    def close(self) -> None:
        self.stopped.set()
        self.thread.join(2)
        self.bus.shutdown()


@pytest.fixture
def scripted() -> Iterator[tuple[str, _ScriptedNode]]:
    name = f"akd-{uuid.uuid4().hex[:10]}"
    node = _ScriptedNode(name)
    try:
        yield name, node
    finally:
        node.close()


@pytest.mark.parametrize("fast", [True, False], ids=["read-here", "handed-over"])
def test_emergency_and_heartbeat_during_an_upload_reach_their_listeners(
        scripted: tuple[str, _ScriptedNode], fast: bool) -> None:
    name, node = scripted
    transport = _transport(name, node=node.node)
    try:
        assert transport.sdo_client is not None
        seen = _Threads(0x580 + node.node)
        transport.sdo_client.reader.add_listener(seen)
        transport._watch(node.node)  # the heartbeat consumer listens from now on
        channel = _channel(transport, fast=fast)
        read_here = []
        for _ in range(5):  # the first call may find the receive thread reading; the next ones read here
            seen.readers.clear()
            assert channel.upload(0x1018, 1) == (0x12345678).to_bytes(4, "little")
            emergencies = channel.take_emergencies()
            assert [(e.error_code, e.error_register) for e in emergencies] == [(0x8110, 0x11)]
            read_here.append(seen.readers == [threading.current_thread().name])
        assert any(read_here) is fast
        assert transport.nmt_state(node.node, timeout=1.0) == "PRE-OPERATIONAL"
        channel.detach()
    finally:
        transport.close()


def test_frames_between_calls_are_read_once_the_caller_is_done(scripted: tuple[str, _ScriptedNode]) -> None:
    """After an upload the receive thread stands aside; an emergency sent then still reaches the channel, both
    through ``wait_emergencies`` (which gives the bus back at once) and by a listener that asks nothing."""
    name, node = scripted
    transport = _transport(name, node=node.node)
    try:
        assert transport.network is not None
        came = threading.Event()
        transport.sdo_client.reader.add_listener(lambda msg: came.set() if msg.data[:2] == b"\x00\x50" else None)
        channel = _channel(transport, fast=True)
        channel.upload(0x1018, 1)
        channel.take_emergencies()
        node.emcy(0x5000)
        assert came.wait(5.0), "a frame sent between two calls never reached its listener"
        node.emcy(0x5000)
        assert [e.error_code for e in channel.wait_emergencies(5.0)][-1] == 0x5000
        channel.detach()
    finally:
        transport.close()


def test_a_call_while_the_thread_reads_takes_the_answer_it_hands_over(channel_name: str) -> None:
    transport = _transport(channel_name)
    try:
        assert transport.network is not None and transport.sdo_client is not None
        reader = transport.sdo_client.reader
        seen = _Threads(0x580 + NODE)
        transport.sdo_client.reader.add_listener(seen)
        channel = _channel(transport, fast=True)
        values = []
        for _ in range(5):
            reader.hand_back()
            wait_until(reader._turn.locked, "the receive thread reading again", timeout=5.0, poll=0.001)
            values.append(channel.upload(0x1018, 1))
        channel.detach()
    finally:
        transport.close()
    assert values == [(0x6A).to_bytes(4, "little")] * 5
    assert any(name != threading.current_thread().name for name in seen.readers)  # some answers were handed over


def _unplugged(timeout: float | None = None) -> None:
    """A bus's ``recv`` once its adapter is gone."""
    raise can.CanOperationError("adapter unplugged")


def test_wait_takes_an_answer_already_queued_without_reading() -> None:
    from akdctl.io.can_reader import BusReader

    bus = can.Bus(interface="virtual", channel=f"akd-{uuid.uuid4().hex[:10]}")
    reader = BusReader(bus, [], 0.05)
    try:
        replies: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        replies.put(b"x")
        assert reader.wait(replies, 0.0) == b"x"
        with pytest.raises(queue.Empty):
            reader.wait(replies, 0.05)
    finally:
        reader.stop(1.0)
        bus.shutdown()


@pytest.mark.parametrize("reading", ["caller", "thread"])
def test_a_read_error_is_one_comm_error_wherever_the_bus_was_read(
        reading: str, channel_name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A read that fails in the caller waiting for its answer, or in the receive thread (which then ends quietly:
    no traceback), makes the next upload one CommError that names it."""
    hooks: list[object] = []
    monkeypatch.setattr(threading, "excepthook", hooks.append)
    transport = _transport(channel_name)
    try:
        assert transport.bus is not None and transport.sdo_client is not None
        reader = transport.sdo_client.reader
        channel = _channel(transport, fast=True)
        channel.upload(0x1018, 1)

        monkeypatch.setattr(transport.bus, "recv", _unplugged)
        if reading == "thread":
            reader.hand_back()  # the thread reads now, and fails
            wait_until(lambda: reader._dead, "the receive thread to stop on the read error", timeout=5.0, poll=0.01)
        with pytest.raises(CommError) as caught:
            channel.upload(0x1018, 1)
        assert "adapter unplugged" in caught.value.message and "\n" not in caught.value.message
        channel.detach()
    finally:
        transport.close()
    assert hooks == []  # no traceback from the thread
