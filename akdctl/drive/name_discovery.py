"""Live discovery of the names a connected drive has, cached per firmware version (issue 24, deliver 3).

Why: the shipped catalogue is launch-firmware facts plus the ESI; the drive itself is authoritative for its own
firmware (reference akd-parameter-names.md 5.4). Where the drive can say which names it has, akdctl asks:

* the service channel (akd://): ``DRV.VER`` for the firmware, ``DRV.LIST`` for every keyword (one or more per
  line: the line format is not public [I], so any whitespace separates);
* CoE (sim, ecat*://): the object dictionary by the SDO information service, the firmware from 0x100A; every
  object of 0x2000-0x5FFF whose name is an AKD name (the ESI's own rule, "M" dropped in 0x5xxx) gives that
  name's object, index and type, and overrides the catalogue's address for this drive.

EtherNet/IP and Modbus cannot be asked for names (no name attribute, [I] reference 2.1); PROFINET neither.
The answer is cached as JSON under ``$XDG_CACHE_HOME/akdctl`` by firmware version, so the next run asks nothing.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akdctl.errors import AkdError, UsageError

if TYPE_CHECKING:
    from akdctl.catalog.akd_params import AkdParam
    from akdctl.connection import Connection

_ESI_NAME = re.compile(r"^([A-Z][A-Z0-9_]*(?:\.[A-Z0-9_]+)+)(?:\s+[a-z].*)?$")
_KEYWORD = re.compile(r"^[A-Za-z][A-Za-z0-9]*\.[A-Za-z0-9.]+$")


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "akdctl"


def _cache_file(how: str, firmware: str) -> Path:
    safe = re.sub(r"[^A-Za-z0-9._-]+", "_", firmware)[:80] or "unknown"
    return cache_dir() / f"akd-names-{how}-{safe}.json"


def _firmware(conn: "Connection", how: str) -> str:
    if how == "ascii":
        match = re.search(r"M_[0-9][0-9A-Za-z_-]*", conn.commands().command("DRV.VER"))
        return match.group(0) if match else "unknown"
    try:
        return conn.objects().upload(0x100A, 0).rstrip(b"\x00").decode("latin-1").strip() or "unknown"
    except AkdError:
        return "unknown"


def _ask(conn: "Connection", how: str) -> dict[str, Any]:
    if how == "ascii":
        text = conn.commands().command("DRV.LIST")
        names = sorted({word.upper() for word in text.split() if _KEYWORD.match(word)})
        return {"names": {name: {} for name in names}}
    channel = conn.objects()
    found: dict[str, dict[str, Any]] = {}
    for index in channel.object_list():
        if not 0x2000 <= index <= 0x5FFF:
            continue
        description = channel.object_description(index)
        match = _ESI_NAME.match(description.name.strip())
        if match is None or description.object_code != 7:
            continue
        name = match.group(1)
        if 0x5000 <= index <= 0x5FFF and name.endswith("M"):
            name = name[:-1]
        from akdctl.protocol import datatypes

        try:
            ctype = datatypes.type_for_code(description.data_type)
        except datatypes.DataTypeError:
            continue
        found.setdefault(name, {"coe": [index, 0], "type": ctype})
    return {"names": found}


def discover(conn: "Connection", how: str, *, refresh: bool = False) -> dict[str, Any]:
    """{"firmware": ..., "route": ..., "cached": bool, "names": {NAME: {"coe": [index, sub], "type": ...}}}."""
    if how not in ("ascii", "coe"):
        raise UsageError(f"the drive cannot be asked for its names over this transport ({how}); use akd://HOST "
                         "(DRV.LIST) or a CoE target (SDO information)")
    firmware = _firmware(conn, how)
    path = _cache_file(how, firmware)
    if not refresh and firmware != "unknown":
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            if isinstance(data, dict) and isinstance(data.get("names"), dict):
                return {**data, "cached": True}
        except (OSError, ValueError):
            pass
    data = {"firmware": firmware, "route": how, **_ask(conn, how)}
    if firmware != "unknown":
        try:
            from akdctl.io.atomic import write_atomic

            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, json.dumps(data, indent=1, sort_keys=True))
        except OSError:
            pass   # a cache that cannot be written costs a second question next time, nothing else
    return {**data, "cached": False}


def live_row(row: "AkdParam | None", name: str, found: dict[str, Any]) -> "AkdParam | None":
    """The catalogue row as this drive has it: the drive's CoE address overrides the shipped one; a name the
    catalogue lacks becomes a 'raw' row (values as the drive gives them, scale and class unknown [I])."""
    from akdctl.catalog.akd_params import AkdParam

    info = found.get(name)
    if info is None:
        return row
    coe = tuple(info["coe"]) if info.get("coe") else None
    if row is not None:
        if coe is None or row.coe == coe:
            return row
        return row.replace(coe=coe, coe_type=info.get("type") or row.coe_type,
                           marks=tuple((k, v) for k, v in row.marks if k != "coe") + (("coe", "live"),))
    return AkdParam(name, re.sub(r"\d+", "", name.split(".")[0]), "RW", "raw", "", "", "", "", coe,  # type: ignore[arg-type]
                    info.get("type", ""), "1" if coe else "", None, None, (("coe", "live"), ("scale", "I")),
                    "live", "reported by the drive; not in the shipped catalogue")
