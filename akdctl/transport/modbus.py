"""``mb://HOST[:502][?unit=N]``: Modbus TCP through pymodbus's client, for the AKD's parameter registers.

The AKD's map (AKD User Guide ch. 22, reference ethernetip.md 3 and akd-parameter-names.md 2.4): parameter ``n``
sits at holding register ``2(n-1)``; a parameter of 32 bits or less is two registers read or written in one
message, the lower address holding the most significant word [V]; floats travel x1000 [V]. Which names have
which ``n`` is the catalogue's business (``drive/names.py`` turns a name into registers); this transport only
reads and writes registers, every wait bounded by the command's timeout (pymodbus's own retries are off: a
request is sent once, as the Budget's rule for writes asks).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akdctl.errors import CommError, ModbusRefused, NoAnswer, UsageError
from akdctl.links import RegisterLink
from akdctl.transport.base import LinkOptions, Transport

if TYPE_CHECKING:
    from akdctl.transport.target import Target

PORT = 502
#: Modbus exception codes in words (Modbus Application Protocol v1.1b3, 7).
EXCEPTIONS = {1: "illegal function", 2: "illegal data address", 3: "illegal data value", 4: "server device failure",
              5: "acknowledge", 6: "server device busy"}


class ModbusLink(RegisterLink):
    def __init__(self, client: Any, unit: int, options: LinkOptions, label: str) -> None:
        self.client = client
        self.unit = unit
        self.options = options
        self.label = label

    def _call(self, what: str, call: Any) -> Any:
        from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

        with self.options.budget.request(attempts=1) as deadline:
            self.client.comm_params.timeout_connect = max(deadline.remaining(), 0.001)
            try:
                result = call()
            except ModbusIOException:
                raise NoAnswer(f"{self.label}: no answer to {what} within {deadline.describe()}") from None
            except ConnectionException as exc:
                raise CommError(f"{self.label}: connection failed during {what} ({exc})") from None
            except ModbusException as exc:
                raise CommError(f"{self.label}: {what} failed ({exc})") from None
            except OSError as exc:   # pymodbus lets a reset or refused socket through as it is
                raise CommError(f"{self.label}: connection failed during {what} ({exc.strerror or exc})") from None
        if result.isError():
            code = getattr(result, "exception_code", None)
            text = EXCEPTIONS.get(code, "exception") if code is not None else "error"
            raise ModbusRefused(f"{self.label}: the drive refused {what}: {text} (exception {code})", code=code)
        return result

    def read_registers(self, address: int, count: int) -> list[int]:
        what = f"reading registers {address}..{address + count - 1}"
        result = self._call(what, lambda: self.client.read_holding_registers(address, count=count,
                                                                             device_id=self.unit))
        return list(result.registers)

    def write_registers(self, address: int, values: list[int]) -> None:
        what = f"writing registers {address}..{address + len(values) - 1}"
        self._call(what, lambda: self.client.write_registers(address, list(values), device_id=self.unit))


class ModbusTransport(Transport):
    """``mb://``: offers holding registers as a :class:`~akdctl.links.RegisterLink`."""

    scheme = "mb"

    def __init__(self, target: "Target", options: LinkOptions) -> None:
        super().__init__(target, options)
        self._client: Any = None

    def open(self) -> None:
        import logging

        from pymodbus.client import ModbusTcpClient

        # pymodbus logs its failures itself; akdctl says them once, in its one error line
        logging.getLogger("pymodbus").addHandler(logging.NullHandler())
        logging.getLogger("pymodbus").propagate = False

        host, port = self.target.host, self.target.port or PORT
        label = f"mb://{host}:{port}"
        try:
            unit = int(self.target.query.get("unit", "1"), 0)
        except ValueError:
            unit = -1
        if not 0 <= unit <= 247:
            raise UsageError(f"{label}: unit must be 0..247")
        timeout = self.options.budget.left()
        tracer = self.options.tracer

        def trace(sending: bool, packet: bytes) -> bytes:   # the Modbus TCP ADUs (--trace, --pcap; layer mb)
            if tracer.active:
                meta: dict[str, object] = {}
                sock = getattr(client, "socket", None)
                try:
                    local, remote = sock.getsockname()[:2], sock.getpeername()[:2]  # type: ignore[union-attr]
                    src, dst = (local, remote) if sending else (remote, local)
                    meta = {"proto": "tcp", "src": src, "dst": dst}
                except (AttributeError, OSError):
                    pass
                tracer.frame("tx" if sending else "rx", "mb", packet, note=label, meta=meta)
            return packet

        client = ModbusTcpClient(host, port=port, timeout=timeout, retries=0, reconnect_delay=0, trace_packet=trace)
        self._client = client
        try:
            connected = client.connect()
        except OSError as exc:
            raise CommError(f"{label}: cannot connect ({exc.strerror or exc})") from None
        if not connected:
            raise CommError(f"{label}: cannot connect (no Modbus TCP server answering; the AKD listens on 502)")
        self.register_link = ModbusLink(client, unit, self.options, label)

    def close(self) -> None:
        client, self._client = self._client, None
        self.register_link = None
        if client is not None:
            try:
                client.close()
            except Exception:  # noqa: BLE001 - closing must not fail the command
                pass


__all__ = ["ModbusTransport", "ModbusLink", "PORT"]
