"""akdctl's udp_multicast bus drops its own looped-back datagrams and decodes every other one as python-can does.

Two ways: with python-can's multicast socket replaced by an in-process group that loops every datagram back to
every member (as Linux does), and -- root, in a network namespace of the test's own -- over real sockets next to
python-can's own bus.
"""

from __future__ import annotations

import json
import queue
import socket
import subprocess
import sys
from typing import Any

import pytest

can = pytest.importorskip("can")
pytest.importorskip("msgpack")

from can.interfaces.udp_multicast import bus as udp_bus  # noqa: E402

from akdctl.io.udp_multicast_own import OwnFramesDropped  # noqa: E402
from tests.netns import LoopbackNetns  # noqa: E402


class _LoopedGroup:
    """Stands in for python-can's GeneralPurposeUdpMulticastBus: a datagram sent reaches every member of the group,
    the sender too (IP_MULTICAST_LOOP), with a receive timestamp."""

    members: list[_LoopedGroup] = []

    def __init__(self, group: str, port: int, hop_limit: int, max_buffer: int = 4096) -> None:
        self.ip_version = 4
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # a fresh one loops back: Linux's default
        self.inbox: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        self.clock = 100.0
        _LoopedGroup.members.append(self)

    def send(self, data: bytes, timeout: float | None = None) -> None:
        for member in _LoopedGroup.members:
            member.inbox.put(data)

    def recv(self, timeout: float | None = None) -> tuple[bytes, Any, float] | None:
        try:
            data = self.inbox.get(timeout=timeout)
        except queue.Empty:
            return None
        self.clock += 1.0
        return data, ("127.0.0.1", 43113), self.clock

    def fileno(self) -> int:
        return self._socket.fileno()

    def shutdown(self) -> None:
        self._socket.close()


@pytest.fixture
def group(monkeypatch: pytest.MonkeyPatch) -> Any:
    _LoopedGroup.members = []
    monkeypatch.setattr(udp_bus, "GeneralPurposeUdpMulticastBus", _LoopedGroup)
    buses: list[Any] = []

    def make(cls: Any) -> Any:
        bus = cls("239.74.163.9")
        buses.append(bus)
        return bus

    yield make
    for bus in buses:
        bus.shutdown()


def _fields(msg: Any) -> tuple[object, ...]:
    return (msg.arbitration_id, bytes(msg.data), msg.is_extended_id, msg.is_remote_frame, msg.dlc, msg.timestamp,
            msg.is_fd, msg.is_error_frame)


def _drain(bus: Any) -> list[tuple[object, ...]]:
    """Every frame the bus hands up until its inbox is empty (a dropped copy ends a ``recv(0)`` early, as python-can's
    own filters do), without the receive timestamp."""
    frames = []
    while True:
        msg = bus.recv(0.0)
        if msg is not None:
            frames.append(_fields(msg)[:5] + _fields(msg)[6:])
        elif bus._multicast.inbox.empty():
            return frames


def _frame(can_id: int, data: bytes) -> Any:
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=False)


def test_own_frames_are_dropped_and_others_decoded_as_python_can_does(group: Any) -> None:
    ours, plain, other = group(OwnFramesDropped), group(udp_bus.UdpMulticastBus), group(udp_bus.UdpMulticastBus)
    ours.send(_frame(0x603, b"\x40\x18\x10\x01\0\0\0\0"))
    assert _fields(plain.recv(0.1))[:2] == (0x603, b"\x40\x18\x10\x01\0\0\0\0")  # the others get it
    assert ours.recv(0.05) is None  # its own copy is gone
    other.send(_frame(0x583, b"\x43\x18\x10\x01\x6a\0\0\0"))
    mine, theirs = ours.recv(0.1), plain.recv(0.1)
    assert mine is not None and theirs is not None
    assert _fields(mine)[:5] == _fields(theirs)[:5] == (0x583, b"\x43\x18\x10\x01\x6a\0\0\0", False, False, 8)
    assert ours.recv(0.05) is None


def test_a_frame_like_one_of_ours_from_another_node_is_delivered_once(group: Any) -> None:
    ours, other = group(OwnFramesDropped), group(udp_bus.UdpMulticastBus)
    frame = b"\x40\x18\x10\x01\0\0\0\0"
    other.send(_frame(0x603, frame))  # the same bytes as ours will be (both timestamps 0)
    ours.send(_frame(0x603, frame))
    got = ours.recv(0.1)
    assert got is not None and bytes(got.data) == frame
    assert ours.recv(0.05) is None  # one frame with that content, as on a CAN bus


def test_nothing_is_dropped_when_the_group_is_not_looped_back(group: Any) -> None:
    ours = group(OwnFramesDropped)
    ours._looped = False
    ours.send(_frame(0x603, b"\x40\x18\x10\x01\0\0\0\0"))
    assert ours.recv(0.1) is not None


def test_a_send_that_fails_leaves_nothing_waiting(group: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    ours, other = group(OwnFramesDropped), group(udp_bus.UdpMulticastBus)

    def refuse(data: bytes, timeout: float | None = None) -> None:
        raise can.CanOperationError("failed to send via socket")

    monkeypatch.setattr(ours._multicast, "send", refuse)
    with pytest.raises(can.CanOperationError):
        ours.send(_frame(0x603, b"\x40\x18\x10\x01\0\0\0\0"))
    assert ours._pending == {}
    other.send(_frame(0x603, b"\x40\x18\x10\x01\0\0\0\0"))
    assert ours.recv(0.1) is not None  # another node's frame of those bytes is not taken for an echo


_REAL = r"""
import json, sys, can
from akdctl.io.udp_multicast_own import OwnFramesDropped
group = "239.74.163.77"
ours, plain = OwnFramesDropped(group, port=43177), can.Bus(interface="udp_multicast", channel=group, port=43177)
ours.send(can.Message(arbitration_id=0x603, data=b"\x40\x18\x10\x01\0\0\0\0", is_extended_id=False))
seen_by_plain = plain.recv(2.0)
own_copy = ours.recv(0.3)
plain.send(can.Message(arbitration_id=0x583, data=b"\x43\x18\x10\x01\x6a\0\0\0", is_extended_id=False))
from_plain = ours.recv(2.0)
print(json.dumps({"plain": seen_by_plain.arbitration_id, "own": own_copy is not None,
                  "ours": [from_plain.arbitration_id, from_plain.data.hex(), from_plain.timestamp > 0],
                  "looped": ours._looped}))
ours.shutdown(); plain.shutdown()
"""


@pytest.mark.root
@pytest.mark.slow
def test_real_sockets_in_a_namespace() -> None:
    with LoopbackNetns("akdo") as netns:
        done = subprocess.run(["ip", "netns", "exec", netns.name, sys.executable, "-c", _REAL], capture_output=True,
                              text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result == {"plain": 0x603, "own": False, "ours": [0x583, "431810016a000000", True], "looped": True}


@pytest.mark.root
@pytest.mark.slow
def test_trace_shows_each_request_once_over_udp_multicast() -> None:
    """The CLI's ``--trace`` over a served drive: the request goes out once and is not read back as received."""
    from tests.harness import SimServer, run_akdctl

    with LoopbackNetns("akdo") as netns, SimServer("--can", "udp_multicast:239.74.163.78:4", netns=netns.name):
        code, out, err = run_akdctl("-T", "can://udp_multicast/239.74.163.78/4", "--trace", "sdo", "read", "0x1018:1",
                                    netns=netns.name)
    assert code == 0, err
    frames = [line.split("(")[-1] for line in err.splitlines() if line.startswith("trace")]
    assert frames == ["id 0x604 SDO rx node 4)", "id 0x584 SDO tx node 4)"]
    assert "106 (Kollmorgen)" in out


def test_any_foreign_frame_decodes_as_python_can_decodes_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """Property: whatever another node sends (ids, lengths, extended, remote, error frames) comes out of akdctl's bus
    exactly as out of python-can's own, and the bus's own frames never come out."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    _LoopedGroup.members = []
    monkeypatch.setattr(udp_bus, "GeneralPurposeUdpMulticastBus", _LoopedGroup)
    ours, plain, other = (OwnFramesDropped("239.74.163.9"), udp_bus.UdpMulticastBus("239.74.163.9"),
                          udp_bus.UdpMulticastBus("239.74.163.9"))
    frames = st.builds(
        lambda extended, can_id, data, remote, error: can.Message(
            arbitration_id=can_id & (0x1FFFFFFF if extended else 0x7FF), is_extended_id=extended,
            data=b"" if remote else data, dlc=len(data), is_remote_frame=remote, is_error_frame=error and not remote),
        st.booleans(), st.integers(0, 0x1FFFFFFF), st.binary(max_size=8), st.booleans(), st.booleans())

    @settings(max_examples=150, deadline=None)
    @given(st.lists(st.tuples(st.booleans(), frames), min_size=1, max_size=6))
    def check(sends: list[tuple[bool, Any]]) -> None:
        for mine, frame in sends:
            (ours if mine else other).send(frame)
        got, expected = _drain(ours), _drain(plain)
        _drain(other)
        foreign = [f[:5] + f[6:] for f in map(_fields, (frame for mine, frame in sends if not mine))]
        # every foreign frame and none of ours (a foreign frame equal to one of ours still on its way may come out
        # where our copy would have: the same content, so compared as a multiset)
        assert sorted(got, key=repr) == sorted(foreign, key=repr)
        own = [f[:5] + f[6:] for f in map(_fields, (frame for mine, frame in sends if mine))]
        if not set(own) & set(foreign):
            assert got == foreign  # in order when nothing of ours looks like a foreign frame
        assert len(expected) == len(sends) and all(f in expected for f in got)  # as python-can's own bus decodes

    try:
        check()
    finally:
        for bus in (ours, plain, other):
            bus.shutdown()
