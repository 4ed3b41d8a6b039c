"""Where a CANopen SDO reply goes (issue 29): the channel's uploads take the node's SDO response COB-ID, canopen's
own transfers (downloads, block transfers, a client used beside the channel) still get theirs, and closing the
channel gives the COB-ID back to canopen's client. In-process on python-can's ``virtual`` interface.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator

import pytest

from akdctl.connection import Connection
from akdctl.sim.drive import SimDrive
from akdctl.sim.face_can import CanFace, parse_spec
from akdctl.transport.base import LinkOptions
from akdctl.transport.canopen_bus import CanopenTransport
from akdctl.transport.registry import parse_target
from akdctl.transport.trace import Tracer

NODE = 3


@pytest.fixture
def conn(tmp_path) -> Iterator[Connection]:  # noqa: ANN001
    channel = f"akd-{uuid.uuid4().hex[:10]}"
    face = CanFace(SimDrive("default", tmp_path), parse_spec(f"virtual:{channel}:{NODE}"))
    face.start()
    target = parse_target(f"can://virtual/{channel}/{NODE}")
    connection = Connection.over(CanopenTransport(target, LinkOptions(timeout=2.0, retries=0,
                                                                      tracer=Tracer(record=False))))
    try:
        yield connection
    finally:
        connection.close()
        face.stop()


def test_the_channel_and_canopens_own_client_share_the_reply_cob_id(conn: Connection) -> None:
    objects = conn.objects()
    sdo = objects.sdo  # type: ignore[attr-defined]
    network = sdo.network
    assert network.subscribers[sdo.tx_cobid] == [objects._on_reply]  # type: ignore[attr-defined]
    assert objects.upload(0x1018, 1) == (0x6A).to_bytes(4, "little")
    # canopen's own client beside the channel: its replies reach its queue, not the channel's
    assert sdo.upload(0x1018, 1) == (0x6A).to_bytes(4, "little")
    objects.download(0x6060, 0, b"\x01")  # a download runs on canopen's client
    assert objects.upload(0x6060, 0) == b"\x01"
    assert objects._replies.empty()  # type: ignore[attr-defined]


def test_closing_the_channel_gives_the_reply_cob_id_back(conn: Connection) -> None:
    objects = conn.objects()
    sdo = objects.sdo  # type: ignore[attr-defined]
    objects.close()
    assert sdo.network.subscribers[sdo.tx_cobid] == [sdo.on_response]
    assert sdo.upload(0x1018, 1) == (0x6A).to_bytes(4, "little")
