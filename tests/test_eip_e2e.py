"""eip:// end to end: `sim serve --ethernetip` in its own process, akdctl as a client, independent peers.

Everything runs on 127.0.0.1 with ports the OS picks; every process is stopped at teardown.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.harness import CliResult, SimServer, run_akdctl

pytestmark = pytest.mark.slow
READY = re.compile(r"listening: ethernetip ([\d.]+):(\d+) \(class-1 I/O on udp [\d.]+:(\d+)\)")


def _env(state: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["AKDCTL_STATE_DIR"] = str(state)
    env.pop("AKDCTL_TARGET", None)
    root = str(Path(__file__).resolve().parents[1])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def stop_process(proc: subprocess.Popen) -> None:
    """Terminate, then kill if it does not end; close its pipes."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    for stream in (proc.stdout, proc.stderr):
        if stream is not None:
            stream.close()


class Server:
    """``sim serve --ethernetip`` on ports the OS picks, through the shared harness (bounded ready wait, always
    stopped and reaped); the ports come from its ready line."""

    def __init__(self, state: Path, *extra: str) -> None:
        self._server = SimServer("--ethernetip", "127.0.0.1:0", "--eip-io-port", "0", *extra,
                                 env={"AKDCTL_STATE_DIR": str(state)}).start()
        match = READY.search("listening: " + self._server.ready[0])
        assert match, self._server.ready
        self.port, self.io_port = int(match.group(2)), int(match.group(3))

    @property
    def target(self) -> str:
        return f"eip://127.0.0.1:{self.port}"

    def stop(self) -> None:
        self._server.stop()


@pytest.fixture
def serve(tmp_path: Path) -> Iterator:
    servers: list[Server] = []

    def start(*extra: str) -> Server:
        server = Server(tmp_path / "state", *extra)
        servers.append(server)
        return server

    yield start
    for server in servers:
        server.stop()


def akdctl(tmp_path: Path, target: str, *argv: str, timeout: float = 2.0) -> CliResult:
    return run_akdctl("-T", target, "--timeout", str(timeout), *argv, env=_env(tmp_path / "state"), timeout=120)


# ------------------------------------------------------------------ commands over the simulator's face

def test_info_cip_get_set_and_parameters(serve, tmp_path) -> None:
    server = serve()
    info = akdctl(tmp_path, server.target, "--json", "info")
    assert info.returncode == 0, info.stderr
    ident = json.loads(info.stdout)["cip_identity"]
    assert ident["vendor"] == 452 and ident["device_type"] == 16 and ident["product_name"].startswith("AKD-")
    got = akdctl(tmp_path, server.target, "--json", "cip", "get", "0x0F/796/1", "u32")
    assert got.returncode == 0 and json.loads(got.stdout)["value"] == 65536
    assert akdctl(tmp_path, server.target, "cip", "set", "0x0F/797/1", "u32", "0x20000").returncode == 0
    back = akdctl(tmp_path, server.target, "--json", "eip", "param", "get", "EIP.PROFUNIT")
    assert back.returncode == 0 and json.loads(back.stdout)["value"] == 0x20000
    assert json.loads(back.stdout)["type"] == "UDINT" and json.loads(back.stdout)["length"] == 4
    assert akdctl(tmp_path, server.target, "eip", "param", "set", "EIP.PROFUNIT", "65536").returncode == 0


@pytest.fixture(scope="module")
def refusing_table_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Server, Path]]:
    """One served drive for the whole bad-input table, and the folder whose ``state`` it and the clients share.

    Why shared: every row is refused (by the face or before anything is sent), so none changes what the next one
    sees, and a server start per row was most of the table's time."""
    folder = tmp_path_factory.mktemp("eip-bad-input")
    server = Server(folder / "state")
    try:
        yield server, folder
    finally:
        server.stop()


@pytest.mark.parametrize("argv, code, words", [
    (("cip", "get", "0x99/1/1"), 1, "object does not exist"),                      # unknown class
    (("cip", "get", "0x0F/999/1"), 1, "object does not exist"),                    # unknown instance
    (("cip", "get", "0x0F/796/9"), 1, "attribute not supported"),                  # unknown attribute
    (("cip", "set", "0x0F/796/1", "u16", "5"), 1, "not enough data"),              # wrong length
    (("cip", "set", "0x0F/796/5", "u8", "1"), 1, "not settable"),                  # read-only
    (("cip", "set", "0x0F/796/1", "u32", "0"), 1, "out of range"),                 # value out of range
    (("cip", "set", "1/1/1", "u16", "7"), 1, "service not supported"),             # Set on Identity
    (("eip", "param", "get", "DRV.EN"), 2, "unknown AKD parameter"),              # no cited instance
    (("cip", "get", "0x0F/796"), 2, "CLASS/INSTANCE/ATTRIBUTE"),
    (("cip", "get", "0x0F/x/1"), 2, "not a number"),
    (("cip", "set", "0x0F/796/1", "u99", "1"), 2, "unknown type"),
])
def test_bad_input_one_line_and_exit_code(refusing_table_server, argv, code, words) -> None:
    server, folder = refusing_table_server
    result = akdctl(folder, server.target, *argv)
    assert result.returncode == code, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in result.stderr


def test_refused_session_exits_3(serve, tmp_path) -> None:
    server = serve("--eip-refuse-session")
    result = akdctl(tmp_path, server.target, "cip", "get", "1/1/7")
    assert result.returncode == 3 and "refuses the session" in result.stderr


def test_server_closing_mid_request_and_injected_status(serve, tmp_path) -> None:
    server = serve("--eip-inject", "close=2")
    result = akdctl(tmp_path, server.target, "cip", "get", "1/1/7")
    assert result.returncode == 3 and "closed the connection" in result.stderr
    server = serve("--eip-inject", "status=2:0x10")
    result = akdctl(tmp_path, server.target, "cip", "get", "1/1/7")
    assert result.returncode == 1 and "device state conflict" in result.stderr.lower()
    server = serve("--eip-inject", "drop=2")
    started = time.monotonic()
    result = akdctl(tmp_path, server.target, "cip", "get", "1/1/7", timeout=0.5)
    assert result.returncode == 3 and "no answer" in result.stderr and time.monotonic() - started < 20


def _fake_server(behaviour) -> tuple[socket.socket, threading.Thread]:
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    listener.settimeout(10)

    def run() -> None:
        try:
            conn, _ = listener.accept()
        except OSError:
            return
        with conn:
            behaviour(conn)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return listener, thread


@pytest.mark.parametrize("name, behaviour, words", [
    ("silent", lambda c: (c.recv(100), time.sleep(3)), "no answer"),
    ("truncated", lambda c: (c.recv(100), c.sendall(b"\x65\x00\x04\x00" + bytes(6))), "closed the connection"),
    ("inconsistent", lambda c: (c.recv(100), c.sendall(b"\x6f\x00\x00\x00" + bytes(20)), time.sleep(1)),
     "SendRRData"),
])
def test_broken_servers_one_line_exit_3(tmp_path, name, behaviour, words) -> None:
    listener, thread = _fake_server(behaviour)
    port = listener.getsockname()[1]
    started = time.monotonic()
    result = akdctl(tmp_path, f"eip://127.0.0.1:{port}", "cip", "get", "1/1/7", timeout=0.5)
    listener.close()
    thread.join(timeout=5)
    assert result.returncode == 3, result.stderr
    assert words in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert time.monotonic() - started < 30


def test_motion_over_the_position_controller_acts_on_the_one_drive(serve, tmp_path) -> None:
    server = serve()
    assert akdctl(tmp_path, server.target, "-y", "enable").returncode == 0
    home = akdctl(tmp_path, server.target, "-y", "home", "--mode", "0", timeout=3)
    assert home.returncode == 0, home.stderr
    move = akdctl(tmp_path, server.target, "-y", "--json", "move", "1.5", "--relative", timeout=3)
    assert move.returncode == 0, move.stderr
    assert json.loads(move.stdout)["status"]["position_counts"] == 98304
    # the same simulated drive, seen through the default (in-process) target
    sim = run_akdctl("--json", "status", env=_env(tmp_path / "state"), timeout=60)
    status = json.loads(sim.stdout)["status"]
    assert status["enabled"] and status["position_counts"] == 98304
    # no attribute tells the homed state over explicit messaging: absolute moves are refused (exit 4)
    absolute = akdctl(tmp_path, server.target, "-y", "move", "0")
    assert absolute.returncode == 4 and "absolute moves are not possible" in absolute.stderr
    assert akdctl(tmp_path, server.target, "disable").returncode == 0


def test_eip_scan_unicast_and_never_broadcast_by_default(serve, tmp_path) -> None:
    server = serve()
    result = run_akdctl("--json", "eip", "scan", "127.0.0.1", "--port", str(server.port),
                        env=_env(tmp_path / "state"), timeout=60)
    assert result.returncode == 0, result.stderr
    devices = json.loads(result.stdout)["devices"]
    assert devices and devices[0]["vendor_name"] == "Kollmorgen"
    refused = run_akdctl("eip", "scan", env=_env(tmp_path / "state"), timeout=60)
    assert refused.returncode == 2 and "never broadcasts" in refused.stderr


# ------------------------------------------------------------------ independent peers

PYCOMM3 = textwrap.dedent("""
    import json, sys
    from pycomm3 import CIPDriver, Services, UDINT
    kw = dict(connected=False, unconnected_send=False, route_path=False)
    out = {}
    with CIPDriver(sys.argv[1]) as d:
        out["name"] = d.generic_message(service=Services.get_attribute_single, class_code=1, instance=1,
                                        attribute=7, **kw).value.decode("ascii", "replace")
        out["set"] = d.generic_message(service=Services.set_attribute_single, class_code=0x0F, instance=796,
                                       attribute=1, request_data=UDINT.encode(4096), **kw).error
        out["read"] = d.generic_message(service=Services.get_attribute_single, class_code=0x0F, instance=796,
                                        attribute=1, data_type=UDINT, **kw).value
        out["missing"] = d.generic_message(service=Services.get_attribute_single, class_code=0x0F, instance=999,
                                           attribute=1, **kw).error
        out["readonly"] = d.generic_message(service=Services.set_attribute_single, class_code=0x0F, instance=796,
                                            attribute=6, request_data=b"\\x04", **kw).error
    print(json.dumps(out))
""")


def test_pycomm3_as_client_of_the_face(serve, tmp_path) -> None:
    pytest.importorskip("pycomm3", reason="pycomm3 is not installed (pip install 'akdctl[test]')")
    server = serve()
    result = subprocess.run([sys.executable, "-c", PYCOMM3, f"127.0.0.1:{server.port}"], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout)
    assert out["name"].endswith("AKD-P00606-NBCC-E000") and out["set"] is None and out["read"] == 4096  # sim/identity.py
    assert "Object does not exist" in out["missing"] and "not settable" in out["readonly"].lower()


def _free_port() -> int:
    """A port for cpppo's server, which cannot report the one it bound (a third-party server: probe, then bind)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_cpppo_server_serves_akdctl_client(tmp_path) -> None:
    pytest.importorskip("cpppo", reason="cpppo is not installed (pip install 'akdctl[test]')")
    port = _free_port()
    proc = subprocess.Popen([sys.executable, "-m", "cpppo.server.enip", "--address", f"127.0.0.1:{port}",
                             "EIP_POSUNIT@0x0F/796/1=UDINT", "PC_MODE@0x25/1/3=USINT"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 30
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
                break
            except OSError:
                if time.monotonic() > deadline or proc.poll() is not None:
                    pytest.fail("cpppo's EtherNet/IP server did not start")
                time.sleep(0.2)
        target = f"eip://127.0.0.1:{port}"
        assert akdctl(tmp_path, target, "cip", "set", "0x0F/796/1", "u32", "65536", timeout=5).returncode == 0
        got = akdctl(tmp_path, target, "--json", "cip", "get", "0x0F/796/1", "u32", timeout=5)
        assert got.returncode == 0, got.stderr
        assert json.loads(got.stdout)["value"] == 65536
        # cpppo closes the session on an unknown instance instead of answering (reference 2): one line, exit 3
        missing = akdctl(tmp_path, target, "cip", "get", "0x0F/205/1", timeout=5)
        assert missing.returncode in (1, 3) and len(missing.stderr.strip().splitlines()) == 1
    finally:
        stop_process(proc)


def test_tshark_dissects_enip_and_cip_in_the_pcap(serve, tmp_path) -> None:
    tshark = shutil.which("tshark")
    if tshark is None:
        if os.environ.get("CI") == "true":
            pytest.fail("tshark is required in CI")
        pytest.skip("tshark is not installed (apt-get install tshark); CI runs this test")
    server = serve()
    capture = tmp_path / "eip.pcap"
    result = akdctl(tmp_path, server.target, "--pcap", str(capture), "cip", "get", "0x0F/796/1", "u32")
    assert result.returncode == 0, result.stderr
    out = subprocess.run([tshark, "-r", str(capture), "-d", f"tcp.port=={server.port},enip", "-T", "fields",
                          "-e", "enip.command", "-e", "cip.service", "-e", "cip.class", "-e", "cip.instance",
                          "-e", "cip.genstat"], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "HOME": str(tmp_path)})
    assert out.returncode == 0, out.stderr
    rows = [line.split("\t") for line in out.stdout.strip().splitlines()]
    commands = [r[0] for r in rows]
    assert commands[:2] == ["0x0065", "0x0065"] and "0x0066" in commands
    request = next(r for r in rows if r[1] == "0x0e")
    assert request[2] == "0x0f" and int(request[3], 0) == 796
    assert any(r[1] == "0x8e" and r[4] == "0x00" for r in rows)


@pytest.mark.root
def test_eip_scan_broadcasts_only_on_the_named_interface_in_a_private_namespace(tmp_path) -> None:
    """A namespace of its own with a veth pair: the broadcast never leaves it, and is removed afterwards."""
    ns = f"akdeip{os.getpid()}"

    def ip(*args: str) -> None:
        subprocess.run(["ip", *args], check=True, capture_output=True, timeout=30)

    ip("netns", "add", ns)
    server: SimServer | None = None
    try:
        for args in (("link", "set", "lo", "up"), ("link", "add", "veth0", "type", "veth", "peer", "name", "veth1"),
                     ("addr", "add", "10.213.0.1/24", "brd", "10.213.0.255", "dev", "veth0"),
                     ("link", "set", "veth0", "up"), ("link", "set", "veth1", "up")):
            ip("netns", "exec", ns, "ip", *args)
        server = SimServer("--ethernetip", "0.0.0.0:44818", "--eip-io-port", "0", netns=ns,
                           env={"AKDCTL_STATE_DIR": str(tmp_path / "state")}).start()
        result = subprocess.run(["ip", "netns", "exec", ns, sys.executable, "-m", "akdctl", "--json", "eip", "scan",
                                 "--iface", "veth0", "--wait", "1"], capture_output=True, text=True,
                                env=_env(tmp_path / "state"), timeout=60)
        assert result.returncode == 0, result.stderr
        data = json.loads(result.stdout)
        assert data["query"] == "10.213.0.255"
        assert [d["product_name"] for d in data["devices"]] == ["AKD-P00606-NBCC-E000"]  # sim/identity.py
    finally:
        if server is not None:
            server.stop()
        subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=30)


def test_unhomed_position_move_is_refused_in_words(serve, tmp_path) -> None:
    """[V] "The amplifier must be homed before motion is begun in position mode" (reference/ethernetip.md, M-11):
    explicit messaging cannot read the homed state, so the drive's refusal is reported as that rule, exit 1."""
    server = serve()
    assert akdctl(tmp_path, server.target, "-y", "enable").returncode == 0
    move = akdctl(tmp_path, server.target, "-y", "move", "0.5", "--relative", timeout=3)
    assert move.returncode == 1, move.stderr
    assert "only once homed" in move.stderr and "akdctl home" in move.stderr
    assert len(move.stderr.strip().splitlines()) == 1


def test_raw_cip_writes_that_power_or_move_pass_the_one_gate(serve, tmp_path) -> None:
    """`cip set` of the Position Controller's enable and `eip param run HOME.MOVE` need consent like `enable`
    (drive/gate.py); without a terminal and --yes: exit 4, and the simulated axis stays disabled and unhomed."""
    server = serve()
    for argv in (("cip", "set", "0x25/1/17", "u8", "1"), ("eip", "param", "run", "HOME.MOVE"),
                 ("eip", "param", "run", "205"), ("cip", "set", "0x0F/205/1", "u8", "1")):
        refused = akdctl(tmp_path, server.target, *argv)
        assert refused.returncode == 4, (argv, refused.stderr)
        assert "no terminal to ask for consent" in refused.stderr and "nothing was written" in refused.stderr
    status = akdctl(tmp_path, server.target, "--json", "status")
    assert json.loads(status.stdout)["status"]["enabled"] is False
    # an attribute that moves nothing is written without asking
    assert akdctl(tmp_path, server.target, "cip", "set", "0x0F/797/1", "u32", "65536").returncode == 0
    assert akdctl(tmp_path, server.target, "-y", "cip", "set", "0x25/1/17", "u8", "1").returncode == 0
    assert json.loads(akdctl(tmp_path, server.target, "--json", "status").stdout)["status"]["enabled"] is True
