"""Row ``ascii``: AKD ASCII-channel reads/s, ``akd://`` against a minimal socket client.

The work: ``DRV.OPMODE`` read over the AKD's TCP command channel (reference akd-ascii-channel.md 0-2: the line
``DRV.OPMODE\\r\\n`` out, the value, ``\\r\\n`` and the ``-->`` prompt back). akdctl reads it through the
Connection's command link (``conn.commands().command("DRV.OPMODE")``, what ``param get`` does over akd://). The
peer is the smallest correct client written here: one socket with TCP_NODELAY and a timeout set once,
``sendall`` of the line, ``recv`` until the buffer ends with the prompt, the value taken from before
``\\r\\n-->`` (Telnet option bytes the face offers on connect are drained once after connecting). Both talk to one
``sim serve --akd`` face (``--akd-clients 2``) on loopback, each from its own worker process, interleaved.
"""

from __future__ import annotations

from benchlib import Result, Settings, started_on_comparison_cpu
from row_tcp_peers import compare

COMMAND = "DRV.OPMODE"

SCRIPT = r"""
import socket, sys, time
kind, where = sys.argv[1], sys.argv[2]
host, port = where.rsplit(":", 1)
COMMAND = @COMMAND@
if kind == "akdctl":
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target
    conn = Connection(parse_target(f"akd://{host}:{port}"), LinkOptions(timeout=1.0))
    link = conn.commands()
    def op():
        if not link.command(COMMAND).strip().isdigit():
            raise SystemExit("akdctl: unexpected reply")
elif kind == "socket":
    sock = socket.create_connection((host, int(port)), timeout=1.0)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    sock.settimeout(0.2)
    try:
        while sock.recv(4096):   # the face's Telnet offer on connect: drained, not answered
            pass
    except socket.timeout:
        pass
    sock.settimeout(1.0)
    request = (COMMAND + "\r\n").encode("ascii")
    def op():
        sock.sendall(request)
        reply = b""
        while not reply.endswith(b"-->"):
            chunk = sock.recv(4096)
            if not chunk:
                raise SystemExit("socket: connection closed")
            reply += chunk
        if not reply[:-5].strip().isdigit():
            raise SystemExit(f"socket: unexpected reply {reply!r}")
else:
    raise SystemExit(f"unknown worker {kind}")
""".replace("@COMMAND@", repr(COMMAND))


def ascii_vs_socket(s: Settings) -> Result:
    import re

    from servers import sim_server

    env = {"AKDCTL_STATE_DIR": str(s.tmp / "ascii")}
    face = ("--name", "asciipeer", "--akd", "127.0.0.1:0", "--akd-clients", "2")
    with started_on_comparison_cpu(sim_server(*face, env=env)) as server:
        match = re.match(r"akd ascii tcp ([\d.]+):(\d+)", server.ready[0])
        if match is None:
            raise RuntimeError(f"unexpected ready line {server.ready[0]!r}")
        where = f"{match.group(1)}:{match.group(2)}"
        result = compare(SCRIPT, {"akdctl": where, "socket": where}, s, max(50, s.block // 2), peer="socket")
    result.notes.append(f"each op: {COMMAND!r} and its reply up to the '-->' prompt")
    return result
