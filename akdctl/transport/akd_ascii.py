"""``akd://HOST[:23]``: the AKD's ASCII command channel (the service port's "Telnet") as a transport.

What the public record says (reference akd-ascii-channel.md 0-2): plain TCP on port 23, one command per line
sent as ``NAME[ value]\\r\\n``, the reply text followed by ``\\r\\n-->``, errors as replies beginning ``Error:``,
replies in Latin-1 (units such as µs). What it leaves open and this client therefore tolerates [I]: Telnet option
negotiation from the drive (every option is refused once, RFC 854/1143: ``DO`` -> ``WONT``, ``WILL`` -> ``DONT``,
subnegotiations skipped, later repeats ignored so an IAC storm cannot make us talk forever), an echo of the
command line (dropped when the reply's first line repeats it), a banner or prompt on connect (drained), and one
client at a time (a drive that closes a new connection at once is reported as busy).

Every wait is bounded: the connect by the command's timeout, each command (its send and every receive until the
prompt) by one deadline of the command's Budget (the socket waits through :mod:`akdctl.transport.tcp_stream`), and
a reply is at most :data:`MAX_REPLY` bytes, so an endless reply without a prompt ends in one error. A command costs
one send and, for a short reply, one receive. With tracing off and nothing left from before, :meth:`AsciiLink.command`
takes a quick path: the line out and the usual reply (one plain ASCII line and the prompt, whole in the first
segment) checked in one pass; anything else -- more segments, Telnet bytes, Latin-1, several lines, an echo, a
refusal (or any ':'), silence, a close -- goes on as the same request in the general path from the bytes it has
(tests/test_akd_ascii_quick_path.py runs every such case both ways). The check is a pure function of the reply's
bytes and the line, so each line keeps its last quick reply's bytes and text: a reply of the very same bytes (a
status read polled again) is that text without checking it again; any other bytes are checked. Nothing of the
drive's is kept -- every command sends its line and reads its reply -- only what a check of those bytes gave.
After a command that got no prompt the connection is out of step (a late reply would answer the next command), so
the link refuses further commands.
"""

from __future__ import annotations

import socket
from typing import TYPE_CHECKING, Any

from akdctl.errors import CommandRefused, CommError, MalformedReply, NoAnswer, UsageError
from akdctl.links import CommandLink
from akdctl.transport.base import LinkOptions, Transport
from akdctl.transport.tcp_stream import TcpStream

if TYPE_CHECKING:
    from akdctl.links import Deadline
    from akdctl.transport.target import Target

PORT = 23
PROMPT = b"-->"
MAX_REPLY = 1 << 20       # a DRV.HELPALL is long; a reply larger than this never ends
MAX_LINE = 256            # a command line akdctl sends (the drive's own limit is not public)
IAC, DONT, DO, WONT, WILL, SB, SE = 255, 254, 253, 252, 251, 250, 240
_E = ("E", "e")   # how a refusal ("Error: ...") begins: checked before the slice and lower()
REPLY_END = b"\r\n" + PROMPT   # how the usual reply ends: its one line, then the prompt
_UNSEEN = object()   # a line's last quick reply before it has one: equal to no bytes, to None neither
#: How long the client listens for a banner, a prompt or options right after connecting (at most).
SETTLE = 0.15
#: What the quick path reads of a reply's first segment: a usual reply is a few bytes, and a bytes object of this
#: size still comes from Python's small-object allocator (a 4 KiB one costs a malloc, a realloc and a free); a
#: longer reply continues through the general path's receives.
QUICK_READ = 448


class Telnet:
    """Strips Telnet commands from received bytes and collects the refusals to send (each option once)."""

    def __init__(self) -> None:
        self.refused: set[tuple[int, int]] = set()
        self.pending = b""      # an IAC sequence cut by a segment boundary
        self.in_sb = False
        self.idle = True        # neither of the two: the next bytes start fresh

    def feed(self, data: bytes) -> tuple[bytes, bytes]:
        """(text bytes, bytes to send back)."""
        if not self.pending and not self.in_sb and IAC not in data:
            return data, b""   # the usual reply: no Telnet command in it
        data = self.pending + data
        self.pending = b""
        text = bytearray()
        reply = bytearray()
        i = 0
        while i < len(data):
            byte = data[i]
            if self.in_sb:
                if byte == IAC and i + 1 < len(data) and data[i + 1] == SE:
                    self.in_sb = False
                    i += 2
                    continue
                if byte == IAC and i + 1 == len(data):
                    self.pending = data[i:]
                    break
                i += 1
                continue
            if byte != IAC:
                text.append(byte)
                i += 1
                continue
            if i + 1 >= len(data):
                self.pending = data[i:]
                break
            command = data[i + 1]
            if command == IAC:
                text.append(IAC)
                i += 2
            elif command in (DO, DONT, WILL, WONT):
                if i + 2 >= len(data):
                    self.pending = data[i:]
                    break
                option = data[i + 2]
                answer = {DO: WONT, WILL: DONT}.get(command)
                if answer is not None and (command, option) not in self.refused:
                    self.refused.add((command, option))
                    reply += bytes([IAC, answer, option])
                i += 3
            elif command == SB:
                self.in_sb = True
                i += 2
            else:  # NOP, GA, DM ... carry no text
                i += 2
        self.idle = not self.pending and not self.in_sb
        return bytes(text), bytes(reply)


class AsciiLink(CommandLink):
    """One TCP connection to the service channel. Not thread-safe (one invocation, one caller)."""

    def __init__(self, stream: TcpStream, options: LinkOptions, label: str) -> None:
        self.stream = stream
        self.options = options
        self.tracer = options.tracer
        self.label = label
        self.telnet = Telnet()
        self.buffer = b""
        self.broken = ""
        self.budget = options.budget
        # command line -> (wire bytes, its length, [the last reply's bytes, its text]): checked once; see _wire
        self._lines: dict[str, tuple[bytes, int, list[Any]]] = {}
        self._plain = True   # see _settled

    # ---------------------------------------------------------------- bytes
    def _receive(self, at: float, what: str) -> bool:
        """Receive what arrives before the monotonic time ``at`` into the buffer; False on nothing. CommError on
        close."""
        try:
            data = self.stream.recv(at)
        except OSError as exc:
            raise CommError(f"{self.label}: connection failed during {what} ({exc.strerror or exc})") from None
        if data is None:
            return False
        if not data:
            raise CommError(f"{self.label}: the drive closed the connection during {what}")
        if self.tracer.active:
            self._trace("rx", data, what)
        text, answer = self.telnet.feed(data)
        if answer:
            self._send(answer, what)
        self.buffer += text
        if len(self.buffer) > MAX_REPLY:
            self.broken = "a reply without a prompt"
            raise MalformedReply(f"{self.label}: {what}: more than {MAX_REPLY} bytes without the '-->' prompt")
        return True

    def _trace(self, direction: str, data: bytes, note: str) -> None:
        """The wire bytes as TCP segments (``--trace``, ``--pcap``; layer ``akd``)."""
        ends = self.stream.local_and_remote()
        meta: dict[str, object] = {}
        if ends is not None:
            local, remote = ends
            src, dst = (local, remote) if direction == "tx" else (remote, local)
            meta = {"proto": "tcp", "src": src, "dst": dst}
        self.tracer.frame(direction, "akd", data, note=note, meta=meta)  # type: ignore[arg-type]

    def _send(self, data: bytes, what: str) -> None:
        if self.tracer.active:
            self._trace("tx", data, what)
        try:
            self.stream.send(data)
        except OSError as exc:
            raise self._send_failed(exc, what) from None

    def _send_failed(self, exc: OSError, what: str) -> CommError:
        if isinstance(exc, socket.timeout):
            return NoAnswer(f"{self.label}: could not send {what} in time")
        return CommError(f"{self.label}: cannot send {what} ({exc.strerror or exc})")

    def settle(self, budget: float) -> None:
        """Drain a banner, a first prompt and option offers right after connecting; a drive that hangs up at
        once is busy with another client."""
        import time

        end = time.monotonic() + budget
        try:
            while time.monotonic() < end and self._receive(end, "connecting"):
                pass
        except CommError as exc:
            if "closed" in exc.message:
                raise CommError(f"{self.label}: the drive closed the connection at once: its service channel is "
                                "probably in use by another client (WorkBench, a terminal, another akdctl); it "
                                "serves one at a time") from None
            raise
        finally:
            self.buffer = b""
            self._settled()

    # ---------------------------------------------------------------- the contract
    def _wire(self, line: str) -> tuple[bytes, int, list[Any]]:
        """The bytes of a command line, its length and its last quick reply (checked and encoded once per line)."""
        known = self._lines.get(line)
        if known is None:
            text = line.strip()
            if not text or len(text) > MAX_LINE or not (text.isascii() and text.isprintable()):
                raise UsageError(f"a command line for the AKD is printable ASCII, 1..{MAX_LINE} characters, one line")
            known = (text.encode("ascii") + b"\r\n", len(text), [_UNSEEN, ""])
            if len(self._lines) < 256:
                self._lines[line] = known
        return known

    def command(self, line: str) -> str:
        try:
            wire, size, last = self._lines[line]
        except KeyError:
            wire, size, last = self._wire(line)
        if self._plain and not self.tracer.active:
            budget = self.budget
            at = budget.lone()
            if at is not None:
                # The quick path (no Deadline object: links.Budget.lone): the line out, and the usual reply -- one
                # plain line, then the prompt, whole in the first segment -- answered here. Anything else goes on
                # as the same request under its Deadline in the general path, from the bytes received so far.
                try:
                    data = self.stream.request(wire, at, QUICK_READ, budget.timeout)
                except OSError as exc:
                    with budget.request(attempts=1, at=at):
                        raise self._request_failed(exc, wire) from None
                if data == last[0]:   # the very bytes of this line's last quick reply: the same text (see above)
                    return last[1]    # type: ignore[no-any-return]
                if data:
                    head = data.removesuffix(REPLY_END)
                    if head is not data and head.isascii():   # ASCII: no Telnet command (IAC is 255)
                        text = head.decode()
                        # one line of printable text (no CR or LF) and no other prompt, not a refusal (no ':' --
                        # "Error:" has one), not only an echo of the line (another length)
                        if text.isprintable() and ":" not in text and "-->" not in text:
                            text = text.strip()
                            if len(text) != size:
                                last[0] = data
                                last[1] = text
                                return text
                return self._handover(wire, at, data)
        return self._general(wire)

    def _general(self, wire: bytes) -> str:
        """The whole command through the general path: bytes left from before, tracing on, a request enclosing
        this one or unanswered time counted, or a connection out of step (refused here)."""
        try:
            if self.broken:
                raise CommError(f"{self.label}: the connection is out of step after {self.broken}; reconnect")
            with self.budget.request(attempts=1) as deadline:
                self._send(wire, repr(wire[:-2].decode()))
                return self._rest(wire, deadline)
        finally:
            self._settled()

    def _handover(self, wire: bytes, at: float, data: bytes | None) -> str:
        """The quick path's request from where it stopped: ``data`` is its first segment (None: nothing came in
        time; b"": the drive closed the connection)."""
        try:
            with self.budget.request(attempts=1, at=at) as deadline:
                if data:
                    self.buffer = self._fed(data, wire)
                return self._rest(wire, deadline)
        finally:
            self._settled()

    def _settled(self) -> None:
        """Whether the next command may take the quick path: nothing left from before (no bytes in the buffer, no
        Telnet command cut short) and the connection in step. Kept as one flag, set after every step that can
        change it (the general path, settling), so the quick path tests one attribute instead of three."""
        self._plain = not self.broken and not self.buffer and self.telnet.idle

    def _request_failed(self, exc: OSError, wire: bytes) -> CommError:
        what = repr(wire[:-2].decode())
        if isinstance(exc, socket.timeout):   # only the send waits in a way that raises
            return self._send_failed(exc, what)
        return CommError(f"{self.label}: connection failed during {what} ({exc.strerror or exc})")

    def _fed(self, data: bytes, wire: bytes) -> bytes:
        """A first segment that is not a whole plain reply: Telnet bytes stripped, options answered."""
        text, answer = self.telnet.feed(data)
        if answer:
            self._send(answer, repr(wire[:-2].decode()))
        return text

    def _rest(self, wire: bytes, deadline: "Deadline") -> str:
        """Receive until the prompt, within the request's deadline (several segments, Telnet bytes, tracing)."""
        what = repr(wire[:-2].decode())
        while True:
            cut = self.buffer.find(PROMPT)
            if cut >= 0:
                break
            if not self._receive(deadline.at, what):   # nothing before the deadline
                self.broken = "a command without a prompt"
                got = f" (got {len(self.buffer)} bytes, no '-->')" if self.buffer else ""
                raise NoAnswer(f"{self.label}: no prompt after {what} within {deadline.describe()}{got}")
        reply = self.buffer[:cut]
        self.buffer = self.buffer[cut + len(PROMPT):]
        return self._text(wire[:-2].decode("ascii"), reply)

    def _text(self, line: str, reply: bytes) -> str:
        text = reply.decode("latin-1").strip()
        if "\n" not in text and "\r" not in text:   # one line (the usual read): no splitting
            if len(text) == len(line) and text.upper() == line.upper():   # only an echo of our line [I: echo unknown]
                text = ""
        else:
            text = self._lines_of(line, text)
        if text[:1] in _E and text[:6].lower() == "error:":
            raise CommandRefused(f"the drive refused {line!r}: {text.splitlines()[0].strip()[:200]}",
                                 details={"reply": text[:2000]})
        return text

    @staticmethod
    def _lines_of(line: str, text: str) -> str:
        """A reply of several lines: CR, LF or CRLF between them, an echo of our line dropped."""
        text = text.replace("\r\n", "\n").replace("\r", "\n")
        lines = text.split("\n")
        while lines and not lines[0].strip():
            lines.pop(0)
        if lines and lines[0].strip().upper() == line.upper():   # an echo of our line [I: echo unknown]
            lines.pop(0)
        return "\n".join(lines).strip()

    def close(self) -> None:
        self.stream.close()


class AkdAsciiTransport(Transport):
    """``akd://HOST[:23]``: offers the AKD's command channel as a :class:`~akdctl.links.CommandLink`."""

    scheme = "akd"

    def __init__(self, target: "Target", options: LinkOptions) -> None:
        super().__init__(target, options)
        self._link: AsciiLink | None = None

    def open(self) -> None:
        host, port = self.target.host, self.target.port or PORT
        label = f"akd://{host}:{port}"
        timeout = self.options.budget.left()
        try:
            stream = TcpStream.connect(host, port, timeout)
        except socket.timeout:
            raise NoAnswer(f"{label}: no answer within {timeout:g} s (TCP connect)") from None
        except (socket.gaierror, UnicodeError) as exc:
            raise UsageError(f"{label}: cannot resolve host {host!r} ({exc})") from None
        except ConnectionRefusedError:
            raise CommError(f"{label}: connection refused (is this the drive's service port? default 23)") from None
        except OSError as exc:
            raise CommError(f"{label}: cannot connect ({exc.strerror or exc})") from None
        link = AsciiLink(stream, self.options, label)
        self._link = link
        link.settle(min(SETTLE, timeout / 4))
        self.command_link = link

    def close(self) -> None:
        link, self._link = self._link, None
        self.command_link = None
        if link is not None:
            link.close()


__all__ = ["AkdAsciiTransport", "AsciiLink", "Telnet", "PORT"]
