"""The simulated AKD describes its object dictionary: the answers to the SDO information service (CoE service 8).

Why a module of its own: the SDO server (``sim/sdo_server.py``) already speaks service 8 for any model that offers
:class:`~akdctl.sim.sdo_server.ObjectInfoAccess`, but the drive model did not offer it, so ``akdctl sdo list``
(IgH's ``ethercat sdos``) had nothing to list on the simulator. The simulated drive's dictionary *is* the
catalogue (``catalog/objects.py``, generated from the AKD ESI): every object the model answers is an entry there.
This module turns catalogue entries into the descriptions ETG.1000.6 defines; the model only forwards to it.

Object code: 7 VAR (sub 0 only), 8 ARRAY (subs 1.. share one type), 9 RECORD (otherwise). Access bits
(ETG.1000.6 entry description): 0x07 read in PREOP/SAFEOP/OP, 0x38 write in PREOP/SAFEOP/OP, 0x40 RxPDO and
0x80 TxPDO mappable — the ESI gives one access for all states, so a writable entry is writable in all three.
"""

from __future__ import annotations

from akdctl.sim.errors import SdoAccessError
from akdctl.sim.sdo_server import EntryInfo, ObjectInfo

ABORT_NO_OBJECT = 0x06020000
VAR, ARRAY, RECORD = 7, 8, 9
READ_ALL_STATES, WRITE_ALL_STATES, RX_MAPPABLE, TX_MAPPABLE = 0x07, 0x38, 0x40, 0x80


def object_indices() -> list[int]:
    """Every object index of the simulated drive, ascending."""
    from akdctl.catalog.objects import indices

    return list(indices())


def _entry(entry: object) -> EntryInfo:
    from akdctl.protocol.datatypes import TYPES

    access = (READ_ALL_STATES if entry.readable else 0) | (WRITE_ALL_STATES if entry.writable else 0)  # type: ignore[attr-defined]
    access |= RX_MAPPABLE if entry.rx_mappable else 0  # type: ignore[attr-defined]
    access |= TX_MAPPABLE if entry.tx_mappable else 0  # type: ignore[attr-defined]
    return EntryInfo(entry.name, TYPES[entry.short_type].code, entry.bits, access)  # type: ignore[attr-defined]


def object_info(index: int) -> ObjectInfo:
    """One object's description; SdoAccessError(0x06020000) for an index the drive does not have."""
    from akdctl.catalog.objects import object_name, subentries

    subs = subentries(index)
    if not subs:
        raise SdoAccessError(ABORT_NO_OBJECT)
    entries = {e.subindex: _entry(e) for e in subs}
    elements = {e.data_type for sub, e in entries.items() if sub > 0}
    if len(entries) == 1 and 0 in entries:
        code, data_type = VAR, entries[0].data_type
    elif len(elements) == 1:
        code, data_type = ARRAY, elements.pop()
    else:
        code, data_type = RECORD, 0
    return ObjectInfo(index, object_name(index) or subs[0].name, code, data_type, max(entries), entries)
