"""Fault injection shared by the simulator's EtherCAT faces.

A technician's real failures are a reply lost on the wire, a slave refusing a
whole mailbox (mailbox error reply, type 0) and an SDO abort. ``drop=N`` loses
the reply to every N-th mailbox request, ``mbxerr=N`` answers every N-th with a
mailbox error, ``abort=N`` answers every N-th SDO request with abort
0x08000000. Counting every N-th (rather than "the first N") keeps a retrying
client able to recover, which is the behaviour the tests prove.
"""

from __future__ import annotations

import struct
import threading
from dataclasses import dataclass, field

from akdctl.sim.inject_spec import parse_every_nth

KINDS = ("drop", "mbxerr", "abort")
MBX_ERR_SERVICE_NOT_SUPPORTED = 4
MBX_ERR_NO_MORE_MEMORY = 7


@dataclass
class Injector:
    """Decides, per mailbox request, which fault (if any) to inject."""

    every: dict[str, int] = field(default_factory=dict)
    _count: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock)

    @classmethod
    def parse(cls, text: str | None, option: str = "--ecat-inject") -> "Injector":
        """``drop=3,abort=5`` -> Injector; empty/None -> no faults."""
        found = parse_every_nth(text, option, {kind: "" for kind in KINDS})
        return cls({kind: n for kind, (n, _) in found.items()})

    def decide(self) -> str | None:
        """Count one request; the fault to inject into its reply, or None."""
        with self._lock:
            self._count += 1
            count = self._count
        for kind in KINDS:
            n = self.every.get(kind)
            if n and count % n == 0:
                return kind
        return None

    def describe(self) -> str:
        return ",".join(f"{k}={v}" for k, v in self.every.items()) or "none"


# CoE SDO upload request for 0x1000:00 (device type), used to warm a drive up before a face reports ready
WARMUP_REQUEST = bytes.fromhex("0a00 0000 0003 0020 4000 1000 0000 0000")


def warm_up(drive: object) -> None:
    """Answer one harmless SDO so imports and catalogue loading happen before the first real request
    (SOEM waits only 700 ms for a mailbox reply)."""
    import contextlib

    with contextlib.suppress(Exception):
        drive.handle_mailbox(WARMUP_REQUEST)  # type: ignore[attr-defined]


def mailbox_error_reply(request: bytes, code: int = MBX_ERR_SERVICE_NOT_SUPPORTED) -> bytes:
    """A type-0 mailbox error reply to ``request`` (same address, counter kept)."""
    from akdctl.protocol.mailbox import (
        Mailbox,
        MailboxErrorReply,
        decode_mailbox,
        encode_error_reply,
        encode_mailbox,
    )

    mbx = decode_mailbox(request)
    return encode_mailbox(Mailbox(0, encode_error_reply(MailboxErrorReply(code)), mbx.address,
                                  counter=mbx.counter))


def sdo_abort_reply(request: bytes, code: int | None = None) -> bytes | None:
    """An SDO abort (``code``, default general error) answering the SDO request in ``request``; None if it is no
    SDO request."""
    from akdctl.protocol.coe import ABORT_GENERAL, CoeService, SdoAbort, decode_coe, encode_coe, encode_sdo
    from akdctl.protocol.errors import CodecError
    from akdctl.protocol.mailbox import Mailbox, MailboxType, decode_mailbox, encode_mailbox

    try:
        mbx = decode_mailbox(request)
        if mbx.type != MailboxType.COE:
            return None
        service, _number, payload = decode_coe(mbx.data)
        if service != CoeService.SDO_REQUEST or len(payload) < 4:
            return None
        index, sub = struct.unpack_from("<HB", payload, 1)
        abort = encode_sdo(SdoAbort(index, sub, ABORT_GENERAL if code is None else code))
        # an abort travels as CoE service 2 (SDO request), as ETG.1000.6 has it and SOEM expects
        return encode_mailbox(Mailbox(MailboxType.COE, encode_coe(CoeService.SDO_REQUEST, abort), mbx.address,
                                      counter=mbx.counter))
    except CodecError:
        return None


def failure_reply(request: bytes) -> list[bytes]:
    """What the slave answers a mailbox it failed to carry out (its drive raised): an SDO abort (general error) for
    an SDO request, else a mailbox error; nothing when the request is not even a mailbox. Shared by the EtherCAT
    faces so the master always learns that the request failed instead of waiting for its timeout."""
    from akdctl.protocol.errors import CodecError

    try:
        return [sdo_abort_reply(request) or mailbox_error_reply(request, MBX_ERR_NO_MORE_MEMORY)]
    except CodecError:
        return []
