"""EtherCAT frames and datagrams (ETG.1000.4), the ESC registers a master uses,
and the AL state texts. (The ETG.8200 gateway header, an EtherCAT header of
type 5 in front of a mailbox, lives with the mailbox codec in
:mod:`akdctl.protocol.mailbox`.)

The raw master and the simulated slave both speak through this module, so a
frame the master builds is exactly what the slave parses (and what Wireshark
dissects). All fields are little-endian. Only :class:`CodecError` escapes.

Frame on the wire::

    Ethernet (dst, src, 0x88A4) | EtherCAT header u16 (len bits 0-10, type bits 12-15)
    | datagram* | padding to the 60-byte Ethernet minimum

Datagram::

    cmd u8 | idx u8 | ADP u16 | ADO u16 | len u16 (0-10 length, 14 circulating, 15 more)
    | IRQ u16 | data[len] | WKC u16
"""

from __future__ import annotations

import operator
import struct
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from akdctl.protocol.errors import CodecError

ETHERTYPE_ECAT = 0x88A4
FRAME_TYPE_DATAGRAMS = 1
FRAME_TYPE_MAILBOX = 5
BROADCAST_MAC = b"\xff" * 6
ETH_HEADER = 14
ETH_MIN_FRAME = 60  # without FCS; shorter frames are padded
MAX_DATAGRAM_DATA = 1486  # 1500 - 2 (ecat header) - 10 (datagram header) - 2 (WKC)

# --- ESC registers (ETG.1000.4 / Beckhoff ESC datasheet section II) ---------------------------------
REG_TYPE = 0x0000
REG_REVISION = 0x0001
REG_BUILD = 0x0002
REG_FMMU_COUNT = 0x0004
REG_SM_COUNT = 0x0005
REG_RAM_SIZE = 0x0006
REG_PORT_DESC = 0x0007
REG_FEATURES = 0x0008
REG_STATION_ADDR = 0x0010
REG_STATION_ALIAS = 0x0012
REG_DL_CONTROL = 0x0100
REG_DL_STATUS = 0x0110
REG_AL_CONTROL = 0x0120
REG_AL_STATUS = 0x0130
REG_AL_STATUS_CODE = 0x0134
REG_PDI_CONTROL = 0x0140
REG_IRQ_MASK = 0x0200
REG_AL_EVENT_MASK = 0x0204
REG_AL_EVENT = 0x0220
REG_RX_ERROR = 0x0300
REG_WD_DIVIDER = 0x0400
REG_EEP_CONFIG = 0x0500
REG_EEP_PDI = 0x0501
REG_EEP_CONTROL = 0x0502
REG_EEP_ADDRESS = 0x0504
REG_EEP_DATA = 0x0508
REG_FMMU0 = 0x0600
REG_SM0 = 0x0800
SM_STRIDE = 8
REG_DC_SYSTIME = 0x0910
REG_DC_CYCLIC = 0x0980

# EEPROM control/status register (0x0502) bits
EEP_CMD_READ = 0x0100
EEP_CMD_WRITE = 0x0200
EEP_CMD_RELOAD = 0x0400
EEP_READ_8_BYTES = 0x0040  # status: this ESC returns 8 bytes per read (else 4)
EEP_ERROR_CHECKSUM = 0x0800
EEP_ERROR_ACK = 0x2000
EEP_ERROR_WRITE_ENABLE = 0x4000
EEP_BUSY = 0x8000

# SyncManager status (byte 5 of the SM block) and activate (byte 6) / PDI control (byte 7) bits
SM_STATUS_MAILBOX_FULL = 0x08
SM_ACTIVATE_ENABLE = 0x01
SM_ACTIVATE_REPEAT = 0x02
SM_PDI_REPEAT_ACK = 0x02


class Cmd(IntEnum):
    """Datagram commands (ETG.1000.4 table 12)."""

    NOP = 0
    APRD = 1
    APWR = 2
    APRW = 3
    FPRD = 4
    FPWR = 5
    FPRW = 6
    BRD = 7
    BWR = 8
    BRW = 9
    LRD = 10
    LWR = 11
    LRW = 12
    ARMW = 13
    FRMW = 14


READ_CMDS = frozenset({Cmd.APRD, Cmd.FPRD, Cmd.BRD, Cmd.LRD, Cmd.ARMW, Cmd.FRMW})
WRITE_CMDS = frozenset({Cmd.APWR, Cmd.FPWR, Cmd.BWR, Cmd.LWR})
READWRITE_CMDS = frozenset({Cmd.APRW, Cmd.FPRW, Cmd.BRW, Cmd.LRW})
AUTO_INCREMENT_CMDS = frozenset({Cmd.APRD, Cmd.APWR, Cmd.APRW, Cmd.ARMW})
CONFIGURED_CMDS = frozenset({Cmd.FPRD, Cmd.FPWR, Cmd.FPRW, Cmd.FRMW})
BROADCAST_CMDS = frozenset({Cmd.BRD, Cmd.BWR, Cmd.BRW})
LOGICAL_CMDS = frozenset({Cmd.LRD, Cmd.LWR, Cmd.LRW})


class AlState(IntEnum):
    """Application-layer states (AL control/status bits 0-3)."""

    INIT = 0x01
    PREOP = 0x02
    BOOT = 0x03
    SAFEOP = 0x04
    OP = 0x08


AL_ERROR_FLAG = 0x10  # AL status: error indication / AL control: acknowledge

AL_STATE_NAMES: dict[int, str] = {1: "INIT", 2: "PREOP", 3: "BOOT", 4: "SAFEOP", 8: "OP"}
# AL status codes (register 0x0134) are returned as numbers; their words are akdctl.catalog.texts.al_status_text
# and the state-and-code line akdctl.catalog.texts.al_status_line (issue 22: codecs return codes).

def al_state_name(status: int) -> str:
    """'PREOP', 'SAFEOP+ERR', or 'UNKNOWN(0x5)' for an AL status word."""
    name = AL_STATE_NAMES.get(status & 0x0F, f"UNKNOWN(0x{status & 0x0F:X})")
    return name + ("+ERR" if status & AL_ERROR_FLAG else "")


def normal_al_state(state: object) -> str | None:
    """The one spelling of an EtherCAT AL state: 'PREOP', 'SAFEOP', 'OP', 'INIT', 'BOOT' ('+ERR' kept; None stays
    None) -- how the Connection reports it whatever the transport said ('Pre-Op', 'SAFE_OP')."""
    return None if state is None else str(state).upper().replace("-", "").replace("_", "").replace(" ", "")


def parse_al_state(text: str) -> AlState:
    """'preop', 'PRE-OP', 'PREOP', '2' -> AlState.PREOP; CodecError otherwise."""
    key = text.strip().upper().replace("-", "").replace("_", "")
    aliases = {"INIT": AlState.INIT, "PREOP": AlState.PREOP, "BOOT": AlState.BOOT, "BOOTSTRAP": AlState.BOOT,
               "SAFEOP": AlState.SAFEOP, "OP": AlState.OP}
    if key in aliases:
        return aliases[key]
    try:
        return AlState(int(key, 0))
    except ValueError:
        raise CodecError(f"unknown AL state {text!r}; use INIT, PREOP, BOOT, SAFEOP or OP") from None


@dataclass
class Datagram:
    """One EtherCAT datagram. For position/configured/broadcast commands ``adp``
    is the slave address and ``ado`` the register; for logical commands the
    32-bit logical address is ``adp | ado << 16`` (see :attr:`logical`)."""

    cmd: int
    adp: int = 0
    ado: int = 0
    data: bytes = b""
    index: int = 0
    wkc: int = 0
    irq: int = 0
    circulating: bool = False

    @property
    def logical(self) -> int:
        return self.adp | (self.ado << 16)

    @property
    def cmd_name(self) -> str:
        try:
            return Cmd(self.cmd).name
        except ValueError:
            return f"CMD{self.cmd}"

    def encode(self, more: bool) -> bytes:
        if not 0 <= self.cmd <= 0xFF or not 0 <= self.index <= 0xFF:
            raise CodecError(f"datagram cmd/index out of range: {self.cmd}/{self.index}")
        if not 0 <= self.adp <= 0xFFFF or not 0 <= self.ado <= 0xFFFF:
            raise CodecError(f"datagram address out of range: ADP 0x{self.adp:X} ADO 0x{self.ado:X}")
        if len(self.data) > MAX_DATAGRAM_DATA:
            raise CodecError(f"datagram data of {len(self.data)} bytes exceeds {MAX_DATAGRAM_DATA}")
        if not 0 <= self.wkc <= 0xFFFF or not 0 <= self.irq <= 0xFFFF:
            raise CodecError("datagram WKC/IRQ out of range")
        length = len(self.data) | (0x4000 if self.circulating else 0) | (0x8000 if more else 0)
        return _DG_HEAD.pack(self.cmd, self.index, self.adp, self.ado, length, self.irq) + bytes(self.data) \
            + _U16.pack(self.wkc)


def logical_datagram(cmd: int, address: int, data: bytes, index: int = 0) -> Datagram:
    """A logical (LRD/LWR/LRW) datagram at a 32-bit logical address."""
    if not 0 <= address <= 0xFFFFFFFF:
        raise CodecError(f"logical address 0x{address:X} out of range")
    return Datagram(cmd, address & 0xFFFF, address >> 16, data, index)


_DG_HEAD = struct.Struct("<BBHHHH")
_U16 = struct.Struct("<H")


def encode_datagrams(datagrams: list[Datagram]) -> bytes:
    """EtherCAT header + datagrams (the Ethernet payload, unpadded)."""
    if not datagrams:
        raise CodecError("an EtherCAT frame needs at least one datagram")
    body = b"".join(d.encode(more=i < len(datagrams) - 1) for i, d in enumerate(datagrams))
    if len(body) > 0x7FF:
        raise CodecError(f"datagrams of {len(body)} bytes do not fit one EtherCAT frame (max 2047)")
    return struct.pack("<H", len(body) | (FRAME_TYPE_DATAGRAMS << 12)) + body


def decode_datagrams(payload: bytes) -> list[Datagram]:
    """Parse an EtherCAT payload (header + datagrams; trailing padding ignored)."""
    if len(payload) < 2:
        raise CodecError("EtherCAT frame shorter than its 2-byte header")
    (header,) = struct.unpack_from("<H", payload)
    length, ftype = header & 0x7FF, header >> 12
    if ftype != FRAME_TYPE_DATAGRAMS:
        raise CodecError(f"EtherCAT frame type {ftype} is not 1 (datagrams)")
    if length + 2 > len(payload):
        raise CodecError(f"EtherCAT header announces {length} bytes, frame holds {len(payload) - 2}")
    out: list[Datagram] = []
    pos, end = 2, 2 + length
    while True:
        if pos + 12 > end:
            raise CodecError("truncated datagram header")
        cmd, idx, adp, ado, dlen, irq = _DG_HEAD.unpack_from(payload, pos)
        size = dlen & 0x7FF
        if pos + 10 + size + 2 > end:
            raise CodecError(f"datagram {len(out)} announces {size} data bytes beyond the frame")
        data = bytes(payload[pos + 10 : pos + 10 + size])
        (wkc,) = _U16.unpack_from(payload, pos + 10 + size)
        out.append(Datagram(cmd, adp, ado, data, idx, wkc, irq, bool(dlen & 0x4000)))
        pos += 12 + size
        if not dlen & 0x8000:
            break
    return out


def encode_ethernet(payload: bytes, src: bytes, dst: bytes = BROADCAST_MAC, ethertype: int = ETHERTYPE_ECAT) -> bytes:
    """An Ethernet II frame, padded to the 60-byte minimum (the NIC adds the FCS)."""
    if len(src) != 6 or len(dst) != 6:
        raise CodecError("MAC addresses are 6 bytes")
    frame = dst + src + struct.pack(">H", ethertype) + payload
    return frame + bytes(max(0, ETH_MIN_FRAME - len(frame)))


def decode_ethernet(frame: bytes | bytearray) -> tuple[bytes, bytes, int, bytes]:
    """(dst, src, ethertype, payload); a 802.1Q tag is skipped."""
    if len(frame) < ETH_HEADER:
        raise CodecError("Ethernet frame shorter than 14 bytes")
    dst, src = bytes(frame[0:6]), bytes(frame[6:12])
    (ethertype,) = struct.unpack_from(">H", frame, 12)
    pos = 14
    if ethertype == 0x8100:
        if len(frame) < 18:
            raise CodecError("truncated VLAN tag")
        (ethertype,) = struct.unpack_from(">H", frame, 16)
        pos = 18
    return dst, src, ethertype, bytes(frame[pos:])


def encode_frame(datagrams: list[Datagram], src: bytes, dst: bytes = BROADCAST_MAC) -> bytes:
    return encode_ethernet(encode_datagrams(datagrams), src, dst)


def decode_frame(frame: bytes | bytearray) -> tuple[bytes, bytes, list[Datagram]]:
    """(dst, src, datagrams) of an EtherCAT Ethernet frame."""
    dst, src, ethertype, payload = decode_ethernet(frame)
    if ethertype != ETHERTYPE_ECAT:
        raise CodecError(f"EtherType 0x{ethertype:04X} is not EtherCAT (0x88A4)")
    return dst, src, decode_datagrams(payload)


class FrameTemplate:
    """A frame whose datagrams keep their command, address and length from use to use, encoded once.

    Why: a master's mailbox polls send the same frame over and over; building datagram objects and
    encoding them per frame cost more than the frame's trip through the slave. Per use only the
    index (and, for :meth:`stamp` with ``data``, the first datagram's data) changes, and a reply is
    read with one precompiled struct (:meth:`read`), checked against the command, register and length
    sent (the ADP is not compared: position and broadcast commands count it on the way).
    """

    __slots__ = ("frame", "size", "count", "index_at", "_data_at", "_head", "_reply", "_fields", "_expect",
                 "_results", "_answer", "answer_from")

    def __init__(self, datagrams: list[Datagram], src: bytes, answer_from: int = 0) -> None:
        """``answer_from``: where in the first datagram's data :meth:`answer` starts what it gives (a process-data
        LRW's inputs lie behind its outputs)."""
        self.frame = bytearray(encode_frame(datagrams, src))
        self.answer_from = answer_from
        self.count = len(datagrams)
        self._head = bytes(self.frame[12:ETH_HEADER + 2])  # EtherType and EtherCAT header
        self.index_at: list[int] = []  # where each datagram's index byte sits (stamp_in_place writes them)
        pos = ETH_HEADER + 2
        for d in datagrams:
            self.index_at.append(pos + 1)
            pos += 12 + len(d.data)
        self.size = pos
        self._data_at = (ETH_HEADER + 12, ETH_HEADER + 12 + len(datagrams[0].data))
        # The frame as it comes back from the EtherType on: EtherType and EtherCAT header (4 bytes), then cmd,
        # index, ADP, ADO, length, IRQ, data, WKC of each datagram (the layout above).
        self._reply = struct.Struct("<4s" + "".join(f"BBHHHH{len(d.data)}sH" for d in datagrams))
        self._fields = operator.itemgetter(0, *(1 + 8 * k + f for k in range(self.count) for f in (0, 1, 3, 4)))
        self._results = operator.itemgetter(*(1 + 8 * k + f for k in range(self.count) for f in (6, 7)))
        sent = self._reply.unpack_from(self.frame, 12)
        self._expect = [(self._head, *(v for k in range(self.count) for v in (sent[1 + 8 * k], index,
                                                                             sent[1 + 8 * k + 3], sent[1 + 8 * k + 4])))
                        for index in range(256)]  # what _fields reads from the reply, per index
        self._answer: Any = None  # answer()'s one-datagram reader, made on first use

    def stamp(self, index: int, data: bytes | None = None) -> bytes:
        """The frame with ``index`` in every datagram (and ``data`` in the first, of the template's length)."""
        return bytes(self.stamp_in_place(index, data))

    def stamp_in_place(self, index: int, data: bytes | None = None) -> bytearray:
        """:meth:`stamp` without the copy: the template's own buffer, to be sent before the next stamp.

        Why: the cyclic process-data frame goes out every bus cycle with the same outputs; a copy per cycle
        and a data copy of outputs that did not change are work the master repeats for nothing. Data left out
        stays as last stamped."""
        frame = self.frame
        for at in self.index_at:
            frame[at] = index
        if data is not None:
            start, end = self._data_at
            if len(data) != end - start:
                raise CodecError(f"datagram data of {len(data)} bytes for a {end - start}-byte slot")
            frame[start:end] = data
        return frame

    def answer(self, reply: bytes | bytearray, index: int, size: int) -> tuple[Any, ...] | None:
        """:meth:`read`, and None as well for a frame carrying this template's own source address (the frame
        itself, seen on its way out): what a master takes as the answer to this frame at these offsets. The
        first datagram's data is given from ``answer_from`` on (:meth:`from_answer_from`).

        Why: the process-data frame is answered every bus cycle; for a one-datagram frame one struct reads the
        source address, the header fields :meth:`read` compares, the data and the WKC at once, and two bytes
        compares judge them, where :meth:`read` and a separate look at the source cost several times that."""
        lean = self._answer
        if lean is None:
            lean = self._answer = self._lean_reader() if self.count == 1 else False
        if lean is False:
            if reply[6:12] == self.frame[6:12]:
                return None
            got = self.read(reply, index, size)
            return None if got is None else self.from_answer_from(got)
        if size < self.size:
            return None
        src, head, fixed, data, wkc = lean[0](reply, 6)
        if src == lean[1] or head != lean[2][index] or fixed != lean[3]:
            return None
        return data, wkc

    def _lean_reader(self) -> tuple[Any, ...]:
        """(unpack, own source, EtherType + header + cmd + index per index, ADO + length) for :meth:`answer`: the
        fields :meth:`read` compares (the ADP and IRQ skipped as it skips them)."""
        start, end = self._data_at
        frame = self.frame
        skip = min(self.answer_from, end - start)
        unpack = struct.Struct(f"<6s6s2x4s2x{skip}x{end - start - skip}sH").unpack_from
        cmd = frame[ETH_HEADER + 2]
        heads = [self._head + bytes((cmd, index)) for index in range(256)]
        return unpack, bytes(frame[6:12]), heads, bytes(frame[ETH_HEADER + 6:ETH_HEADER + 10])

    def from_answer_from(self, got: tuple[Any, ...]) -> tuple[Any, ...]:
        """:meth:`read`'s result with the first datagram's data from ``answer_from`` on, as :meth:`answer` gives it."""
        skip = self.answer_from
        return (got[0][skip:], *got[1:]) if skip else got

    def read(self, reply: bytes | bytearray, index: int, size: int | None = None) -> tuple[Any, ...] | None:
        """``(data, working counter)`` of each datagram in turn, flat (``data0, wkc0, data1, wkc1 ...``), if
        ``reply`` (its first ``size`` bytes: a receive buffer may be longer) is this frame with ``index`` coming
        back; else None (another frame, a VLAN tag: the caller decodes it the general way)."""
        if (len(reply) if size is None else size) < self.size:
            return None
        got = self._reply.unpack_from(reply, 12)
        if self._fields(got) != self._expect[index]:  # (the EtherType and EtherCAT header compared with the rest)
            return None
        return self._results(got)  # type: ignore[no-any-return]


# --- SyncManager and FMMU register blocks --------------------------------------------------------------

@dataclass(frozen=True)
class SyncManager:
    """One 8-byte SyncManager register block (0x0800 + 8*n)."""

    start: int
    length: int
    control: int
    status: int = 0
    activate: int = 0
    pdi_control: int = 0

    def encode(self) -> bytes:
        try:
            return struct.pack("<HHBBBB", self.start, self.length, self.control, self.status, self.activate,
                               self.pdi_control)
        except struct.error as exc:
            raise CodecError(f"SyncManager field out of range: {exc}") from None

    @classmethod
    def decode(cls, data: bytes) -> "SyncManager":
        if len(data) < 8:
            raise CodecError("SyncManager block shorter than 8 bytes")
        return cls(*struct.unpack_from("<HHBBBB", data))

    @property
    def enabled(self) -> bool:
        return bool(self.activate & SM_ACTIVATE_ENABLE)

    @property
    def is_mailbox(self) -> bool:
        return (self.control & 0x03) == 0x02

    @property
    def writes_to_slave(self) -> bool:
        """Direction bits 2-3: 01 = ECAT writes (master -> slave)."""
        return (self.control & 0x0C) == 0x04

