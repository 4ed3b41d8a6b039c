"""The simulator's Modbus TCP face (``sim serve --modbus HOST:PORT``), built on pymodbus's server.

Every holding register is computed from the one drive model on each request (pymodbus's device ``action``
hook), through :mod:`akdctl.sim.akd_params`: parameter ``n`` at registers ``2(n-1)`` and ``2(n-1)+1``, most
significant word first, floats x1000 (AKD User Guide ch. 22 [V]). A write must cover whole parameters (the AKD
takes a 32-bit value "in one message" [V]); a register of no catalogue parameter, a text or a command is an
"illegal data address" exception, a value the drive refuses "illegal data value". Up to three clients at once,
as the AKD allows beside WorkBench [V]; a fourth is closed at once.
"""

from __future__ import annotations

import asyncio
import threading
from typing import Any

from akdctl.errors import UsageError
from akdctl.sim.face import Face, FaceOption, request_failed

DEFAULT_ADDRESS = "127.0.0.1:1502"
MAX_CLIENTS = 3
#: Registers served: every n up to this (the AKD's numbers reach about 1160, reference akd-parameter-names.md 9).
MAX_N = 1200

OPTIONS = (
    FaceOption("--modbus", "modbus", flag_value=DEFAULT_ADDRESS, metavar="[ADDR]",
               help=f"Serve the drive's parameters over Modbus TCP (a real AKD: 502), default {DEFAULT_ADDRESS}."),
)


def from_options(drive: Any, **kwargs: Any) -> "ModbusFace | None":
    address = kwargs.get("modbus")
    if address is None:
        return None
    from akdctl.sim.face_profinet import parse_address

    host, port = parse_address(address, 502, "--modbus")
    return ModbusFace(drive, host, port)


class RegisterMap:
    """Registers <-> the drive model's parameters (the part of the face that knows no pymodbus)."""

    ILLEGAL_ADDRESS = 2
    ILLEGAL_VALUE = 3

    def __init__(self, drive: Any) -> None:
        self.drive = drive

    @staticmethod
    def row_at(register: int) -> Any:
        from akdctl.sim import akd_params as store

        row = store.by_number(register // 2 + 1)
        if row is None or row.is_command or row.kind in ("text", "string"):
            return None
        return row

    def read(self, address: int, count: int) -> list[int] | int:
        """Register values, or an exception code."""
        from akdctl.sim import akd_params as store

        out: list[int] = []
        with self.drive.transaction() as model:
            register = address
            while register < address + count:
                row = self.row_at(register)
                if row is None or not row.readable:
                    return self.ILLEGAL_ADDRESS
                try:
                    number = store.wire(model, row) & 0xFFFFFFFF
                except store.ParamError:
                    return self.ILLEGAL_ADDRESS
                words = [number >> 16, number & 0xFFFF]
                start = register - 2 * (row.n - 1)
                take = min(2 - start, address + count - register)
                out += words[start:start + take]
                register += take
        return out

    def write(self, address: int, values: list[int]) -> int | None:
        """None when written, else an exception code."""
        from akdctl.sim import akd_params as store

        if address % 2 or len(values) % 2:
            return self.ILLEGAL_ADDRESS   # a parameter is written whole, in one message [V]
        with self.drive.transaction() as model:
            for offset in range(0, len(values), 2):
                row = self.row_at(address + offset)
                if row is None or not row.writable:
                    return self.ILLEGAL_ADDRESS
                number = (values[offset] << 16) | values[offset + 1]
                signed = row.kind == "float" or not row.coe_type.startswith("u")
                if signed and number >= 1 << 31:
                    number -= 1 << 32
                try:
                    store.write_wire(model, row, number)
                except store.ParamError:
                    return self.ILLEGAL_VALUE
        return None


class ModbusFace(Face):
    """pymodbus's TCP server on its own event loop thread, registers from :class:`RegisterMap`."""

    def __init__(self, drive: Any, host: str, port: int) -> None:
        self.map = RegisterMap(drive)
        self.host = host
        self.port = port
        self.loop: asyncio.AbstractEventLoop | None = None
        self.server: Any = None
        self.thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None

    async def _action(self, function_code: int, start_address: int, address: int, count: int,
                      registers: list[int], set_values: Any) -> Any:
        from pymodbus.constants import ExcCodes

        codes = {RegisterMap.ILLEGAL_ADDRESS: ExcCodes.ILLEGAL_ADDRESS, RegisterMap.ILLEGAL_VALUE: ExcCodes.ILLEGAL_VALUE}
        try:
            if set_values is None:
                got = self.map.read(address, count)
                if isinstance(got, int):
                    return codes[got]
                for i, value in enumerate(got):
                    registers[address - start_address + i] = value
                return None
            if function_code not in (16, 23):
                return ExcCodes.ILLEGAL_FUNCTION   # single-register writes would split a parameter [V]
            failed = self.map.write(address, [int(v) for v in set_values])
            return codes[failed] if failed is not None else None
        except Exception as exc:  # a face never dies of a request
            request_failed("modbus face", exc)
            return ExcCodes.DEVICE_FAILURE

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self.loop = loop
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._serve())
        except BaseException as exc:  # reported by start()
            self._error = self._error or exc
            self._ready.set()

    async def _serve(self) -> None:
        import logging

        from pymodbus.server import ModbusTcpServer
        from pymodbus.simulator import DataType, SimData, SimDevice

        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)   # the face reports in its own words
        device = SimDevice(id=0, simdata=SimData(0, count=2 * MAX_N, values=0, datatype=DataType.REGISTERS),
                           action=self._action)
        server = ModbusTcpServer(device, address=(self.host, self.port))
        self._limit_clients(server)
        self.server = server
        try:
            await server.serve_forever(background=True)
        except RuntimeError:
            self._error = OSError(f"address {self.host}:{self.port} not available")
            self._ready.set()
            return
        listener = server.transport  # pymodbus's listener: an asyncio.Server once serving (its sockets bound)
        sockets = list(listener.sockets or []) if listener is not None else []
        if sockets:
            self.port = sockets[0].getsockname()[1]
        self._ready.set()
        await server.serving

    @staticmethod
    def _limit_clients(server: Any) -> None:
        """Up to three clients (AKD User Guide ch. 22 [V]): a fourth is closed as soon as it connects."""
        original = server.handle_new_connection

        def limited() -> Any:
            protocol = original()
            if len(server.active_connections) > MAX_CLIENTS:
                made = protocol.connection_made

                def close_at_once(transport: Any) -> None:
                    made(transport)
                    transport.close()

                protocol.connection_made = close_at_once
            return protocol

        server.handle_new_connection = limited

    def start(self) -> None:
        self.thread = threading.Thread(target=self._run, name="modbus-face", daemon=True)
        self.thread.start()
        self._ready.wait(10)
        if self._error is not None:
            text = getattr(self._error, "strerror", None) or str(self._error)
            raise UsageError(f"--modbus {self.host}:{self.port}: cannot listen ({text})")

    def stop(self) -> None:
        if self.loop is not None and self.server is not None:
            try:
                asyncio.run_coroutine_threadsafe(self.server.shutdown(), self.loop).result(5)
            except Exception:  # noqa: BLE001
                pass
        if self.thread is not None:
            self.thread.join(timeout=5)

    def describe(self) -> str:
        return f"modbus tcp {self.host}:{self.port}"
