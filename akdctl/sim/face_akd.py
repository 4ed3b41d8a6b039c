"""The simulator's ASCII command channel face (``sim serve --akd HOST:PORT``): the AKD's service-port "Telnet".

What it does, from reference akd-ascii-channel.md 1-2 and 8: TCP, one command per line (CR, LF or CRLF), the
keyword case-insensitive, the reply's lines joined by CRLF and followed by ``\\r\\n-->`` (an empty reply is just
``\\r\\n-->``), Latin-1 text, reads as ``value`` or ``value [unit]`` with floats to 3 decimals, writes and commands
answered with the bare prompt, refusals as ``Error: ...``, an unknown keyword as ``Error: Command was not found.``.
Every value comes from the one drive model through :mod:`akdctl.sim.akd_params`, so a write here shows on the CoE,
PNU, EtherNet/IP and Modbus views and back.

Where the public record is silent the face chooses, and says so [I]: it offers Telnet option ``DO NAWS`` on
connect (aakd answers NAWS, so real drives negotiate; which options they offer is unknown), and ``--akd-quirks``
switches the other open points: ``echo`` (repeat the command line before the reply), ``prompt`` (send ``-->`` on
connect), ``no-telnet`` (offer no option). The wording of ``Error:`` texts other than "Command was not found" is
ours. One client at a time (``--akd-clients``): a further client is accepted and closed at once [I].

``REC.*`` lines are answered by ``akdctl.sim.recorder.handle_rec`` when that module is present (the recorder's
face), imported on first use.
"""

from __future__ import annotations

import socket
import struct
import sys
import threading
from typing import Any

from akdctl.catalog.akd_params import AkdParam, all_params, lookup
from akdctl.errors import UsageError
from akdctl.profiles.akd_values import ValueFormError, format_value, parse_text
from akdctl.sim import akd_params as store
from akdctl.sim.face import Face, FaceOption, request_failed

DEFAULT_ADDRESS = "127.0.0.1:2323"
IAC, SB, SE, DO, NAWS = 255, 250, 240, 253, 31
MAX_LINE = 1024
IDLE_TIMEOUT_S = 300.0
GRACE_S = 0.3   # how long a newcomer waits for a slot a leaving client is about to free
QUIRKS = ("echo", "prompt", "no-telnet")
NOT_FOUND = "Error: Command was not found."
_EOL_BYTES = b"\r\n"   # a line ends with CR, LF or CRLF

OPTIONS = (
    FaceOption("--akd", "akd", flag_value=DEFAULT_ADDRESS, metavar="[ADDR]",
               help=f"Serve the drive's ASCII command channel (a real AKD: TCP 23), default {DEFAULT_ADDRESS}."),
    FaceOption("--akd-clients", "akd_clients", type=int, range=(1, 16), default=1, show_default=True,
               help="Clients the ASCII channel serves at once; a further one is closed at once [I]."),
    FaceOption("--akd-quirks", "akd_quirks", metavar="LIST",
               help="Open points of the public record [I]: echo (repeat the line), prompt (send '-->' on "
                    "connect), no-telnet (offer no Telnet option on connect); comma-separated."),
)


def from_options(drive: Any, **kwargs: Any) -> "AkdFace | None":
    address = kwargs.get("akd")
    if address is None:
        return None
    from akdctl.sim.face_profinet import parse_address

    host, port = parse_address(address, 23, "--akd")
    quirks = {q.strip().lower() for q in (kwargs.get("akd_quirks") or "").split(",") if q.strip()}
    unknown = sorted(quirks - set(QUIRKS))
    if unknown:
        raise UsageError(f"--akd-quirks: unknown {', '.join(unknown)}; choose from {', '.join(QUIRKS)}")
    return AkdFace(drive, host, port, clients=int(kwargs.get("akd_clients") or 1), quirks=quirks)


def strip_telnet(data: bytes, state: dict[str, Any]) -> bytes:
    """Remove Telnet commands (a client's WONT/DONT answers, subnegotiations) from received bytes."""
    if IAC not in data and not state.get("pending") and not state.get("sb"):
        return data   # the usual line: nothing to strip, nothing cut short before it (the loop below gives the same)
    data = state.get("pending", b"") + data
    state["pending"] = b""
    out = bytearray()
    i = 0
    while i < len(data):
        byte = data[i]
        if state.get("sb"):
            if byte == IAC and i + 1 < len(data) and data[i + 1] == SE:
                state["sb"] = False
                i += 2
            else:
                i += 1
            continue
        if byte != IAC:
            out.append(byte)
            i += 1
            continue
        if i + 1 >= len(data):
            state["pending"] = data[i:]
            break
        command = data[i + 1]
        if command == IAC:
            out.append(IAC)
            i += 2
        elif command == SB:
            state["sb"] = True
            i += 2
        elif command in (251, 252, 253, 254):
            if i + 2 >= len(data):
                state["pending"] = data[i:]
                break
            i += 3
        else:
            i += 2
    return bytes(out)


class _ModelSlot:
    """The ``server`` :meth:`SimDrive._serve <akdctl.sim.drive.SimDrive._serve>` lends the model to for one request
    (its ``access``; outside a request the drive's refusing stand-in)."""

    __slots__ = ("access",)

    def __init__(self) -> None:
        self.access: Any = None


class AkdFace(Face):
    """A TCP listener and one thread per client, answering lines from the drive model."""

    def __init__(self, drive: Any, host: str, port: int, *, clients: int = 1, quirks: set[str] | None = None) -> None:
        self.drive = drive
        self.host = host
        self.port = port
        self.cap = clients
        self.quirks = set(quirks or ())
        self.sock: socket.socket | None = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._clients: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._freed = threading.Condition(self._lock)
        self._model = _ModelSlot()   # what SimDrive._serve hands the model through during a request

    # ---------------------------------------------------------------- life cycle
    def start(self) -> None:
        try:
            self.sock = socket.socket(socket.AF_INET6 if ":" in self.host else socket.AF_INET, socket.SOCK_STREAM)
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self.sock.bind((self.host, self.port))
            self.sock.listen(8)
        except OSError as exc:
            raise UsageError(f"--akd {self.host}:{self.port}: cannot listen ({exc.strerror})") from None
        self.port = self.sock.getsockname()[1]
        thread = threading.Thread(target=self._accept, name="akd-accept", daemon=True)
        thread.start()
        self._threads.append(thread)

    def stop(self) -> None:
        self._stop.set()
        if self.sock is not None:
            try:   # wakes the accept thread (closing alone does not on Linux: stop waited out its join)
                self.sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            try:
                self.sock.close()
            except OSError:
                pass
        with self._lock:
            for client in list(self._clients):
                try:
                    client.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
        for thread in self._threads:
            thread.join(timeout=2)

    def describe(self) -> str:
        return f"akd ascii tcp {self.host}:{self.port}"

    def warnings(self) -> list[str]:
        if self.quirks:
            return [f"--akd-quirks {','.join(sorted(self.quirks))}: inferred behaviour [I], not a verified drive's"]
        return []

    # ---------------------------------------------------------------- clients
    def _accept(self) -> None:
        assert self.sock is not None
        while not self._stop.is_set():
            try:
                client, _ = self.sock.accept()
            except OSError:
                return
            with self._freed:   # a client that just hung up may not have been counted out yet: a short grace
                full = not self._freed.wait_for(lambda: len(self._clients) < self.cap, timeout=GRACE_S)
                if not full:
                    self._clients.add(client)
            if full:  # one client at a time [I]: the newcomer is closed at once
                try:
                    client.close()
                except OSError:
                    pass
                continue
            thread = threading.Thread(target=self._serve, args=(client,), name="akd-client", daemon=True)
            thread.start()
            self._threads = [t for t in self._threads if t.is_alive()] + [thread]

    def _serve(self, client: socket.socket) -> None:
        state: dict[str, Any] = {}   # strip_telnet's: empty while no Telnet command is cut short or open
        buffer = b""                 # the start of a line not ended yet
        echo = "echo" in self.quirks
        try:
            _idle_timeout(client)
            if "no-telnet" not in self.quirks:
                client.sendall(bytes([IAC, DO, NAWS]))
            if "prompt" in self.quirks:
                client.sendall(b"-->")
            while not self._stop.is_set():
                data = client.recv(4096)
                if not data:
                    return
                if IAC in data or state:   # strip_telnet's own test, inline: the usual line holds no IAC
                    data = strip_telnet(data, state)
                    if not state.get("pending") and not state.get("sb"):
                        state.clear()
                if buffer:
                    data = buffer + data
                elif not data:
                    continue
                # lines end with CR, LF or CRLF: bytes.splitlines splits at exactly those; what follows the last
                # end is the start of the next line
                lines = data.splitlines()
                buffer = b"" if data[-1] in _EOL_BYTES else lines.pop()
                for line in lines:
                    text = line.decode("latin-1").strip()
                    reply = self.answer(text) if text else ""
                    if "\n" in reply:
                        reply = reply.replace("\n", "\r\n")
                    if echo and text:
                        reply = text + "\r\n" + reply
                    client.sendall((reply + "\r\n-->").encode("latin-1", "replace"))
                if len(buffer) > MAX_LINE:
                    buffer = b""
                    client.sendall(b"Error: the line is too long.\r\n-->")
        except OSError:
            return
        finally:
            with self._freed:
                self._clients.discard(client)
                self._freed.notify_all()
            try:
                client.close()
            except OSError:
                pass

    # ---------------------------------------------------------------- the drive's answers
    def answer(self, line: str) -> str:
        """The reply to one command line (without prompt); ``Error: ...`` for a refusal."""
        keyword, _, argument = line.partition(" ")
        key, argument = keyword.upper(), argument.strip()
        if not (line.isascii() and line.isprintable()):   # every character 32..126
            return "Error: the line holds characters the drive does not accept."
        try:
            if key.startswith("REC."):
                return self._recorder(key, argument)
            # one transaction of the drive, as its other faces' requests are (SimDrive._serve: the model reached
            # through self._model only while _answer runs; a refusal raised in it drops what it changed)
            return self.drive._serve(self._model, self._answer, (key, argument))  # type: ignore[no-any-return]
        except store.ParamError as exc:
            return f"Error: {exc}."
        except Exception as exc:  # a face never dies of a request
            request_failed("akd ascii face", exc)
            return "Error: the drive is busy; try again."

    def _answer(self, request: tuple[str, str]) -> str:
        """The reply to ``KEYWORD`` and its argument, inside the transaction (the model: ``self._model.access``)."""
        key, argument = request
        model = self._model.access
        special = _SPECIAL.get(key)
        if special is not None:
            return special(self, model, argument)
        row = lookup(key)
        if row is None or row.kind == "text":
            return NOT_FOUND
        if row.is_command:
            return f"Error: {row.name} is not simulated over the service channel."
        if not argument:
            return format_value(row.kind, store.read(model, row), row.unit)
        return self._write(model, row, argument)

    def _write(self, model: Any, row: AkdParam, argument: str) -> str:
        try:
            value = parse_text(row.kind if row.kind in ("int", "float", "string") else "int", argument)
        except ValueFormError as exc:
            return f"Error: {exc}."
        store.write(model, row, value)
        return ""

    def _recorder(self, key: str, argument: str) -> str:
        try:
            from akdctl.sim import recorder  # type: ignore[attr-defined]  # the scope engineer's module
        except ImportError:
            return NOT_FOUND
        with self.drive.transaction() as model:
            try:
                return str(recorder.handle_rec(model, key, argument))
            except recorder.RecorderError as exc:   # its text is the drive's error text (with or without "Error:")
                text = str(exc)
                return text if text.startswith("Error:") else f"Error: {text}"

    # specials: the commands and reports the face computes from the model
    def _active(self, model: Any, argument: str) -> str:
        return "1" if _enabled(model) else "0"

    def _enable(self, model: Any, argument: str) -> str:
        if model.faults.fault_present:
            return "Error: the drive has a fault; clear it first (DRV.CLRFAULTS)."
        if not _enabled(model):
            for word in (0x06, 0x07, 0x0F):
                _control(model, word)
        return ""

    def _disable(self, model: Any, argument: str) -> str:
        _control(model, 0x06)
        return ""

    def _stop_motion(self, model: Any, argument: str) -> str:
        if _enabled(model):
            _control(model, 0x010F)   # halt, power kept [I: the simulator's reading of DRV.STOP]
        return ""

    def _clear(self, model: Any, argument: str) -> str:
        _control(model, 0x00)
        _control(model, 0x80)
        _control(model, 0x00)
        return ""

    def _faults(self, model: Any, argument: str, warnings: bool = False) -> str:
        from akdctl.catalog.faults import by_code

        codes = [c for c in model.faults.active() if c.startswith("n" if warnings else "F")]
        if not codes:
            return "No warnings active" if warnings else "No faults active"
        lines = []
        for code in codes:
            fault = by_code(code)
            lines.append(f"{code[1:]}: {fault.name if fault else 'unknown'}.")
        return "\n".join(lines)

    def _warnings(self, model: Any, argument: str) -> str:
        return self._faults(model, argument, warnings=True)

    def _info(self, model: Any, argument: str) -> str:
        return "\n".join(["Drive information (simulated):", "-" * 40, "Model number      : AKD (akdctl simulator)",
                          "Fieldbus type     : EtherCAT, CANopen, PROFINET, EtherNet/IP, Modbus (simulated)",
                          f"Drive name        : {store.read(model, lookup('DRV.NAME')) or 'No-Name'}"])  # type: ignore[arg-type]

    def _version(self, model: Any, argument: str) -> str:
        return "\n".join(["akdctl simulated AKD", "-" * 40, "FPGA version      : (simulated)",
                          "Firmware Version  : M_01-20-00-001"])

    def _list(self, model: Any, argument: str) -> str:
        prefix = argument.upper()
        return "\n".join(p.name for p in all_params() if p.name.startswith(prefix))

    def _help(self, model: Any, argument: str) -> str:
        row = lookup(argument)
        if row is None:
            return NOT_FOUND
        lines = [f"{row.name}"]
        for label, value in (("Minimum", row.minimum), ("Maximum", row.maximum), ("Default", row.default)):
            if value:
                lines.append(f"{label} : {value}")
        if row.readable and row.kind != "text":
            lines.append(f"Actual : {format_value(row.kind, store.read(model, row), row.unit)}")
        return "\n".join(lines)

    def _nvlist(self, model: Any, argument: str) -> str:
        return "\n".join(f"{row.name} {format_value(row.kind, store.read(model, row))}" for row in _nv_rows())

    def _difvar(self, model: Any, argument: str) -> str:
        lines = []
        for row in _nv_rows():
            if not row.default:
                continue
            value = store.read(model, row)
            try:
                default = parse_text(row.kind, row.default)
            except ValueFormError:
                continue
            if format_value(row.kind, value) != format_value(row.kind, default):
                lines.append(f"{row.name} {format_value(row.kind, value)} ({row.default})")
        return "\n".join(lines)

    def _accepted(self, model: Any, argument: str) -> str:
        return ""   # DRV.NVSAVE / NVLOAD: the simulator keeps one copy of its parameters [I]


def _idle_timeout(client: socket.socket) -> None:
    """A client silent for :data:`IDLE_TIMEOUT_S` is dropped. On Linux the kernel's timeouts on a blocking socket
    bound each receive and send in the one system call (Python's timeout polls first: two per line and reply);
    elsewhere Python's. Either way the wait ends in an ``OSError``, which ends the client."""
    if sys.platform.startswith("linux"):
        client.settimeout(None)
        timeval = struct.pack("@ll", int(IDLE_TIMEOUT_S), 0)   # the OS's struct timeval, not a wire layout
        client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, timeval)
        client.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, timeval)
    else:
        client.settimeout(IDLE_TIMEOUT_S)


def _nv_rows() -> list[AkdParam]:
    return [r for r in all_params() if r.access == "NV" and r.kind in ("int", "float", "string")]


def _enabled(model: Any) -> bool:
    return model.object_value(0x6041, 0) & 0x6F == 0x27


def _control(model: Any, word: int) -> None:
    model.object_write(0x6040, 0, word.to_bytes(2, "little"))


_SPECIAL = {
    "DRV.ACTIVE": AkdFace._active, "DRV.EN": AkdFace._enable, "DRV.DIS": AkdFace._disable,
    "DRV.STOP": AkdFace._stop_motion, "DRV.CLRFAULTS": AkdFace._clear, "DRV.FAULTS": AkdFace._faults,
    "DRV.WARNINGS": AkdFace._warnings, "DRV.INFO": AkdFace._info, "DRV.VER": AkdFace._version,
    "DRV.LIST": AkdFace._list, "DRV.HELP": AkdFace._help, "DRV.NVLIST": AkdFace._nvlist,
    "DRV.DIFVAR": AkdFace._difvar, "DRV.NVSAVE": AkdFace._accepted, "DRV.NVLOAD": AkdFace._accepted,
}
