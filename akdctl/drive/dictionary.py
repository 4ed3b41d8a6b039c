"""The object dictionary as the drive reports it (SDO information service, CoE service 8), or as our catalogue has it.

Why both in one shape: ``sdo list`` (like IgH's ``ethercat sdos``) asks the drive which objects it has — the
truth for this firmware — while ``sdo list --catalogue`` shows what akdctl knows (the AKD ESI). Comparing the two
answers "does this drive have 0x2012?" and "why does akdctl not know 0x5FFF?". One request per object
description and one per entry, as IgH does; a subindex the drive does not describe (a gap) is skipped.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from akdctl.errors import CommError, SdoAborted

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel

OBJECT_CODES = {7: "VAR", 8: "ARRAY", 9: "RECORD"}


@dataclass
class EntryRow:
    subindex: int
    name: str
    type: str
    bits: int
    access: str  # "rw", "r-", "-w" (or per state "P:rw S:r- O:r-" when the states differ)
    pdo: str  # "R" RxPDO-mappable, "T" TxPDO-mappable, "RT" both, "" neither

    def to_json(self) -> dict[str, Any]:
        return {"subindex": self.subindex, "name": self.name, "type": self.type, "bits": self.bits,
                "access": self.access, "pdo": self.pdo}


@dataclass
class ObjectRow:
    index: int
    name: str
    object_code: str
    max_subindex: int
    entries: list[EntryRow] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {"index": self.index, "index_hex": f"0x{self.index:04X}", "name": self.name,
                "object_code": self.object_code, "max_subindex": self.max_subindex,
                "entries": [e.to_json() for e in self.entries]}


def _type_name(code: int) -> str:
    from akdctl.protocol.datatypes import DataTypeError, type_for_code

    try:
        return type_for_code(code)
    except DataTypeError:
        return f"0x{code:04X}"


def access_text(bits: int) -> str:
    """ETG.1000.6 entry access bits (read 0-2, write 3-5 in PREOP/SAFEOP/OP) in words."""
    states = [("r" if bits >> n & 1 else "-") + ("w" if bits >> (n + 3) & 1 else "-") for n in range(3)]
    if len(set(states)) == 1:
        return states[0]
    return " ".join(f"{s}:{a}" for s, a in zip("PSO", states))


def _pdo_text(bits: int) -> str:
    return ("R" if bits & 0x40 else "") + ("T" if bits & 0x80 else "")


def read_dictionary(channel: "ObjectChannel", *, entries: bool = True, wanted: Callable[[int], bool] | None = None) -> list[ObjectRow]:
    """The drive's own list (service 8): every object's description and, with ``entries``, each entry's."""
    rows = []
    for index in channel.object_list():
        if wanted is not None and not wanted(index):
            continue
        description = channel.object_description(index)
        row = ObjectRow(index, description.name, OBJECT_CODES.get(description.object_code,
                                                                  f"code {description.object_code}"),
                        description.max_subindex)
        for sub in range(description.max_subindex + 1) if entries else ():
            try:
                entry = channel.entry_description(index, sub)
            except CommError:
                raise
            except SdoAborted:
                continue  # a gap in a record: the drive does not describe this subindex
            row.entries.append(EntryRow(sub, entry.name, _type_name(entry.data_type), entry.bit_length,
                                        access_text(entry.access), _pdo_text(entry.access)))
        rows.append(row)
    return rows


def catalogue_dictionary(*, entries: bool = True, wanted: Callable[[int], bool] | None = None) -> list[ObjectRow]:
    """Our catalogue (the AKD ESI) in the same shape."""
    from akdctl.catalog.objects import indices, object_name, subentries

    rows = []
    for index in indices():
        if wanted is not None and not wanted(index):
            continue
        subs = subentries(index)
        kinds = {e.short_type for e in subs if e.subindex > 0}
        code = "VAR" if len(subs) == 1 and subs[0].subindex == 0 else "ARRAY" if len(kinds) == 1 else "RECORD"
        row = ObjectRow(index, object_name(index) or subs[0].name, code, max(e.subindex for e in subs))
        if entries:
            row.entries = [EntryRow(e.subindex, e.name, e.short_type, e.bits,
                                    {"ro": "r-", "rw": "rw", "wo": "-w"}.get(e.access, e.access),
                                    ("R" if e.rx_mappable else "") + ("T" if e.tx_mappable else ""))
                           for e in subs]
        rows.append(row)
    return rows
