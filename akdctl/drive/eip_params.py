"""AKD parameters through the CIP Parameter object (class 0x0F), the way the AKD manual prescribes.

Rules from the manual [M-25], [M-26] (reference/ethernetip.md 1.9), kept in this one place:

* the instance is the parameter number (``catalog/eip_parameters.py``, each row with its source);
  a name not in that table is refused locally rather than guessed;
* attribute 5 is the data type (CIP type code), attribute 6 the length in bytes: both are read
  before every write and the value is packed to exactly that length (a 64-bit parameter also
  accepts a 32-bit write, which is what is sent when the value fits);
* float parameters travel as integers x1000 (1.001 -> 1001);
* a command (HOME.MOVE, AIN.ZERO ...) runs on a 1-byte Set of attribute 1; reading never runs it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from akdctl.catalog import eip_parameters as table
from akdctl.errors import MalformedReply, UsageError
from akdctl.protocol import cip

if TYPE_CHECKING:
    from akdctl.channels.cip import CipAttributes

FLOAT_SCALE = 1000


@dataclass(frozen=True)
class ParameterRef:
    instance: int
    name: str
    kind: str          # int, float, position, velocity, command, or "?" for a bare instance number


def resolve(text: str) -> ParameterRef:
    """A parameter name from the cited table, or a bare instance number (decimal or 0x-hex)."""
    try:
        instance = int(text, 0)
    except ValueError:
        entry = table.by_name(text)
        if entry is None:
            raise UsageError(f"unknown AKD parameter {text!r} for EtherNet/IP: akdctl knows the instance numbers "
                             f"of {', '.join(p.name for p in table.PARAMETERS)} (each from a cited manual page); "
                             "give the instance number from the AKD manual's appendix B instead") from None
        return ParameterRef(entry.instance, entry.name, entry.kind)
    if not 1 <= instance <= 0xFFFF:
        raise UsageError(f"parameter instance {instance} is outside 1..65535")
    entry = table.by_instance(instance)
    return ParameterRef(instance, entry.name if entry else "", entry.kind if entry else "?")


def describe(channel: "CipAttributes", ref: ParameterRef) -> tuple[int, int]:
    """(CIP type code, length in bytes) from attributes 5 and 6."""
    type_raw = channel.get(cip.PARAMETER, ref.instance, 5)
    size_raw = channel.get(cip.PARAMETER, ref.instance, 6)
    if len(type_raw) != 1 or len(size_raw) != 1:
        raise MalformedReply(f"parameter {ref.instance}: attributes 5/6 must be one byte each "
                             f"(got {type_raw.hex()} / {size_raw.hex()})")
    return type_raw[0], size_raw[0]


def _signed(type_code: int) -> bool:
    return type_code in (0xC2, 0xC3, 0xC4, 0xC5)


def read(channel: "CipAttributes", ref: ParameterRef) -> dict[str, Any]:
    type_code, size = describe(channel, ref)
    raw = channel.get(cip.PARAMETER, ref.instance, 1)
    if not raw or len(raw) > 8:
        raise MalformedReply(f"parameter {ref.instance}: value of {len(raw)} bytes")
    number = int.from_bytes(raw, "little", signed=_signed(type_code))
    value: Any = number / FLOAT_SCALE if ref.kind == "float" else number
    ctype = cip.CIP_TYPES.get(type_code)
    return {"instance": ref.instance, "name": ref.name, "kind": ref.kind, "type": ctype.name if ctype else
            f"0x{type_code:02X}", "length": size, "raw": raw.hex(), "value": value}


def encode_parameter(channel: "CipAttributes", ref: ParameterRef, text: str) -> tuple[Any, bytes, int]:
    """(value, bytes, length) for a Parameter-object write: the type and length are read first (attributes 5, 6),
    floats travel x1000; a value that does not fit is refused before anything is written."""
    if ref.kind == "command":
        raise UsageError(f"{ref.name} is a command: run it with 'akdctl eip param run {ref.name}'")
    type_code, size = describe(channel, ref)
    try:
        value = float(text) if ref.kind == "float" else int(text, 0)
    except ValueError:
        raise UsageError(f"bad value {text!r} for parameter {ref.name or ref.instance}: expected "
                         f"{'a number' if ref.kind == 'float' else 'an integer (decimal or 0x-hex)'}") from None
    number = round(value * FLOAT_SCALE) if ref.kind == "float" else int(value)
    signed = _signed(type_code)
    for length in ((size, 4) if size == 8 else (size,)):
        if length not in (1, 2, 4, 8):
            raise MalformedReply(f"parameter {ref.instance}: the drive reports a length of {size} bytes")
        low, high = (-(1 << (8 * length - 1)), (1 << (8 * length - 1)) - 1) if signed else (0, (1 << (8 * length)) - 1)
        if low <= number <= high:
            data = number.to_bytes(length, "little", signed=signed)
            break
    else:
        raise UsageError(f"value {text} does not fit parameter {ref.name or ref.instance} "
                         f"({size} bytes, {'signed' if signed else 'unsigned'})")
    if size == 8 and len(data) == 8 and -(1 << 31) <= number < (1 << 31):
        data = data[:4]      # 64-bit parameters also take a 32-bit value [M-26]
    return value, data, size


def write(channel: Any, ref: ParameterRef, text: str) -> dict[str, Any]:
    value, data, size = encode_parameter(channel, ref, text)
    channel.set(cip.PARAMETER, ref.instance, 1, data)
    return {"instance": ref.instance, "name": ref.name, "written": data.hex(), "value": value, "length": size}


# ---------------------------------------------------------------------------- the operation (plan -> execute)
class AttributeWrite:
    """One Set_Attribute_Single: ``cip set`` (``dtype`` and ``value`` as the user typed them) or ``eip param set``
    (the Parameter object's attribute 1, ``ref`` and the value text, packed by the drive's own type)."""

    __slots__ = ("class_id", "instance", "attribute", "dtype", "value", "data", "ref", "text")

    def __init__(self, class_id: int, instance: int, attribute: int, *, dtype: str = "", value: Any = None,
                 data: bytes = b"", ref: ParameterRef | None = None, text: str = "") -> None:
        self.class_id = class_id
        self.instance = instance
        self.attribute = attribute
        self.dtype = dtype
        self.value = value
        self.data = bytes(data)
        self.ref = ref
        self.text = text


def attribute_request(class_id: int, instance: int, attribute: int, dtype: str, value: Any,
                      data: bytes) -> AttributeWrite:
    return AttributeWrite(class_id, instance, attribute, dtype=dtype, value=value, data=data)


def parameter_request(ref: ParameterRef, text: str) -> AttributeWrite:
    if ref.kind == "command":
        raise UsageError(f"{ref.name} is a command: run it with 'akdctl eip param run {ref.name}'")
    return AttributeWrite(cip.PARAMETER, ref.instance, 1, ref=ref, text=text)


def plan(conn: Any, request: AttributeWrite) -> Any:
    """The write with the gate's verdict (akdctl.drive.gate.classify_cip); a parameter's type and length are
    read first, so its bytes are known (and a value that does not fit refused) before anything is written."""
    from akdctl.drive.gate import classify_cip
    from akdctl.drive.operation import PlannedWrite, WritePlan, read_enabled

    label = f"0x{request.class_id:02X}/{request.instance}/{request.attribute}"
    if request.ref is not None:
        value, data, size = encode_parameter(conn.cip(), request.ref, request.text)
        name = request.ref.name or ""
        address, operation, shown = (f"parameter {name or request.instance} ({label})", "eip param set",
                                     f"{value}" + (" (x1000 on the wire)" if request.ref.kind == "float" else ""))
    else:
        value, data, size, name = request.value, request.data, len(request.data), ""
        address, operation, shown = label, "cip set", f"{request.value} ({request.dtype})"
    writes = [PlannedWrite(address, data, shown, classify_cip(request.class_id, request.instance,
                                                              request.attribute, name))]
    return WritePlan(operation, conn.target.display, writes, enabled=read_enabled(conn, writes),
                     data={"request": request, "bytes": data, "value": value, "length": size})


def plan_command(conn: Any, ref: ParameterRef) -> Any:
    """``eip param run``: a command parameter runs on a 1-byte write of 1 to its attribute 1, planned like any
    write: the gate's verdict by name (HOME.MOVE starts homing: consent), ``--dry-run``, then :func:`execute`."""
    if ref.kind not in ("command", "?"):
        raise UsageError(f"{ref.name} is not a command parameter")
    from akdctl.drive.gate import classify_cip
    from akdctl.drive.operation import PlannedWrite, WritePlan, read_enabled

    conn.cip()  # a target without CIP is refused before anything else
    request = AttributeWrite(cip.PARAMETER, ref.instance, 1, dtype="u8", value=1, data=b"\x01", ref=ref)
    label = f"0x{cip.PARAMETER:02X}/{ref.instance}/1"
    writes = [PlannedWrite(f"parameter {ref.name or ref.instance} ({label})", request.data, "1 (run the command)",
                           classify_cip(cip.PARAMETER, ref.instance, 1, ref.name or ""))]
    return WritePlan("eip param run", conn.target.display, writes, enabled=read_enabled(conn, writes),
                     data={"request": request, "bytes": request.data, "value": 1, "length": 1})


def execute(conn: Any, plan: Any) -> dict[str, Any]:
    """Send the one Set_Attribute_Single of the plan."""
    request: AttributeWrite = plan.data["request"]
    data: bytes = plan.data["bytes"]
    conn.cip().set(request.class_id, request.instance, request.attribute, data)
    return {"class": request.class_id, "instance": request.instance, "attribute": request.attribute,
            "written": data.hex()}


__all__ = ["AttributeWrite", "ParameterRef", "attribute_request", "describe", "encode_parameter", "execute",
           "parameter_request", "plan", "plan_command", "read", "resolve", "write"]
