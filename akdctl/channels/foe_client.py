"""FoE client: write or read one file through an EtherCAT mailbox (ETG.1000.6 FoE; reference foe-alias-recorder.md A1).

Why our own client instead of SOEM's: SOEM and pysoem drop the slave's FoE error code and text ("take a
Wireshark dump", SOEM issue #76); a technician flashing a drive needs the code *and* the words, a progress
bar and a bounded wait. The client works over any :class:`~akdctl.links.MailboxLink` (the raw master's
bootstrap mailbox, in-memory links in tests); it never changes the AL state -- the caller puts the slave in
BOOT (firmware) or leaves it where it is.

Rules, as SOEM, IgH and SOES agree (reference A1):

* write: WRQ -> ACK 0, DATA n -> ACK n; a DATA shorter than mailbox - 12 bytes ends the file, so a file
  that fills its last packet exactly is followed by an empty DATA;
* read: RRQ -> DATA 1, ACK n -> DATA n+1 until a short DATA, which is acknowledged too;
* BUSY (the slave is flashing) instead of an ACK: send the same DATA again (write) or the same ACK again
  (read; SOEM does not handle that, IgH and SSC 5.11 do) -- bounded by the per-packet timeout;
* an ACK or DATA with an unexpected packet number ends the transfer with a FoE error frame to the slave
  (0x8005) and a one-line :class:`~akdctl.errors.MalformedReply`;
* the slave's ERR frame becomes a :class:`~akdctl.errors.DriveError` with its code and text (and the
  standard words for the code; codes seen without the 0x8000 base -- SOEM issue #729 -- are named too).

Every wait is bounded by ``timeout`` per packet (the AKD ESI's mailbox timeout is 3 s) and, when given,
an overall ``deadline`` (monotonic seconds), whatever the slave keeps sending.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from akdctl.errors import DriveError, MalformedReply, NoAnswer
from akdctl.links import MailboxLink
from akdctl.protocol import foe
from akdctl.protocol import mailbox as mbx
from akdctl.protocol.errors import CodecError

#: progress(bytes done, bytes in all or None when unknown) -- called after each acknowledged packet.
Progress = Callable[[int, "int | None"], None]


class FoeRefusedError(DriveError):
    """The slave answered a FoE request with an ERR frame: ``code`` is its FoE error code."""


def foe_error_words(code: int, text: str = "") -> str:
    """'0x8001 Not found' (+ the slave's own text when it sent one)."""
    from akdctl.catalog.texts import FOE_ERROR_TEXTS

    words = FOE_ERROR_TEXTS.get(code) or FOE_ERROR_TEXTS.get(code | 0x8000) or "unknown FoE error code"
    slave = text.strip().strip("\0")
    return f"FoE error 0x{code:04X} {words}" + (f" (slave says: {slave!r})" if slave and slave != words else "")


class FoeClient:
    """One FoE conversation over ``link``; ``mailbox_size`` is the receive mailbox (SM0) length."""

    def __init__(self, link: MailboxLink, mailbox_size: int, timeout: float = 3.0, deadline: float | None = None,
                 who: str = "slave") -> None:
        if foe.packet_data_size(mailbox_size) < 1:
            raise MalformedReply(f"{who}: a mailbox of {mailbox_size} bytes cannot carry FoE data")
        self.link, self.mailbox_size, self.timeout, self.deadline, self.who = link, mailbox_size, timeout, deadline, who
        self.chunk = foe.packet_data_size(mailbox_size)
        self._counter = 0
        self.busy_count = 0
        self.packets = 0
        #: How long one packet may stay BUSY, seconds [I]: the AKD's flashing time per packet is not published;
        #: its ESI allows 50 s for the bootstrap transitions, which bounds this from above.
        self.busy_timeout = 50.0

    # ------------------------------------------------------------ frames
    def _send(self, frame: foe.FoeFrame) -> None:
        self._counter = mbx.next_counter(self._counter)
        self.link.send(mbx.pack(mbx.MailboxType.FOE, foe.encode_foe(frame), 0, self._counter))

    def _receive(self, waiting_for: str) -> foe.FoeFrame:
        """The next FoE frame; mailboxes of other types (an emergency) are skipped; bounded by the timeouts."""
        end = time.monotonic() + self.timeout
        if self.deadline is not None:
            end = min(end, self.deadline)
        while True:
            left = end - time.monotonic()
            if left <= 0:
                raise NoAnswer(f"{self.who} did not answer the FoE {waiting_for} within {self.timeout:g} s")
            raw = self.link.receive(left)
            if raw is None:
                continue
            try:
                mtype, _counter, _addr, data = mbx.split(raw)
            except CodecError:
                continue
            if mtype == 0:  # mailbox error reply: FoE is not served (state or protocol)
                try:
                    reply = mbx.decode_error_reply(data)
                except CodecError:
                    raise MalformedReply(f"{self.who} sent a malformed mailbox error reply") from None
                raise DriveError(f"{self.who} refused the FoE request with a mailbox error {reply.code} "
                                 f"({_mailbox_error_words(reply.code)}): FoE is not served in this state",
                                 code=reply.code)
            if mtype != mbx.MailboxType.FOE:
                continue
            try:
                return foe.decode_foe(data)
            except CodecError as exc:
                raise MalformedReply(f"{self.who} sent a FoE frame that does not decode: {exc}") from None

    def _refused(self, frame: foe.FoeFrame, what: str) -> FoeRefusedError:
        text = frame.data.decode("latin-1", "replace")
        return FoeRefusedError(f"{self.who} refused the FoE {what}: {foe_error_words(frame.value, text)}",
                               code=frame.value, details={"foe_error": frame.value, "foe_text": text})

    def _abort(self, message: str) -> MalformedReply:
        """Tell the slave the transfer is over (0x8005), then the error for our caller."""
        try:
            self._send(foe.error(foe.ERR_PACKET_NUMBER, "packet number wrong"))
        except Exception:  # noqa: BLE001 - the error we report is the reason, not the goodbye
            pass
        return MalformedReply(f"{self.who}: {message}; transfer stopped")

    # ------------------------------------------------------------ write
    def write(self, name: str, data: bytes, password: int = 0, progress: Progress | None = None) -> int:
        """Send ``data`` as file ``name``; returns the number of DATA packets. Raises on refusal or silence."""
        self._send(foe.write_request(name, password))
        reply = self._receive("write request's acknowledgement")
        if reply.opcode == foe.FoeOpcode.ERROR:
            raise self._refused(reply, f"write of {name!r}")
        if reply.opcode != foe.FoeOpcode.ACK or reply.value != 0:
            raise self._abort(f"answered the write request with opcode {reply.opcode} #{reply.value}, not ACK 0")
        total, sent, number = len(data), 0, 0
        while True:
            chunk = data[sent:sent + self.chunk]
            number += 1
            packet = foe.data_packet(number & 0xFFFFFFFF, chunk)
            busy_until = time.monotonic() + self.busy_timeout
            while True:
                self._send(packet)
                reply = self._receive(f"acknowledgement of packet {number}")
                if reply.opcode == foe.FoeOpcode.BUSY:
                    self.busy_count += 1  # flashing: the same packet again (SOEM, IgH), for a bounded time
                    self._busy_check(busy_until, reply, f"packet {number}")
                    continue
                break
            if reply.opcode == foe.FoeOpcode.ERROR:
                raise self._refused(reply, f"write of {name!r} at packet {number} (byte {sent})")
            if reply.opcode != foe.FoeOpcode.ACK:
                raise self._abort(f"answered packet {number} with opcode {reply.opcode}, not ACK")
            if reply.value != number:
                raise self._abort(f"acknowledged packet {reply.value} when packet {number} was sent")
            sent += len(chunk)
            self.packets = number
            if progress is not None:
                progress(sent, total)
            if len(chunk) < self.chunk:
                return number

    # ------------------------------------------------------------ read
    def read(self, name: str, password: int = 0, max_size: int = 16 * 1024 * 1024,
             progress: Progress | None = None) -> bytes:
        """Read file ``name``; at most ``max_size`` bytes (a larger file is refused, not stored)."""
        self._send(foe.read_request(name, password))
        out = bytearray()
        number = 0
        busy_until = 0.0
        while True:
            reply = self._receive(f"data packet {number + 1}")
            if reply.opcode == foe.FoeOpcode.BUSY:
                self.busy_count += 1
                busy_until = busy_until or time.monotonic() + self.busy_timeout
                self._busy_check(busy_until, reply, f"data packet {number + 1}")
                self._send(foe.ack(number) if number else foe.read_request(name, password))
                continue
            busy_until = 0.0
            if reply.opcode == foe.FoeOpcode.ERROR:
                raise self._refused(reply, f"read of {name!r}" + (f" at packet {number + 1}" if number else ""))
            if reply.opcode != foe.FoeOpcode.DATA:
                raise self._abort(f"answered with opcode {reply.opcode} where data packet {number + 1} was due")
            if reply.value != number + 1:
                raise self._abort(f"sent data packet {reply.value} where packet {number + 1} was due")
            if len(reply.data) > self.chunk:
                raise self._abort(f"sent {len(reply.data)} bytes in one packet, more than the {self.chunk} "
                                  "its mailbox allows")
            number = reply.value
            out += reply.data
            if len(out) > max_size:
                raise self._abort(f"file {name!r} is larger than the {max_size} bytes allowed (--max-size)")
            self._send(foe.ack(number))
            self.packets = number
            if progress is not None:
                progress(len(out), None)
            if len(reply.data) < self.chunk:
                return bytes(out)

    def _busy_check(self, until: float, reply: foe.FoeFrame, what: str) -> None:
        """A BUSY slave is asked again after a short pause -- until ``busy_timeout`` or the deadline runs out."""
        now = time.monotonic()
        if now > until or (self.deadline is not None and now > self.deadline):
            done, entire = foe.busy_progress(reply)
            raise NoAnswer(f"{self.who} stayed busy for {self.busy_timeout:g} s at {what} "
                           f"(busy {done}/{entire}); transfer not finished")
        self._pause()

    def _pause(self) -> None:
        wait = 0.01
        if self.deadline is not None:
            wait = max(0.0, min(wait, self.deadline - time.monotonic()))
        time.sleep(wait)


def _mailbox_error_words(code: int) -> str:
    from akdctl.catalog.texts import mailbox_error_text

    return mailbox_error_text(code)
