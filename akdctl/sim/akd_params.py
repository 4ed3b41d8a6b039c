"""The simulated AKD's parameters by name: one store behind the ASCII, Modbus and EtherNet/IP faces and CoE.

Why here: "a write by name on one transport shows on all the others" only holds if every face reads and
writes the same place. A name with a CoE object in the catalogue lives in that object of the one
:class:`~akdctl.sim.model.DriveModel` (so ``sdo read``/``sdo write`` see it, and live quantities computed by the
model's components, such as VL.FB or the status, come from there); a name without one lives in the model's
stored values under a private key (``0x10000 | n``, or ``0x20000 |`` a hash of the name), as its text. Values cross
this module in the drive's own form: numbers (floats for float parameters), text for strings.

A name with a PNU (DRV.OPMODE 930, HOME.MODE 1001) is written to the PNU and to its CoE object, and read from the
CoE object. The motion component binds both objects (35B4h, 50CBh) to what the PNU holds, so every address shows one
value: a write by name, by PNU number (``pnu set 1001=...``) or by SDO shows on all the others.

The simulator's own simplifications [I]: a ``var``-scaled CoE object (CiA 402 velocities/positions) is taken 1:1;
an [I] float scale is applied as the catalogue states it; ranges are the catalogue's published ones.
"""

from __future__ import annotations

import zlib
from typing import Any

from akdctl.catalog.akd_params import AkdParam
from akdctl.profiles.akd_values import ValueFormError, format_value, from_fixed, parse_text, to_fixed
from akdctl.sim.errors import PnuAccessError, SdoAccessError


class ParamError(Exception):
    """A request the drive refuses; the text is the reply after ``Error: `` [I wording]."""


def _coe_entry(model: Any, row: AkdParam) -> Any:
    if row.coe is None:
        return None
    import akdctl.catalog.objects as objects   # lazy; this form skips importlib's per-call fromlist step

    return objects.lookup(*row.coe)


def _key(row: AkdParam) -> tuple[int, int]:
    if row.n:
        return (0x10000 | row.n, 0)
    return (0x20000 | (zlib.crc32(row.name.encode()) & 0xFFFF), 0)


def _factor(row: AkdParam) -> int:
    return row.factor or 1


def read(model: Any, row: AkdParam) -> Any:
    """The value of ``row`` now (number or text); ParamError when it cannot be read.

    A name is read from its CoE object where it has one, else from its PNU, else from the name store."""
    if not row.readable:
        raise ParamError(f"{row.name} is a command")
    entry = _coe_entry(model, row)   # once: the face's every read passes here
    if row.pnu is not None and entry is None:
        try:
            info = model.pnu_info(row.pnu)
            _, values = model.pnu_read_raw(row.pnu, 0, 1)
        except PnuAccessError as exc:
            raise ParamError(f"{row.name} cannot be read (PNU error 0x{exc.error:02X})") from None
        value = values[0]
        if info.signed and value >= 1 << (info.bits - 1):
            value -= 1 << info.bits
        return value
    if entry is not None:
        import akdctl.protocol.datatypes as datatypes

        try:
            data = model.object_read(*row.coe)  # type: ignore[misc]
        except SdoAccessError as exc:
            raise ParamError(f"{row.name} cannot be read (0x{exc.code:08X})") from None
        ctype = row.coe_type or entry.short_type
        if ctype == "vs" or row.kind == "string":
            return data.rstrip(b"\x00").decode("latin-1")
        size = datatypes.get_type(ctype).size or len(data)
        raw = datatypes.unpack(ctype, data[:size].ljust(size, b"\x00"))
        return from_fixed(int(raw), row.kind, _factor(row))  # type: ignore[call-overload]
    stored = model.object_values.get(_key(row))
    text = stored.decode("latin-1") if stored is not None else (row.default or ("" if row.kind == "string" else "0"))
    try:
        return parse_text(row.kind if row.kind in ("int", "float", "string") else "int", text)
    except ValueFormError:
        return text


def write(model: Any, row: AkdParam, value: Any) -> None:
    """Store ``value`` (already a number/text of the row's kind); ParamError when the drive refuses it."""
    if not row.writable:
        raise ParamError(f"{row.name} is read-only")
    if isinstance(value, (int, float)) and not isinstance(value, bool) and row.mark("range") != "I":
        for bound, ok in ((row.minimum, lambda b: value >= b), (row.maximum, lambda b: value <= b)):
            if bound and not ok(float(bound)):
                raise ParamError(f"{value} is out of range for {row.name}")
    if row.pnu is not None:   # the PNU is the name's home; its CoE object follows (module docstring)
        try:
            info = model.pnu_info(row.pnu)
            model.pnu_write_raw(row.pnu, 0, info.wire_format, [int(value) & ((1 << info.bits) - 1)])
        except (PnuAccessError, TypeError, ValueError):
            raise ParamError(f"{value} is refused by {row.name}") from None
    entry = _coe_entry(model, row)
    if entry is not None:
        from akdctl.protocol import datatypes

        ctype = row.coe_type or entry.short_type
        try:
            if ctype == "vs" or row.kind == "string":
                data = str(value).encode("latin-1", errors="replace")[:entry.nbytes].ljust(entry.nbytes, b"\x00")
            else:
                data = datatypes.pack(ctype, to_fixed(value, _factor(row)))
        except (datatypes.DataTypeError, ValueFormError) as exc:
            raise ParamError(f"{value} does not fit {row.name} ({exc})") from None
        try:
            model.object_write(row.coe[0], row.coe[1], data)  # type: ignore[index]
        except SdoAccessError as exc:
            raise ParamError(f"{row.name} refused the value (0x{exc.code:08X})") from None
        return
    model.set_stored_object(*_key(row), format_value(row.kind, value).encode("latin-1", errors="replace"))


def wire(model: Any, row: AkdParam, factor: int = 1000) -> int:
    """The value as a fieldbus integer (EtherNet/IP, Modbus: floats x1000)."""
    value = read(model, row)
    if isinstance(value, str):
        raise ParamError(f"{row.name} is text")
    return to_fixed(value, factor if row.kind == "float" else 1)


def write_wire(model: Any, row: AkdParam, number: int, factor: int = 1000) -> None:
    write(model, row, from_fixed(number, row.kind, factor if row.kind == "float" else 1))


def by_number(n: int) -> AkdParam | None:
    """The catalogue row of parameter number ``n`` (EIP instance, Modbus register 2(n-1))."""
    from akdctl.catalog.akd_params import all_params

    for row in all_params():
        if row.n == n:
            return row
    return None
