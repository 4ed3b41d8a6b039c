"""Issue 23.14: a mailbox that repeats the previous one's counter is a repeat, never executed twice.

Through a relay that duplicates and delays request datagrams (``ecat-udp://``), 15 of 60 ``sdo write``s were
applied twice by the simulator's ETG.8200 gateway. The gateway and the raw slave now answer a repeat with the
first one's replies and change nothing.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from akdctl.protocol import coe
from akdctl.protocol import mailbox as mbx
from akdctl.sim import face_ethercat_udp
from akdctl.sim.drive import SimDrive
from akdctl.sim.mailbox_repeat import REPEAT_WINDOW_S, MailboxRepeats
from tests.harness import LossyUdpRelay, SimServer


def _writes(directory: Path) -> int:
    drive = SimDrive("default", directory)
    try:
        with drive.transaction() as model:
            return model.writes
    finally:
        drive.close()


def test_a_duplicated_write_datagram_is_applied_once(tmp_path: Path) -> None:
    drive = SimDrive("default", tmp_path)
    handler = face_ethercat_udp.GatewayHandler({1001: drive})
    sdo = coe.encode_sdo(coe.SdoDownloadInitiate(0x6081, 0, (100).to_bytes(4, "little"), 4, True))
    write = mbx.wrap_gateway(mbx.pack(mbx.MailboxType.COE, coe.encode_coe(coe.CoeService.SDO_REQUEST, sdo), 1001, 5))
    first = handler.handle(write, ("127.0.0.1", 5000))
    again = handler.handle(write, ("127.0.0.1", 5000))
    assert again == first and len(first) == 1
    assert _writes(tmp_path) == 1 and handler.repeats.repeats == 1
    # the same bytes from another client, or a new counter, are new requests
    handler.handle(write, ("127.0.0.1", 5001))
    assert _writes(tmp_path) == 2


def test_a_repeat_is_only_recognised_within_its_window(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[bytes] = []
    repeats = MailboxRepeats()
    request = mbx.pack(mbx.MailboxType.COE, coe.upload_request(0x6041, 0), 0, 1)
    handle = lambda data: calls.append(data) or [b"reply"]
    repeats.answer("link", request, handle)
    repeats.answer("link", request, handle)
    assert len(calls) == 1
    now = time.monotonic()
    monkeypatch.setattr(time, "monotonic", lambda: now + REPEAT_WINDOW_S + 0.1)
    repeats.answer("link", request, handle)  # a new master process starting its counter at 1 again
    assert len(calls) == 2
    no_counter = mbx.pack(mbx.MailboxType.COE, coe.upload_request(0x6041, 0), 0, 0)
    repeats.answer("link", no_counter, handle)
    repeats.answer("link", no_counter, handle)
    assert len(calls) == 4  # counter 0: "no counter", every mailbox is new


@pytest.mark.slow
def test_sdo_writes_through_a_duplicating_relay_are_applied_once(akd, isolated_env: Path) -> None:
    """The real CLI through a relay that duplicates every second request and reply and delays them: the gateway
    applies each write exactly once (``DriveModel.writes`` counts what it applied)."""
    with SimServer("--ethercat-udp", "127.0.0.1:0") as server:
        base = _writes(isolated_env)
        with LossyUdpRelay(server.address, dup=0.5, delay=0.02, seed=23) as relay:
            target = f"ecat-udp://127.0.0.1:{relay.port}/1001"
            outcomes = [akd("-T", target, "sdo", "write", "0x6065", str(100 + i), timeout=60).returncode
                        for i in range(12)]
            duplicated = relay.stats["duplicated"]
        applied = _writes(isolated_env) - base
    assert duplicated > 0, relay.stats
    assert outcomes.count(0) == 12, outcomes
    assert applied == 12, f"{applied} writes applied for 12 sdo writes"
