"""FoE (File access over EtherCAT) in the simulated AKD: the files it keeps and the transfers that move them.

Why: the AKD EtherCAT manual (4.6.3) names FoE as the way to download firmware ("must be performed using File
over EtherCAT (FoE)"), and the real drive's SII advertises FoE; a simulated drive that advertised it and then
refused it taught users the wrong thing (issue 16 item 11, docs/fidelity.md F10). The simulated drive stores a
written file and returns it on a read; it does not change its own firmware, and it accepts FoE in every state
with a mailbox (the BOOT state of a real firmware update is not simulated).

* :class:`FoeFiles` is the model component: the stored files (persisted), at most :data:`MAX_STORED` bytes in
  all (a larger write ends with "disk full").
* :class:`FoeServer` keeps one transfer's state between mailboxes (like the SDO server's segmented transfer):
  write request → ack 0, data n → ack n until a short packet; read request → data 1, ack n → data n+1.
"""

from __future__ import annotations

import base64
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

from akdctl.protocol import foe
from akdctl.sim.component import Component

if TYPE_CHECKING:
    from akdctl.sim.model import DriveModel

MAX_STORED = 256 * 1024  # the simulator keeps files in its state file: a real firmware image does not fit


class FoeRefused(Exception):
    """The drive refuses a file access with a FoE error code."""

    def __init__(self, code: int, text: str = "") -> None:
        from akdctl.catalog.texts import foe_error_text

        super().__init__(text or foe_error_text(code))
        self.code = code


class FileAccess(Protocol):
    """What :class:`FoeServer` needs from the drive model (``DriveModel`` implements it)."""

    def foe_read(self, name: str, password: int) -> bytes: ...

    def foe_write(self, name: str, password: int, data: bytes) -> None: ...


class FoeFiles(Component):
    """The files written to the simulated drive by FoE."""

    name = "foe"
    PERSISTED = ("files",)

    def __init__(self, model: "DriveModel") -> None:
        super().__init__(model)
        self.files: dict[str, bytes] = {}

    def read(self, name: str) -> bytes:
        if name not in self.files:
            raise FoeRefused(foe.ERR_NOT_FOUND, f"no file {name!r} on the drive")
        return self.files[name]

    def write(self, name: str, data: bytes) -> None:
        if not name:
            raise FoeRefused(foe.ERR_ILLEGAL, "empty file name")
        used = sum(len(v) for k, v in self.files.items() if k != name)
        if used + len(data) > MAX_STORED:
            raise FoeRefused(foe.ERR_DISK_FULL, f"the simulated drive keeps at most {MAX_STORED} bytes of files")
        self.files[name] = bytes(data)
        self.changed()

    def to_state(self) -> dict[str, Any]:
        return {"files": {name: base64.b64encode(data).decode("ascii") for name, data in sorted(self.files.items())}}

    def load_state(self, state: dict[str, Any]) -> None:
        self.files = {str(k): base64.b64decode(str(v)) for k, v in dict(state.get("files", {})).items()}


@dataclass
class _Transfer:
    name: str
    writing: bool
    packet: int = 0                 # last packet acknowledged (write) / sent (read)
    buffer: bytearray = field(default_factory=bytearray)
    data: bytes = b""               # read: the whole file
    finished: bool = False          # read: the short last packet was sent


class FoeServer:
    """The FoE side of one simulated slave: request frame in, reply frame (or None) out."""

    def __init__(self) -> None:
        self._transfer: _Transfer | None = None
        self._password = 0

    def handle(self, access: FileAccess, frame: foe.FoeFrame, max_data: int) -> foe.FoeFrame | None:
        """The reply to ``frame``; ``max_data`` is the data a packet carries (mailbox minus both headers)."""
        try:
            return self._handle(access, frame, max_data)
        except FoeRefused as exc:
            self._transfer = None
            return foe.error(exc.code, str(exc))

    def _handle(self, access: FileAccess, frame: foe.FoeFrame, max_data: int) -> foe.FoeFrame | None:
        op, t = frame.opcode, self._transfer
        if op == foe.FoeOpcode.WRITE:
            self._transfer = _Transfer(frame.name, writing=True)
            self._password = frame.value
            return foe.ack(0)
        if op == foe.FoeOpcode.READ:
            data = access.foe_read(frame.name, frame.value)
            self._transfer = _Transfer(frame.name, writing=False, data=data)
            return self._next_packet(self._transfer, max_data)
        if op == foe.FoeOpcode.DATA and t is not None and t.writing:
            if frame.value != t.packet + 1:
                raise FoeRefused(foe.ERR_PACKET_NUMBER, f"expected packet {t.packet + 1}, got {frame.value}")
            if len(frame.data) > max_data:
                raise FoeRefused(foe.ERR_ILLEGAL, f"packet of {len(frame.data)} bytes, at most {max_data}")
            t.buffer += frame.data
            if len(t.buffer) > MAX_STORED:
                raise FoeRefused(foe.ERR_DISK_FULL, f"the simulated drive keeps at most {MAX_STORED} bytes of files")
            t.packet = frame.value
            if len(frame.data) < max_data:  # the short packet ends the file
                access.foe_write(t.name, self._password, bytes(t.buffer))
                self._transfer = None
            return foe.ack(frame.value)
        if op == foe.FoeOpcode.ACK and t is not None and not t.writing:
            if frame.value != t.packet:
                raise FoeRefused(foe.ERR_PACKET_NUMBER, f"expected the ack of packet {t.packet}, got {frame.value}")
            if t.finished:
                self._transfer = None
                return None
            return self._next_packet(t, max_data)
        if op == foe.FoeOpcode.ERROR:  # the client gives up: forget the transfer, nothing to answer
            self._transfer = None
            return None
        raise FoeRefused(foe.ERR_ILLEGAL, f"FoE opcode {op} outside a transfer that expects it")

    @staticmethod
    def _next_packet(t: _Transfer, max_data: int) -> foe.FoeFrame:
        start = t.packet * max_data
        chunk = t.data[start:start + max_data]
        t.packet += 1
        t.finished = len(chunk) < max_data
        return foe.data_packet(t.packet, chunk)
