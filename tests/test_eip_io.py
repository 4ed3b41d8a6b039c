"""Class-1 I/O against `sim serve --ethernetip`: the seed's handshake byte for byte over a real connection
(SPEC-NOTES 24), an exclusive owner, Forward_Open refusals, and the `ethernetip` package as an
independent originator. All on 127.0.0.1, ports chosen by the OS, every process stopped.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from tests.test_eip_e2e import Server, akdctl

pytestmark = pytest.mark.slow


@pytest.fixture
def drive(tmp_path: Path):
    """A served, enabled and homed simulated drive: (server, its I/O port).

    Enabling and homing are the preparation, not what these tests are about: they run the CLI's entry point in
    this process (run_akdctl_inproc, same arguments and state folder as the subprocess runs) instead of two cold
    starts per test."""
    from tests.harness import run_akdctl_inproc

    server = Server(tmp_path / "state")
    try:
        with pytest.MonkeyPatch.context() as patch:
            patch.setenv("AKDCTL_STATE_DIR", str(tmp_path / "state"))
            for timeout, args in (("2.0", ("-y", "enable")), ("3", ("-y", "home", "--mode", "0"))):
                prepared = run_akdctl_inproc("-T", server.target, "--timeout", timeout, *args)
                assert prepared.code == 0, (args, prepared.err)
        yield server, server.io_port
    finally:
        server.stop()


@pytest.fixture
def session(drive):
    """A second client's registered encapsulation session to the served drive."""
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.ethernetip import EnipSession

    server, _ = drive
    sess = EnipSession("127.0.0.1", server.port, LinkOptions(timeout=2.0), "plc")
    sess.register()
    yield sess
    sess.close()


def test_seed_handshake_byte_for_byte_over_a_class1_connection(drive, tmp_path) -> None:
    server, io_port = drive
    result = akdctl(tmp_path, server.target, "--json", "eip", "io", "position", "1000", "-y", "--port", str(io_port))
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    sent, seen = data["sent"], data["responses"]
    assert sent[0].startswith("80 00 21 20 e8 03 00 00")      # seed step 1
    assert seen[0].startswith("84 00 00 20 00 00 00 00")      # seed step 2
    assert sent[1].startswith("81 00 21 20 e8 03 00 00")      # seed step 3
    assert int(seen[1].split()[2], 16) & 0x80                  # Load Complete
    assert not int(seen[2].split()[2], 16) & 0x80              # cleared after Load/Start = 0
    assert data["actual_position"] == 1000
    # the connection ended: the Enable bit is gone, the drive disabled the axis
    status = akdctl(tmp_path, server.target, "--json", "status")
    assert json.loads(status.stdout)["status"]["enabled"] is False


def test_io_command_error_comes_back_as_type_0x14(tmp_path) -> None:
    server = Server(tmp_path / "state")
    try:
        assert akdctl(tmp_path, server.target, "-y", "enable").returncode == 0   # enabled but not homed
        result = akdctl(tmp_path, server.target, "eip", "io", "position", "1000", "-y", "--port", str(server.io_port))
        assert result.returncode == 1 and "response type 0x14" in result.stderr
        assert "device state conflict" in result.stderr.lower() and len(result.stderr.strip().splitlines()) == 1
    finally:
        server.stop()


def test_refuses_when_another_scanner_owns_the_drive(drive, session, tmp_path) -> None:
    from akdctl.transport.eip_io import IoConnection

    server, io_port = drive
    with IoConnection(session, "127.0.0.1", rpi_ms=20, port=io_port, timeout=2.0):
        result = akdctl(tmp_path, server.target, "eip", "io", "position", "10", "-y", "--port", str(io_port))
        assert result.returncode == 4 and "another scanner" in result.stderr


def test_forward_open_refusals_in_words(drive, session, tmp_path) -> None:
    from akdctl.protocol import cip
    from akdctl.protocol import akd_assembly as asm

    server, _ = drive
    path = cip.Path(cip.ASSEMBLY, asm.CONFIG_INSTANCE, None, (asm.OUTPUT_INSTANCE, asm.INPUT_INSTANCE)).encode()
    for rpi, ot_size, path_, ext in ((5000, 70, path, cip.EXT_RPI_NOT_SUPPORTED),
                                     (20000, 40, path, cip.EXT_INVALID_OT_SIZE),
                                     (20000, 70, cip.Path(4, 100, None, (150, 102)).encode(),
                                      cip.EXT_INVALID_CONSUMING_PATH)):
        fo = cip.ForwardOpen(0, 5, 1, 0xFFFF, 2, rpi, cip.NetParams(ot_size), rpi, cip.NetParams(66), path_)
        reply = session.request(cip.Request(cip.FORWARD_OPEN, cip.Path(6, 1).encode(), fo.encode()))
        assert reply.status == 0x01 and reply.extended == (ext,)
    low = akdctl(tmp_path, server.target, "eip", "io", "position", "1", "-y", "--rpi", "5")
    assert low.returncode == 2


def test_consumer_timeout_disables_the_axis(drive, session, tmp_path) -> None:
    from akdctl.protocol import akd_assembly as asm
    from akdctl.transport.eip_io import IoConnection

    server, io_port = drive
    conn = IoConnection(session, "127.0.0.1", rpi_ms=10, port=io_port, timeout=2.0)
    try:
        conn.open()
        conn.set_output(asm.Command(control=asm.CTL_ENABLE))
        conn.wait_input(lambda r: bool(r.status1 & asm.ST1_ENABLED), "enabled")
        conn._stop.set()                # the originator goes silent (a pulled cable) without Forward_Close
        conn._thread.join(timeout=2)    # type: ignore[union-attr]
        conn._open = False
        deadline = time.monotonic() + 5
        while True:
            status = json.loads(akdctl(tmp_path, server.target, "--json", "status").stdout)["status"]
            if not status["enabled"]:
                break
            assert time.monotonic() < deadline, "the face kept the axis enabled after the consumer timeout"
            time.sleep(0.1)
    finally:
        conn.close()


ORIGINATOR = textwrap.dedent("""
    import json, sys, time
    import ethernetip.ethernetip as E
    port, ioport = int(sys.argv[1]), int(sys.argv[2])
    E.ENIP_TCP_PORT = port          # the package's own module constants name the target's ports
    E.ENIP_UDP_PORT = ioport
    enip = E.EtherNetIP("127.0.0.1")
    conn = enip.explicit_conn("127.0.0.1")
    assert conn.registerSession() == 0
    inp = enip.registerAssembly(E.EtherNetIP.ENIP_IO_TYPE_INPUT, 64, 102, conn)
    out = enip.registerAssembly(E.EtherNetIP.ENIP_IO_TYPE_OUTPUT, 64, 101, conn)
    enip.startIO(udp_port=0)
    status = conn.sendFwdOpenReq(102, 101, 100, torpi=20, otrpi=20, originator_udp_port=enip.originator_udp_port)
    def put(raw):
        for i, byte in enumerate(raw):
            for b in range(8):
                out[i * 8 + b] = bool(byte >> b & 1)
    def get():
        return bytes(sum(1 << b for b in range(8) if inp[i * 8 + b]) for i in range(8)).hex(" ")
    result = {"fwdopen": status}
    if status == 0:
        conn.produce()
        for name, raw in (("r1", "80 00 21 20 E8 03 00 00"), ("r2", "81 00 21 20 E8 03 00 00"),
                          ("r3", "80 00 21 20 E8 03 00 00")):
            put(bytes.fromhex(raw))
            time.sleep(0.3)
            result[name] = get()
        conn.stopProduce()
        result["fwdclose"] = conn.sendFwdCloseReq(102, 101, 100)
    enip.stopIO()
    print(json.dumps(result))
""")


def test_ethernetip_package_as_class1_originator(drive) -> None:
    pytest.importorskip("ethernetip", reason="the ethernetip package is not installed (pip install 'akdctl[test]')")
    server, io_port = drive
    result = subprocess.run([sys.executable, "-c", ORIGINATOR, str(server.port), str(io_port)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout)
    assert out["fwdopen"] == 0 and out["fwdclose"] == 0
    assert out["r1"] == "84 00 00 20 00 00 00 00"              # seed step 2, seen by an independent originator
    assert int(out["r2"].split()[2], 16) & 0x80                 # Load Complete after the 0 -> 1 edge
    assert not int(out["r3"].split()[2], 16) & 0x80


def test_tshark_cipcm_dissects_the_io_session(drive, tmp_path) -> None:
    import os
    import shutil

    tshark = shutil.which("tshark")
    if tshark is None:
        if os.environ.get("CI") == "true":
            pytest.fail("tshark is required in CI")
        pytest.skip("tshark is not installed (apt-get install tshark); CI runs this test")
    server, io_port = drive
    capture = tmp_path / "io.pcap"
    result = akdctl(tmp_path, server.target, "--pcap", str(capture), "eip", "io", "position", "1000", "-y",
                    "--port", str(io_port), "--rpi", "20")
    assert result.returncode == 0, result.stderr
    out = subprocess.run([tshark, "-r", str(capture), "-d", f"tcp.port=={server.port},enip",
                          "-d", f"udp.port=={io_port},cipio", "-T", "fields", "-e", "frame.protocols",
                          "-e", "cip.service", "-e", "cip.cm.otrpi", "-e", "cip.cm.fwo.consize",
                          "-e", "cipio.data"], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "HOME": str(tmp_path)})
    assert out.returncode == 0, out.stderr
    rows = [line.split("\t") for line in out.stdout.strip().splitlines()]
    forward_open = [r for r in rows if r[0].endswith(":cipcm") and r[1] == "0x54"]
    assert forward_open and forward_open[0][2] == "20000" and forward_open[0][3] == "70,66"   # 64 + 6, 64 + 2
    assert any(r[0].endswith(":cipcm") and r[1] == "0x4e" for r in rows)                       # Forward_Close
    io_data = [r[4] for r in rows if ":udp:cipio" in r[0] and r[4]]
    assert len(io_data) >= 4
    assert any(d[4:20] == "8400002000000000" for d in io_data)     # seed step 2 after the 16-bit sequence count


def test_large_forward_open_and_forward_close_of_an_unknown_connection(drive, session) -> None:
    from akdctl.protocol import akd_assembly as asm
    from akdctl.protocol import cip

    server, _ = drive
    path = cip.Path(cip.ASSEMBLY, asm.CONFIG_INSTANCE, None, (asm.OUTPUT_INSTANCE, asm.INPUT_INSTANCE)).encode()
    fo = cip.ForwardOpen(0, 9, 3, 0xFFFF, 4, 20000, cip.NetParams(70), 20000, cip.NetParams(66), path, large=True)
    reply = session.request(cip.Request(cip.LARGE_FORWARD_OPEN, cip.Path(6, 1).encode(), fo.encode()))
    assert reply.ok, reply
    opened = cip.ForwardOpenReply.decode(reply.data)
    assert opened.to_connection_id == 9 and opened.ot_connection_id and opened.ot_api_us == 20000
    close = cip.Request(cip.FORWARD_CLOSE, cip.Path(6, 1).encode(), cip.ForwardClose(3, 0xFFFF, 4, path).encode())
    assert session.request(close).ok
    again = session.request(close)
    assert again.status == 0x01 and again.extended == (cip.EXT_CONNECTION_NOT_FOUND,)


def test_io_needs_consent_that_names_the_disable(drive, tmp_path) -> None:
    server, io_port = drive
    result = akdctl(tmp_path, server.target, "eip", "io", "position", "10", "--port", str(io_port))
    assert result.returncode == 4 and "disables the axis" in result.stderr and "--yes" in result.stderr
    jog = akdctl(tmp_path, server.target, "eip", "io", "jog", "-100", "-y", "--port", str(io_port))
    assert jog.returncode == 2 and "--for" in jog.stderr                  # unbounded motion is refused
