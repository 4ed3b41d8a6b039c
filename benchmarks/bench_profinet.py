"""PNU reads per second through `akdctl sim serve --profinet` on loopback, single and batched (39 per
request), each as a ratio against a bare Python UDP request/response loop measured in the same run.

Both servers run in their own process, the client in this one. One PNU read over PROFINET is two UDP round
trips (write record, read record) plus the simulated drive's work, so the single-read ratio is at most 0.5 by
construction; batching 39 parameters per request is how a real tool gets its speed.

    python benchmarks/bench_profinet.py [--seconds 2]
"""

from __future__ import annotations

import argparse
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

ECHO_SERVER = """
import socket, sys
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1], flush=True)
while True:
    data, peer = s.recvfrom(65535)
    s.sendto(data, peer)
"""


def _env(state: str) -> dict[str, str]:
    env = dict(os.environ, AKDCTL_STATE_DIR=state)
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def bare_loop(seconds: float) -> float:
    """Round trips per second of a plain UDP request/response loop (payload the size of a PNIO read)."""
    proc = subprocess.Popen([sys.executable, "-c", ECHO_SERVER], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        port = int(proc.stdout.readline())
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.connect(("127.0.0.1", port))
        sock.settimeout(2)
        payload = bytes(80 + 20 + 64)
        count, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            sock.send(payload)
            sock.recv(65535)
            count += 1
        elapsed = time.perf_counter() - start
        sock.close()
        return count / elapsed
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def pn_reads(seconds: float, batch: int, state: str) -> float:
    """PNU values read per second through the PROFINET face (``batch`` parameters per request)."""
    from akdctl.protocol.bmp import ParameterAddress
    from akdctl.transport.base import LinkOptions
    from akdctl.connection import Connection
    from akdctl.transport.target import split_target

    proc = subprocess.Popen([sys.executable, "-m", "akdctl", "sim", "serve", "--profinet", "127.0.0.1:0"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=_env(state))
    try:
        assert proc.stdout is not None
        match = re.search(r"127\.0\.0\.1:(\d+)", proc.stdout.readline())
        assert match, "sim serve did not start"
        os.environ["AKDCTL_STATE_DIR"] = state
        conn = Connection(split_target(f"pn://127.0.0.1:{match.group(1)}"), LinkOptions(timeout=2))
        try:
            channel = conn.parameters()
            addresses = [ParameterAddress(930)] * batch
            channel.read(addresses)                                  # warm up
            values, start = 0, time.perf_counter()
            while time.perf_counter() - start < seconds:
                values += len(channel.read(addresses))
            return values / (time.perf_counter() - start)
        finally:
            conn.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="akdctl-bench-") as state:
        bare = bare_loop(args.seconds)
        single = pn_reads(args.seconds, 1, state)
        batched = pn_reads(args.seconds, 39, state)
    print(f"bare UDP request/response loop: {bare:10.0f} round trips/s")
    print(f"PROFINET single PNU reads:      {single:10.0f} PNU/s   ratio {single / bare:.3f}"
          "  (2 round trips per read: at most 0.5)")
    print(f"PROFINET batched (39/request):  {batched:10.0f} PNU/s   ratio {batched / bare:.3f}")


if __name__ == "__main__":
    main()
