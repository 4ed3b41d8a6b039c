"""The two new faces checked by independent clients, and akd:// against hostile peers (issue 24).

* the ASCII face by a plain socket client written here from the reference's facts (akd-ascii-channel.md 1-2:
  CRLF out, ``\\r\\n-->`` back, ``value [unit]``, ``Error:`` replies, Latin-1, Telnet options, one client);
* the Modbus face by pymodbus's own client (register 2(n-1), most significant word first, x1000 floats);
* the akd:// client against peers that misbehave: silent, an endless reply without a prompt, a reply in another
  encoding, an IAC storm, a drive that hangs up at once (busy): one line, a documented exit code, within --timeout.

Everything runs in this process on loopback (faces and peers are threads).
"""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from akdctl.sim.drive import SimDrive


@pytest.fixture
def drive(tmp_path: Path) -> SimDrive:
    return SimDrive("default", tmp_path)


@pytest.fixture
def ascii_face(drive: SimDrive) -> Iterator[int]:
    from akdctl.sim import face_akd

    face = face_akd.from_options(drive, akd="127.0.0.1:0")
    assert face is not None
    face.start()
    try:
        yield face.port
    finally:
        face.stop()


def _until_prompt(sock: socket.socket, timeout: float = 3.0) -> bytes:
    data = b""
    end = time.monotonic() + timeout
    while not data.endswith(b"-->"):
        sock.settimeout(max(0.01, end - time.monotonic()))
        chunk = sock.recv(4096)
        assert chunk, f"closed after {data!r}"
        data += chunk
    return data


def test_ascii_face_speaks_as_the_reference_says(ascii_face: int) -> None:
    with socket.create_connection(("127.0.0.1", ascii_face), timeout=3) as sock:
        assert sock.recv(3) == bytes([255, 253, 31])          # IAC DO NAWS offered on connect [I]
        sock.sendall(bytes([255, 252, 31]))                   # WONT NAWS: the client refuses
        sock.sendall(b"vl.kp\r\n")                            # case-insensitive keyword, CRLF
        reply = _until_prompt(sock)
        assert reply.endswith(b"\r\n-->") and reply.rstrip(b"\r\n->").endswith(b"[A/(rad/s)]"), reply
        sock.sendall(b"VL.KP 2.5\r\n")
        assert _until_prompt(sock) == b"\r\n-->"              # a write: the bare prompt
        sock.sendall(b"VL.KP\n")                              # LF alone is a line too
        assert _until_prompt(sock) == b"2.500 [A/(rad/s)]\r\n-->"
        sock.sendall(b"NOPE.NOTHING\r\n")
        assert _until_prompt(sock) == b"Error: Command was not found.\r\n-->"
        sock.sendall(b"VL.KP 1.23456\r\n")                    # more than 3 decimals: refused
        assert _until_prompt(sock).startswith(b"Error:")
        sock.sendall(b"DRV.INFO\r\n")
        info = _until_prompt(sock)
        assert info.count(b"\r\n") >= 3                       # a multi-line reply, CRLF between lines
        sock.sendall(b"MOTOR.INERTIA\r\n")
        assert b"[kg\xb7cm\xb2]" in _until_prompt(sock)       # Latin-1: one byte per character
        with socket.create_connection(("127.0.0.1", ascii_face), timeout=3) as second:
            second.settimeout(2)
            assert second.recv(16) == b""                     # one client at a time: the second is closed
        sock.sendall(b"DRV.ACTIVE\r\n")
        assert _until_prompt(sock) == b"0\r\n-->"             # the first still served


def test_a_write_over_the_ascii_face_shows_on_coe_and_back(ascii_face: int, drive: SimDrive, akd_inproc) -> None:
    code, _, err = akd_inproc("-T", f"akd://127.0.0.1:{ascii_face}", "-y", "param", "set", "HOME.MODE=7")
    assert code == 0, err
    with drive.transaction() as model:
        assert model.object_value(0x50CB, 0) == 7            # the CoE view of HOME.MODE
        model.object_write(0x3548, 0, (4321).to_bytes(4, "little"))   # VL.KP by SDO, x1000
    code, out, err = akd_inproc("-T", f"akd://127.0.0.1:{ascii_face}", "param", "get", "VL.KP")
    assert code == 0 and "4.321 [A/(rad/s)]" in out, err


def test_modbus_face_with_pymodbus_client(drive: SimDrive) -> None:
    pytest.importorskip("pymodbus")
    from pymodbus.client import ModbusTcpClient

    from akdctl.catalog.akd_params import lookup
    from akdctl.sim import face_modbus

    face = face_modbus.from_options(drive, modbus="127.0.0.1:0")
    assert face is not None
    face.start()
    client = ModbusTcpClient("127.0.0.1", port=face.port, timeout=2, retries=0)
    try:
        assert client.connect()
        kp = lookup("VL.KP")
        assert kp is not None and kp.modbus == 872                # 2(437-1)
        assert not client.write_registers(872, [0, 1500]).isError()    # 1.500 x1000, MSW first
        with drive.transaction() as model:
            assert model.object_value(0x3548, 0) == 1500         # shows on CoE
        offset = lookup("AIN.OFFSET")
        assert offset is not None and offset.modbus == 6
        assert not client.write_registers(6, [0xFFFF, 0xFF06]).isError()   # -0.250 as a signed 32-bit pair
        assert client.read_holding_registers(6, count=2).registers == [0xFFFF, 0xFF06]
        assert client.read_holding_registers(872, count=2).registers == [0, 1500]
        assert client.read_holding_registers(2 * 5000, count=2).isError()   # no parameter there
        assert client.write_register(872, 5).isError()         # half a parameter: refused
    finally:
        client.close()
        face.stop()


# ---------------------------------------------------------------- hostile peers for akd://
class Peer:
    """A one-connection TCP server thread that plays ``behave(conn)``."""

    def __init__(self, behave: Callable[[socket.socket], None]) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(4)
        self.port = self.sock.getsockname()[1]
        self.behave = behave
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        try:
            while True:
                conn, _ = self.sock.accept()
                threading.Thread(target=self._one, args=(conn,), daemon=True).start()
        except OSError:
            return

    def _one(self, conn: socket.socket) -> None:
        try:
            self.behave(conn)
        except OSError:
            pass
        finally:
            conn.close()

    def close(self) -> None:
        self.sock.close()


def _silent(conn: socket.socket) -> None:
    conn.recv(100)
    time.sleep(5)


def _endless(conn: socket.socket) -> None:
    conn.recv(100)
    end = time.monotonic() + 5
    while time.monotonic() < end:
        conn.sendall(b"1234567890 " * 100)


def _wrong_encoding(conn: socket.socket) -> None:
    conn.recv(100)
    conn.sendall(b"\xe9\x80\x9b1.0 [\xb5s]\x00\r\n-->")


def _iac_storm(conn: socket.socket) -> None:
    conn.settimeout(0.05)
    end = time.monotonic() + 5
    while time.monotonic() < end:
        conn.sendall(bytes(b for option in range(40) for b in (255, 253, option)) + bytes([255, 250, 1, 2, 3]))
        try:
            conn.recv(65536)
        except socket.timeout:
            pass


def _hang_up(conn: socket.socket) -> None:
    conn.close()


def _warm_up(akd_inproc: Callable[..., tuple[int, str, str]], scheme: str) -> None:
    """Run the same command once against a port that refuses at once, so the timed run below measures the wait
    for the peer and not this process's first imports of the CLI and the transport (pymodbus among them): on a
    loaded machine those alone took seconds, which says nothing about how long a hostile peer can hold a command."""
    refusing = socket.socket()
    refusing.bind(("127.0.0.1", 0))  # bound, never listening: a connect is refused
    try:
        akd_inproc("-T", f"{scheme}://127.0.0.1:{refusing.getsockname()[1]}", "--timeout", "1", "param", "get", "VL.KP")
    finally:
        refusing.close()


@pytest.mark.parametrize(("behave", "words"), [
    (_silent, "no prompt"), (_endless, "prompt"), (_wrong_encoding, "not a value"),
    (_iac_storm, "no prompt"), (_hang_up, "in use by another client")])
def test_hostile_ascii_peers_end_in_one_line(behave: Callable[[socket.socket], None], words: str, akd_inproc) -> None:
    _warm_up(akd_inproc, "akd")
    peer = Peer(behave)
    try:
        start = time.monotonic()
        code, out, err = akd_inproc("-T", f"akd://127.0.0.1:{peer.port}", "--timeout", "1", "param", "get", "VL.KP")
        took = time.monotonic() - start
    finally:
        peer.close()
    assert code == 3, err
    assert err.count("\n") == 1 and words in err and "Traceback" not in err, err
    assert took < 2.5, took


def test_telnet_options_are_refused_once_each() -> None:
    from akdctl.transport.akd_ascii import Telnet

    telnet = Telnet()
    text, answer = telnet.feed(bytes([255, 253, 31, 255, 251, 1]) + b"ab" + bytes([255, 255]) + b"c")
    assert text == b"ab\xffc" and answer == bytes([255, 252, 31, 255, 254, 1])
    assert telnet.feed(bytes([255, 253, 31]))[1] == b""          # a repeated offer is not answered again
    text, answer = telnet.feed(bytes([255, 250, 31, 0, 80, 255]))   # a subnegotiation cut mid-way
    assert text == b"" and telnet.feed(bytes([240]) + b"x") == (b"x", b"")


def test_status_enable_disable_and_faults_over_the_ascii_channel(ascii_face: int, drive: SimDrive, akd_inproc) -> None:
    target = ("-T", f"akd://127.0.0.1:{ascii_face}", "--timeout", "3")
    code, out, err = akd_inproc(*target, "--json", "status")
    assert code == 0 and json.loads(out)["status"]["state"] == "disabled", err
    code, out, err = akd_inproc(*target, "enable")           # powers the axis: consent
    assert code == 4 and "consent" in err
    code, out, err = akd_inproc(*target, "-y", "--json", "enable")
    assert code == 0 and json.loads(out)["status"]["enabled"] is True, err
    with drive.transaction() as model:
        assert model.object_value(0x6041, 0) & 0x6F == 0x27  # the one model is enabled
    code, out, err = akd_inproc(*target, "--json", "disable")
    assert code == 0 and json.loads(out)["status"]["enabled"] is False, err
    with drive.transaction() as model:
        model.faults.raise_fault("F501")
    code, out, err = akd_inproc(*target, "--json", "fault", "dump")
    assert code == 0 and json.loads(out)["akd"]["faults"][0]["code"] == "F501", err
    with drive.transaction() as model:
        model.faults.clear_causes()
    code, out, err = akd_inproc(*target, "fault", "ack")
    assert code == 0 and "F501" in out, err
    code, out, err = akd_inproc(*target, "cmd", "DRV.FAULTS")
    assert code == 0 and "No faults active" in out, err
    code, out, err = akd_inproc(*target, "cmd", "DRV.EN")            # the passthrough is gated too
    assert code == 4, err
    code, out, err = akd_inproc(*target, "-y", "jog", "100")
    assert code == 2 and "not offered over the AKD service channel" in err, err


def _modbus_garbage(conn: socket.socket) -> None:
    conn.recv(100)
    conn.sendall(b"\x00\x01\x00\x00\x00\xff\x01\x03" + b"\xee" * 40)   # a length that never arrives


def _closed(conn: socket.socket) -> None:  # never called: the port is closed before the client connects
    conn.close()


@pytest.mark.parametrize("behave", [_silent, _modbus_garbage, _hang_up, _closed])
def test_hostile_modbus_peers_end_in_one_line(behave: Callable[[socket.socket], None], akd_inproc) -> None:
    pytest.importorskip("pymodbus")
    _warm_up(akd_inproc, "mb")
    peer = Peer(behave)
    if behave is _closed:
        peer.close()
    try:
        start = time.monotonic()
        code, out, err = akd_inproc("-T", f"mb://127.0.0.1:{peer.port}", "--timeout", "1", "param", "get", "VL.KP")
        took = time.monotonic() - start
    finally:
        peer.close()
    assert code == 3, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert took < 3, took


def test_rec_lines_go_to_the_recorder_hook(ascii_face: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """``REC.*`` lines are answered by akdctl.sim.recorder.handle_rec (the scope face's module), imported on use;
    its RecorderError text is the reply; without the module the keyword is unknown."""
    import sys
    import types

    sock = socket.create_connection(("127.0.0.1", ascii_face), timeout=3)   # one client: one connection

    def ask(line: bytes) -> bytes:
        sock.sendall(line + b"\r\n")
        return _until_prompt(sock).split(bytes([255, 253, 31]))[-1]

    fake = types.ModuleType("akdctl.sim.recorder")

    class RecorderError(Exception):
        pass

    def handle_rec(model: object, name: str, arg: str) -> str:
        if arg == "bad":
            raise RecorderError("Error: Value out of range.")
        return f"{name}|{arg}"

    fake.RecorderError = RecorderError   # type: ignore[attr-defined]
    fake.handle_rec = handle_rec         # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "akdctl.sim.recorder", fake)
    import akdctl.sim

    monkeypatch.setattr(akdctl.sim, "recorder", fake, raising=False)
    assert ask(b"rec.numpoints 500") == b"REC.NUMPOINTS|500\r\n-->"
    assert ask(b"REC.GAP bad") == b"Error: Value out of range.\r\n-->"
    sock.close()


def test_modbus_face_with_a_second_independent_client(drive: SimDrive) -> None:
    """pyModbusTCP (its own framing, no pymodbus code) reads and writes the same registers."""
    pytest.importorskip("pymodbus")
    client_module = pytest.importorskip("pyModbusTCP.client")
    from akdctl.sim import face_modbus

    face = face_modbus.from_options(drive, modbus="127.0.0.1:0")
    assert face is not None
    face.start()
    try:
        client = client_module.ModbusClient(host="127.0.0.1", port=face.port, unit_id=1, timeout=2)
        assert client.write_multiple_registers(406, [0, 3])          # HOME.MODE (n 204) = 3, MSW first
        with drive.transaction() as model:
            assert model.object_value(0x50CB, 0) == 3
        assert client.read_holding_registers(406, 2) == [0, 3]
        assert client.read_holding_registers(2 * 5000, 2) is None    # an exception response
        assert client.last_except == 2                              # illegal data address
        client.close()
    finally:
        face.stop()


@pytest.mark.parametrize("quirks", ["echo", "prompt", "echo,prompt", "no-telnet"])
def test_the_client_reads_every_variant_the_public_record_leaves_open(drive: SimDrive, quirks: str,
                                                                       akd_inproc) -> None:
    """Echo or none, a prompt on connect or none, Telnet options or none [I]: the same values either way."""
    from akdctl.sim import face_akd

    face = face_akd.from_options(drive, akd="127.0.0.1:0", akd_quirks=quirks)
    assert face is not None
    face.start()
    try:
        target = ("-T", f"akd://127.0.0.1:{face.port}", "--timeout", "3")
        code, _, err = akd_inproc(*target, "-y", "param", "set", "VL.KP=1.75", "HOME.MODE=2")
        assert code == 0, err
        code, out, err = akd_inproc(*target, "--json", "param", "get", "VL.KP", "HOME.MODE", "DRV.INFO")
        values = {p["name"]: p["value"] for p in json.loads(out)["parameters"]}
        assert code == 0 and values["VL.KP"] == 1.75 and values["HOME.MODE"] == 2, err
        assert values["DRV.INFO"].startswith("Drive information")      # the echo is not part of the reply
    finally:
        face.stop()


def test_opmode_by_name_is_gated_only_while_enabled(ascii_face: int, akd_inproc) -> None:
    target = ("-T", f"akd://127.0.0.1:{ascii_face}", "--timeout", "3")
    code, out, err = akd_inproc(*target, "param", "set", "DRV.OPMODE=2")       # disabled: no consent needed
    assert code == 0, err
    assert akd_inproc(*target, "-y", "enable")[0] == 0
    code, out, err = akd_inproc(*target, "param", "set", "DRV.OPMODE=1")       # enabled (DRV.ACTIVE 1): consent
    assert code == 4 and "operating mode" in err, err
    assert akd_inproc(*target, "disable")[0] == 0
