"""The simulated AKD's process-data configuration: CoE PDO mapping/assignment and PROFIdrive telegrams.

Why a component: the drive, not the tool, is the last line of defence. Whatever
client writes 0x1C12/0x1C13, 0x1600-0x1603/0x1A00-0x1A03 or PNU 915/916/922
(akdctl with ``--force``, TwinCAT, a CANopen master, ``sdo write``) meets the
same rules a real AKD enforces, checked on every single write:

* mapping and assignment change only in PRE-OP (0x08000022, SPEC-NOTES 18);
* a sub-index >= 1 is written only while sub-index 0 is 0 (0x06010003, SPEC-NOTES 17);
* a mapping entry names a PDO-mappable object of the PDO's direction with its own
  bit length (0x06040041);
* a PDO holds at most 8 bytes and an even number of bytes, the assigned PDOs at most
  22 (Rx) / 32 (Tx) bytes (0x06040042, SPEC-NOTES 18);
* an assignment names a PDO of its direction (unknown numbers such as the manual's
  0x1704: 0x06090030, SPEC-NOTES 16); a fixed PDO excludes every other PDO of its
  direction (ESI ``<Exclude>``; 0x06040043);
* PNU 922 accepts the telegrams 0, 1, 7, 9, 350, 351 (else PROFIdrive error 0x14);
  PNU 915/916 change only in telegram 0 (0x11) and only to signals of PNU 923 in the
  right direction (0x14, additional info = the offending element).

The EtherCAT AL state lives here too (``al_state``) because the mapping rules
depend on it; the EtherCAT faces set it with :meth:`PdoComponent.set_al_state`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from akdctl.catalog import objects as oc
from akdctl.catalog import telegrams as tc
from akdctl.sim.component import (
    ABORT_DEVICE_STATE,
    ABORT_NO_SUBINDEX,
    ABORT_VALUE_HIGH,
    ABORT_VALUE_LOW,
    ABORT_VALUE_RANGE,
    PE_OPERATING_STATE,
    PE_VALUE_IMPERMISSIBLE,
    Component,
)
from akdctl.sim.errors import PnuAccessError
from akdctl.sim.errors import SdoAccessError

if TYPE_CHECKING:
    from akdctl.sim.model import DriveModel

ABORT_SUBINDEX_0_NOT_ZERO = 0x06010003
ABORT_NOT_MAPPABLE = 0x06040041
ABORT_PDO_LENGTH = 0x06040042
ABORT_INCOMPATIBLE = 0x06040043

AL_STATES = ("INIT", "PREOP", "BOOT", "SAFEOP", "OP")
_AL_CODES = {0x01: "INIT", 0x02: "PREOP", 0x03: "BOOT", 0x04: "SAFEOP", 0x08: "OP"}

#: AL state name -> the AL status code an ESC shows for it.
AL_STATE_CODES = {name: code for code, name in _AL_CODES.items()}

_FLEXIBLE = tuple(oc.FLEXIBLE_RX) + tuple(oc.FLEXIBLE_TX)


def _u(data: bytes) -> int:
    return int.from_bytes(data, "little")


def normalise_al_state(state: object) -> str:
    """'PREOP', 'pre-op', AlState.PREOP or 2 -> 'PREOP'; ValueError otherwise."""
    if isinstance(state, int):
        name = _AL_CODES.get(int(state) & 0x0F)
        if name is None:
            raise ValueError(f"unknown AL state code {state!r}")
        return name
    key = str(state).strip().upper().replace("-", "").replace("_", "")
    if key == "BOOTSTRAP":
        key = "BOOT"
    if key not in AL_STATES:
        raise ValueError(f"unknown AL state {state!r}; use one of {', '.join(AL_STATES)}")
    return key


class PdoComponent(Component):
    """Owns 0x1C12/0x1C13, 0x1600-0x1603, 0x1A00-0x1A03, the fixed PDOs, PNU 915/916/922/923 and the AL state."""

    name = "pdo"
    PERSISTED = ("al_state", "assign", "mapping", "telegram", "free_words")

    def __init__(self, model: "DriveModel") -> None:
        super().__init__(model)
        self.al_state = "PREOP"
        self.cyclic = False  # True only while apply_outputs() writes the RxPDO's objects (not persisted)
        # assignment: [count, sub1..sub4] per direction (ESI default 0x1701 / 0x1B01)
        self.assign: dict[int, list[int]] = {
            oc.RX_ASSIGN: [1, oc.DEFAULT_RX_PDO, 0, 0, 0],
            oc.TX_ASSIGN: [1, oc.DEFAULT_TX_PDO, 0, 0, 0],
        }
        # flexible mappings: [count, entry1..entry8] (ESI defaults)
        self.mapping: dict[int, list[int]] = {pdo: self._esi_default(pdo) for pdo in _FLEXIBLE}
        self.telegram = 1
        self.free_words = {
            915: tc.expand_words(tc.TELEGRAMS[1].setpoint),
            916: tc.expand_words(tc.TELEGRAMS[1].actual),
        }
        for index in (oc.RX_ASSIGN, oc.TX_ASSIGN):
            model.bind_object(index, read=self._reader(index, self._read_assign),
                              write=self._writer(index, self._write_assign))
        for pdo in _FLEXIBLE:
            model.bind_object(pdo, read=self._reader(pdo, self._read_mapping),
                              write=self._writer(pdo, self._write_mapping))
        for pdo in (*oc.FIXED_RX_PDOS, *oc.FIXED_TX_PDOS):
            model.bind_object(pdo, read=self._reader(pdo, self._read_fixed))
        model.bind_pnu(922, read=lambda sub, count: [self.telegram], write=self._write_922)
        model.bind_pnu(915, read=lambda sub, count: self._words(915)[sub:sub + count],
                       write=lambda sub, values: self._write_words(915, sub, values))
        model.bind_pnu(916, read=lambda sub, count: self._words(916)[sub:sub + count],
                       write=lambda sub, values: self._write_words(916, sub, values))
        model.bind_pnu(923, read=lambda sub, count: tc.signal_list()[sub:sub + count])
        model.bind_object(0x60C2, write=self._write_cycle_time)

    # ------------------------------------------------------------------ public API
    def set_al_state(self, state: object) -> None:
        """Set the EtherCAT AL state ('INIT'/'PREOP'/'BOOT'/'SAFEOP'/'OP' or its AL code); ValueError if unknown."""
        self.al_state = normalise_al_state(state)

    def assigned(self, direction: str) -> list[int]:
        """PDO numbers assigned (0x1C12 for "rx", 0x1C13 for "tx"), in order."""
        values = self.assign[oc.RX_ASSIGN if direction == "rx" else oc.TX_ASSIGN]
        return [v for v in values[1:1 + values[0]] if v]

    def pdo_entries(self, pdo: int) -> tuple[oc.PdoEntry, ...]:
        """Current entries of a fixed or flexible PDO (empty for an unknown number)."""
        fixed = oc.fixed_pdo(pdo)
        if fixed is not None:
            return fixed
        values = self.mapping.get(pdo)
        if values is None:
            return ()
        return tuple(oc.PdoEntry.from_mapping_value(v) for v in values[1:1 + values[0]])

    def active_entries(self, direction: str) -> list[oc.PdoEntry]:
        """Every entry of the assigned PDOs of a direction, in process-image order."""
        out: list[oc.PdoEntry] = []
        for pdo in self.assigned(direction):
            out.extend(self.pdo_entries(pdo))
        return out

    def controlword_in_active_rxpdo(self) -> bool:
        """True in OP while 0x6040:00 travels in an assigned RxPDO: SDO writes of it then have no effect (SPEC-NOTES 23).

        False while the process data itself is being applied (:func:`apply_outputs`): that write is the one
        that wins."""
        if self.al_state != "OP" or self.cyclic:
            return False
        return any(e.index == 0x6040 and e.subindex == 0 for e in self.active_entries("rx"))

    def telegram_signals(self) -> tuple[list[int], list[int]]:
        """(set-point signals, actual-value signals) of the selected telegram, in IO order."""
        return tc.words_to_signals(self._words(915)), tc.words_to_signals(self._words(916))

    # ------------------------------------------------------------------ persistence
    def to_state(self) -> dict[str, Any]:
        return {
            "al_state": self.al_state,
            "assign": {f"{k:04X}": list(v) for k, v in self.assign.items()},
            "mapping": {f"{k:04X}": list(v) for k, v in self.mapping.items()},
            "telegram": self.telegram,
            "free_words": {str(k): list(v) for k, v in self.free_words.items()},
        }

    def load_state(self, state: dict[str, Any]) -> None:
        if "al_state" in state:
            self.al_state = normalise_al_state(state["al_state"])
        for key, values in dict(state.get("assign", {})).items():
            index = int(key, 16)
            if index in self.assign and len(values) == 5:
                self.assign[index] = [int(v) for v in values]
                self.changed()
        for key, values in dict(state.get("mapping", {})).items():
            index = int(key, 16)
            if index in self.mapping and len(values) == 9:
                self.mapping[index] = [int(v) for v in values]
                self.changed()
        if "telegram" in state:
            self.telegram = int(state["telegram"])
        for key, values in dict(state.get("free_words", {})).items():
            if int(key) in self.free_words and len(values) == tc.PZD_MAX_WORDS:
                self.free_words[int(key)] = [int(v) for v in values]
                self.changed()

    # ------------------------------------------------------------------ object plumbing
    def _write_cycle_time(self, sub: int, data: bytes) -> None:
        """0x60C2 (interpolation time period): the drive turns it into FBUS.SAMPLEPERIOD ticks of 62.5 µs, so a
        period off that grid (0x06090030) or below 250 µs (0x06090032) is refused and nothing changes
        (EtherCAT manual 5.9/5.10; docs/fidelity.md F5). Each sub-index write is checked with the other one's
        current value."""
        from akdctl.catalog.texts import cycle_time_text
        from akdctl.profiles.units import CYCLE_TOO_SHORT, cycle_time_problem

        period = {1: self.model.stored_object(0x60C2, 1)[0],
                  2: int.from_bytes(self.model.stored_object(0x60C2, 2), "little", signed=True)}
        period[sub] = int.from_bytes(data, "little", signed=sub == 2)
        problem = cycle_time_problem(period[1], period[2])
        if problem is not None:
            raise SdoAccessError(ABORT_VALUE_LOW if problem == CYCLE_TOO_SHORT else ABORT_VALUE_RANGE,
                                 cycle_time_text(problem, period[1], period[2]))
        self.model.set_stored_object(0x60C2, sub, data)

    @staticmethod
    def _esi_default(pdo: int) -> list[int]:
        values = [0] * 9
        for entry in oc.subentries(pdo):
            if 0 <= entry.subindex <= 8 and entry.default is not None:
                values[entry.subindex] = entry.default
        return values

    def _reader(self, index: int, func: Any) -> Any:
        def read(sub: int) -> bytes:
            entry = self.model.object_entry(index, sub)  # unknown sub-index -> 0x06090011
            return func(index, sub).to_bytes(entry.nbytes, "little")
        return read

    def _writer(self, index: int, func: Any) -> Any:
        def write(sub: int, data: bytes) -> None:
            if self.al_state != "PREOP":
                raise SdoAccessError(ABORT_DEVICE_STATE,
                                     f"PDO mapping/assignment changes only in PRE-OP (AL state is {self.al_state})")
            func(index, sub, _u(data))
        return write

    def _read_assign(self, index: int, sub: int) -> int:
        return self.assign[index][sub]

    def _read_mapping(self, index: int, sub: int) -> int:
        return self.mapping[index][sub]

    def _read_fixed(self, index: int, sub: int) -> int:
        entries = oc.fixed_pdo(index) or ()
        if sub == 0:
            return len(entries)
        if sub > len(entries):
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        return entries[sub - 1].mapping_value

    # ------------------------------------------------------------------ assignment rules
    def _write_assign(self, index: int, sub: int, value: int) -> None:
        rx = index == oc.RX_ASSIGN
        values = self.assign[index]
        if sub == 0:
            self._check_assignment(rx, values, value)
            values[0] = value
            self.changed()
            return
        if values[0] != 0:
            raise SdoAccessError(ABORT_SUBINDEX_0_NOT_ZERO)
        if value != 0 and not (oc.is_rx_pdo(value) if rx else oc.is_tx_pdo(value)):
            raise SdoAccessError(ABORT_VALUE_RANGE, f"0x{value:04X} is not a {'Rx' if rx else 'Tx'}PDO of the AKD")
        values[sub] = value
        self.changed()

    def _check_assignment(self, rx: bool, values: list[int], count: int) -> None:
        if count > oc.MAX_ASSIGNED_PDOS:
            raise SdoAccessError(ABORT_VALUE_HIGH)
        pdos = values[1:1 + count]
        if any(p == 0 for p in pdos) or len(set(pdos)) != len(pdos):
            raise SdoAccessError(ABORT_VALUE_RANGE, "empty or repeated PDO in the assignment")
        fixed = oc.FIXED_RX_PDOS if rx else oc.FIXED_TX_PDOS
        if len(pdos) > 1 and any(p in fixed for p in pdos):
            raise SdoAccessError(ABORT_INCOMPATIBLE, "a fixed PDO excludes every other PDO of its direction")
        for p in pdos:
            bits = sum(e.bits for e in self.pdo_entries(p))
            if bits % 16:  # e.g. the ESI default of 0x1601 (0x6040 + 0x6060, 3 bytes)
                raise SdoAccessError(ABORT_PDO_LENGTH, f"PDO 0x{p:04X} has an odd length")
        total = sum(oc.pdo_bytes(self.pdo_entries(p)) for p in pdos)
        if total > (oc.RX_TOTAL_MAX_BYTES if rx else oc.TX_TOTAL_MAX_BYTES):
            raise SdoAccessError(ABORT_PDO_LENGTH, f"assigned PDOs hold {total} bytes")

    # ------------------------------------------------------------------ mapping rules
    def _write_mapping(self, index: int, sub: int, value: int) -> None:
        rx = index in oc.FLEXIBLE_RX
        values = self.mapping[index]
        if sub == 0:
            self._check_mapping(index, rx, values, value)
            values[0] = value
            self.changed()
            return
        if values[0] != 0:
            raise SdoAccessError(ABORT_SUBINDEX_0_NOT_ZERO)
        if value != 0:
            self._check_entry(rx, oc.PdoEntry.from_mapping_value(value))
        values[sub] = value
        self.changed()

    @staticmethod
    def _check_entry(rx: bool, entry: oc.PdoEntry) -> None:
        obj = oc.lookup(entry.index, entry.subindex)
        if obj is None or not (obj.rx_mappable if rx else obj.tx_mappable) or obj.bits != entry.bits:
            raise SdoAccessError(ABORT_NOT_MAPPABLE, f"{entry} cannot be mapped into a {'Rx' if rx else 'Tx'}PDO")

    def _check_mapping(self, index: int, rx: bool, values: list[int], count: int) -> None:
        if count > oc.MAX_MAPPING_ENTRIES:
            raise SdoAccessError(ABORT_VALUE_HIGH)
        entries = []
        for value in values[1:1 + count]:
            if value == 0:
                raise SdoAccessError(ABORT_NOT_MAPPABLE, "empty mapping entry inside the count")
            entry = oc.PdoEntry.from_mapping_value(value)
            self._check_entry(rx, entry)
            entries.append(entry)
        bits = sum(e.bits for e in entries)
        if bits > 8 * oc.PDO_MAX_BYTES or bits % 16:
            raise SdoAccessError(ABORT_PDO_LENGTH, f"PDO 0x{index:04X} would hold {bits} bits")
        assign = oc.RX_ASSIGN if rx else oc.TX_ASSIGN
        if index in self.assigned("rx" if rx else "tx"):
            others = sum(oc.pdo_bytes(self.pdo_entries(p)) for p in self.assigned("rx" if rx else "tx") if p != index)
            limit = oc.RX_TOTAL_MAX_BYTES if rx else oc.TX_TOTAL_MAX_BYTES
            if others + bits // 8 > limit:
                raise SdoAccessError(ABORT_PDO_LENGTH, f"0x{assign:04X} would hold more than {limit} bytes")

    # ------------------------------------------------------------------ PROFIdrive telegrams
    def _words(self, pnu: int) -> list[int]:
        layout = tc.telegram(self.telegram)
        if layout is None:
            return list(self.free_words[pnu])
        return tc.expand_words(layout.setpoint if pnu == 915 else layout.actual)

    def _write_922(self, sub: int, values: list[int]) -> None:
        number = values[0]
        if number != tc.FREE_TELEGRAM and number not in tc.TELEGRAMS:
            raise PnuAccessError(PE_VALUE_IMPERMISSIBLE, sub)
        if number == tc.FREE_TELEGRAM and self.telegram != tc.FREE_TELEGRAM:
            # telegram 0 starts from the layout in use, so the IO shape does not jump
            self.free_words = {915: self._words(915), 916: self._words(916)}
        self.telegram = number

    def _write_words(self, pnu: int, sub: int, values: list[int]) -> None:
        if self.telegram != tc.FREE_TELEGRAM:
            raise PnuAccessError(PE_OPERATING_STATE)
        words = list(self.free_words[pnu])
        words[sub:sub + len(values)] = values
        direction = "setpoint" if pnu == 915 else "actual"
        offered = tc.signal_list()
        for i, number in enumerate(words):
            if number == 0:
                continue
            sig = tc.signal(number)
            if (number >= len(offered) or offered[number] == 0 or sig is None or sig.direction != direction):
                raise PnuAccessError(PE_VALUE_IMPERMISSIBLE, i)
        try:
            tc.words_to_signals(words)
        except tc.TelegramDataError as exc:
            raise PnuAccessError(PE_VALUE_IMPERMISSIBLE, exc.index) from None
        self.free_words[pnu] = words
        self.changed()


# ---------------------------------------------------------------------- cyclic process data (EtherCAT)
# Why here: the mapping that decides the byte layout lives in this component, so the faces that exchange
# process data (the raw EtherCAT face) pack and unpack through it and never keep a copy of the layout.

def image_size(model: "DriveModel", direction: str) -> int:
    """Bytes of the process image of one direction ("rx" outputs of the master, "tx" inputs) as mapped now."""
    return (sum(e.bits for e in model.pdo.active_entries(direction)) + 7) // 8


def _is_padding(entry: oc.PdoEntry) -> bool:
    return entry.index < 0x0008 or entry.is_padding


def apply_outputs(model: "DriveModel", data: bytes) -> None:
    """Write a received RxPDO image into the mapped objects, as the drive's cyclic task does in OP.

    The controlword written here wins over SDO writes (SPEC-NOTES 23): the component's ``cyclic`` flag
    lifts the "mapped controlword" rule for this write only. A value the drive refuses is skipped, as a
    real drive ignores a set point it cannot take from process data.
    """
    entries = model.pdo.active_entries("rx")
    value, offset = int.from_bytes(bytes(data), "little"), 0
    model.pdo.cyclic = True
    try:
        for entry in entries:
            if not _is_padding(entry) and offset + entry.bits <= 8 * len(data):
                raw = (value >> offset) & ((1 << entry.bits) - 1)
                try:
                    model.object_write(entry.index, entry.subindex, raw.to_bytes((entry.bits + 7) // 8, "little"))
                except SdoAccessError:
                    pass
            offset += entry.bits
    finally:
        model.pdo.cyclic = False


def sample_inputs(model: "DriveModel") -> bytes:
    """The TxPDO image: every mapped object's current value, packed LSB first in mapping order."""
    value, offset = 0, 0
    for entry in model.pdo.active_entries("tx"):
        if not _is_padding(entry):
            try:
                raw = int.from_bytes(model.object_read(entry.index, entry.subindex), "little")
            except SdoAccessError:
                raw = 0
            value |= (raw & ((1 << entry.bits) - 1)) << offset
        offset += entry.bits
    return value.to_bytes((offset + 7) // 8, "little")
