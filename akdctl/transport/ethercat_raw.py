"""``ecat://IFNAME[/POSITION]``: akdctl as the EtherCAT master on a raw interface,
in pure Python (AF_PACKET, EtherType 0x88A4).

Bring-up follows SOEM's order (reference notes, "Reaching the mailbox"): count
the slaves with BRD, give each a station address (0x1001 + position, as SOEM),
read the SII through the ESC's EEPROM interface, program SM0/SM1 from the SII's
mailbox layout, request PRE-OP and report the AL status code in words if the
slave refuses. Mailbox traffic writes SM0 and polls SM1's "mailbox full" bit; a
reply lost on the wire is recovered with the sync manager's repeat request.

A missing CAP_NET_RAW is a :class:`UsageError` (exit 2): it is a setup problem
the user fixes with one command, not a communication failure.

Only the slave at POSITION is touched beyond address assignment; a slave that
is already in PRE-OP or higher with its mailbox configured is used as it is.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

from akdctl.errors import CommError, DriveError, NoAnswer, UsageError
from akdctl.io import raw_socket
from akdctl.protocol import ethercat as ec
from akdctl.protocol.errors import CodecError
from akdctl.protocol.mailbox import HEADER_SIZE as MAILBOX_HEADER
from akdctl.protocol.sii import CAT_END, MAILBOX_LAYOUT_OFFSET, SiiImage, decode_mailbox_layout, parse_sii
from akdctl.links import MailboxLink
from akdctl.transport.base import LinkOptions, Transport
from akdctl.transport.target import Target
from akdctl.transport.trace import Tracer

MASTER_MAC = b"\x01\x01\x01\x01\x01\x01"  # as SOEM: EtherCAT ignores MACs; slaves set bit 1 of byte 0
STATION_BASE = 0x1001
#: Seconds a slave leaving BOOT may take to answer again: the AKD ESI's back-to-INIT timeout.
BOOT_EXIT_TIMEOUT = 50.0
SII_MAX_BYTES = 0x4000
_TIMEVAL = struct.Struct("@ll")  # struct timeval (seconds, microseconds) for SO_RCVTIMEO


class FrameLost(NoAnswer):
    """No frame came back (after the allowed repeats)."""

    kind = "timeout"


def open_raw_socket(ifname: str) -> socket.socket:
    """The master's EtherCAT socket on ``ifname`` (errors name the ``ecat://`` target)."""
    return raw_socket.open_raw_socket(ifname, ec.ETHERTYPE_ECAT, f"ecat://{ifname}", ignore_outgoing=True)


@dataclass
class SlaveInfo:
    position: int
    station: int
    al_status: int
    al_code: int
    sii: SiiImage | None = None

    @property
    def state_text(self) -> str:
        from akdctl.catalog.texts import al_status_line

        return al_status_line(self.al_status, self.al_code)


class EcatMaster:
    """Frames, datagrams and ESC register access on one interface."""

    def __init__(self, ifname: str, tracer: Tracer, timeout: float = 2.0, retries: int = 2,
                 sock: socket.socket | None = None) -> None:
        """``sock`` replaces the raw socket (tests run the master against an in-process slave over a socketpair)."""
        self.ifname = ifname
        self.tracer = tracer
        self.timeout = timeout
        self.retries = retries
        self.frame_timeout = min(timeout, 0.2)
        self.sock: socket.socket | None = sock if sock is not None else open_raw_socket(ifname)
        # A blocking socket whose receive timeout the kernel keeps (SO_RCVTIMEO): one system call per send and
        # per receive. A Python socket timeout instead polls before every send and every receive, and each
        # settimeout() is another call.
        self.sock.settimeout(None)
        self._waits: float | None = None  # the receive timeout set now
        self._index = 0
        self._buffer = bytearray(2048)  # one receive buffer for every frame
        self.frames = 0

    def close(self) -> None:
        if self.sock is not None:
            with contextlib.suppress(OSError):
                self.sock.close()
            self.sock = None

    # ------------------------------------------------------------------ frames
    def _wait_at_most(self, sock: socket.socket, seconds: float) -> None:
        """The receive timeout, set only when it changes (at least 1 µs: 0 would mean no timeout)."""
        if seconds != self._waits:
            us = max(1, int(seconds * 1e6))
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, _TIMEVAL.pack(us // 1_000_000, us % 1_000_000))
            self._waits = seconds

    def _lost(self) -> FrameLost:
        return FrameLost(f"no EtherCAT frame came back on {self.ifname} within {self.frame_timeout:g} s: "
                         "no slave connected, or the link is down")

    def _trace(self, direction: str, frame: bytes, note: str) -> None:
        # data is the whole Ethernet frame, so the pcap sink takes it as it is (no EtherType in meta)
        self.tracer.frame(direction, "ecat", frame, note=note, meta={"proto": "ethernet"})  # type: ignore[arg-type]

    def txrx(self, datagrams: list[ec.Datagram], retries: int | None = None) -> list[ec.Datagram]:
        """Send one frame and return its datagrams as they came back; FrameLost after the repeats."""
        sock = self.sock
        if sock is None:
            raise CommError(f"ecat://{self.ifname}: the link is closed")
        attempts = 1 + (self.retries if retries is None else retries)
        for _ in range(attempts):
            self._index = (self._index + 1) & 0xFF
            for d in datagrams:
                d.index = self._index
            frame = ec.encode_frame(datagrams, src=MASTER_MAC)
            if self.tracer.active:
                self._trace("tx", frame, " ".join(f"{d.cmd_name} 0x{d.adp:04X}:0x{d.ado:04X}/{len(d.data)}"
                                                  for d in datagrams))
            try:
                sock.send(frame)
            except OSError as exc:
                raise self._cannot_send(exc) from None
            self.frames += 1
            reply = self._wait(self._index, len(datagrams))
            if reply is not None:
                return reply
        raise FrameLost(f"no EtherCAT frame came back on {self.ifname} within {self.frame_timeout:g} s "
                        f"({attempts} attempt{'s' if attempts > 1 else ''}): no slave connected, or the link is down")

    def txrx_template(self, template: ec.FrameTemplate, data: bytes | None = None) -> tuple[Any, ...]:
        """:meth:`txrx` for a frame encoded once (mailbox polls): one try; data and WKC of each datagram in
        turn, flat (:meth:`FrameTemplate.read`). FrameLost when it does not come back."""
        sock = self.sock
        if sock is None:
            raise CommError(f"ecat://{self.ifname}: the link is closed")
        index = self._index = (self._index + 1) & 0xFF
        return self._template_trip(sock, template, index, template.stamp(index, data), "mailbox poll/fetch")

    def txrx_cyclic(self, template: ec.FrameTemplate, data: bytes | None = None) -> tuple[Any, ...]:
        """:meth:`txrx_template` for the process-data frame, sent every bus cycle: the template's own buffer
        goes out as it is (:meth:`FrameTemplate.stamp_in_place`; ``data`` None keeps the outputs stamped last);
        the answer as :meth:`FrameTemplate.answer` gives it (the first datagram's data from ``answer_from`` on).

        Why its own path: this runs once per bus cycle, so the usual cycle -- the first frame received is the
        answer, nothing traced -- is taken in one go; anything else (our own frame, another frame, tracing on)
        continues the general way (:meth:`_template_answer`), with the same checks and the same time left."""
        sock = self.sock
        if sock is None:
            raise CommError(f"ecat://{self.ifname}: the link is closed")
        index = self._index = (self._index + 1) & 0xFF
        if data is None:  # the usual cycle: only the index changes (stamp_in_place without a call per cycle)
            frame = template.frame
            for at in template.index_at:
                frame[at] = index
        else:
            frame = template.stamp_in_place(index, data)
        if self.tracer.active:
            return template.from_answer_from(self._template_trip(sock, template, index, frame, "process data"))
        sent = self._put(sock, frame)
        buffer = self._buffer
        try:
            size = sock.recv_into(buffer)
        except (BlockingIOError, socket.timeout):  # the receive timeout ran out
            raise self._lost() from None
        except OSError as exc:
            raise self._receive_failed(exc) from None
        got = template.answer(buffer, index, size)  # (our own frame, seen on the way out, is not the answer)
        if got is not None:
            return got
        return template.from_answer_from(self._template_answer(sock, template, index, sent, size))

    def _cannot_send(self, exc: OSError) -> CommError:
        return CommError(f"ecat://{self.ifname}: cannot send: {exc.strerror}")

    def _receive_failed(self, exc: OSError) -> CommError:
        return CommError(f"ecat://{self.ifname}: receive failed: {exc.strerror}")

    def _template_trip(self, sock: socket.socket, template: ec.FrameTemplate, index: int, frame: bytes | bytearray,
                       note: str) -> tuple[Any, ...]:
        """Send a stamped template frame and wait for its answer (:meth:`txrx_template`)."""
        if self.tracer.active:
            self._trace("tx", bytes(frame), note)
        return self._template_answer(sock, template, index, self._put(sock, frame))

    def _put(self, sock: socket.socket, frame: bytes | bytearray) -> float:
        """Send one template frame, count it, bound the receive by the frame timeout; the instant it went out."""
        try:
            sock.send(frame)
        except OSError as exc:
            raise self._cannot_send(exc) from None
        self.frames += 1
        sent = time.monotonic()
        if self._waits != self.frame_timeout:
            self._wait_at_most(sock, self.frame_timeout)
        return sent

    def _template_answer(self, sock: socket.socket, template: ec.FrameTemplate, index: int, sent: float,
                         size: int | None = None) -> tuple[Any, ...]:
        """The answer to a template frame sent at ``sent`` (``size``: a frame already received into the buffer,
        looked at first); frames that are not the answer are passed over until the frame timeout."""
        buffer = self._buffer
        while True:
            if size is None:
                try:
                    size = sock.recv_into(buffer)
                except (BlockingIOError, socket.timeout):  # the receive timeout ran out
                    raise self._lost() from None
                except OSError as exc:
                    raise self._receive_failed(exc) from None
            own = buffer.startswith(MASTER_MAC, 6)  # our own frame, seen on the way out, is not the answer
            got = None if own else template.read(buffer, index, size)
            if got is None and not own:  # not at the template's offsets: decode it the general way
                try:
                    _dst, _src, datagrams = ec.decode_frame(buffer[:size])
                except CodecError:
                    datagrams = []
                if len(datagrams) == template.count and datagrams[0].index == index:
                    got = tuple(x for d in datagrams for x in (d.data, d.wkc))
            if got is not None:
                self._traced_rx(buffer, size, got)
                return got
            # Not the answer: wait for the rest of the frame's time only, so a peer flooding frames that are not
            # the answer does not hold us past it.
            left = sent + self.frame_timeout - time.monotonic()
            if left <= 0:
                raise self._lost()
            self._wait_at_most(sock, left)
            size = None

    def txrx_pair(self, first: ec.FrameTemplate, data: bytes, second: ec.FrameTemplate
                  ) -> tuple[tuple[Any, ...] | None, tuple[Any, ...] | None]:
        """Two template frames sent back to back -- the second without waiting for the first's answer (a
        mailbox write and the poll for its reply) -- and each one's answer as :meth:`txrx_template` gives it,
        None for one that did not come back. Every receive waits at most the frame timeout and the pair at
        most twice that."""
        sock = self.sock
        if sock is None:
            raise CommError(f"ecat://{self.ifname}: the link is closed")
        one = self._index = (self._index + 1) & 0xFF
        two = self._index = (self._index + 1) & 0xFF
        frames = (first.stamp(one, data), second.stamp(two))
        try:
            for frame in frames:
                if self.tracer.active:
                    self._trace("tx", frame, "mailbox write" if frame is frames[0] else "mailbox poll/fetch")
                sock.send(frame)
                self.frames += 1
        except OSError as exc:
            raise self._cannot_send(exc) from None
        sent = time.monotonic()
        buffer = self._buffer
        if self._waits != self.frame_timeout:
            self._wait_at_most(sock, self.frame_timeout)
        got_one = got_two = None
        while got_one is None or got_two is None:
            try:
                size = sock.recv_into(buffer)
            except (BlockingIOError, socket.timeout):  # the receive timeout ran out
                break
            except OSError as exc:
                raise CommError(f"ecat://{self.ifname}: receive failed: {exc.strerror}") from None
            if not buffer.startswith(MASTER_MAC, 6):  # (our own frames, seen on the way out, are not answers)
                if got_one is None and (got_one := first.read(buffer, one, size)) is not None:
                    self._traced_rx(buffer, size, got_one)
                    continue
                if got_two is None and (got_two := second.read(buffer, two, size)) is not None:
                    self._traced_rx(buffer, size, got_two)
                    continue
            left = sent + self.frame_timeout - time.monotonic()  # not an answer: only the rest of the time
            if left <= 0:
                break
            self._wait_at_most(sock, left)
        return got_one, got_two

    def _traced_rx(self, buffer: bytearray, size: int, got: tuple[Any, ...]) -> None:
        if self.tracer.active:
            self._trace("rx", bytes(buffer[:size]), f"wkc {','.join(str(w) for w in got[1::2])}")

    def _wait(self, index: int, count: int) -> list[ec.Datagram] | None:
        sock = self.sock
        assert sock is not None
        deadline = time.monotonic() + self.frame_timeout
        buffer = self._buffer
        self._wait_at_most(sock, self.frame_timeout)
        while True:
            try:
                size = sock.recv_into(buffer)
            except (BlockingIOError, socket.timeout):  # the receive timeout ran out
                return None
            except OSError as exc:
                raise CommError(f"ecat://{self.ifname}: receive failed: {exc.strerror}") from None
            frame = buffer[:size]
            if frame[6:12] != MASTER_MAC:  # (our own frame, seen on the way out, is not the answer)
                try:
                    _dst, _src, got = ec.decode_frame(frame)
                except CodecError:
                    got = []
                if got and got[0].index == index and len(got) == count:  # (else a late answer to an earlier try)
                    if self.tracer.active:
                        self._trace("rx", bytes(frame), f"wkc {','.join(str(d.wkc) for d in got)}")
                    return got
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            self._wait_at_most(sock, remaining)

    # ------------------------------------------------------------------ register helpers
    def read(self, cmd: int, adp: int, ado: int, length: int, retries: int | None = None) -> tuple[bytes, int]:
        (d,) = self.txrx([ec.Datagram(cmd, adp, ado, bytes(length))], retries)
        return d.data, d.wkc

    def write(self, cmd: int, adp: int, ado: int, data: bytes, retries: int | None = None) -> int:
        (d,) = self.txrx([ec.Datagram(cmd, adp, ado, bytes(data))], retries)
        return d.wkc

    def fprd(self, station: int, ado: int, length: int, retries: int | None = None) -> bytes:
        data, wkc = self.read(ec.Cmd.FPRD, station, ado, length, retries)
        if wkc != 1:
            raise CommError(f"slave 0x{station:04X} did not answer a read of register 0x{ado:04X} (WKC {wkc})")
        return data

    def fpwr(self, station: int, ado: int, data: bytes) -> None:
        wkc = self.write(ec.Cmd.FPWR, station, ado, data)
        if wkc != 1:
            raise CommError(f"slave 0x{station:04X} did not take a write of register 0x{ado:04X} (WKC {wkc})")

    # ------------------------------------------------------------------ bring-up
    def count_slaves(self) -> int:
        _data, wkc = self.read(ec.Cmd.BRD, 0, ec.REG_TYPE, 2)
        return wkc

    def assign_addresses(self, count: int) -> list[int]:
        stations = []
        for pos in range(count):
            station = STATION_BASE + pos
            wkc = self.write(ec.Cmd.APWR, (-pos) & 0xFFFF, ec.REG_STATION_ADDR, struct.pack("<H", station))
            if wkc != 1:
                raise CommError(f"slave at position {pos} did not take station address 0x{station:04X}")
            stations.append(station)
        return stations

    def al_status(self, station: int) -> tuple[int, int]:
        data = self.fprd(station, ec.REG_AL_STATUS, 6)
        status, _reserved, code = struct.unpack("<HHH", data)
        return status, code

    def read_eeprom(self, station: int, word: int) -> bytes:
        """4 or 8 bytes of SII from ``word`` through the ESC's EEPROM interface."""
        deadline = time.monotonic() + self.timeout
        self.fpwr(station, ec.REG_EEP_CONTROL, struct.pack("<HI", ec.EEP_CMD_READ, word))
        while True:
            data = self.fprd(station, ec.REG_EEP_CONTROL, 14)
            (ctl,) = struct.unpack_from("<H", data)
            if not ctl & ec.EEP_BUSY:
                if ctl & (ec.EEP_ERROR_ACK | ec.EEP_ERROR_CHECKSUM):
                    raise CommError(f"slave 0x{station:04X}: SII EEPROM read at word 0x{word:X} failed "
                                    f"(status 0x{ctl:04X})")
                return data[6:14] if ctl & ec.EEP_READ_8_BYTES else data[6:10]
            if time.monotonic() > deadline:
                raise NoAnswer(f"slave 0x{station:04X}: SII EEPROM stays busy")

    def write_eeprom(self, station: int, word: int, value: int) -> None:
        """Write one SII word through the ESC's EEPROM interface and wait for it (IgH's way: data, address and
        the write command with write enable in one 8-byte access at 0x0502; reference B). A NACK or a
        write-enable error is a one-line CommError; the wait is bounded by the timeout."""
        deadline = time.monotonic() + self.timeout
        with contextlib.suppress(CommError):
            self.fpwr(station, ec.REG_EEP_CONFIG, b"\x00")  # EEPROM access by ECAT (the master)
        self.fpwr(station, ec.REG_EEP_CONTROL, struct.pack("<HIH", ec.EEP_CMD_WRITE | 0x0001, word, value & 0xFFFF))
        while True:
            (ctl,) = struct.unpack("<H", self.fprd(station, ec.REG_EEP_CONTROL, 2))
            if not ctl & ec.EEP_BUSY:
                if ctl & (ec.EEP_ERROR_ACK | ec.EEP_ERROR_WRITE_ENABLE):
                    raise CommError(f"slave 0x{station:04X}: SII EEPROM write of word 0x{word:X} failed "
                                    f"(status 0x{ctl:04X}: "
                                    + ("write not enabled" if ctl & ec.EEP_ERROR_WRITE_ENABLE else "not acknowledged")
                                    + ")")
                return
            if time.monotonic() > deadline:
                raise NoAnswer(f"slave 0x{station:04X}: SII EEPROM stays busy after a write of word 0x{word:X}")
            time.sleep(0.001)

    def read_sii_bytes(self, station: int, start: int, length: int) -> bytes:
        out = bytearray()
        word = start // 2
        while len(out) < length + (start % 2):
            out += self.read_eeprom(station, word + len(out) // 2)
        return bytes(out[start % 2 : start % 2 + length])

    def read_sii(self, station: int, full: bool = True) -> tuple[SiiImage, bytes]:
        """The SII: the fixed area and (``full``) every category up to the end marker."""
        with contextlib.suppress(CommError):
            self.fpwr(station, ec.REG_EEP_CONFIG, b"\x00")  # EEPROM access by ECAT (the master)
        raw = bytearray(self.read_sii_bytes(station, 0, 0x80))
        pos = 0x80
        while full and pos + 4 <= SII_MAX_BYTES:
            head = self.read_sii_bytes(station, pos, 4)
            ctype, words = struct.unpack("<HH", head)
            if ctype == CAT_END:
                raw += head[:2]
                break
            if pos + 4 + 2 * words > SII_MAX_BYTES:
                raise CommError(f"slave 0x{station:04X}: SII category {ctype} runs past {SII_MAX_BYTES} bytes")
            raw += head + self.read_sii_bytes(station, pos + 4, 2 * words)
            pos += 4 + 2 * words
        try:
            return parse_sii(bytes(raw)), bytes(raw)
        except CodecError as exc:
            raise CommError(f"slave 0x{station:04X}: SII EEPROM content does not decode: {exc}") from None

    def mailbox_layout(self, station: int) -> tuple[int, int, int, int]:
        """The standard mailbox the slave's SII declares (receive offset/size, send offset/size):
        one 8-byte EEPROM read, so a master can check the sync managers against it at every open."""
        with contextlib.suppress(CommError):
            self.fpwr(station, ec.REG_EEP_CONFIG, b"\x00")  # EEPROM access by ECAT (the master)
        try:
            return decode_mailbox_layout(self.read_sii_bytes(station, MAILBOX_LAYOUT_OFFSET, 8))
        except CodecError as exc:
            raise CommError(f"slave 0x{station:04X}: SII mailbox words do not decode: {exc}") from None

    def configure_mailbox(self, station: int, sii: SiiImage) -> None:
        if not sii.std_rx_size or not sii.std_tx_size:
            raise UsageError(f"slave 0x{station:04X} has no mailbox (SII declares none): no CoE access")
        sm0 = ec.SyncManager(sii.std_rx_offset, sii.std_rx_size, 0x26, 0, ec.SM_ACTIVATE_ENABLE)
        sm1 = ec.SyncManager(sii.std_tx_offset, sii.std_tx_size, 0x22, 0, ec.SM_ACTIVATE_ENABLE)
        self.fpwr(station, ec.REG_SM0, sm0.encode() + sm1.encode())

    def request_state(self, station: int, state: int) -> tuple[int, int]:
        """Request an AL state and wait for it; DriveError with the AL status code in words if refused."""
        self.fpwr(station, ec.REG_AL_CONTROL, struct.pack("<H", state | ec.AL_ERROR_FLAG))
        deadline = time.monotonic() + max(self.timeout, 1.0)
        while True:
            status, code = self.al_status(station)
            if status & ec.AL_ERROR_FLAG:
                from akdctl.catalog.texts import al_status_text

                raise DriveError(
                    f"slave 0x{station:04X} refused {ec.AL_STATE_NAMES.get(state, hex(state))}: "
                    f"AL status code 0x{code:04X} {al_status_text(code)} (now {ec.al_state_name(status)})",
                    code=code, details={"al_status": status, "al_status_code": code})
            if status & 0x0F == state:
                return status, code
            if time.monotonic() > deadline:
                raise NoAnswer(f"slave 0x{station:04X} did not reach {ec.AL_STATE_NAMES.get(state, hex(state))} "
                               f"(still {ec.al_state_name(status)})")
            time.sleep(0.002)

    def scan(self, with_sii: bool = True) -> list[SlaveInfo]:
        count = self.count_slaves()
        if count == 0:
            raise NoAnswer(f"no EtherCAT slave answered on {self.ifname}")
        out = []
        for pos, station in enumerate(self.assign_addresses(count)):
            status, code = self.al_status(station)
            sii = self.read_sii(station, full=True)[0] if with_sii else None
            out.append(SlaveInfo(pos, station, status, code, sii))
        return out


class RawMailboxLink(MailboxLink):
    """The mailbox of one slave: write SM0, poll SM1, read about the reply's length.

    Per request: one frame writes SM0 (the whole buffer, as SOEM and IgH do: the ESC takes the
    mailbox when its last byte is written), and the first poll follows it at once, before the write's
    answer is back: it reaches the slave right behind the request, so a slave that answers within a
    frame's round trip (the simulator; a fast application) has the reply in SM1 when the poll passes,
    and the master's turnaround between the two frames is off the request's critical path; a slower
    slave costs that one poll, as polling right after the write's answer did. Each poll is one frame
    of two datagrams: the first ``K``
    bytes of SM1 and SM1's last byte. While SM1 is empty the ESC refuses both reads (WKC 0, nothing
    happens); once it is full the frame brings the reply and hands the buffer back to the slave
    (reading the last byte does), so a reply costs one frame, not a status poll plus a read -- and the
    working counter already says what SM1's "mailbox full" status bit would (so no datagram reads it:
    the slave has one less to process per poll). ``K`` is the length of the last reply (at least
    :data:`FIRST_READ`; SM1's whole length in one datagram when K reaches it); a reply longer
    than ``K`` is asked for again with the sync manager's repeat request and read whole -- the same
    mechanism that recovers a reply lost on the wire. Polls follow each other at once, then with
    growing pauses (20 µs doubling to 1 ms): no fixed sleep on the happy path. Replies left from an
    unanswered request are drained by the channel, only after a timeout.
    """

    #: Bytes of SM1 the first poll reads: a CoE SDO reply with up to 4 data bytes (6 + 10) and room.
    FIRST_READ = 32

    def __init__(self, master: EcatMaster, station: int, sm0: ec.SyncManager, sm1: ec.SyncManager) -> None:
        self.master, self.station, self.sm0, self.sm1 = master, station, sm0, sm1
        self.mailbox_size = min(sm0.length, sm1.length)
        self.repeats = 0
        self.polls = 0
        self.rereads = 0  # replies longer than the poll read, fetched again with the repeat request
        self._status_reg = self._sm_reg(1, 5)
        self._write = ec.FrameTemplate([ec.Datagram(ec.Cmd.FPWR, station, sm0.start, bytes(sm0.length))], MASTER_MAC)
        self._polls: dict[int, ec.FrameTemplate] = {}
        self._read = self._first_read = min(self.FIRST_READ, sm1.length)
        #: Polls sent with a request (:meth:`send`) not yet looked at: (their answer or None if lost, bytes read).
        self._early: deque[tuple[tuple[Any, ...] | None, int]] = deque()

    def _sm_reg(self, n: int, offset: int) -> int:
        return ec.REG_SM0 + ec.SM_STRIDE * n + offset

    def _poll_frame(self, size: int) -> ec.FrameTemplate:
        template = self._polls.get(size)
        if template is None:
            fprd, station, sm1 = ec.Cmd.FPRD, self.station, self.sm1
            datagrams = [ec.Datagram(fprd, station, sm1.start, bytes(size))]
            if size < sm1.length:
                datagrams.append(ec.Datagram(fprd, station, sm1.start + sm1.length - 1, b"\0"))
            template = self._polls[size] = ec.FrameTemplate(datagrams, MASTER_MAC)
        return template

    def send(self, mailbox: bytes) -> None:
        if len(mailbox) > self.sm0.length:
            raise CommError(f"mailbox of {len(mailbox)} bytes exceeds the slave's {self.sm0.length}-byte SM0")
        data = bytes(mailbox).ljust(self.sm0.length, b"\0")
        size = self._read
        self.polls += 1
        wrote, poll = self.master.txrx_pair(self._write, data, self._polls.get(size) or self._poll_frame(size))
        self._early.append((poll, size))
        if wrote is None:
            raise self.master._lost()  # the channel listens for the reply anyway (see below)
        if wrote[1] == 1:
            return
        deadline = time.monotonic() + self.master.timeout
        pause = _Pause()
        while True:
            # A lost frame is not repeated: the slave may have taken the request (and, with a fast
            # application, emptied SM0 again), so a repeat could apply it twice. FrameLost goes up: the
            # channel listens for the reply anyway and judges the outcome. WKC 0 means refused (SM0 still
            # full with an earlier request): nothing was written, so writing again is safe.
            if time.monotonic() > deadline:
                raise NoAnswer(f"slave 0x{self.station:04X} does not empty its receive mailbox (SM0 stays full)")
            pause.wait(deadline)
            _data, wkc = self.master.txrx_template(self._write, data)
            if wkc == 1:
                return

    def receive(self, timeout: float) -> bytes | None:
        deadline = time.monotonic() + max(0.0, timeout)
        pause: _Pause | None = None
        master = self.master
        early = self._early
        while True:
            got: tuple[Any, ...] | None
            if early:  # the poll that went out with the request: its answer first
                got, size = early.popleft()
                if got is not None and got[1] != 1:
                    continue  # it found SM1 empty: poll now (even a receive(0) polls once, as it always did)
            else:
                size = self._read
                self.polls += 1
                try:
                    got = master.txrx_template(self._polls.get(size) or self._poll_frame(size))
                except FrameLost:
                    got = None
            if got is None:  # the poll frame was lost, and perhaps the reply it read with it
                self._recover(deadline)
                continue
            data, data_wkc = got[0], got[1]
            if data_wkc == 1 and (len(got) == 2 or got[3] == 1):  # SM1 was full: read, and the slave's again
                length = min(MAILBOX_HEADER + (data[0] | data[1] << 8), self.sm1.length)
                if length <= size:
                    self._read = max(self._first_read, length)
                    return data[:length]
                # Longer than this poll read, and the buffer is the slave's again: have it put back, read it whole.
                self.rereads += 1
                self._read = length
                self._repeat(self.master.fprd(self.station, self._status_reg, 2)[1], deadline)  # 0x080E: activate
                continue
            if time.monotonic() >= deadline:
                return None
            if pause is None:
                pause = _Pause()
            pause.wait(deadline)

    def _recover(self, deadline: float) -> None:
        """A polling frame was lost: if it took the reply with it (SM1 now empty after having been read),
        ask for it again with the repeat request; if SM1 still holds it, just poll again."""
        try:
            status = self.master.fprd(self.station, self._sm_reg(1, 5), 2)
        except FrameLost:
            if time.monotonic() > deadline:
                raise
            return
        if not status[0] & ec.SM_STATUS_MAILBOX_FULL:
            self._repeat(status[1], deadline)

    def _repeat(self, activate: int, deadline: float) -> None:
        """The reply frame was lost: toggle the repeat request and wait for the acknowledge."""
        self.repeats += 1
        want = (activate ^ ec.SM_ACTIVATE_REPEAT) & 0xFF
        self.master.fpwr(self.station, self._sm_reg(1, 6), bytes([want]))
        pause = _Pause()
        while time.monotonic() < deadline + self.master.timeout:
            pdi = self.master.fprd(self.station, self._sm_reg(1, 7), 1)[0]
            if (pdi & ec.SM_PDI_REPEAT_ACK) == (want & ec.SM_ACTIVATE_REPEAT):
                return
            pause.wait(deadline + self.master.timeout)
        raise NoAnswer(f"slave 0x{self.station:04X} did not acknowledge the mailbox repeat request")


class _Pause:
    """Waits between polls: none for the first two, then 20 µs doubling to 1 ms, never past the deadline.

    Why not a fixed sleep: a slave answers a mailbox in microseconds (the simulator) to milliseconds (a
    drive's mailbox cycle); a fixed 200 µs sleep is too long for the one and too many polls for the other.
    """

    __slots__ = ("count", "seconds")
    FREE = 2
    FIRST = 20e-6
    LONGEST = 1e-3

    def __init__(self) -> None:
        self.count = 0
        self.seconds = self.FIRST

    def wait(self, deadline: float) -> None:
        self.count += 1
        if self.count <= self.FREE:
            return
        time.sleep(max(0.0, min(self.seconds, deadline - time.monotonic())))
        self.seconds = min(self.LONGEST, self.seconds * 2)


def interface_name(target: Target) -> str:
    """The interface as typed: URL parsing lower-cases host names, interface names are case-sensitive."""
    rest = target.raw.split("://", 1)[-1]
    name = rest.split("/", 1)[0].split("?", 1)[0]
    return name or target.host


class EthercatRawTransport(Transport):
    """CoE object channel to the slave at POSITION, with akdctl as the master."""

    scheme = "ecat"

    def __init__(self, target: Target, options: LinkOptions) -> None:
        super().__init__(target, options)
        self.master: EcatMaster | None = None
        self.slave: SlaveInfo | None = None
        self.link: RawMailboxLink | None = None

    @property
    def position(self) -> int:
        parts = self.target.path_parts
        return int(parts[0], 0) if parts else 0

    def open(self) -> None:
        self.open_bus()
        self.open_mailbox()

    def open_bus(self) -> EcatMaster:
        """Socket, slave count and station addresses; nothing changes state yet."""
        if self.master is None:
            self.master = EcatMaster(interface_name(self.target), self.options.tracer, self.options.timeout,
                                     self.options.retries)
        master = self.master
        count = master.count_slaves()
        if count == 0:
            raise NoAnswer(f"no EtherCAT slave answered on {interface_name(self.target)} (BRD working counter 0)")
        if self.position >= count:
            raise UsageError(f"target {self.target.raw!r}: no slave at position {self.position} "
                             f"({count} slave{'s' if count != 1 else ''} found, positions 0..{count - 1})")
        stations = master.assign_addresses(count)
        station = stations[self.position]
        status, code = master.al_status(station)
        self.slave = SlaveInfo(self.position, station, status, code)
        return master

    def open_mailbox(self) -> None:
        """Use the slave's mailbox as it is when it is running and its sync managers agree with the SII;
        otherwise (re)configure it from the SII: INIT, SM0/SM1, PRE-OP.

        Why check the SII every time: a slave whose SM registers were changed behind our back (fuzzed
        ESC writes left a 1-byte SM0) would otherwise be trusted until someone ran ``ecat state INIT``.
        The check costs one 8-byte EEPROM read.
        """
        master, slave = self.master, self.slave
        assert master is not None and slave is not None
        state = slave.al_status & 0x0F
        sm0 = ec.SyncManager.decode(master.fprd(slave.station, ec.REG_SM0, 8))
        sm1 = ec.SyncManager.decode(master.fprd(slave.station, ec.REG_SM0 + ec.SM_STRIDE, 8))
        ready = (state in (ec.AlState.PREOP, ec.AlState.SAFEOP, ec.AlState.OP)
                 and not slave.al_status & ec.AL_ERROR_FLAG and sm0.enabled and sm1.enabled
                 and sm0.is_mailbox and sm1.is_mailbox)  # an SM1 in buffered mode presents stale data for ever
        if ready and (sm0.start, sm0.length, sm1.start, sm1.length) != master.mailbox_layout(slave.station):
            ready = False  # the sync managers disagree with the SII: re-establish the mailbox from it
        if not ready:
            if state == ec.AlState.BOOT:  # BOOT leaves to INIT only, and the drive restarts (a firmware download)
                self.leave_boot(BOOT_EXIT_TIMEOUT)
                slave = self.slave
                assert slave is not None
            sii, _raw = master.read_sii(slave.station, full=False)
            slave.sii = sii
            if state != ec.AlState.INIT or slave.al_status & ec.AL_ERROR_FLAG:
                master.request_state(slave.station, ec.AlState.INIT)
            master.configure_mailbox(slave.station, sii)
            slave.al_status, slave.al_code = master.request_state(slave.station, ec.AlState.PREOP)
            sm0 = ec.SyncManager.decode(master.fprd(slave.station, ec.REG_SM0, 8))
            sm1 = ec.SyncManager.decode(master.fprd(slave.station, ec.REG_SM0 + ec.SM_STRIDE, 8))
        self.link = self.mailbox_link = RawMailboxLink(master, slave.station, sm0, sm1)

    # ------------------------------------------------------------------ bootstrap (firmware download)
    def enter_boot(self) -> RawMailboxLink:
        """INIT, SM0/SM1 from the SII's bootstrap mailbox (words 0x14-0x17), BOOT: the state a firmware file is
        written in (reference foe-alias-recorder.md A1/A6; SOEM's firm_update does the same). Returns the
        bootstrap mailbox; a slave whose SII declares none is refused before anything changes."""
        master, slave = self.master, self.slave
        assert master is not None and slave is not None
        sii, _raw = master.read_sii(slave.station, full=False)
        slave.sii = sii
        if not sii.boot_rx_size or not sii.boot_tx_size:
            raise UsageError(f"slave 0x{slave.station:04X} declares no bootstrap mailbox in its SII (words 0x14-0x17): "
                             "it cannot take a file in BOOT")
        if slave.al_status & 0x0F != ec.AlState.INIT or slave.al_status & ec.AL_ERROR_FLAG:
            master.request_state(slave.station, ec.AlState.INIT)
        sm0 = ec.SyncManager(sii.boot_rx_offset, sii.boot_rx_size, 0x26, 0, ec.SM_ACTIVATE_ENABLE)
        sm1 = ec.SyncManager(sii.boot_tx_offset, sii.boot_tx_size, 0x22, 0, ec.SM_ACTIVATE_ENABLE)
        master.fpwr(slave.station, ec.REG_SM0, sm0.encode() + sm1.encode())
        slave.al_status, slave.al_code = master.request_state(slave.station, ec.AlState.BOOT)
        self.link = self.mailbox_link = RawMailboxLink(master, slave.station, sm0, sm1)
        return self.link

    def leave_boot(self, timeout: float) -> float:
        """Request INIT from BOOT -- the drive takes the file and restarts -- and wait until it answers again in
        INIT; returns the seconds it took. The AL-control write may go unanswered (the slave restarting):
        that is expected. NoAnswer (exit 3) when it is not back within ``timeout``."""
        master, slave = self.master, self.slave
        assert master is not None and slave is not None
        start = time.monotonic()
        self.link = self.mailbox_link = None
        with contextlib.suppress(CommError):
            master.write(ec.Cmd.FPWR, slave.station, ec.REG_AL_CONTROL, struct.pack("<H", ec.AlState.INIT), retries=0)
        return self.wait_back(timeout, start)

    def wait_back(self, timeout: float, start: float | None = None) -> float:
        """Poll the line until the slave at POSITION answers again (a restart clears its station address, so
        addresses are given again), in INIT or higher and not in BOOT; seconds since ``start``."""
        master = self.master
        assert master is not None
        start = time.monotonic() if start is None else start
        deadline = start + timeout
        last = "no frame came back"
        while True:
            try:
                count = master.count_slaves()
                if count > self.position:
                    station = master.assign_addresses(count)[self.position]
                    status, code = master.al_status(station)
                    if status & 0x0F not in (0, ec.AlState.BOOT):
                        self.slave = SlaveInfo(self.position, station, status, code)
                        return time.monotonic() - start
                    last = f"still in {ec.al_state_name(status)}"
                else:
                    last = f"{count} slave(s) answer"
            except CommError as exc:
                last = str(exc)
            if time.monotonic() > deadline:
                raise NoAnswer(f"the drive did not answer again within {timeout:g} s after leaving BOOT ({last}); "
                               "power-cycle it and check its firmware with 'akdctl ecat scan'")
            time.sleep(0.2)

    cyclic_master = True

    def process_data(self, rx_bytes: int, tx_bytes: int) -> "ProcessDataCycle":
        """Our master's cyclic exchange with the slave this target names (opened: its station is known)."""
        if self.master is None or self.slave is None:
            raise CommError(f"{self.target.display}: the bus is not open")
        return ProcessDataCycle(self.master, self.slave.station, rx_bytes, tx_bytes)

    def al_state(self) -> str | None:
        """The slave's AL state read now from its AL status register (0x0130): 'PREOP', 'OP', 'SAFEOP+ERR' …

        Rules that depend on it (SPEC-NOTES 23: an SDO controlword does nothing while process data owns it
        in OP; PDO mapping only in PRE-OP) ask every transport the same way; None before the bus is open.
        """
        if self.master is None or self.slave is None:
            return None
        status, code = self.master.al_status(self.slave.station)
        self.slave.al_status, self.slave.al_code = status, code
        return ec.al_state_name(status)

    def close(self) -> None:
        self.mailbox_link = None
        if self.master is not None:
            self.master.close()
            self.master = None


# ---------------------------------------------------------------------- cyclic process data (our master)

#: The logical address our master maps the slave's process data to (outputs first, inputs behind them).
LOGICAL_BASE = 0x00010000
#: SM2/SM3 of the AKD (ESI and the real SII: outputs 0x1100, inputs 0x1140), control bytes as its SII gives them:
#: 0x64 = buffered, ECAT writes, watchdog on; 0x20 = buffered, ECAT reads.
SM2_START, SM3_START = 0x1100, 0x1140
SM2_CONTROL, SM3_CONTROL = 0x64, 0x20


class ProcessDataCycle:
    """Our master's cyclic exchange with one slave: SM2/SM3 and two FMMUs programmed in PRE-OP, then one frame
    per cycle holding an LRW of the whole image and, when asked (``ecat pdo watch``: every display refresh), an
    FPRD of the AL status, so the working counter and whether the slave is still in OP come in one frame.

    Why LRW: one datagram writes the outputs and reads the inputs (WKC 3 per slave in OP: +1 read, +2 write);
    the expected WKC is derived from the mapping (``expected_wkc``), as SOEM derives it from its groups.
    """

    def __init__(self, master: EcatMaster, station: int, rx_bytes: int, tx_bytes: int) -> None:
        if rx_bytes + tx_bytes == 0:
            raise UsageError("the slave maps no process data (0x1C12/0x1C13 assign nothing): nothing to exchange")
        self.master, self.station, self.rx_bytes, self.tx_bytes = master, station, rx_bytes, tx_bytes
        self.expected_wkc = (2 if rx_bytes else 0) + (1 if tx_bytes else 0)
        self.cycles = 0
        # with/without the AL status read: each encoded once, with the outputs it holds now (stamped again only
        # when they change)
        self._frames: dict[bool, list[Any]] = {}  # [template, the outputs it holds (None: not stamped yet)]

    def configure(self) -> None:
        """In PRE-OP: SM2/SM3 with the mapping's lengths, FMMU0 outputs, FMMU1 inputs."""
        m, st = self.master, self.station
        sms = b""
        for start, length, control in ((SM2_START, self.rx_bytes, SM2_CONTROL), (SM3_START, self.tx_bytes, SM3_CONTROL)):
            sms += ec.SyncManager(start, length, control, 0, ec.SM_ACTIVATE_ENABLE if length else 0).encode()
        m.fpwr(st, ec.REG_SM0 + 2 * ec.SM_STRIDE, sms)
        fmmus = b""
        for logical, length, physical, kind in ((LOGICAL_BASE, self.rx_bytes, SM2_START, 2),
                                                 (LOGICAL_BASE + self.rx_bytes, self.tx_bytes, SM3_START, 1)):
            fmmus += struct.pack("<IHBBHBBB3x", logical, length, 0, 7, physical, 0, kind, 1 if length else 0)
        m.fpwr(st, ec.REG_FMMU0, fmmus)

    def exchange(self, outputs: bytes, with_status: bool = True) -> tuple[bytes, int, int | None]:
        """One cycle: (inputs, working counter of the LRW, AL status or None when not asked for). FrameLost when
        the frame is lost. The AL status rides in the same frame when ``with_status``."""
        known = self._frames.get(with_status)
        if known is None:  # the same frame every cycle but for its index and outputs (as the mailbox polls)
            datagrams = [ec.logical_datagram(ec.Cmd.LRW, LOGICAL_BASE, bytes(self.rx_bytes + self.tx_bytes))]
            if with_status:
                datagrams.append(ec.Datagram(ec.Cmd.FPRD, self.station, ec.REG_AL_STATUS, bytes(2)))
            known = self._frames[with_status] = [ec.FrameTemplate(datagrams, MASTER_MAC, answer_from=self.rx_bytes),
                                                 None]
        if outputs == known[1]:  # the outputs the frame holds (the usual cycle: the same outputs again)
            got = self.master.txrx_cyclic(known[0])
        else:  # (the inputs' part of the LRW goes out as zeros)
            image = bytes(outputs[:self.rx_bytes]).ljust(self.rx_bytes, b"\0") + bytes(self.tx_bytes)
            got = self.master.txrx_cyclic(known[0], image)
            known[1] = bytes(outputs)  # stamped and sent: the frame holds these outputs now
        self.cycles += 1
        if not with_status:
            return got[0], got[1], None  # (the LRW's data from the inputs on: answer_from)
        return got[0], got[1], (struct.unpack("<H", got[2])[0] if got[3] == 1 else 0)  # (data, WKC) flat

    # The steps around the exchange (drive/ecat_pdo_watch.py enter/leave, the scope's pdo source) talk to the one
    # slave this cycle serves, so they take the cycle alone, never the transport behind it.
    def al_status(self) -> tuple[int, int]:
        """(AL status, AL status code) of the slave now."""
        return self.master.al_status(self.station)

    def request_state(self, state: int) -> tuple[int, int]:
        """Take the slave to ``state`` (:meth:`EcatMaster.request_state`)."""
        return self.master.request_state(self.station, state)

    @property
    def safeop_wkc(self) -> int:
        """The LRW's working counter in SAFE-OP: the inputs only (the slave takes no outputs before OP)."""
        return 1 if self.tx_bytes else 0
