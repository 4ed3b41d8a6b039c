"""PDO exchange of the simulated CANopen node, driven by its own object dictionary.

The drive model owns the PDO communication (0x1400+/0x1800+) and mapping
(0x1600+/0x1A00+) objects, so whatever a client configures by SDO -- akdctl's
pdo commands or any CANopen master -- is what goes on the bus. This module
reads those objects and packs/unpacks PDO payloads bit by bit (CiA 301 7.4.7).
canopen's own PDO classes need a typed object dictionary on the node side;
the drive model already knows types and access, so packing here stays short.

COB-ID sub-index 1: bit 31 set = PDO not valid; an 11-bit id of 0 means the
predefined connection set (TPDOn 0x180 + 0x100*(n-1) + node, RPDOn 0x200 + ...).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from akdctl.sim.errors import SdoAccessError

PDO_COUNT = 4
#: Indices 0x0001..0x0007 are the CiA 301 dummy-mapping data types (padding).
DUMMY_INDICES = range(0x0001, 0x0008)


@dataclass
class PdoConfig:
    """One PDO as its communication and mapping objects describe it."""

    number: int
    cob_id: int
    transmission: int = 255
    event_ms: int = 0
    entries: list[tuple[int, int, int]] = field(default_factory=list)  # (index, subindex, bits)
    sync_count: int = 0
    last: bytes | None = None
    next_event: float = 0.0

    @property
    def size(self) -> int:
        return (sum(bits for _, _, bits in self.entries) + 7) // 8


def predefined_cob_id(index: int, subindex: int, data: bytes, node: int) -> bytes:
    """Show the predefined connection set's COB-ID where the stored PDO COB-ID is 0.

    The catalogue comes from the EtherCAT ESI, which has no COB-IDs; on CAN the
    drive reports 0x180/0x200 + 0x100*(n-1) + node, as every CiA 301 node does.
    """
    if subindex != 1 or len(data) != 4 or not (0x1400 <= index <= 0x1403 or 0x1800 <= index <= 0x1803):
        return data
    value = int.from_bytes(data, "little")
    if value & 0x7FF:
        return data
    base = 0x180 if index >= 0x1800 else 0x200
    return (value | (base + 0x100 * (index & 0x3) + node)).to_bytes(4, "little")


def _u(model: Any, index: int, sub: int, default: int = 0) -> int:
    try:
        return int.from_bytes(model.object_read(index, sub), "little")
    except SdoAccessError:
        return default


def read_configs(model: Any, node: int, transmit: bool) -> list[PdoConfig]:
    """The valid TPDOs (``transmit``) or RPDOs of the model, in PDO number order."""
    comm_base, map_base, id_base = (0x1800, 0x1A00, 0x180) if transmit else (0x1400, 0x1600, 0x200)
    configs: list[PdoConfig] = []
    for n in range(PDO_COUNT):
        try:
            cob = int.from_bytes(model.object_read(comm_base + n, 1), "little")
        except SdoAccessError:
            continue  # this PDO does not exist
        if cob & 0x80000000:
            continue
        can_id = cob & 0x7FF or id_base + 0x100 * n + node
        count = _u(model, map_base + n, 0)
        entries = []
        for sub in range(1, count + 1):
            value = _u(model, map_base + n, sub)
            entries.append((value >> 16, (value >> 8) & 0xFF, value & 0xFF))
        if not entries or sum(bits for _, _, bits in entries) > 64:
            continue
        configs.append(PdoConfig(n + 1, can_id, _u(model, comm_base + n, 2, 255),
                                 _u(model, comm_base + n, 5) if transmit else 0, entries))
    return configs


def pack(model: Any, config: PdoConfig) -> bytes:
    """Sample the mapped objects and pack them LSB first into the PDO payload."""
    value, offset = 0, 0
    for index, sub, bits in config.entries:
        if index not in DUMMY_INDICES:
            try:
                raw = int.from_bytes(model.object_read(index, sub), "little")
            except SdoAccessError:
                raw = 0
            value |= (raw & ((1 << bits) - 1)) << offset
        offset += bits
    return value.to_bytes(config.size, "little")


def unpack(model: Any, config: PdoConfig, data: bytes) -> bool:
    """Write a received RPDO into the mapped objects; False if it is too short (EMCY 0x8210)."""
    if len(data) < config.size:
        return False
    value, offset = int.from_bytes(bytes(data), "little"), 0
    for index, sub, bits in config.entries:
        if index not in DUMMY_INDICES:
            raw = (value >> offset) & ((1 << bits) - 1)
            try:
                model.object_write(index, sub, raw.to_bytes((bits + 7) // 8, "little"))
            except SdoAccessError:
                pass  # a real drive ignores a value it cannot take from a PDO
        offset += bits
    return True
