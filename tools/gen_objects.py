#!/usr/bin/env python3
"""Generate akdctl/catalog/data/objects.tsv from the AKD EtherCAT ESI (AKD.xml).

Usage: python3 tools/gen_objects.py PATH/TO/AKD_EtherCAT_Device_Description.xml [-o OUT.tsv]

Why a generator: the ESI is Kollmorgen's file and is not committed; what we keep is a
small table of facts (index, sub-index, type, size, access, PDO direction, default) in
our own columns, regenerated whenever a newer ESI appears. The newest <Device>
revision in the file wins, because it is a superset of the older ones.

Rows are one per sub-entry: records/arrays are expanded, sub 0 ("highest sub-index")
included. Defaults are decoded from the ESI's little-endian DefaultData hex. The
`param` column holds the AKD ASCII parameter name when the ESI names one
(upper case, e.g. DRV.FAULT1), or, for CiA 402 profile objects, a lower-case short
name derived from the object name (e.g. controlword) so the CLI can address objects
by name.
"""
from __future__ import annotations

import argparse
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

COLUMNS = ("index", "subindex", "name", "type", "bits", "access", "pdo", "default", "param", "object")

SIGNED = {"SINT", "INT", "INT24", "DINT", "LINT"}
UNSIGNED = {"BOOL", "BYTE", "USINT", "UINT", "UINT24", "UDINT", "ULINT"}

# AKD parameter names that the EtherCAT manual (section 5.7, "Supported cyclical setpoint
# values") gives for CiA 402 objects; they take precedence over the derived short names.
MANUAL_PARAMS: dict[tuple[int, int], str] = {
    (0x6081, 0): "MT.V",
    (0x6083, 0): "MT.ACC",
    (0x6084, 0): "MT.DEC",
}

# Objects that the AKD implements but this ESI leaves out of its dictionary:
# 0x0002 is the 8-bit dummy object for padding RxPDOs (EtherCAT manual 5.6; present in
# the ESI only as a commented-out block).
SUPPLEMENT = [
    {"index": 0x0002, "subindex": 0, "name": "Dummy (SINT)", "type": "SINT", "bits": 8,
     "access": "wo", "pdo": "R", "default": "", "param": "", "object": "Dummy (SINT)"},
]

_PARAM_RE = re.compile(r"^([A-Z][A-Z0-9_]*(?:\.[A-Z0-9_]+)+)(?:\s+[a-z].*)?$")


def _int(text: str) -> int:
    text = text.strip()
    if text.startswith("#x"):
        return int(text[2:], 16)
    return int(text, 0)


def _decode_default(hexdata: str | None, type_name: str, bits: int) -> str:
    """Turn ESI DefaultData (little-endian hex bytes) into a number literal, or ''."""
    if not hexdata or type_name.startswith("STRING"):
        return ""
    try:
        raw = bytes.fromhex(hexdata.strip())
    except ValueError:
        return ""
    if not raw:
        return ""
    signed = type_name in SIGNED
    value = int.from_bytes(raw, "little", signed=signed)
    if not signed and bits >= 16:
        return f"0x{value:0{max(1, (bits + 3) // 4)}X}"
    return str(value)


def akd_param(name: str, index: int) -> str:
    """AKD ASCII parameter named by an ESI object/sub-item name, or ''.

    Objects 0x5000-0x5FFF carry the parameter name with an 'M' appended (e.g.
    'DRV.IPEAKM' is DRV.IPEAK); that suffix is removed.
    """
    m = _PARAM_RE.match(name.strip())
    if not m:
        return ""
    param = m.group(1)
    if 0x5000 <= index <= 0x5FFF and param.endswith("M"):
        param = param[:-1]
    return param


def short_alias(name: str) -> str:
    """Lower-case identifier from a CiA 402 object name ('Modes of operation' -> modes_of_operation)."""
    alias = re.sub(r"[^0-9a-z]+", "_", name.lower()).strip("_")
    return alias


def _flags(elem: ET.Element | None) -> tuple[str, str]:
    if elem is None:
        return "", ""
    access = (elem.findtext("Flags/Access") or "").strip()
    pdo = (elem.findtext("Flags/PdoMapping") or "").strip().upper()
    return access, pdo


def _info_defaults(obj: ET.Element) -> tuple[dict[str, str | None], list[str | None]]:
    """Per-sub-item defaults of an object: by name, and in document order."""
    by_name: dict[str, str | None] = {}
    ordered: list[str | None] = []
    for sub in obj.findall("Info/SubItem"):
        data = sub.findtext("Info/DefaultData")
        by_name[(sub.findtext("Name") or "").strip()] = data
        ordered.append(data)
    return by_name, ordered


def _info_names(obj: ET.Element) -> list[str]:
    return [(s.findtext("Name") or "").strip() for s in obj.findall("Info/SubItem")]


def pdo_entry_names(device: ET.Element) -> dict[tuple[int, int], str]:
    """Names that the ESI's PDO descriptions give to mapped entries (e.g. 3470:04 'AIN.VALUE')."""
    names: dict[tuple[int, int], str] = {}
    for pdo in device.findall("RxPdo") + device.findall("TxPdo"):
        for entry in pdo.findall("Entry"):
            idx = _int(entry.findtext("Index") or "0")
            if idx == 0:
                continue
            sub = _int(entry.findtext("SubIndex") or "0")
            names[(idx, sub)] = (entry.findtext("Name") or "").strip()
    return names


def expand_object(obj: ET.Element, types: dict[str, ET.Element]) -> list[dict]:
    """One row per sub-entry of an ESI <Object>."""
    index = _int(obj.findtext("Index") or "")
    obj_name = (obj.findtext("Name") or "").strip()
    type_name = (obj.findtext("Type") or "").strip()
    bits = int(obj.findtext("BitSize") or "0")
    obj_access, obj_pdo = _flags(obj)
    dtype = types.get(type_name)
    subitems = dtype.findall("SubItem") if dtype is not None else []
    rows: list[dict] = []
    if not subitems:
        rows.append({
            "index": index, "subindex": 0, "name": obj_name, "type": type_name, "bits": bits,
            "access": obj_access, "pdo": obj_pdo,
            "default": _decode_default(obj.findtext("Info/DefaultData"), type_name, bits),
            "object": obj_name,
        })
        return rows
    defaults_by_name, defaults_ordered = _info_defaults(obj)
    info_names = _info_names(obj)
    position = 0
    for sub in subitems:
        sub_type = (sub.findtext("Type") or "").strip()
        sub_bits = int(sub.findtext("BitSize") or "0")
        sub_name = (sub.findtext("Name") or "").strip()
        access, pdo = _flags(sub)
        access = access or obj_access
        inner = types.get(sub_type)
        if sub.find("SubIdx") is None and inner is not None and inner.find("ArrayInfo") is not None:
            # An array element block (e.g. 0x1C00 "Elements"): expand LBound..LBound+n-1.
            base = (inner.findtext("BaseType") or "").strip()
            lbound = int(inner.findtext("ArrayInfo/LBound") or "1")
            count = int(inner.findtext("ArrayInfo/Elements") or "0")
            elem_bits = sub_bits // count if count else 0
            for k in range(count):
                name = info_names[position] if position < len(info_names) else f"{sub_name} {k + lbound}"
                data = defaults_ordered[position] if position < len(defaults_ordered) else None
                position += 1
                rows.append({
                    "index": index, "subindex": lbound + k, "name": name, "type": base,
                    "bits": elem_bits, "access": access, "pdo": pdo,
                    "default": _decode_default(data, base, elem_bits), "object": obj_name,
                })
            continue
        subidx = int(sub.findtext("SubIdx") or "0")
        if sub_name in defaults_by_name:
            data = defaults_by_name[sub_name]
        else:
            data = defaults_ordered[position] if position < len(defaults_ordered) else None
        position += 1
        rows.append({
            "index": index, "subindex": subidx, "name": sub_name, "type": sub_type, "bits": sub_bits,
            "access": access, "pdo": pdo, "default": _decode_default(data, sub_type, sub_bits),
            "object": obj_name,
        })
    return rows


def assign_params(rows: list[dict], pdo_names: dict[tuple[int, int], str]) -> None:
    """Fill the `param` column (see module docstring)."""
    for row in rows:
        key = (row["index"], row["subindex"])
        index = row["index"]
        is_record = row["name"] != row["object"] or row["subindex"] != 0
        param = MANUAL_PARAMS.get(key, "")
        if not param and key in pdo_names:
            param = akd_param(pdo_names[key], index)
        if not param:
            param = akd_param(row["name"], index)
        if not param and 0x6000 <= index <= 0x67FF:
            if not is_record:
                param = short_alias(row["object"])
            elif row["subindex"] != 0:
                param = f"{short_alias(row['object'])}.{short_alias(row['name'])}"
        row["param"] = param


def newest_device(root: ET.Element) -> ET.Element:
    devices = root.findall("./Descriptions/Devices/Device")
    if not devices:
        raise SystemExit("no <Device> in the ESI")
    return max(devices, key=lambda d: _int(d.find("Type").get("RevisionNo", "0")))


def generate(xml_path: Path) -> tuple[str, list[dict]]:
    root = ET.parse(xml_path).getroot()
    device = newest_device(root)
    revision = device.find("Type").get("RevisionNo", "")
    types = {(t.findtext("Name") or "").strip(): t for t in device.findall("./Profile/Dictionary/DataTypes/DataType")}
    rows: list[dict] = []
    for obj in device.findall("./Profile/Dictionary/Objects/Object"):
        rows.extend(expand_object(obj, types))
    assign_params(rows, pdo_entry_names(device))
    present = {(r["index"], r["subindex"]) for r in rows}
    rows.extend(dict(s) for s in SUPPLEMENT if (s["index"], s["subindex"]) not in present)
    rows.sort(key=lambda r: (r["index"], r["subindex"]))
    fill_identity(device, rows)
    fill_fixed_pdos(device, rows)
    return revision, rows


def fill_identity(device: ET.Element, rows: list[dict]) -> None:
    """0x1018:02/03 from the device's <Type ProductCode RevisionNo>.

    The dictionary lists the product code default as 0 and omits the revision; the
    device description itself states both, and a drive reports them there.
    """
    type_elem = device.find("Type")
    facts = {2: type_elem.get("ProductCode"), 3: type_elem.get("RevisionNo")}
    for row in rows:
        if row["index"] == 0x1018 and facts.get(row["subindex"]):
            value = _int(facts[row["subindex"]])
            if not row["default"] or int(row["default"], 0) == 0:
                row["default"] = f"0x{value:08X}"


def fill_fixed_pdos(device: ET.Element, rows: list[dict]) -> None:
    """Mapping entries of the fixed PDOs as their defaults.

    The ESI dictionary gives real defaults only for 0x1701/0x1702 and zeros for the
    other fixed PDOs; its <RxPdo>/<TxPdo> descriptions (identical to a real drive's SII)
    list the entries, and the drive reports them when 0x17xx/0x1Bxx sub n is read.
    Where the dictionary has a non-zero default that disagrees, we say so and keep the
    PDO description.
    """
    table = {(r["index"], r["subindex"]): r for r in rows}
    for pdo in device.findall("RxPdo") + device.findall("TxPdo"):
        idx = _int(pdo.findtext("Index") or "0")
        if pdo.get("Fixed") != "1":
            continue
        entries = pdo.findall("Entry")
        sub0 = table.get((idx, 0))
        if sub0 is not None and sub0["default"] and int(sub0["default"], 0) != len(entries):
            print(f"warning: 0x{idx:04X}:0 default {sub0['default']} but {len(entries)} PDO entries", file=sys.stderr)
        for n, entry in enumerate(entries, start=1):
            value = (_int(entry.findtext("Index") or "0") << 16) | (_int(entry.findtext("SubIndex") or "0") << 8) \
                | int(entry.findtext("BitLen") or "0")
            row = table.get((idx, n))
            if row is None:
                print(f"warning: 0x{idx:04X}:{n} missing from the dictionary", file=sys.stderr)
                continue
            old = int(row["default"], 0) if row["default"] else 0
            if old not in (0, value):
                print(f"warning: 0x{idx:04X}:{n} dictionary default 0x{old:08X} != PDO entry 0x{value:08X}",
                      file=sys.stderr)
            row["default"] = f"0x{value:08X}"


def write_tsv(revision: str, rows: list[dict], out: Path) -> None:
    lines = [
        "# AKD CoE object dictionary, one row per sub-entry.",
        f"# Generated by tools/gen_objects.py from the AKD EtherCAT ESI (AKD.xml), device revision 0x{_int(revision):08X}.",
        "# default: ESI default value as a number literal (empty when the ESI gives none);"
        " param: AKD parameter (upper case) or CiA 402 short name (lower case).",
        "\t".join(COLUMNS),
    ]
    for r in rows:
        lines.append("\t".join([
            f"0x{r['index']:04X}", str(r["subindex"]), r["name"], r["type"], str(r["bits"]),
            r["access"], r["pdo"], r["default"], r["param"], r["object"],
        ]))
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("esi", type=Path, help="AKD ESI XML file")
    parser.add_argument("-o", "--output", type=Path,
                        default=Path(__file__).resolve().parent.parent / "akdctl" / "catalog" / "data" / "objects.tsv")
    args = parser.parse_args(argv)
    revision, rows = generate(args.esi)
    write_tsv(revision, rows, args.output)
    print(f"{len(rows)} rows, device revision 0x{_int(revision):08X}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
