"""The adapter side of an slcan (Lawicel ASCII) serial line, as a python-can bus.

A USB-CAN adapter speaking slcan (CANable, CANtact, Lawicel CANUSB ...) sits
between a serial port and a CAN bus. To test akdctl's ``can://slcan/...``
path end to end -- python-can's slcan interface through pyserial -- the
simulator plays that adapter on a pseudo-terminal: the host opens the pty's
slave device as its serial port; this bus owns the master side, parses the
host's commands (``S``/``s`` bitrate, ``O``/``L`` open, ``C`` close, ``V``/``v``
version, ``N`` serial, ``F`` status, ``t``/``T``/``r``/``R`` transmit) and
writes every frame the simulated node sends as ``tIIIL<data>`` lines while the
channel is open.

The simulator's own code keeps a slave descriptor open so that the master never
reads EIO between clients; frames sent while no host has the channel open are
dropped, as an adapter whose channel is closed drops them.
"""

from __future__ import annotations

import errno
import os
import select
import threading
import time
import tty
from typing import Any

import can

from akdctl.errors import UsageError

OK = b"\r"
ERROR = b"\a"
#: Bitrates of the ``Sn`` command (Lawicel).
BITRATES = {0: 10000, 1: 20000, 2: 50000, 3: 100000, 4: 125000, 5: 250000, 6: 500000, 7: 750000, 8: 1000000, 9: 83300}


class SlcanDeviceBus(can.BusABC):
    """A python-can bus whose wire is the master side of a fresh pseudo-terminal.

    ``tty_path`` is the device a host opens (``can://slcan//dev/pts/N/NODE``);
    ``link`` optionally names a symlink to it that is created and removed with the bus. The link must be a new
    path: whatever already exists there (a user's file, a link of another run) is never replaced or removed.
    """

    def __init__(self, channel: Any = None, link: str | None = None, **kwargs: Any) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no line editing: the line carries a protocol
        os.set_blocking(self._master, False)
        self.tty_path = os.ttyname(self._slave)
        self.link = link
        if link:
            try:
                os.symlink(self.tty_path, link)  # fails on any existing path: nothing is overwritten
            except OSError as exc:
                self._close_pty()
                raise UsageError(_link_refusal(link, exc)) from None
        self.is_open = False
        self.bitrate: int | None = None
        self._buffer = bytearray()
        self._pending: list[can.Message] = []
        self._write_lock = threading.Lock()
        self._closed = False
        self.channel_info = f"slcan device on {self.tty_path}"
        super().__init__(channel=self.tty_path, **kwargs)

    # -- host -> adapter --------------------------------------------------------------------------------------
    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if self._pending:
                return self._pending.pop(0), False
            line = self._take_line()
            if line is not None:
                self._handle(line)
                continue
            wait = None if deadline is None else max(0.0, deadline - time.monotonic())
            if self._closed:
                return None, False
            ready, _, _ = select.select([self._master], [], [], wait if wait is not None else 0.5)
            if ready:
                try:
                    chunk = os.read(self._master, 4096)
                except BlockingIOError:
                    chunk = b""
                except OSError as exc:
                    if exc.errno != errno.EIO:
                        raise can.CanOperationError(f"slcan pty read failed: {exc}") from None
                    chunk = b""
                    time.sleep(0.01)
                self._buffer.extend(chunk)
            elif deadline is not None and time.monotonic() >= deadline:
                return None, False

    def _take_line(self) -> bytes | None:
        cut = self._buffer.find(b"\r")
        if cut < 0:
            if len(self._buffer) > 256:  # garbage without a terminator: drop it
                self._buffer.clear()
            return None
        line = bytes(self._buffer[:cut]).lstrip(b"\n")
        del self._buffer[:cut + 1]
        return line

    def _handle(self, line: bytes) -> None:
        """Execute one host command and answer it the way a Lawicel adapter does."""
        if not line:
            return self._reply(OK)
        cmd, arg = chr(line[0]), line[1:].decode("ascii", "replace")
        try:
            if cmd in "tTrR":
                if not self.is_open:
                    return self._reply(ERROR)
                self._pending.append(parse_frame(line))
                return self._reply(b"z\r" if cmd in "tr" else b"Z\r")
            if cmd == "S":
                self.bitrate = BITRATES[int(arg)]
            elif cmd == "s":
                int(arg, 16)
            elif cmd in "OL":
                self.is_open = True
            elif cmd == "C":
                self.is_open = False
            elif cmd == "V":
                return self._reply(b"V1013\r")
            elif cmd == "v":
                return self._reply(b"vSTM32\r")
            elif cmd == "N":
                return self._reply(b"NAKD0\r")
            elif cmd == "F":
                return self._reply(b"F00\r")
            elif cmd in "XWMmZQY":
                pass  # options a real adapter accepts; they do not change the simulation
            else:
                return self._reply(ERROR)
        except (ValueError, KeyError, IndexError):
            return self._reply(ERROR)
        return self._reply(OK)

    # -- adapter -> host --------------------------------------------------------------------------------------
    def _reply(self, data: bytes) -> None:
        self._write(data)

    def _write(self, data: bytes) -> None:
        with self._write_lock:
            view = memoryview(data)
            deadline = time.monotonic() + 0.5
            while view:
                try:
                    written = os.write(self._master, view)
                    view = view[written:]
                except BlockingIOError:
                    if time.monotonic() > deadline:
                        return  # nobody reads the line: drop, as a full adapter FIFO does
                    select.select([], [self._master], [], 0.05)
                except OSError:
                    return

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if not self.is_open:
            return  # channel closed: the frame goes to the bus, nobody on the serial side sees it
        self._write(format_frame(msg))

    def shutdown(self) -> None:
        if self._closed:
            return
        self._closed = True
        super().shutdown()
        self._close_pty()
        if self.link:
            try:
                if os.readlink(self.link) == self.tty_path:  # still the link we made, not a path put there since
                    os.unlink(self.link)
            except OSError:
                pass

    def _close_pty(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass


def _link_refusal(link: str, exc: OSError) -> str:
    if exc.errno == errno.EEXIST:
        return (f"--can slcan-pty:{link}: {link} already exists and is left alone; name a new path for the link "
                "(remove it yourself if it is a link an earlier run left behind)")
    return f"--can slcan-pty:{link}: cannot create the link: {exc.strerror or exc}"


def format_frame(msg: can.Message) -> bytes:
    """One frame as an slcan line (``t``/``T`` data, ``r``/``R`` remote)."""
    if msg.is_extended_id:
        head = f"{'R' if msg.is_remote_frame else 'T'}{msg.arbitration_id:08X}{msg.dlc:d}"
    else:
        head = f"{'r' if msg.is_remote_frame else 't'}{msg.arbitration_id:03X}{msg.dlc:d}"
    body = "" if msg.is_remote_frame else bytes(msg.data).hex().upper()
    return (head + body).encode("ascii") + b"\r"


def parse_frame(line: bytes) -> can.Message:
    """Parse a ``t``/``T``/``r``/``R`` line; raises ``ValueError`` if it is malformed."""
    text = line.decode("ascii")
    kind = text[0]
    extended = kind in "TR"
    id_len = 8 if extended else 3
    can_id = int(text[1:1 + id_len], 16)
    dlc = int(text[1 + id_len])
    if dlc > 8 or can_id > (0x1FFFFFFF if extended else 0x7FF):
        raise ValueError("slcan frame out of range")
    remote = kind in "rR"
    hexdata = text[2 + id_len:]
    if remote:
        data = b""
    else:
        if len(hexdata) != 2 * dlc:
            raise ValueError("slcan frame length does not match its DLC")
        data = bytes.fromhex(hexdata)
    return can.Message(arbitration_id=can_id, is_extended_id=extended, is_remote_frame=remote, dlc=dlc,
                       data=data, timestamp=time.time())
