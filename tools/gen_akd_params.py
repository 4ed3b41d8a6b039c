#!/usr/bin/env python3
"""Generate ``akdctl/catalog/data/akd_params.tsv``: the AKD parameter catalogue by name.

Why generated: the ESI carries 458 dotted AKD names with their CoE index, type and access, and a hand-copied table
of them would drift from it; the facts the ESI lacks (class, kind, unit, range, default, sign, scale, ``n``, PNU)
are kept by hand in ``tools/akd_param_facts.py``, one fact per source. This script merges the two:

* every AKD name of the ESI's manufacturer range 0x2000-0x5FFF, object or sub-entry level (0x5xxx "M" names
  lose their M; 64-bit parameters split into "low/high" halves are left out: no single address);
* the ESI's known duplicates are resolved as reference/akd-parameter-names.md 1.3 says (VL.KVFF at 0x354B,
  VL.ERR at 0x3407:1, DRV.DISTO at 0x3445 -- 0x36DC is CS.TMAX in the 2009 guide);
* ``n`` of a 0x5000-block name is ``index - 0x5000 + 1`` (the data verified for a dozen points, the rule [I]);
* the fact table adds names the ESI lacks (CiA 402 aliases, commands) and overrides what it knows better.

Input: the shipped object table ``akdctl/catalog/data/objects.tsv`` (generated from the ESI's newest device revision
by ``tools/gen_objects.py``, its ``param`` column the AKD name), so both tables name the same objects.
Run: ``python tools/gen_akd_params.py``; ``--check`` exits 1 when the shipped file differs from what it would write.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

from akd_param_facts import FACTS

OUT = ROOT / "akdctl" / "catalog" / "data" / "akd_params.tsv"
OBJECTS = ROOT / "akdctl" / "catalog" / "data" / "objects.tsv"
COLUMNS = ("name", "family", "access", "kind", "unit", "min", "max", "default", "coe", "coe_type", "scale", "n",
           "pnu", "marks", "source", "note")
_SHORT = {"SINT": "i8", "INT": "i16", "DINT": "i32", "USINT": "u8", "UINT": "u16", "UDINT": "u32", "BOOL": "u8"}
_NAME = re.compile(r"^[A-Z][A-Z0-9]*\.[A-Z0-9.]+$")

#: ESI duplicates: the address that stays (reference akd-parameter-names.md 1.3).
_PREFERRED = {"VL.KVFF": "0x354B:0", "VL.ERR": "0x3407:1", "DRV.DISTO": "0x3445:0"}


def short_type(esi: str) -> str:
    if esi.startswith("STRING"):
        return "vs"
    return _SHORT.get(esi, "")


def esi_rows(path: Path = OBJECTS) -> dict[str, dict[str, str]]:
    """The AKD names of the shipped object table (``akdctl/catalog/data/objects.tsv``, generated from the ESI's
    newest device revision by tools/gen_objects.py, whose ``param`` column names them), in the manufacturer range."""
    rows: dict[str, dict[str, str]] = {}
    header: list[str] = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line or line.startswith("#"):
            continue
        cells = line.split("\t")
        if not header:
            header = cells
            continue
        cell = dict(zip(header, cells))
        index, sub = int(cell["index"], 16), int(cell["subindex"])
        name = cell.get("param", "")
        if not 0x2000 <= index <= 0x5FFF or not _NAME.match(name):
            continue
        if cell["name"].endswith((" low", " high")):
            continue   # one half of a 64-bit parameter (no single address)
        address = f"0x{index:04X}:{sub}"
        if name in rows and _PREFERRED.get(name) != address:
            continue
        row = {"name": name, "coe": address, "coe_type": short_type(cell["type"]), "access": cell["access"],
               "source": "ESI", "marks": "coe=V", "n": "", "note": ""}
        if 0x5000 <= index <= 0x5FFF:
            row["n"] = str(index - 0x5000 + 1)
            row["marks"] += " n=I"
        rows[name] = row
    return rows


def family(name: str) -> str:
    return re.sub(r"\d+", "", name.split(".", 1)[0])


def merge(rows: dict[str, dict[str, str]]) -> list[dict[str, str]]:
    out: dict[str, dict[str, str]] = {}
    for name, row in rows.items():
        # The ESI's write-only objects are all commands (DRV.NVSAVE, HOME.SET, DRV.STOP, MT.SET, MT.LOAD, WS.ARM,
        # COGCOMP.TEACH, PLS.RESET: reference akd-parameter-names.md 1.1).
        access = {"rw": "RW", "ro": "RO", "wo": "CMD"}[row["access"]]
        kind = "command" if access == "CMD" else "string" if row["coe_type"] == "vs" else "raw"
        out[name] = {**dict.fromkeys(COLUMNS, ""), **row, "access": access, "kind": kind,
                     "scale": "1" if kind == "raw" else ""}
        if kind == "raw":
            out[name]["marks"] += " scale=I"
    for fact in FACTS:
        (name, access, kind, unit, lo, hi, default, coe, coe_type, scale, n, pnu, source, marks, note) = fact
        row = out.setdefault(name, dict.fromkeys(COLUMNS, ""))
        esi = rows.get(name)
        if coe == "-":
            coe = ""
        elif not coe:
            coe = esi["coe"] if esi else ""
        if esi and coe and coe != esi["coe"] and "coe=" not in marks:
            marks += " coe=V"
        ctype = coe_type or (esi["coe_type"] if esi and esi["coe"] == coe else "") or ("u32" if coe else "")
        if kind == "command" and not coe:
            scale = ""
        if kind in ("text", "string", "command"):
            scale = "" if kind != "string" else scale
        elif coe and not scale:
            scale = "1000" if kind == "float" else "1"
            marks += " scale=I"
        if esi and esi.get("n") and not n:
            n = esi["n"]
            if "n=" not in marks:
                marks += " n=I"
        row.update(name=name, access=access, kind=kind, unit=unit, min=lo, max=hi, default=default, coe=coe,
                   coe_type=ctype if coe else "", scale=scale if coe else "", n=n, pnu=pnu, marks=marks.strip(),
                   source=source, note=note)
    for row in out.values():
        row["family"] = family(row["name"])
        row["marks"] = " ".join(sorted(set(row["marks"].split())))
    return [out[name] for name in sorted(out)]


def render(rows: list[dict[str, str]]) -> str:
    head = [
        "# AKD parameters by name. Generated by tools/gen_akd_params.py from the AKD ESI (AKD.xml v2.50, the",
        "# reference TSV of its objects) and the hand-kept facts of tools/akd_param_facts.py; do not edit.",
        "# access NV/RW/RO/WO/CMD; kind int/float/string/text/command/raw (raw: the ESI gives no kind or scale);",
        "# coe INDEX:SUB, scale the CoE float factor (1000 = wire 1000 is 1.000; var = depends on UNIT.*/FBUS.PARAM05);",
        "# n the parameter number (EIP Parameter instance n, Modbus register 2(n-1)); marks: V read in a source, I inferred.",
        "\t".join(COLUMNS),
    ]
    body = ["\t".join(row[c] for c in COLUMNS) for row in rows]
    return "\n".join(head + body) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=Path, default=OBJECTS, help="the object table generated from the ESI")
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args()
    text = render(merge(esi_rows(args.objects)))
    if args.check:
        return 0 if OUT.read_text(encoding="utf-8") == text else 1
    OUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}: {text.count(chr(10)) - 6} names")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
