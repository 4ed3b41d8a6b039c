"""Who is this drive: PROFIdrive identification PNUs and/or the CANopen identity objects.

One batched read for the PNUs (964, 965, 975) and a handful of SDO uploads for
0x1018/0x1008/0x1009/0x100A, whichever channels the transport offers.
"""

from __future__ import annotations

from typing import Any

from akdctl.errors import AkdError


def _pnu_identity(channel: Any) -> dict[str, Any]:
    from akdctl.drive.params import parse_pnu_spec, read_pnus

    readings = read_pnus(channel, [parse_pnu_spec(t) for t in ("964", "965", "975")])
    out: dict[str, Any] = {}
    du, profile, do = readings
    if du.ok and du.values:
        v = du.values + [0] * (5 - len(du.values))
        out["drive_unit"] = {
            "manufacturer": v[0], "drive_unit_type": v[1], "software_version": f"{v[2] // 100}.{v[2] % 100:02d}",
            "firmware_date": f"{v[4] // 100:02d}.{v[4] % 100:02d}.{v[3]}", "raw": du.values,
        }
    else:
        out["drive_unit"] = {"error": du.error_text}
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


def _object_identity(channel: Any) -> dict[str, Any]:
    from akdctl.protocol.datatypes import unpack

    out: dict[str, Any] = {}
    for key, index, sub, dtype in (
        ("vendor_id", 0x1018, 1, "u32"), ("product_code", 0x1018, 2, "u32"), ("revision", 0x1018, 3, "u32"),
        ("serial", 0x1018, 4, "u32"), ("device_name", 0x1008, 0, "vs"), ("hardware_version", 0x1009, 0, "vs"),
        ("software_version", 0x100A, 0, "vs"),
    ):
        try:
            out[key] = unpack(dtype, channel.upload(index, sub))
        except AkdError as exc:
            if exc.exit_code == 3:
                raise
            out[key] = None
    return out


def read_identity(transport: Any) -> dict[str, Any]:
    """Everything the transport's channels can tell about the drive's identity."""
    result: dict[str, Any] = {}
    if transport.parameters is not None:
        result["profidrive"] = _pnu_identity(transport.parameters)
    if transport.objects is not None:
        result["canopen"] = _object_identity(transport.objects)
    read_cip = getattr(transport, "read_cip_identity", None)
    if read_cip is not None:
        result["cip_identity"] = read_cip()
    read_im0 = getattr(transport, "read_im0", None)
    if read_im0 is not None:
        result["im0"] = read_im0()
    return result
