"""The simulated node's CANopen SDO server: canopen's SdoServer plus block transfer.

canopen's :class:`canopen.sdo.SdoServer` does expedited and segmented
transfers but declines block transfers. A real AKD on CANopen supports SDO
block transfer (CiA 301 7.2.4.3.9 ff.), and akdctl's client can use it
(``?block=1``), so the simulator adds the server side here: block upload and
block download with sub-block acknowledgement, retransmission from the last
good sequence number, and the CRC-16 (XMODEM polynomial 0x1021) when the
client asks for it. Everything else stays canopen's code.

A block transfer the client leaves unfinished is aborted with 0x05040000
("SDO protocol timed out") after :attr:`BlockSdoServer.TRANSFER_TIMEOUT`, as a
CiA 301 server does, and an NMT reset forgets any transfer: otherwise one stray
block-download initiate would make the server take every later request for a
sub-block segment.
"""

from __future__ import annotations

import binascii
import logging
import struct
import threading
import time
from typing import Any

from canopen.sdo import SdoAbortedError, SdoServer
from canopen.sdo.constants import (
    ABORT_CRC_ERROR,
    ABORT_GENERAL_ERROR,
    ABORT_INVALID_BLOCK_SIZE,
    ABORT_INVALID_COMMAND_SPECIFIER,
    ABORT_NO_DATA_AVAILABLE,
    ABORT_TIMED_OUT,
    REQUEST_ABORTED,
    REQUEST_BLOCK_DOWNLOAD,
    REQUEST_BLOCK_UPLOAD,
    RESPONSE_BLOCK_DOWNLOAD,
    RESPONSE_BLOCK_UPLOAD,
    SDO_STRUCT,
)

logger = logging.getLogger(__name__)

#: Segments per sub-block the server offers (CiA 301: 1..127).
BLOCK_SIZE = 64


def crc16(data: bytes, value: int = 0) -> int:
    """CRC-16/XMODEM as CiA 301 block transfer uses it."""
    return binascii.crc_hqx(bytes(data), value)


class BlockSdoServer(SdoServer):
    """SDO server with CiA 301 block upload and block download."""

    #: Seconds a block transfer may wait for the client's next frame (CiA 301 leaves the value to the device; the
    #: AKD's is not documented [I]; 1 s is well above a client's pace between sub-blocks).
    TRANSFER_TIMEOUT = 1.0

    def __init__(self, rx_cobid: int, tx_cobid: int, node: Any) -> None:
        super().__init__(rx_cobid, tx_cobid, node)
        self._guard = threading.RLock()  # requests arrive on the bus thread, expiry on the face's worker
        self._last = 0.0  # monotonic time of the last frame of the transfer in progress
        self._index = 0
        self._subindex = 0
        self._mode: str | None = None  # None, "up", "down"
        self._crc = False
        self._data = b""
        self._pos = 0  # upload: start of the current sub-block
        self._sent = 0  # upload: segments sent in the current sub-block
        self._blksize = BLOCK_SIZE
        self._expect = 1  # download: next sequence number
        self._last_good = 0
        self._down = bytearray()
        self._down_done = False

    # -- dispatch ---------------------------------------------------------------------------------------------
    def on_request(self, can_id: int, data: bytes, timestamp: float) -> None:
        with self._guard:
            if self._mode is not None and time.monotonic() - self._last > self.TRANSFER_TIMEOUT:
                self._reset()  # stale: expire() normally aborted it already; this frame starts afresh
            self._last = time.monotonic()
            self._on_request(can_id, data, timestamp)

    def expire(self) -> None:
        """Abort a block transfer the client left unfinished for longer than :attr:`TRANSFER_TIMEOUT`."""
        with self._guard:
            if self._mode is not None and time.monotonic() - self._last > self.TRANSFER_TIMEOUT:
                self.abort(ABORT_TIMED_OUT)

    def reset(self) -> None:
        """Forget any transfer in progress (NMT reset node / reset communication)."""
        with self._guard:
            self._reset()
            self._buffer, self._toggle = None, 0

    def _on_request(self, can_id: int, data: bytes, timestamp: float) -> None:
        if len(data) < 8:
            data = bytes(data).ljust(8, b"\0")
        if self._mode == "down" and not self._down_done:
            # Sub-block segments carry a sequence number in byte 0, not a command specifier.
            if data[0] == REQUEST_ABORTED:  # seqno 0 with the last bit cannot be a segment
                self._reset()
                return super().on_request(can_id, data, timestamp)
            try:
                self._download_segment(bytes(data))
            except SdoAbortedError as exc:
                self._reset()
                self.abort(exc.code)
            return
        ccs = data[0] & 0xE0
        if self._mode is not None and ccs not in (REQUEST_BLOCK_UPLOAD, REQUEST_BLOCK_DOWNLOAD, REQUEST_ABORTED):
            self._reset()  # a new normal transfer ends an unfinished block transfer
        if ccs == REQUEST_ABORTED:
            self._reset()
        super().on_request(can_id, data, timestamp)

    def abort(self, abort_code: int = ABORT_GENERAL_ERROR) -> None:
        """Send an abort and forget any block transfer in progress."""
        self._reset()
        super().abort(abort_code)

    def _reset(self) -> None:
        self._mode = None
        self._data = b""
        self._down = bytearray()
        self._down_done = False

    # -- block upload -----------------------------------------------------------------------------------------
    def block_upload(self, data: bytes) -> None:
        cs = data[0] & 0x03
        if cs == 0:  # initiate
            _, index, subindex = SDO_STRUCT.unpack_from(data)
            self._index, self._subindex = index, subindex
            blksize = data[4]
            if not 1 <= blksize <= 127:
                raise SdoAbortedError(ABORT_INVALID_BLOCK_SIZE)
            payload = self._node.get_data(index, subindex, check_readable=True)
            if not payload:
                raise SdoAbortedError(ABORT_NO_DATA_AVAILABLE)
            self._mode, self._data, self._pos, self._blksize = "up", bytes(payload), 0, blksize
            self._crc = bool(data[0] & 0x04)
            response = bytearray(8)
            crc_flag = 0x04 if self._crc else 0
            SDO_STRUCT.pack_into(response, 0, RESPONSE_BLOCK_UPLOAD | crc_flag | 0x02, index, subindex)
            struct.pack_into("<L", response, 4, len(self._data))
            self.send_response(response)
            return
        if self._mode != "up":
            raise SdoAbortedError(ABORT_INVALID_COMMAND_SPECIFIER)
        if cs == 3:  # start
            self._send_sub_block()
        elif cs == 2:  # block acknowledge
            ackseq, blksize = data[1], data[2]
            if not 1 <= blksize <= 127 or ackseq > self._sent:
                raise SdoAbortedError(ABORT_INVALID_BLOCK_SIZE)
            self._pos += 7 * ackseq
            self._blksize = blksize
            if self._pos >= len(self._data):
                last = len(self._data) % 7 or 7
                response = bytearray(8)
                response[0] = RESPONSE_BLOCK_UPLOAD | ((7 - last) << 2) | 0x01
                struct.pack_into("<H", response, 1, crc16(self._data) if self._crc else 0)
                self.send_response(response)
            else:
                self._send_sub_block()
        elif cs == 1:  # end response from the client
            self._reset()
        else:
            raise SdoAbortedError(ABORT_INVALID_COMMAND_SPECIFIER)

    def _send_sub_block(self) -> None:
        self._sent = 0
        pos = self._pos
        for seqno in range(1, self._blksize + 1):
            chunk = self._data[pos:pos + 7]
            pos += 7
            last = pos >= len(self._data)
            frame = bytes([seqno | (0x80 if last else 0)]) + chunk.ljust(7, b"\0")
            self.send_response(frame)
            self._sent = seqno
            if last:
                break

    # -- block download ---------------------------------------------------------------------------------------
    def block_download(self, data: bytes) -> None:
        cs = data[0] & 0x01
        if self._mode != "down":
            if cs != 0:
                raise SdoAbortedError(ABORT_INVALID_COMMAND_SPECIFIER)
            _, index, subindex = SDO_STRUCT.unpack_from(data)
            self._index, self._subindex = index, subindex
            # existence and access are checked when the data is written at the end (as a drive buffers it)
            self._mode, self._down, self._expect, self._last_good = "down", bytearray(), 1, 0
            self._down_done = False
            self._crc = bool(data[0] & 0x04)
            response = bytearray(8)
            SDO_STRUCT.pack_into(response, 0, RESPONSE_BLOCK_DOWNLOAD | (0x04 if self._crc else 0), index, subindex)
            response[4] = self._blksize = BLOCK_SIZE
            self.send_response(response)
            return
        # end of block download: client says how many bytes of the last segment were padding
        if cs != 1:
            raise SdoAbortedError(ABORT_INVALID_COMMAND_SPECIFIER)
        unused = (data[0] >> 2) & 0x07
        if unused:
            del self._down[-unused:]
        if self._crc:
            (crc,) = struct.unpack_from("<H", data, 1)
            if crc != crc16(self._down):
                raise SdoAbortedError(ABORT_CRC_ERROR)
        payload = bytes(self._down)
        self._reset()
        self._node.set_data(self._index, self._subindex, payload, check_writable=True)
        response = bytearray(8)
        response[0] = RESPONSE_BLOCK_DOWNLOAD | 0x01
        self.send_response(response)

    def _download_segment(self, data: bytes) -> None:
        seqno, last = data[0] & 0x7F, bool(data[0] & 0x80)
        if seqno == self._expect:
            self._down.extend(data[1:8])
            self._last_good = seqno
            self._expect += 1
        # a wrong sequence number is dropped; the acknowledgement tells the client where to resume
        if last and seqno == self._last_good:
            self._down_done = True
        if seqno >= self._blksize or last:
            response = bytearray(8)
            response[0] = RESPONSE_BLOCK_DOWNLOAD | 0x02
            response[1] = self._last_good
            response[2] = self._blksize
            self.send_response(response)
            self._expect, self._last_good = 1, 0
