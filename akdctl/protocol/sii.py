"""SII EEPROM image codec (ETG.1000.6 / ETG.2010): what an EtherCAT master reads
from a slave before it can talk to it.

The fixed area (words 0x00-0x3F) carries the ESC configuration, identity and
mailbox layout; categories follow from word 0x40. We parse a real AKD dump and
build an image from the AKD facts for the simulated slave, with the same codec,
so the master and the simulator cannot disagree. Only :class:`CodecError` escapes.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, replace

from akdctl.protocol.errors import CodecError

CAT_NOP = 0
CAT_STRINGS = 10
CAT_DATATYPES = 20
CAT_GENERAL = 30
CAT_FMMU = 40
CAT_SYNCM = 41
CAT_FMMUX = 42
CAT_SYNCUNIT = 43
CAT_TXPDO = 50
CAT_RXPDO = 51
CAT_DC = 60
CAT_END = 0xFFFF
CAT_NAMES = {CAT_NOP: "NOP", CAT_STRINGS: "strings", CAT_DATATYPES: "data types", CAT_GENERAL: "general",
             CAT_FMMU: "FMMU", CAT_SYNCM: "sync managers", CAT_FMMUX: "FMMU extension", CAT_SYNCUNIT: "sync units",
             CAT_TXPDO: "TxPDO", CAT_RXPDO: "RxPDO", CAT_DC: "distributed clocks",
             0x0800: "AKD order string", 0x0801: "AKD firmware version"}

MAILBOX_PROTOCOLS = {0x01: "AoE", 0x02: "EoE", 0x04: "CoE", 0x08: "FoE", 0x10: "SoE", 0x20: "VoE"}
SM_TYPES = {0: "unused", 1: "mailbox out", 2: "mailbox in", 3: "process data out", 4: "process data in"}
FMMU_USAGE = {0: "unused", 1: "outputs", 2: "inputs", 3: "sync manager status"}

FIXED_WORDS = 0x40  # categories start at word 0x40 (byte 0x80)


def crc8(data: bytes) -> int:
    """The SII config-area checksum: CRC-8, polynomial x^8+x^2+x+1 (0x07), init 0xFF."""
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


@dataclass(frozen=True)
class SiiGeneral:
    """Category 30 (32 bytes): names as string indices plus capability bytes."""

    group_idx: int = 0
    image_idx: int = 0
    order_idx: int = 0
    name_idx: int = 0
    coe_details: int = 0
    foe_details: int = 0
    eoe_details: int = 0
    soe_channels: int = 0
    ds402_channels: int = 0
    sysman_class: int = 0
    flags: int = 0
    ebus_current: int = 0
    physical_port: int = 0
    physical_memory_address: int = 0
    reserved1: int = 0
    group_idx2: int = 0

    def encode(self) -> bytes:
        try:
            return self._encode()
        except struct.error as exc:
            raise CodecError(f"general category field out of range: {exc}") from None

    def _encode(self) -> bytes:
        return struct.pack("<BBBBBBBBBBBBhBBHH12x", self.group_idx, self.image_idx, self.order_idx,
                           self.name_idx, self.reserved1, self.coe_details, self.foe_details, self.eoe_details,
                           self.soe_channels, self.ds402_channels, self.sysman_class, self.flags,
                           self.ebus_current, self.group_idx2, 0, self.physical_port,
                           self.physical_memory_address)

    @classmethod
    def decode(cls, data: bytes) -> "SiiGeneral":
        if len(data) < 18:
            raise CodecError(f"general category of {len(data)} bytes is shorter than 18")
        f = struct.unpack_from("<BBBBBBBBBBBBhBBHH", data.ljust(20, b"\0"))
        return cls(f[0], f[1], f[2], f[3], f[5], f[6], f[7], f[8], f[9], f[10], f[11], f[12], f[15], f[16], f[4], f[13])


@dataclass(frozen=True)
class SiiSyncManager:
    """Category 41 entry (8 bytes)."""

    start: int
    length: int
    control: int
    enable: int
    sm_type: int
    status: int = 0

    def encode(self) -> bytes:
        return struct.pack("<HHBBBB", self.start, self.length, self.control, self.status, self.enable,
                           self.sm_type)

    @classmethod
    def decode(cls, data: bytes) -> "SiiSyncManager":
        start, length, control, status, enable, sm_type = struct.unpack_from("<HHBBBB", data)
        return cls(start, length, control, enable, sm_type, status)

    @property
    def type_name(self) -> str:
        return SM_TYPES.get(self.sm_type, f"type {self.sm_type}")


@dataclass(frozen=True)
class SiiPdoEntry:
    index: int
    subindex: int
    name_idx: int
    data_type: int
    bit_length: int
    flags: int = 0

    def encode(self) -> bytes:
        return struct.pack("<HBBBBH", self.index, self.subindex, self.name_idx, self.data_type,
                           self.bit_length, self.flags)


@dataclass(frozen=True)
class SiiPdo:
    """Category 50/51 PDO: 8-byte header then 8 bytes per entry."""

    index: int
    sm: int
    name_idx: int
    entries: tuple[SiiPdoEntry, ...] = ()
    dc_sync: int = 0
    flags: int = 0

    def encode(self) -> bytes:
        head = struct.pack("<HBBBBH", self.index, len(self.entries), self.sm, self.dc_sync, self.name_idx,
                           self.flags)
        return head + b"".join(e.encode() for e in self.entries)


@dataclass
class SiiImage:
    """A decoded SII EEPROM. Unknown categories (the AKD's vendor 0x0800/0x0801,
    DC, sync units) are kept raw in ``categories`` so an image rebuilds byte-exact."""

    pdi_control: int = 0
    pdi_config: int = 0
    sync_impulse_len: int = 0
    pdi_config2: int = 0
    station_alias: int = 0
    checksum: int = 0
    vendor_id: int = 0
    product_code: int = 0
    revision: int = 0
    serial: int = 0
    boot_rx_offset: int = 0
    boot_rx_size: int = 0
    boot_tx_offset: int = 0
    boot_tx_size: int = 0
    std_rx_offset: int = 0
    std_rx_size: int = 0
    std_tx_offset: int = 0
    std_tx_size: int = 0
    mailbox_protocols: int = 0
    size_kbit_minus1: int = 0
    version: int = 1
    categories: list[tuple[int, bytes]] = field(default_factory=list)
    eeprom_bytes: int = 0  # total size the image was parsed from / is padded to (0 = minimum)

    # -- derived views of the categories -----------------------------------------------------------------
    def category(self, cat_type: int) -> bytes | None:
        for ctype, data in self.categories:
            if ctype == cat_type:
                return data
        return None

    @property
    def strings(self) -> list[str]:
        """String table; index 0 is the empty string (string indices count from 1)."""
        data = self.category(CAT_STRINGS)
        return [""] + decode_strings(data) if data is not None else [""]

    def string(self, idx: int) -> str:
        table = self.strings
        return table[idx] if 0 <= idx < len(table) else ""

    @property
    def general(self) -> SiiGeneral | None:
        data = self.category(CAT_GENERAL)
        return SiiGeneral.decode(data) if data is not None else None

    @property
    def fmmus(self) -> list[int]:
        return list(self.category(CAT_FMMU) or b"")

    @property
    def sync_managers(self) -> list[SiiSyncManager]:
        data = self.category(CAT_SYNCM) or b""
        return [SiiSyncManager.decode(data[i : i + 8]) for i in range(0, len(data) - 7, 8)]

    @property
    def tx_pdos(self) -> list[SiiPdo]:
        return decode_pdos(self.category(CAT_TXPDO) or b"")

    @property
    def rx_pdos(self) -> list[SiiPdo]:
        return decode_pdos(self.category(CAT_RXPDO) or b"")

    @property
    def protocol_names(self) -> list[str]:
        return [name for bit, name in MAILBOX_PROTOCOLS.items() if self.mailbox_protocols & bit]

    @property
    def name(self) -> str:
        gen = self.general
        return self.string(gen.name_idx) if gen else ""

    @property
    def order(self) -> str:
        """Order code: the AKD's vendor category 0x0800 if present, else the general category's."""
        raw = self.category(0x0800)
        if raw is not None:
            return raw.rstrip(b"\0").decode("latin-1")
        gen = self.general
        return self.string(gen.order_idx) if gen else ""

    @property
    def firmware(self) -> str:
        raw = self.category(0x0801)
        return raw.rstrip(b"\0").decode("latin-1") if raw is not None else ""

    @property
    def is_akd(self) -> bool:
        return self.vendor_id == 0x6A and self.product_code == 0x00414B44

    def to_json(self) -> dict[str, object]:
        gen = self.general
        return {
            "vendor_id": self.vendor_id,
            "product_code": self.product_code,
            "revision": self.revision,
            "serial": self.serial,
            "station_alias": self.station_alias,
            "name": self.name,
            "order": self.order,
            "firmware": self.firmware,
            "akd": self.is_akd,
            "mailbox": {
                "rx_offset": self.std_rx_offset, "rx_size": self.std_rx_size,
                "tx_offset": self.std_tx_offset, "tx_size": self.std_tx_size,
                "boot_rx_offset": self.boot_rx_offset, "boot_rx_size": self.boot_rx_size,
                "boot_tx_offset": self.boot_tx_offset, "boot_tx_size": self.boot_tx_size,
                "protocols": self.protocol_names,
            },
            "general": None if gen is None else {
                "group": self.string(gen.group_idx), "image": self.string(gen.image_idx),
                "order": self.string(gen.order_idx), "name": self.string(gen.name_idx),
                "coe_details": gen.coe_details, "foe_details": gen.foe_details, "eoe_details": gen.eoe_details,
            },
            "fmmu": [FMMU_USAGE.get(u, f"usage {u}") for u in self.fmmus],
            "sync_managers": [
                {"start": s.start, "length": s.length, "control": s.control, "enable": s.enable,
                 "type": s.type_name} for s in self.sync_managers
            ],
            "tx_pdos": [_pdo_json(self, p) for p in self.tx_pdos],
            "rx_pdos": [_pdo_json(self, p) for p in self.rx_pdos],
            "categories": [{"type": t, "name": CAT_NAMES.get(t, f"0x{t:04X}"), "bytes": len(d)}
                           for t, d in self.categories],
        }


def _pdo_json(image: SiiImage, pdo: SiiPdo) -> dict[str, object]:
    return {
        "index": pdo.index, "sm": pdo.sm, "name": image.string(pdo.name_idx), "flags": pdo.flags,
        "entries": [{"index": e.index, "subindex": e.subindex, "bits": e.bit_length, "data_type": e.data_type,
                     "name": image.string(e.name_idx)} for e in pdo.entries],
    }


def decode_strings(data: bytes) -> list[str]:
    """Category 10: count u8, then count × (len u8, bytes)."""
    if not data:
        return []
    count, pos, out = data[0], 1, []
    for i in range(count):
        if pos >= len(data):
            raise CodecError(f"string table truncated at string {i + 1} of {count}")
        n = data[pos]
        if pos + 1 + n > len(data):
            raise CodecError(f"string {i + 1} of {n} bytes runs past the category")
        out.append(data[pos + 1 : pos + 1 + n].decode("latin-1"))
        pos += 1 + n
    return out


def encode_strings(strings: list[str]) -> bytes:
    if len(strings) > 255:
        raise CodecError("at most 255 SII strings")
    out = bytearray([len(strings)])
    for text in strings:
        raw = text.encode("latin-1", errors="replace")
        if len(raw) > 255:
            raise CodecError(f"SII string of {len(raw)} bytes is longer than 255")
        out += bytes([len(raw)]) + raw
    return bytes(out)


def decode_pdos(data: bytes) -> list[SiiPdo]:
    pdos, pos = [], 0
    while pos + 8 <= len(data):
        index, count, sm, dc, name_idx, flags = struct.unpack_from("<HBBBBH", data, pos)
        pos += 8
        if pos + 8 * count > len(data):
            raise CodecError(f"PDO 0x{index:04X} announces {count} entries beyond its category")
        entries = tuple(SiiPdoEntry(*struct.unpack_from("<HBBBBH", data, pos + 8 * i)) for i in range(count))
        pos += 8 * count
        pdos.append(SiiPdo(index, sm, name_idx, entries, dc, flags))
    return pdos


#: Byte offset of the standard mailbox words (0x18-0x1B: receive offset/size, send offset/size) in the SII.
MAILBOX_LAYOUT_OFFSET = 0x30
_MAILBOX_LAYOUT = struct.Struct("<4H")


def decode_mailbox_layout(data: bytes, offset: int = 0) -> tuple[int, int, int, int]:
    """(receive offset, receive size, send offset, send size): the standard mailbox the SII declares,
    from the 8 bytes at SII byte :data:`MAILBOX_LAYOUT_OFFSET` (``data`` holds them at ``offset``)."""
    if len(data) < offset + 8:
        raise CodecError(f"mailbox layout needs 8 SII bytes, got {len(data) - offset}")
    return _MAILBOX_LAYOUT.unpack_from(data, offset)  # type: ignore[return-value]


def parse_sii(data: bytes) -> SiiImage:
    """Decode an SII EEPROM image (at least the 128-byte fixed area)."""
    data = bytes(data)
    if len(data) < FIXED_WORDS * 2:
        raise CodecError(f"SII image of {len(data)} bytes is shorter than the 128-byte fixed area")
    w = struct.unpack_from("<8H", data, 0)
    vendor, product, revision, serial = struct.unpack_from("<4I", data, 0x10)
    boot = struct.unpack_from("<4H", data, 0x28)
    std = decode_mailbox_layout(data, MAILBOX_LAYOUT_OFFSET)
    (protocols,) = struct.unpack_from("<H", data, 0x38)
    size, version = struct.unpack_from("<HH", data, 0x7C)
    categories: list[tuple[int, bytes]] = []
    pos = FIXED_WORDS * 2
    while True:
        if pos + 2 > len(data):
            break  # image ends without an end marker: accept what was there
        (ctype,) = struct.unpack_from("<H", data, pos)
        if ctype == CAT_END:
            break
        if pos + 4 > len(data):
            raise CodecError(f"category header at byte 0x{pos:X} truncated")
        (words,) = struct.unpack_from("<H", data, pos + 2)
        body = data[pos + 4 : pos + 4 + 2 * words]
        if len(body) != 2 * words:
            raise CodecError(f"category {ctype} at byte 0x{pos:X} announces {2 * words} bytes beyond the image")
        categories.append((ctype, body))
        pos += 4 + 2 * words
    image = SiiImage(w[0], w[1], w[2], w[3], w[4], w[7] & 0xFF, vendor, product, revision, serial,
                     boot[0], boot[1], boot[2], boot[3], std[0], std[1], std[2], std[3], protocols, size, version,
                     categories, len(data))
    # validate the derived views once so a malformed category fails here, not later in a renderer
    _ = image.strings, image.general, image.sync_managers, image.tx_pdos, image.rx_pdos
    return image


def build_sii(image: SiiImage, fix_checksum: bool = True) -> bytes:
    """Encode an image; the config-area checksum is recomputed unless told not to."""
    try:
        head = struct.pack("<7H", image.pdi_control, image.pdi_config, image.sync_impulse_len, image.pdi_config2,
                           image.station_alias, 0, 0)
        checksum = crc8(head) if fix_checksum else image.checksum
        fixed = bytearray(FIXED_WORDS * 2)
        fixed[0:14] = head
        fixed[14:16] = struct.pack("<BB", checksum, 0)
        struct.pack_into("<4I", fixed, 0x10, image.vendor_id, image.product_code, image.revision, image.serial)
        struct.pack_into("<4H", fixed, 0x28, image.boot_rx_offset, image.boot_rx_size, image.boot_tx_offset,
                         image.boot_tx_size)
        struct.pack_into("<4H", fixed, 0x30, image.std_rx_offset, image.std_rx_size, image.std_tx_offset,
                         image.std_tx_size)
        struct.pack_into("<H", fixed, 0x38, image.mailbox_protocols)
        struct.pack_into("<HH", fixed, 0x7C, image.size_kbit_minus1, image.version)
        out = bytearray(fixed)
        for ctype, body in image.categories:
            if len(body) % 2:
                body = body + b"\0"
            out += struct.pack("<HH", ctype, len(body) // 2) + body
        out += struct.pack("<H", CAT_END)
    except struct.error as exc:
        raise CodecError(f"SII field out of range: {exc}") from None
    if image.eeprom_bytes > len(out):
        out += b"\xff" * (image.eeprom_bytes - len(out))
    return bytes(out)


class _Strings:
    """Builds a string table while handing out 1-based indices."""

    def __init__(self) -> None:
        self.items: list[str] = []

    def __call__(self, text: str) -> int:
        if not text:
            return 0
        if text not in self.items:
            self.items.append(text)
        return self.items.index(text) + 1


# The AKD's fixed PDOs as its SII lists them (SPEC-NOTES 19; akd_esi_notes): (index, sm, [(obj, sub, bits, dt, name)])
_U16, _I16, _I32, _U32 = 0x06, 0x03, 0x04, 0x07
_E = {
    "sw": (0x6041, 0, 16, _U16, "Statusword"), "cw": (0x6040, 0, 16, _U16, "Controlword"),
    "pint": (0x6063, 0, 32, _I32, "Position actual internal value"),
    "fb2": (0x2050, 0, 32, _I32, "Second position feedback"), "vel": (0x606C, 0, 32, _I32, "Velocity actual value"),
    "din": (0x60FD, 0, 32, _U32, "Digital inputs"), "ferr": (0x60F4, 0, 32, _I32, "Following error actual value"),
    "l1p": (0x20A0, 0, 32, _I32, "Latch 1p"), "l1n": (0x20A1, 0, 32, _I32, "Latch 1n"),
    "l1pn": (0x20A6, 0, 32, _I32, "Latch 1 pn"), "l2pn": (0x20A7, 0, 32, _I32, "Latch 2 pn"),
    "tq": (0x6077, 0, 16, _I16, "Torque actual value"), "lsw": (0x20A5, 0, 16, _U16, "Latch statusword"),
    "ain": (0x3470, 4, 16, _I16, "AIN.VALUE"), "pact": (0x6064, 0, 32, _I32, "Position actual value"),
    "sp": (0x60C1, 1, 32, _I32, "1st set-point"), "tv": (0x60FF, 0, 32, _I32, "Target velocity"),
    "lcw": (0x20A4, 0, 16, _U16, "Latch controlword"), "toff": (0x60B2, 0, 16, _I16, "Torque offset"),
    "pout": (0x60FE, 1, 32, _U32, "Physical outputs"), "maxtq": (0x6072, 0, 16, _U16, "Max torque"),
    "clr": (0x20B8, 0, 16, _U16, "ClearDigInputChangedBit"), "tpos": (0x607A, 0, 32, _I32, "Target position"),
    "aout": (0x3470, 3, 16, _I16, "AOUT.VALUE write"),
}
_TX20 = ["pint", "fb2", "vel", "din", "ferr", "l1p", "sw", "tq", "lsw", "ain"]
AKD_TX_PDOS: list[tuple[int, int, list[str]]] = [
    (0x1A00, 255, ["sw"]), (0x1A01, 255, []), (0x1A02, 255, []), (0x1A03, 255, []),
    (0x1B01, 3, ["pint", "sw"]), (0x1B20, 255, _TX20), (0x1B21, 255, ["pint", "sw"]),
    (0x1B22, 255, [("l1n" if k == "l1p" else k) for k in _TX20]),
    (0x1B23, 255, [("l1pn" if k == "l1p" else k) for k in _TX20]),
    (0x1B24, 255, ["pact", "sw"]),
    (0x1B25, 255, ["pint", "fb2", "l2pn", "din", "ferr", "l1pn", "sw", "tq", "lsw", "ain"]),
    (0x1B26, 255, ["sw", "pact", "tq", "din", "ain", "ferr"]),
]
AKD_RX_PDOS: list[tuple[int, int, list[str]]] = [
    (0x1600, 255, ["cw"]), (0x1601, 255, []), (0x1602, 255, []), (0x1603, 255, []),
    (0x1701, 2, ["sp", "cw"]), (0x1702, 255, ["tv", "cw"]),
    (0x1720, 255, ["cw", "sp", "lcw", "toff", "pout"]), (0x1721, 255, ["sp", "cw", "toff"]),
    (0x1722, 255, ["cw", "sp", "lcw", "toff", "pout", "maxtq"]),
    (0x1723, 255, ["cw", "sp", "lcw", "toff", "pout", "clr"]),
    (0x1724, 255, ["tpos", "cw", "toff"]),
    (0x1725, 255, ["cw", "tpos", "pout", "toff", "aout", "maxtq"]),
]

AKD_VENDOR_ID = 0x0000006A
AKD_PRODUCT_CODE = 0x00414B44


def akd_sii_image(
    *,
    serial: int = 2575499411,
    revision: int = 0x00000002,
    order: str = "AKD-P00606-NBCC-E000",
    firmware: str = "01-20-00-003",
    mailbox_size: int = 1024,
    station_alias: int = 0,
) -> SiiImage:
    """An SII image with the AKD facts (ESI + the real drive's dump): identity,
    mailboxes SM0 0x1800 / SM1 0x1C00, CoE+FoE+EoE, the fixed PDOs, 2048 bytes."""
    s = _Strings()
    for text in ("AKD", "Drive", "Drives", "AKD EtherCAT Drive (CoE)", "DRIVE", "DcSync", "DcOff"):
        s(text)
    tx = [_pdo(s, idx, sm, "Inputs", keys) for idx, sm, keys in AKD_TX_PDOS]
    rx = [_pdo(s, idx, sm, "Outputs", keys) for idx, sm, keys in AKD_RX_PDOS]
    general = SiiGeneral(group_idx=s("Drive"), image_idx=s("DRIVE"), order_idx=s("AKD"),
                         name_idx=s("AKD EtherCAT Drive (CoE)"), coe_details=0x0D, foe_details=0x01,
                         eoe_details=0x03, ds402_channels=1, flags=0x05, physical_port=0x0011, reserved1=1,
                         group_idx2=s("Drives"))
    sms = [SiiSyncManager(0x1800, mailbox_size, 0x26, 0x01, 1), SiiSyncManager(0x1C00, mailbox_size, 0x22, 0x01, 2),
           SiiSyncManager(0x1100, 0, 0x24, 0x01, 3), SiiSyncManager(0x1140, 0, 0x20, 0x01, 4)]
    categories = [
        (0x0800, _padded(order.encode("latin-1"))),
        (0x0801, _padded(firmware.encode("latin-1"))),
        (CAT_STRINGS, _padded(encode_strings(s.items))),
        (CAT_GENERAL, general.encode()),
        (CAT_FMMU, bytes([1, 2, 3, 0xFF])),
        (CAT_SYNCM, b"".join(sm.encode() for sm in sms)),
        (CAT_SYNCUNIT, bytes([0xF0, 0xFF])),
        (CAT_TXPDO, b"".join(p.encode() for p in tx)),
        (CAT_RXPDO, b"".join(p.encode() for p in rx)),
        (CAT_DC, _dc_category(s("DcSync"), s("DcOff"))),
    ]
    return SiiImage(pdi_control=0x0009, pdi_config=0x0800, station_alias=station_alias,
                    vendor_id=AKD_VENDOR_ID, product_code=AKD_PRODUCT_CODE, revision=revision, serial=serial,
                    boot_rx_offset=0x1800, boot_rx_size=mailbox_size, boot_tx_offset=0x1C00, boot_tx_size=mailbox_size,
                    std_rx_offset=0x1800, std_rx_size=mailbox_size, std_tx_offset=0x1C00, std_tx_size=mailbox_size,
                    mailbox_protocols=0x000E, size_kbit_minus1=0x000F, version=1, categories=categories,
                    eeprom_bytes=2048)


def _pdo(s: _Strings, index: int, sm: int, name: str, keys: list[str]) -> SiiPdo:
    name_idx = s(name)
    entries = tuple(SiiPdoEntry(obj, sub, s(text), dt, bits) for obj, sub, bits, dt, text in (_E[k] for k in keys))
    return SiiPdo(index, sm, name_idx, entries, 0, 0x0010 if (index & 0xFF00) in (0x1700, 0x1B00) else 0)  # fixed PDOs


def _dc_category(sync_name: int, off_name: int) -> bytes:
    """Category 60: one 24-byte entry per ESI DC OpMode (DcSync AssignActivate 0x0300, DcOff 0x0000)."""

    def entry(name_idx: int, assign: int) -> bytes:
        # cycle time sync0 u32, shift sync0 u32, shift sync1 u32, sync1 cycle factor i16, assign activate u16,
        # sync0 cycle factor i16, name idx u8, description idx u8, reserved 4
        return struct.pack("<IIIhHhBB4x", 0, 0, 0, 0, assign, 1, name_idx, 0)

    return entry(sync_name, 0x0300) + entry(off_name, 0x0000)


def _padded(raw: bytes) -> bytes:
    return raw + b"\0" if len(raw) % 2 else raw


def with_serial(image: SiiImage, serial: int) -> SiiImage:
    return replace(image, serial=serial)


# ---------------------------------------------------------------------- Intel HEX (ecat sii read/write)
# Why: SII images travel as raw binary (IgH sii_read/sii_write, SOEM eepromtool -r/-w) or Intel HEX (SOEM
# eepromtool -ri/-wi, vendor EEPROM tools). Record types 00 (data), 01 (end), 02/04 (segment/linear base).

def encode_ihex(data: bytes, width: int = 16) -> str:
    lines = []
    for off in range(0, len(data), width):
        chunk = data[off:off + width]
        rec = bytes([len(chunk), (off >> 8) & 0xFF, off & 0xFF, 0]) + chunk
        lines.append(":" + (rec + bytes([(-sum(rec)) & 0xFF])).hex().upper())
    lines.append(":00000001FF")
    return "\n".join(lines) + "\n"


def decode_ihex(text: str, limit: int = 0x10000) -> bytes:
    """The bytes of an Intel HEX text (gaps filled with 0xFF); CodecError naming the line on any defect."""
    out = bytearray()
    base = 0
    ended = False
    for number, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line:
            continue
        if ended:
            raise CodecError(f"Intel HEX line {number}: data after the end record")
        if not line.startswith(":") or len(line) < 11 or len(line) % 2 == 0:
            raise CodecError(f"Intel HEX line {number}: not a record (':' and an odd number of hex digits)")
        try:
            rec = bytes.fromhex(line[1:])
        except ValueError:
            raise CodecError(f"Intel HEX line {number}: not hexadecimal") from None
        if len(rec) != rec[0] + 5:
            raise CodecError(f"Intel HEX line {number}: length byte {rec[0]} does not match the record")
        if sum(rec) & 0xFF:
            raise CodecError(f"Intel HEX line {number}: checksum wrong")
        kind, payload = rec[3], rec[4:-1]
        if kind == 0:
            addr = base + (rec[1] << 8 | rec[2])
            if addr + len(payload) > limit:
                raise CodecError(f"Intel HEX line {number}: address 0x{addr:X} beyond {limit} bytes")
            if len(out) < addr:
                out += b"\xff" * (addr - len(out))
            out[addr:addr + len(payload)] = payload
        elif kind == 1:
            ended = True
        elif kind == 2 and len(payload) == 2:
            base = (payload[0] << 8 | payload[1]) << 4
        elif kind == 4 and len(payload) == 2:
            base = (payload[0] << 8 | payload[1]) << 16
        elif kind in (3, 5):
            continue  # start addresses: meaningless for an EEPROM image
        else:
            raise CodecError(f"Intel HEX line {number}: record type {kind} not understood")
    if not ended:
        raise CodecError("Intel HEX: no end record (file cut short?)")
    return bytes(out)
