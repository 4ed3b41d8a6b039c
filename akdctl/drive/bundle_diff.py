"""Two support bundles compared (``akdctl support diff A B``): identity, firmware, parameters, mapping, faults.

Why a bundle diff refuses two different drives by default: a support engineer compares "before" and "after" of
one drive (what changed since it last worked); two drives' bundles differ in every serial-number-like field and
the report would bury what matters. ``--other-drive`` says the engineer means it (then the comparison is the way
``params diff`` compares two drives). A drive is named by the CANopen identity (vendor, product, serial; 0x1018)
where both bundles hold it, else by the target the bundle was taken from.
"""

from __future__ import annotations

from typing import Any

from akdctl.errors import UsageError


def _configuration_pnu(pnu: Any) -> bool:
    """A PNU the drive lets one write (configuration); read-only ones are measurements or identity."""
    from akdctl.catalog.pnus import pnu_table

    try:
        info = pnu_table().get(int(pnu))
    except (TypeError, ValueError):
        return False
    return info is not None and "w" in info.access and info.pnu not in (1, 3)  # STW1/STW2: the live control word


def _configuration_object(address: Any) -> bool:
    from akdctl.catalog import objects as catalog

    try:
        index_text, _, sub_text = str(address).partition(":")
        entry = catalog.lookup(int(index_text, 16), int(sub_text or "0", 0))
    except ValueError:
        return False
    return entry is not None and "w" in entry.access and entry.index not in (0x6040, 0x607A, 0x60C1)  # set points


def _d(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _l(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


def drive_key(data: dict[str, Any]) -> tuple[str, ...]:
    """What names the drive a bundle came from (see the module's docstring)."""
    co = _d(_d(data.get("identity")).get("canopen"))
    if all(k in co for k in ("vendor_id", "product_code", "serial")):
        return ("canopen", str(co["vendor_id"]), str(co["product_code"]), str(co["serial"]))
    return ("target", str(_d(data.get("target")).get("display")))


def _flat(prefix: str, value: Any, out: dict[str, Any], depth: int = 0) -> None:
    if isinstance(value, dict) and depth < 8:
        for key, sub in value.items():
            _flat(f"{prefix}.{key}" if prefix else str(key), sub, out, depth + 1)
    else:
        out[prefix] = value


def _parameters(data: dict[str, Any], include_live: bool) -> dict[str, Any]:
    params = _d(data.get("parameters"))
    out: dict[str, Any] = {}
    for r in _l(params.get("pnus")):
        r = _d(r)
        if "pnu" in r and "error" not in r and (include_live or _configuration_pnu(r.get("pnu"))):
            out[f"PNU {r['pnu']} {r.get('name') or ''}".strip()] = r.get("values")
    for o in _l(params.get("objects")):
        o = _d(o)
        if "object" in o and "error" not in o and (include_live or _configuration_object(o.get("object"))):
            out[f"{o['object']} {o.get('name') or ''}".strip()] = o.get("value", o.get("hex"))
    return out


def _faults(data: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for source, body in _d(data.get("faults")).items():
        body = _d(body)
        for key in ("active", "faults", "warnings"):
            items = body.get(key)
            if isinstance(items, list):
                out[f"{source} {key}"] = sorted(str(_d(i).get("code") or _d(i).get("number")) for i in items)
    return out


def _firmware(data: dict[str, Any]) -> dict[str, Any]:
    flat: dict[str, Any] = {}
    _flat("", _d(data.get("identity")), flat)
    return {k: v for k, v in flat.items() if any(w in k for w in ("software", "firmware", "revision", "hardware"))}


def _identity(data: dict[str, Any]) -> dict[str, Any]:
    flat: dict[str, Any] = {}
    _flat("", _d(data.get("identity")), flat)
    return {k: v for k, v in flat.items() if k not in _firmware(data)}


def _mapping(data: dict[str, Any]) -> dict[str, Any]:
    flat: dict[str, Any] = {}
    m = _d(data.get("mapping"))
    pd = _d(m.get("profidrive"))
    if pd:
        _flat("profidrive", pd, flat)
    for direction, d in _d(m.get("canopen")).items():
        d = _d(d)
        flat[f"canopen {direction} assigned"] = d.get("assigned")
        for pdo in _l(d.get("pdos")):
            pdo = _d(pdo)
            flat[f"canopen {direction} {pdo.get('name')}"] = [_d(e).get("address") for e in pdo.get("entries") or []
                                                            if isinstance(pdo.get("entries"), list)]
    return flat


SECTIONS = (("identity", _identity), ("firmware", _firmware), ("faults", _faults), ("mapping", _mapping))


def compare(a: dict[str, Any], b: dict[str, Any], *, names: tuple[str, str], other_drive: bool = False,
            include_live: bool = False) -> dict[str, Any]:
    """Every difference, per section, as ``{section: [{key, a, b}]}`` (a key one side lacks shows ``None``).

    Two bundles of different drives are a :class:`UsageError` unless *other_drive*."""
    key_a, key_b = drive_key(a), drive_key(b)
    if key_a != key_b and not other_drive:
        raise UsageError(f"{names[0]} and {names[1]} are bundles of different drives ({' '.join(key_a[1:])} vs "
                         f"{' '.join(key_b[1:])}); add --other-drive to compare them anyway")
    result: dict[str, Any] = {"a": names[0], "b": names[1], "same_drive": key_a == key_b,
                              "created": [a.get("created"), b.get("created")], "sections": {}}
    sections = (*SECTIONS, ("parameters", lambda d: _parameters(d, include_live)))
    total = 0
    for name, pick in sections:
        left, right = pick(a), pick(b)
        rows = [{"key": k, "a": left.get(k), "b": right.get(k)}
                for k in sorted(set(left) | set(right), key=str) if left.get(k) != right.get(k)]
        result["sections"][name] = rows
        total += len(rows)
    result["differences"] = total
    result["equal"] = total == 0
    return result
