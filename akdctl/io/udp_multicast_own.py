"""python-can's ``udp_multicast`` bus without its own frames coming back.

Why: a CAN controller does not receive the frames it sends (SocketCAN's ``CAN_RAW_RECV_OWN_MSGS`` is off by default,
and python-can's ``udp_multicast`` bus documents ``receive_own_messages=False`` as its only mode), but on Linux every
datagram the bus sends to its multicast group is looped back to its own socket (``IP_MULTICAST_LOOP`` is on, so that
other processes on the host receive it), and python-can hands it up as a received frame: each request a client sends
was decoded again and handed to every listener as if another node had sent it (``--trace`` showed it a second time,
as rx). :class:`OwnFramesDropped` remembers the bytes of each datagram it sent until that datagram comes back and
drops the copy before decoding it; every other datagram is decoded exactly as python-can does.

A datagram another node sends that is byte for byte one of ours still waiting to come back (the same frame with the
same timestamp field) is taken for the copy and the copy is then delivered in its place: listeners see one frame
with that content, as on a CAN bus, where two identical frames sent at the same moment are one frame. When the
group is not looped back to the socket (``IP_MULTICAST_LOOP`` off) nothing is dropped.
"""

from __future__ import annotations

import socket
from typing import Any

import can
from can.interfaces.udp_multicast import UdpMulticastBus
from can.interfaces.udp_multicast.utils import pack_message, unpack_message

#: Sent datagrams remembered at most while they wait to come back; more means they do not come back (forget them).
PENDING_MAX = 64
_CAN_FD = can.CanProtocol.CAN_FD


class OwnFramesDropped(UdpMulticastBus):  # type: ignore[misc]
    """``UdpMulticastBus`` whose own datagrams, looped back by the kernel, are dropped before decoding."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._pending: dict[bytes, int] = {}
        self._looped = _loops_back(self._multicast)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self._can_protocol is not _CAN_FD and msg.is_fd:
            raise can.CanOperationError("cannot send FD message over bus with CAN FD disabled")
        data = pack_message(msg)
        if self._looped:
            pending = self._pending
            if len(pending) >= PENDING_MAX:
                pending.clear()
            pending[data] = pending.get(data, 0) + 1
        try:
            self._multicast.send(data, timeout)
        except BaseException:
            self._forget(data)
            raise

    def _forget(self, data: bytes) -> bool:
        """True if ``data`` was a sent datagram waiting to come back (it no longer waits)."""
        pending = self._pending
        count = pending.get(data)
        if count is None:
            return False
        if count > 1:
            pending[data] = count - 1
        else:
            del pending[data]
        return True

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        result = self._multicast.recv(timeout)
        if not result:
            return None, False
        data, _, timestamp = result
        if self._pending and self._forget(data):
            return None, False  # our own frame, looped back
        try:
            message = unpack_message(data, replace={"timestamp": timestamp}, check=True)
        except Exception as exception:
            raise can.CanOperationError("could not unpack received message") from exception
        if self._can_protocol is not _CAN_FD and message.is_fd:
            return None, False
        return message, False


def _loops_back(multicast: Any) -> bool:
    """Whether the kernel loops the group's datagrams back to this bus's socket (Linux's default)."""
    try:
        sock: socket.socket = multicast._socket
        if multicast.ip_version == 4:
            return bool(sock.getsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP))
        return bool(sock.getsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_LOOP))
    except (AttributeError, OSError):
        return False
