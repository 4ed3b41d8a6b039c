"""Row ``modbus``: Modbus TCP holding-register reads/s, ``mb://`` against pymodbus's own ``ModbusTcpClient``.

The work: one AKD parameter read the way ``akdctl param get`` reads it over ``mb://`` -- AOUT.MODE, ``n`` = 11
[V], so holding registers 20 and 21 in one Read Holding Registers request (function 3, two registers, the most
significant word first; the register rule is ``drive/names.py``'s). akdctl reads them through the Connection's
register link (``conn.registers().read_registers(20, 2)``); the peer is pymodbus's ``ModbusTcpClient.
read_holding_registers(20, count=2)``, the library most Python Modbus code uses; pyModbusTCP's ``ModbusClient``
(a small synchronous client) is a second yardstick. All three talk to one ``sim serve --modbus`` face on loopback
(it serves three clients at once, as an AKD does), each from its own worker process, in interleaved blocks.
"""

from __future__ import annotations

from benchlib import Result, Settings, started_on_comparison_cpu
from row_tcp_peers import compare

#: AOUT.MODE: n = 11 [V] -> holding register 2(n-1) = 20, two registers.
REGISTER, COUNT = 20, 2

SCRIPT = r"""
import sys, time
kind, where = sys.argv[1], sys.argv[2]
host, port = where.rsplit(":", 1)
REGISTER, COUNT = @REGISTER@, @COUNT@
if kind == "akdctl":
    from akdctl.connection import Connection
    from akdctl.transport.base import LinkOptions
    from akdctl.transport.registry import parse_target
    conn = Connection(parse_target(f"mb://{host}:{port}"), LinkOptions(timeout=1.0))
    link = conn.registers()
    def op():
        if len(link.read_registers(REGISTER, COUNT)) != COUNT:
            raise SystemExit("akdctl: short read")
elif kind == "pymodbus":
    from pymodbus.client import ModbusTcpClient
    client = ModbusTcpClient(host, port=int(port), timeout=1.0, retries=0)
    if not client.connect():
        raise SystemExit("pymodbus: cannot connect")
    def op():
        reply = client.read_holding_registers(REGISTER, count=COUNT, device_id=1)
        if reply.isError() or len(reply.registers) != COUNT:
            raise SystemExit(f"pymodbus: {reply}")
elif kind == "pyModbusTCP":
    from pyModbusTCP.client import ModbusClient
    client = ModbusClient(host=host, port=int(port), unit_id=1, timeout=1.0, auto_open=True)
    def op():
        words = client.read_holding_registers(REGISTER, COUNT)
        if words is None or len(words) != COUNT:
            raise SystemExit(f"pyModbusTCP: {client.last_error_as_txt}")
else:
    raise SystemExit(f"unknown worker {kind}")
""".replace("@REGISTER@", str(REGISTER)).replace("@COUNT@", str(COUNT))


def modbus_vs_pymodbus(s: Settings) -> Result:
    try:
        import pymodbus  # noqa: F401
    except ImportError:
        return Result("skipped", None, ["pymodbus is not installed (pip install 'akdctl[modbus]')"])
    import re

    from servers import sim_server

    try:
        import pyModbusTCP  # noqa: F401
        yardsticks: tuple[str, ...] = ("pyModbusTCP",)
    except ImportError:
        yardsticks = ()
    env = {"AKDCTL_STATE_DIR": str(s.tmp / "modbus")}
    with started_on_comparison_cpu(sim_server("--name", "mbpeer", "--modbus", "127.0.0.1:0", env=env)) as server:
        match = re.match(r"modbus tcp ([\d.]+):(\d+)", server.ready[0])
        if match is None:
            raise RuntimeError(f"unexpected ready line {server.ready[0]!r}")
        where = f"{match.group(1)}:{match.group(2)}"
        result = compare(SCRIPT, {kind: where for kind in ("akdctl", "pymodbus", *yardsticks)}, s,
                         max(50, s.block // 2), peer="pymodbus", yardsticks=yardsticks)
    result.notes.append(f"each op: Read Holding Registers {REGISTER}..{REGISTER + COUNT - 1} (AOUT.MODE, n = 11)")
    return result
