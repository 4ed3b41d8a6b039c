"""What the tests of the simulated PROFINET face build their datagrams from, and the socket they capture its replies
with: one copy for test_sim_faces, test_pn_face_memo and test_pn_activity_calls."""

from __future__ import annotations

import uuid

from akdctl.protocol import dcerpc, pnio

#: A PROFIdrive base-mode request reading PNU 930 (the poll the face's one pass serves)
READ_930 = bytes.fromhex("01 01 00 01 10 01 03 A2 00 00")


class CaptureSocket:
    """A stand-in for the PROFINET face's socket: what it sends is appended to ``sent`` (the face's one-pass
    replies call ``sendto`` directly, the general path through ``_raw_send``)."""

    def __init__(self, sent: list[bytes]) -> None:
        self.sent = sent

    def sendto(self, data: bytes, peer: object) -> int:
        self.sent.append(data)
        return len(data)


def call(opnum: int, blocks: bytes, sequence: int, activity: uuid.UUID, *, little: bool = False,
         ptype: int = dcerpc.PT_REQUEST, object_node: int = 1, hint: int = 0xFFFF) -> bytes:
    """One DCE/RPC CL datagram to the PNIO device interface, as the face's clients send it."""
    head = dcerpc.RpcHeader(ptype=ptype, object_uuid=pnio.object_uuid(0x100, object_node),
                            interface_uuid=pnio.DEVICE_INTERFACE, activity_uuid=activity, sequence=sequence,
                            opnum=opnum, interface_hint=hint, drep=dcerpc.DREP_LITTLE if little else dcerpc.DREP_BIG)
    return dcerpc.encode_packet(head, pnio.encode_request_args(blocks, little=little))


def connect(ar: uuid.UUID, activity: uuid.UUID, sequence: int = 1) -> bytes:
    """A Connect request for an IOSAR ``ar`` (the AR the record calls then name)."""
    block = pnio.ARBlockReq(pnio.AR_TYPE_IOSAR, ar, 1, b"\x02\0\0\0\0\x01", pnio.object_uuid(0, 0, 0),
                            pnio.DEVICE_ACCESS_PROPERTIES, 100, b"test").encode()
    return call(pnio.OP_CONNECT, block, sequence, activity)
