"""``mb://HOST[:502][?unit=N]``: Modbus TCP to the AKD's parameter registers, through akdctl's own codec.

The AKD's map (AKD User Guide ch. 22, reference ethernetip.md 3 and akd-parameter-names.md 2.4): parameter ``n``
sits at holding register ``2(n-1)``; a parameter of 32 bits or less is two registers read or written in one
message, the lower address holding the most significant word [V]; floats travel x1000 [V]. Which names have
which ``n`` is the catalogue's business (``drive/names.py`` turns a name into registers); this transport only
reads and writes registers. The bytes are :mod:`akdctl.protocol.modbus`'s, the socket waits are
:mod:`akdctl.transport.tcp_stream`'s: a request is one send and, on loopback or a LAN, one receive, every wait
bounded by one deadline of the command's Budget. A request is sent once (the Budget's rule for writes); a reply
whose transaction identifier is not the request's (a late answer to an earlier request that timed out) is
skipped, so the connection stays in step.
"""

from __future__ import annotations

import socket
from typing import TYPE_CHECKING

from akdctl.errors import CommError, MalformedReply, ModbusRefused, NoAnswer, UsageError
from akdctl.links import RegisterLink
from akdctl.protocol import modbus as codec
from akdctl.protocol.errors import CodecError
from akdctl.transport.base import LinkOptions, Transport
from akdctl.transport.tcp_stream import TcpStream

if TYPE_CHECKING:
    from akdctl.links import Deadline
    from akdctl.transport.target import Target

PORT = 502
#: Modbus exception codes in words (Modbus Application Protocol v1.1b3, 7).
EXCEPTIONS = {1: "illegal function", 2: "illegal data address", 3: "illegal data value", 4: "server device failure",
              5: "acknowledge", 6: "server device busy"}


class ModbusLink(RegisterLink):
    """One TCP connection to the drive's Modbus server. Not thread-safe (one invocation, one caller)."""

    def __init__(self, stream: TcpStream, unit: int, options: LinkOptions, label: str) -> None:
        self.stream = stream
        self.unit = unit
        self.options = options
        self.tracer = options.tracer
        self.budget = options.budget
        self.label = label
        self.transaction = 0
        self.buffer = b""   # bytes received after the last whole reply

    def _trace(self, direction: str, adu: bytes) -> None:
        """A Modbus TCP ADU as a TCP segment (``--trace``, ``--pcap``; layer ``mb``)."""
        meta: dict[str, object] = {}
        ends = self.stream.local_and_remote()
        if ends is not None:
            local, remote = ends
            src, dst = (local, remote) if direction == "tx" else (remote, local)
            meta = {"proto": "tcp", "src": src, "dst": dst}
        self.tracer.frame(direction, "mb", adu, note=self.label, meta=meta)  # type: ignore[arg-type]

    def _exchange(self, adu: bytes, what: tuple[str, int, int]) -> bytes:
        """Send one request ADU, return its whole reply ADU (``what``: verb, address, count -- words for an error,
        built only then)."""
        with self.budget.request(attempts=1) as deadline:
            reply = None
            if self.buffer or self.tracer.active:
                self._send(adu, what)
            else:   # the usual exchange: the request out, its reply back whole in one segment (the deadline was
                # set microseconds ago, so its total is what is left, within tcp_stream's slack)
                try:
                    data = self.stream.request(adu, deadline.total or 0.001)
                except OSError as exc:
                    raise self._failed(exc, what) from None
                if data is not None and len(data) >= 6 and data[4] << 8 | data[5] == len(data) - 6:
                    reply = data
                elif data:
                    self.buffer = data
            while reply is None or reply[:2] != adu[:2]:   # a reply to an earlier request is skipped
                reply = self._reply(deadline, what)
        if self.tracer.active:
            self._trace("rx", reply)
        return reply

    def _send(self, adu: bytes, what: tuple[str, int, int]) -> None:
        if self.tracer.active:
            self._trace("tx", adu)
        try:
            self.stream.send(adu)
        except OSError as exc:
            raise self._failed(exc, what) from None

    def _failed(self, exc: OSError, what: tuple[str, int, int]) -> CommError:
        if isinstance(exc, socket.timeout):   # only a send waits in a way that raises
            return NoAnswer(f"{self.label}: could not send {self._words(what)} in time")
        return CommError(f"{self.label}: connection failed during {self._words(what)} ({exc.strerror or exc})")

    def _words(self, what: tuple[str, int, int]) -> str:
        verb, address, count = what
        return f"{verb} registers {address}..{address + count - 1}"

    def _reply(self, deadline: "Deadline", what: tuple[str, int, int]) -> bytes:
        """The next whole ADU from the stream, within the deadline."""
        buffer = self.buffer
        size = 0
        while True:
            if len(buffer) >= 6:
                if not size:
                    try:
                        size = codec.adu_size(buffer)
                    except CodecError as exc:
                        self.buffer = b""
                        raise MalformedReply(f"{self.label}: {self._words(what)}: {exc}") from None
                if len(buffer) >= size:
                    self.buffer = buffer[size:]
                    return buffer[:size]
            left = deadline.remaining()
            try:
                data = self.stream.recv(left) if left > 0 else None
            except OSError as exc:
                raise CommError(f"{self.label}: connection failed during {self._words(what)} "
                                f"({exc.strerror or exc})") from None
            if data is None:
                self.buffer = buffer
                raise NoAnswer(f"{self.label}: no answer to {self._words(what)} within {deadline.describe()}")
            if not data:
                raise CommError(f"{self.label}: the drive closed the connection during {self._words(what)}")
            buffer = buffer + data if buffer else data

    def _refused(self, what: tuple[str, int, int], exception: int) -> ModbusRefused:
        text = EXCEPTIONS.get(exception, "exception")
        return ModbusRefused(f"{self.label}: the drive refused {self._words(what)}: {text} (exception {exception})",
                             code=exception)

    def read_registers(self, address: int, count: int) -> list[int]:
        self.transaction = transaction = (self.transaction + 1) & 0xFFFF
        try:
            adu = codec.pack_read_holding(transaction, self.unit, address, count)
        except CodecError as exc:
            raise UsageError(f"{self.label}: {exc}") from None
        what = ("reading", address, count)
        reply = self._exchange(adu, what)
        try:
            exception, registers = codec.unpack_read_reply(reply, self.unit, count)
        except CodecError as exc:
            raise MalformedReply(f"{self.label}: {self._words(what)}: {exc}") from None
        if exception is not None:
            raise self._refused(what, exception)
        return registers

    def write_registers(self, address: int, values: list[int]) -> None:
        self.transaction = transaction = (self.transaction + 1) & 0xFFFF
        try:
            adu = codec.pack_write_multiple(transaction, self.unit, address, list(values))
        except CodecError as exc:
            raise UsageError(f"{self.label}: {exc}") from None
        what = ("writing", address, len(values))
        reply = self._exchange(adu, what)
        try:
            exception, data = codec.unpack_reply(reply, self.unit, codec.WRITE_MULTIPLE)
            if exception is None:
                codec.check_write_multiple(data, address, len(values))
        except CodecError as exc:
            raise MalformedReply(f"{self.label}: {self._words(what)}: {exc}") from None
        if exception is not None:
            raise self._refused(what, exception)

    def close(self) -> None:
        self.stream.close()


class ModbusTransport(Transport):
    """``mb://``: offers holding registers as a :class:`~akdctl.links.RegisterLink`."""

    scheme = "mb"

    def __init__(self, target: "Target", options: LinkOptions) -> None:
        super().__init__(target, options)
        self._link: ModbusLink | None = None

    def open(self) -> None:
        host, port = self.target.host, self.target.port or PORT
        label = f"mb://{host}:{port}"
        try:
            unit = int(self.target.query.get("unit", "1"), 0)
        except ValueError:
            unit = -1
        if not 0 <= unit <= 247:
            raise UsageError(f"{label}: unit must be 0..247")
        timeout = self.options.budget.left()
        try:
            stream = TcpStream.connect(host, port, timeout)
        except socket.timeout:
            raise NoAnswer(f"{label}: no answer within {timeout:g} s (TCP connect)") from None
        except (socket.gaierror, UnicodeError) as exc:
            raise UsageError(f"{label}: cannot resolve host {host!r} ({exc})") from None
        except ConnectionRefusedError:
            raise CommError(f"{label}: cannot connect (no Modbus TCP server answering; the AKD listens on 502)") \
                from None
        except OSError as exc:
            raise CommError(f"{label}: cannot connect ({exc.strerror or exc})") from None
        self._link = ModbusLink(stream, unit, self.options, label)
        self.register_link = self._link

    def close(self) -> None:
        link, self._link = self._link, None
        self.register_link = None
        if link is not None:
            link.close()


__all__ = ["ModbusTransport", "ModbusLink", "PORT"]
