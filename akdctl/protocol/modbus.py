"""Modbus TCP application data units: the MBAP header and the two functions akdctl uses on an AKD.

The layout (Modbus Messaging on TCP/IP Implementation Guide v1.0b, 3.1.3; Modbus Application Protocol v1.1b3,
6.3 and 6.12): a 7-byte MBAP header -- transaction identifier (u16), protocol identifier 0 (u16), length of what
follows (u16: the unit identifier and the PDU), unit identifier (u8) -- then the PDU: a function code (u8) and its
data, every number big-endian. Read Holding Registers (3): start address and count (1..125) out, a byte count and
the registers back. Write Multiple Registers (16): start address, count (1..123), byte count and the values out,
start address and count back. An exception reply has the function code with bit 7 set and one exception code.

Why akdctl has its own codec rather than a library's client: a register read is two small packs and one unpack;
a general client (pymodbus) builds a transaction manager, a framer and PDU objects for each request, several
times the CPU of the whole exchange on loopback. The simulator's face keeps pymodbus's server, an independent
implementation the client is tested against.
"""

from __future__ import annotations

import struct

from akdctl.protocol.errors import CodecError

READ_HOLDING = 3
WRITE_MULTIPLE = 16
MBAP_SIZE = 7
#: The longest PDU (Modbus Application Protocol 4.1), so the MBAP length is at most 254 (unit + PDU).
MAX_PDU = 253
MAX_READ = 125
MAX_WRITE = 123

_HEADER = struct.Struct(">HHHB")
_READ = struct.Struct(">HHHBBHH")        # MBAP + function 3, address, count
_WRITE_HEAD = struct.Struct(">HHHBBHHB")  # MBAP + function 16, address, count, byte count


def _check_address(address: int, count: int, limit: int) -> None:
    if not 1 <= count <= limit:
        raise CodecError(f"a request carries 1..{limit} registers (got {count})")
    if not 0 <= address <= 0xFFFF or address + count > 0x10000:
        raise CodecError(f"registers {address}..{address + count - 1} are outside 0..65535")


def pack_read_holding(transaction: int, unit: int, address: int, count: int) -> bytes:
    """Read Holding Registers ``address``..``address+count-1`` as one ADU."""
    if not (1 <= count <= MAX_READ and 0 <= address and address + count <= 0x10000):
        _check_address(address, count, MAX_READ)
    return _READ.pack(transaction & 0xFFFF, 0, 6, unit, READ_HOLDING, address, count)


def pack_write_multiple(transaction: int, unit: int, address: int, values: list[int]) -> bytes:
    """Write Multiple Registers: ``values`` (each 0..65535) from ``address`` on, as one ADU."""
    _check_address(address, len(values), MAX_WRITE)
    if any(not 0 <= v <= 0xFFFF for v in values):
        raise CodecError("a register holds 0..65535")
    data = struct.pack(f">{len(values)}H", *values)
    return _WRITE_HEAD.pack(transaction & 0xFFFF, 0, 7 + len(data), unit, WRITE_MULTIPLE, address, len(values),
                            len(data)) + data


def adu_size(header: bytes) -> int:
    """The whole ADU's size from its first 6 bytes (transaction, protocol, length); CodecError when they cannot
    start a Modbus TCP reply."""
    if len(header) < 6:
        raise CodecError("a Modbus TCP header is 7 bytes")
    protocol, length = struct.unpack_from(">HH", header, 2)
    if protocol != 0:
        raise CodecError(f"protocol identifier {protocol} (Modbus is 0)")
    if not 2 <= length <= MAX_PDU + 1:
        raise CodecError(f"MBAP length {length} (2..{MAX_PDU + 1})")
    return 6 + length


def transaction_of(adu: bytes) -> int:
    """The transaction identifier of an ADU (at least 2 bytes)."""
    return (adu[0] << 8) | adu[1]


def unpack_reply(adu: bytes, unit: int, function: int) -> tuple[int | None, bytes]:
    """(exception code or None, the PDU's data after its function code) of a whole reply ADU to ``function`` sent to
    ``unit``; CodecError when it is not one."""
    if len(adu) < MBAP_SIZE + 2:
        raise CodecError(f"a Modbus reply of {len(adu)} bytes")
    _, protocol, length, got_unit = _HEADER.unpack_from(adu)
    if protocol != 0 or length != len(adu) - 6:
        raise CodecError("the MBAP header does not match the reply's size")
    if got_unit != unit:
        raise CodecError(f"a reply from unit {got_unit}, not {unit}")
    code = adu[7]
    if code == function | 0x80:
        if len(adu) != MBAP_SIZE + 2:
            raise CodecError("an exception reply is one byte after its function code")
        return adu[8], b""
    if code != function:
        raise CodecError(f"a reply to function {code}, not {function}")
    return None, adu[8:]


def unpack_read_holding(data: bytes, count: int) -> list[int]:
    """The registers of a Read Holding Registers reply's data (byte count + values), ``count`` of them."""
    if len(data) != 1 + 2 * count or data[0] != 2 * count:
        raise CodecError(f"{len(data) - 1} bytes of registers where {count} were asked for")
    return list(_registers(count).unpack_from(data, 1))


def unpack_read_reply(adu: bytes, unit: int, count: int) -> tuple[int | None, list[int]]:
    """(exception code or None, the ``count`` registers) of a whole reply ADU to Read Holding Registers: the common
    reply checked in one pass, anything else through :func:`unpack_reply`."""
    if (len(adu) == MBAP_SIZE + 2 + 2 * count and adu[7] == READ_HOLDING and adu[8] == 2 * count and adu[6] == unit
            and adu[2] == adu[3] == 0 and (adu[4] << 8 | adu[5]) == len(adu) - 6):
        return None, list(_registers(count).unpack_from(adu, MBAP_SIZE + 2))
    exception, data = unpack_reply(adu, unit, READ_HOLDING)
    if exception is not None:
        return exception, []
    return None, unpack_read_holding(data, count)


_REGISTERS: dict[int, struct.Struct] = {}


def _registers(count: int) -> struct.Struct:
    layout = _REGISTERS.get(count)
    if layout is None:
        layout = _REGISTERS[count] = struct.Struct(f">{count}H")
    return layout


def check_write_multiple(data: bytes, address: int, count: int) -> None:
    """A Write Multiple Registers reply's data repeats the request's address and count."""
    if len(data) != 4 or struct.unpack(">HH", data) != (address, count):
        raise CodecError("the write reply does not repeat the request's address and count")


__all__ = ["READ_HOLDING", "WRITE_MULTIPLE", "MBAP_SIZE", "pack_read_holding", "pack_write_multiple", "adu_size",
           "transaction_of", "unpack_reply", "unpack_read_holding", "unpack_read_reply", "check_write_multiple"]
