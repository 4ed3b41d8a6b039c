"""SDO uploads per second over EtherCAT, each against a baseline measured in the same run.

1. Gateway: ``akdctl sim serve --ethercat-udp`` on loopback, our CoE client (``ecat-udp://``) uploading 0x1018:01,
   against a bare Python UDP request/response loop with the same 18-byte datagrams (aim: >= 0.5 of the bare loop).
2. Raw (root only: a veth pair between two network namespaces, our simulated slave on one end): our pure-Python
   master (``ecat://``) against pysoem on the same slave (aim: not slower than pysoem), and against a bare
   AF_PACKET frame echo on the same veth. One SDO upload over a raw link is at least three frames (write SM0,
   poll SM1 status, read SM1), so that ratio is at most 1/3 by construction.

    python benchmarks/bench_ethercat.py [--seconds 2]
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import textwrap
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

UDP_ECHO = """
import socket
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1], flush=True)
while True:
    data, peer = s.recvfrom(2048)
    s.sendto(data, peer)
"""

RAW_ECHO = """
import socket, sys
s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(0x88A4))
s.bind((sys.argv[1], 0))
print("ready", flush=True)
while True:
    f = s.recv(2048)
    if f[6] & 2:
        continue
    s.send(f[:6] + bytes([f[6] | 2]) + f[7:])
"""


def _env(state: str) -> dict[str, str]:
    env = dict(os.environ, AKDCTL_STATE_DIR=state)
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def _stop(proc: subprocess.Popen) -> None:  # type: ignore[type-arg]
    proc.terminate()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _rate(fn, seconds: float) -> float:  # type: ignore[no-untyped-def]
    fn()  # warm up
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        fn()
        n += 1
    return n / (time.perf_counter() - start)


def gateway(seconds: float, state: str) -> tuple[float, float]:
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target

    echo = subprocess.Popen([sys.executable, "-c", UDP_ECHO], stdout=subprocess.PIPE, text=True)
    serve = None
    try:
        assert echo.stdout is not None
        port = int(echo.stdout.readline())
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.connect(("127.0.0.1", port))
        sock.settimeout(2)
        request = bytes.fromhex("10 50 0a 00 e9 03 00 03 00 20 40 18 10 01 00 00 00 00")

        def bare() -> None:
            sock.send(request)
            sock.recv(2048)

        bare_rate = _rate(bare, seconds)
        sock.close()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind(("127.0.0.1", 0))
            gw_port = s.getsockname()[1]
        serve = subprocess.Popen([sys.executable, "-m", "akdctl", "sim", "serve", "--ethercat-udp",
                                  f"127.0.0.1:{gw_port}", "--duration", str(seconds * 4 + 30)],
                                 stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=_env(state))
        assert serve.stdout is not None
        serve.stdout.readline()
        target = parse_target(f"ecat-udp://127.0.0.1:{gw_port}/1001")
        conn = Connection(target, LinkOptions(timeout=1.0))
        try:
            objects = conn.objects()
            sdo_rate = _rate(lambda: objects.upload(0x1018, 1), seconds)
        finally:
            conn.close()
        return sdo_rate, bare_rate
    finally:
        _stop(echo)
        if serve is not None:
            _stop(serve)


OUR_MASTER = """
import sys, time
from akdctl.connection import Connection
from akdctl.transport.base import LinkOptions
from akdctl.transport.registry import parse_target
conn = Connection(parse_target("ecat://" + sys.argv[1] + "/0"), LinkOptions(timeout=1.0))
objects = conn.objects()
objects.upload(0x1018, 1)
n, start = 0, time.perf_counter()
while time.perf_counter() - start < float(sys.argv[2]):
    objects.upload(0x1018, 1); n += 1
print(n / (time.perf_counter() - start)); conn.close()
"""

PYSOEM = """
import sys, time, pysoem
m = pysoem.Master(); m.open(sys.argv[1]); m.config_init(); s = m.slaves[0]
s.sdo_read(0x1018, 1)
n, start = 0, time.perf_counter()
while time.perf_counter() - start < float(sys.argv[2]):
    s.sdo_read(0x1018, 1); n += 1
print(n / (time.perf_counter() - start)); m.close()
"""

BARE_RAW = """
import socket, sys, time
s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(0x88A4)); s.bind((sys.argv[1], 0))
frame = b"\\xff" * 6 + b"\\x01" * 6 + bytes.fromhex("88a4 0e10 0401 0110 0d08 0200 0000 0000 0000") + bytes(32)
def once():
    s.send(frame)
    while True:
        f = s.recv(2048)
        if f[6] & 2:
            return
once()
n, start = 0, time.perf_counter()
while time.perf_counter() - start < float(sys.argv[2]):
    once(); n += 1
print(n / (time.perf_counter() - start))
"""


def raw(seconds: float, state: str) -> dict[str, float] | str:
    if os.geteuid() != 0:
        return "skipped (needs root for network namespaces)"
    tag = uuid.uuid4().hex[:6]
    ns_a, ns_b, if_a, if_b = f"bA{tag}", f"bB{tag}", f"ba{tag}", f"bb{tag}"
    run = lambda *c: subprocess.run(c, check=True, capture_output=True)  # noqa: E731
    results: dict[str, float] = {}
    try:
        run("ip", "netns", "add", ns_a)
        run("ip", "netns", "add", ns_b)
        run("ip", "link", "add", if_a, "type", "veth", "peer", "name", if_b)
        run("ip", "link", "set", if_a, "netns", ns_a)
        run("ip", "link", "set", if_b, "netns", ns_b)
        run("ip", "-n", ns_a, "link", "set", if_a, "up")
        run("ip", "-n", ns_b, "link", "set", if_b, "up")
        env = _env(state)

        def client(script: str) -> float:
            out = subprocess.run(["ip", "netns", "exec", ns_a, sys.executable, "-c", script, if_a, str(seconds)],
                                 capture_output=True, text=True, env=env, timeout=seconds * 5 + 60)
            return float(out.stdout.strip().splitlines()[-1]) if out.returncode == 0 else float("nan")

        echo = subprocess.Popen(["ip", "netns", "exec", ns_b, sys.executable, "-c", RAW_ECHO, if_b],
                                stdout=subprocess.PIPE, text=True)
        try:
            assert echo.stdout is not None
            echo.stdout.readline()
            results["bare frame loop"] = client(BARE_RAW)
        finally:
            _stop(echo)
        slave = subprocess.Popen(["ip", "netns", "exec", ns_b, sys.executable, "-m", "akdctl", "sim", "serve",
                                  "--ethercat-raw", if_b, "--duration", str(seconds * 6 + 60)],
                                 stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
        try:
            assert slave.stdout is not None
            slave.stdout.readline()
            results["akdctl raw master"] = client(OUR_MASTER)
            try:
                import pysoem  # noqa: F401

                results["pysoem"] = client(PYSOEM)
            except ImportError:
                pass
        finally:
            _stop(slave)
    finally:
        for ns in (ns_a, ns_b):
            subprocess.run(["ip", "netns", "delete", ns], capture_output=True)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as state:
        sdo_rate, bare_rate = gateway(args.seconds, state)
        print(f"gateway (ecat-udp, loopback): {sdo_rate:8.0f} SDO uploads/s   bare UDP loop {bare_rate:8.0f}/s"
              f"   ratio {sdo_rate / bare_rate:.2f}  (aim >= 0.5)")
        results = raw(args.seconds, state)
        if isinstance(results, str):
            print(f"raw (ecat://, veth): {results}")
            return
        ours, bare = results.get("akdctl raw master", float("nan")), results.get("bare frame loop", float("nan"))
        print(f"raw (ecat://, veth):          {ours:8.0f} SDO uploads/s   bare frame loop {bare:8.0f}/s"
              f"   ratio {ours / bare:.2f}  (<= 0.33 by construction)")
        if "pysoem" in results:
            print(textwrap.dedent(f"""\
                pysoem on the same slave:     {results['pysoem']:8.0f} SDO uploads/s   ours/pysoem {ours / results['pysoem']:.2f}  (aim >= 1)"""))


if __name__ == "__main__":
    main()
