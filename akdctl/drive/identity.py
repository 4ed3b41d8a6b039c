"""Who is this drive: the one identity reader (PROFIdrive identification PNUs, CANopen identity objects, I&M0).

One batched read for the PNUs (964, 965, 975) and one SDO upload per identity
object (0x1018:1..4, 0x1008, 0x1009, 0x100A), whichever channels the transport
offers; values are typed by the catalogue (:mod:`akdctl.drive.values`).
``info`` and the support bundle show :func:`read_identity` as it is; a parameter
backup stores the flat :func:`backup_identity` of the same reading (and takes
PNU 964 from its own batched read when it has it: :func:`drive_unit`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akdctl.errors import AkdError, CommError, MalformedReply

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel
    from akdctl.channels.base import ParameterChannel
    from akdctl.connection import Connection

#: Identity PNUs: drive unit (964), profile (965), drive object (975).
PNU_DRIVE_UNIT = 964
PNU_PROFILE = 965
PNU_DRIVE_OBJECT = 975

#: CANopen identity objects: key, index, subindex (types from the catalogue).
IDENTITY_OBJECTS: tuple[tuple[str, int, int], ...] = (
    ("vendor_id", 0x1018, 1), ("product_code", 0x1018, 2), ("revision", 0x1018, 3), ("serial", 0x1018, 4),
    ("device_name", 0x1008, 0), ("hardware_version", 0x1009, 0), ("software_version", 0x100A, 0),
    ("model", 0x2033, 0),  # DRV.MODEL: the order code, as PROFINET's I&M0 and CIP's product name give it
)


def drive_unit(values: list[int]) -> dict[str, Any]:
    """PNU 964's elements in words: manufacturer, drive unit type, software version and date."""
    v = list(values) + [0] * (5 - len(values))
    return {"manufacturer": v[0], "drive_unit_type": v[1], "software_version": f"{v[2] // 100}.{v[2] % 100:02d}",
            "firmware_date": f"{v[4] // 100:02d}.{v[4] % 100:02d}.{v[3]}", "raw": list(values)}


def _pnu_identity(channel: "ParameterChannel") -> dict[str, Any]:
    from akdctl.drive.values import pnu_spec, read_pnus

    du, profile, do = read_pnus(channel, [pnu_spec(PNU_DRIVE_UNIT), pnu_spec(PNU_PROFILE), pnu_spec(PNU_DRIVE_OBJECT)])
    out: dict[str, Any] = {}
    out["drive_unit"] = drive_unit(du.values) if du.ok and du.values else {"error": du.error_text}
    if profile.ok and profile.values:
        number, version = (profile.values + [0, 0])[:2]
        out["profile"] = {"number": number, "version": f"{version // 10}.{version % 10}",
                          "name": "PROFIdrive" if number == 3 else f"profile {number}"}
    else:
        out["profile"] = {"error": profile.error_text}
    if do.ok and do.values:
        v = do.values + [0] * (8 - len(do.values))
        out["drive_object"] = {"type_class": v[5], "sub_class": v[6], "do_id": v[7], "raw": do.values}
    else:
        out["drive_object"] = {"error": do.error_text}
    return out


def _object_identity(channel: "ObjectChannel") -> dict[str, Any]:
    """Each identity object, or None where the drive refuses it or answers what its type cannot hold."""
    from akdctl.drive.values import decode, object_type

    out: dict[str, Any] = {}
    for key, index, sub in IDENTITY_OBJECTS:
        try:
            data = channel.upload(index, sub)
        except CommError:
            raise
        except AkdError:
            out[key] = None
            continue
        try:
            out[key] = decode(object_type(index, sub), data)
        except MalformedReply:
            out[key] = None
    return out


def read_identity(conn: "Connection", *, pnus: bool = True, objects: bool = True, im0: bool = True) -> dict[str, Any]:
    """Everything the connection's channels (those asked for) can tell about the drive's identity."""
    result: dict[str, Any] = {}
    if pnus and conn.has_parameters:
        result["profidrive"] = _pnu_identity(conn.parameters())
    if objects and conn.has_objects:
        result["canopen"] = _object_identity(conn.objects())
    if conn.has_cip:
        result["cip_identity"] = conn.cip().identity_json()
    record = conn.read_im0() if im0 else None
    if record is not None:
        result["im0"] = record
    return result


def serial_number(conn: "Connection") -> str | None:
    """The serial number the drive reports, in decimal, from its cheapest source (one request), else None.

    Why: the owner lock keys an axis by its address; two spellings of one drive (a host name and its address,
    issue 23.15) meet only in what the drive says it is. One read: CoE/CANopen 0x1018:4, else PROFINET's I&M0,
    else CIP Identity attribute 6. None where the drive offers none of them (the ASCII and Modbus channels) or
    refuses the read; a link that does not answer raises, as the command's first read would."""
    if conn.has_objects:
        try:
            data = conn.objects().upload(0x1018, 4)
        except CommError:
            raise
        except AkdError:
            return None
        return str(int.from_bytes(data[:4], "little")) if len(data) >= 4 else None
    if conn.has_cip:
        try:
            data = conn.cip().get(0x01, 1, 6)
        except CommError:
            raise
        except AkdError:
            return None
        return str(int.from_bytes(data[:4], "little")) if len(data) >= 4 else None
    record = conn.read_im0()
    serial = record.get("serial_number") if record else None
    return str(serial).strip() or None if serial is not None else None


def backup_identity(identity: dict[str, Any]) -> dict[str, Any]:
    """The flat identity a parameter backup stores (``[identity]``), from a :func:`read_identity` result.

    Keys: manufacturer, drive_unit_type, firmware, firmware_date (PNU 964), and the
    CANopen keys that came back (vendor_id … software_version, hardware_version).
    """
    out: dict[str, Any] = {}
    unit = identity.get("profidrive", {}).get("drive_unit", {})
    if "error" not in unit and unit:
        out.update(backup_drive_unit(unit))
    out.update({k: v for k, v in identity.get("canopen", {}).items() if v is not None})
    return out


def backup_drive_unit(unit: dict[str, Any]) -> dict[str, Any]:
    """:func:`drive_unit` in the backup's words (``firmware`` for the software version)."""
    return {"manufacturer": unit["manufacturer"], "drive_unit_type": unit["drive_unit_type"],
            "firmware": unit["software_version"], "firmware_date": unit["firmware_date"]}


def summary(identity: dict[str, Any]) -> dict[str, Any]:
    """Who the drive is, in words, from whatever :func:`read_identity` got: vendor, model, firmware, hardware,
    serial and profile (keys missing where no channel told).

    Why a summary: ``info`` used to show ``manufacturer 256 (0x100)``; a technician wants "Kollmorgen" and the
    model. Each field takes the most specific source there is: the model is the I&M0 order number on PROFINET
    (``AKD-P00606-NBCC-E000``), the CIP product name on EtherNet/IP, DRV.MODEL (0x2033) over CoE, else the device name (0x1018:2 product code
    'AKD', 0x1008); vendor names come from ``catalog/texts.py`` (CANopen/EtherCAT 0x1018:1, PI 964[0], CIP).
    """
    from akdctl.catalog.texts import CANOPEN_VENDORS, PI_VENDORS

    canopen = identity.get("canopen") or {}
    unit = (identity.get("profidrive") or {}).get("drive_unit") or {}
    profile = (identity.get("profidrive") or {}).get("profile") or {}
    cip = identity.get("cip_identity") or {}
    im0 = identity.get("im0") or {}

    def first(*values: Any) -> Any:
        return next((v for v in values if v not in (None, "", {})), None)

    im0_vendor = int(str(im0["vendor_id"]), 16) if isinstance(im0.get("vendor_id"), str) else None
    out: dict[str, Any] = {
        "vendor": first(CANOPEN_VENDORS.get(canopen.get("vendor_id")),  # type: ignore[arg-type]
                        PI_VENDORS.get(unit.get("manufacturer")),  # type: ignore[arg-type]
                        cip.get("vendor_name") if cip else None,
                        PI_VENDORS.get(im0_vendor) if im0_vendor is not None else None,
                        _vendor_number(canopen.get("vendor_id"), unit.get("manufacturer"), im0_vendor)),
        "model": first(im0.get("order_id"), cip.get("product_name"), canopen.get("model"), canopen.get("device_name"),
                       f"drive unit type {unit['drive_unit_type']}" if "drive_unit_type" in unit else None),
        # One spelling whatever the face (issue 23.8): firmware as MAJOR.MINOR, the serial in decimal; the
        # sections below keep each protocol's own spelling.
        "firmware": first(*(_major_minor(v) for v in (canopen.get("software_version"), im0.get("software_revision"),
                                                       cip.get("revision"), unit.get("software_version")))),
        "hardware": first(canopen.get("hardware_version"), im0.get("hardware_revision")),
        "serial": first(im0.get("serial_number"), _decimal(cip.get("serial")),
                        f"{canopen['serial']}" if canopen.get("serial") is not None else None),
        "profile": first(f"{profile['name']} {profile['version']}" if "name" in profile else None,
                         "CiA 402" if canopen else None, "CIP" if cip else None),
    }
    return {key: value for key, value in out.items() if value is not None}


def _major_minor(text: Any) -> str | None:
    """A firmware version as MAJOR.MINOR: "M_01-20-00-003" (CoE 0x100A), "V1.20.0" (I&M0), "1.020" (CIP
    revision), "1.20" (PNU 964) all give "1.20"; anything else unchanged."""
    import re

    if not isinstance(text, str) or not text:
        return None
    found = re.fullmatch(r"(?:M_)?(\d+)-(\d+)(?:-\d+)*", text) or re.fullmatch(r"V?(\d+)\.(\d+)(?:\.\d+)*", text)
    return f"{int(found[1])}.{int(found[2]):02d}" if found else text


def _decimal(serial: Any) -> str | None:
    """A CIP serial number ("0x99830093") in decimal, as I&M0 and CoE give it."""
    if isinstance(serial, str) and serial.lower().startswith("0x"):
        try:
            return str(int(serial, 16))
        except ValueError:
            return serial
    return None if serial is None else str(serial)


def _vendor_number(*numbers: Any) -> str | None:
    number = next((n for n in numbers if isinstance(n, int)), None)
    return None if number is None else f"vendor {number} (0x{number:X})"


#: Identity values whose words the catalogue knows (catalog/meanings.py), by their place in read_identity's result.
_VALUE_WORDS: dict[str, dict[str, Any]] = {
    "profidrive.drive_unit.manufacturer": {"pnu": 964, "element": 0},
    "profidrive.drive_object.type_class": {"pnu": 975, "element": 5},
    "canopen.vendor_id": {"obj": (0x1018, 1)},
    "canopen.product_code": {"obj": (0x1018, 2)},
}


def value_text(path: str, value: Any) -> str:
    """One identity value as ``info`` and a support bundle's page show it: a number with its hex form and its words
    where the catalogue knows them (``256 (0x100, Kollmorgen)`` for ``profidrive.drive_unit.manufacturer``), anything
    else as its text. ``path`` is the value's place in :func:`read_identity`'s result, dotted."""
    if not isinstance(value, int) or isinstance(value, bool):
        return str(value)
    from akdctl.drive.values import value_words

    where = _VALUE_WORDS.get(path)
    notes = [f"0x{value:X}" if value > 9 else "", (value_words(value, **where) or "") if where else ""]
    shown = ", ".join(n for n in notes if n)
    return f"{value} ({shown})" if shown else str(value)
