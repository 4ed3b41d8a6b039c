"""The simulated AKD's faults: PROFIdrive fault situations, CiA error objects, emergencies.

One fault reaches a client three ways (SPEC-NOTES 14, 21), so one component
keeps the single truth and renders every view of it:

* **PROFIdrive** (PROFINET manual 5.14): faults form *fault situations* of up
  to 8 fault numbers. Situation 0 (PNU 947[0..7]) holds the active,
  unacknowledged faults; acknowledging shifts every situation by 8 elements,
  so the newest acknowledged one sits at 947[8..15]; only 8 situations fit,
  the oldest falls off. PNU 944 counts the situations ever generated (a fault
  joining an unacknowledged situation makes no new one). Fault numbers are
  the bare AKD F-numbers (501 for F501; SPEC-NOTES 14). Warnings (n-numbers)
  are not faults: they never enter PNU 947 and only set ZSW1 bit 7.
* **CiA 301 / AKD objects**: 0x1001 error register (bits from the EMCY code
  classes of the active faults), 0x1003 pre-defined error field (EMCY codes,
  newest at sub 1, AKD number in the upper 16 bits - the simulator's choice
  for the manufacturer-specific half; writing 0 to sub 0 clears it), 0x2000
  DRV.WARNING1..3, 0x2001 DRV.FAULT1..10, 0x2012/0x2013 the fault history
  numbers and time stamps (virtual operating seconds; the unit of a real
  drive is not verified).
* **Emergencies**: every raised fault or warning queues an EMCY frame (code
  from the AKD table, manufacturer bytes = AKD number as u16 LE); clearing the
  last fault queues the 0x0000 "error reset" frame.

An injected fault's *cause* goes away at once unless injected with
``persist=True``; a persisting fault comes back as a new situation after an
acknowledge, until :meth:`clear_causes` (``akdctl sim clear``). Injected
warnings last until :meth:`clear_causes`, as a warning on a drive lasts while
its condition does.

To test a reader's consistency loop, :meth:`arm` schedules a fault to be
raised right after the drive has answered N more reads of the fault PNUs or
objects (``akdctl sim fault F501 --after-reads N``): the fault then appears
*between* two reads of one dump.

STW1/ZSW1 and the controlword/statusword belong to the motion component: it
calls :meth:`acknowledge` on a rising edge of bit 7 and reads
:attr:`fault_present`/:attr:`warning_present` for bits 3 and 7.
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING, Any

from akdctl.sim.component import ABORT_VALUE_RANGE, Component
from akdctl.sim.errors import SdoAccessError

if TYPE_CHECKING:
    from akdctl.catalog import faults as catalog
    from akdctl.protocol.emcy import Emergency
    from akdctl.sim.model import DriveModel

SITUATIONS = 8  # PNU 947 holds 8 situations (manual 5.14)
FAULTS_PER_SITUATION = 8
HISTORY_LENGTH = 20  # 0x2012/0x2013 have 20 entries (ESI)
ERROR_FIELD_LENGTH = 10  # 0x1003 sub 1..10 (ESI)
WARNING_SLOTS = 3  # 0x2000 DRV.WARNING1..3
FAULT_SLOTS = 10  # 0x2001 DRV.FAULT1..10
EMCY_QUEUE_LIMIT = 32  # undelivered emergencies kept (a bus nobody listens to loses them)

# Indices this component answers; reads of these (and of PNU 944/947) count for `arm`.
OBJ_ERROR_REGISTER = 0x1001
OBJ_ERROR_FIELD = 0x1003
OBJ_WARNINGS = 0x2000
OBJ_FAULTS = 0x2001
OBJ_HISTORY_NUMBERS = 0x2012
OBJ_HISTORY_TIMES = 0x2013
PNU_FAULT_COUNTER = 944
PNU_FAULT_BUFFER = 947


def error_register_bits(emcy_code: int) -> int:
    """The 0x1001 bits an emergency code sets (CiA 301): bit 0 always, plus its class bit.

    Why here: the register must agree with the EMCY frames the same component sends.
    """
    bits = 0x01
    high = emcy_code >> 12
    if high == 0x2:
        bits |= 0x02  # current
    elif high == 0x3:
        bits |= 0x04  # voltage
    elif high == 0x4:
        bits |= 0x08  # temperature
    elif emcy_code >> 8 in (0x81, 0x82):
        bits |= 0x10  # communication
    elif emcy_code >> 8 == 0xFF:
        bits |= 0x80  # manufacturer specific
    return bits


def _u32(values: list[int], sub: int, length: int) -> bytes:
    """Sub 0 = number of entries of an array object, sub n = element n-1 (0 past the end)."""
    if sub == 0:
        return bytes([length])
    if not 1 <= sub <= length:
        raise SdoAccessError(0x06090011)
    value = values[sub - 1] if sub - 1 < len(values) else 0
    return struct.pack("<I", value & 0xFFFFFFFF)


class FaultComponent(Component):
    """Fault situations, warnings, histories and emergencies of the simulated AKD."""

    name = "faults"
    PERSISTED = ("situations", "counter", "warnings", "persistent", "history", "error_field", "emergencies", "armed")

    def __init__(self, model: "DriveModel") -> None:
        super().__init__(model)
        self.situations: list[list[int]] = [[] for _ in range(SITUATIONS)]
        self.counter = 0
        self.warnings: list[int] = []
        self.persistent: list[str] = []
        self.history: list[tuple[int, int]] = []  # (number, time stamp s), newest first
        self.error_field: list[int] = []  # 0x1003 entries, newest first
        self.emergencies: list[Emergency] = []
        self.armed: list[dict[str, Any]] = []
        model.bind_pnu(PNU_FAULT_COUNTER, read=self._read_counter)
        model.bind_pnu(PNU_FAULT_BUFFER, read=self._read_buffer)
        model.bind_object(OBJ_ERROR_REGISTER, read=self._read_error_register)
        model.bind_object(OBJ_ERROR_FIELD, read=self._read_error_field, write=self._write_error_field)
        model.bind_object(OBJ_WARNINGS, read=self._read_warnings)
        model.bind_object(OBJ_FAULTS, read=self._read_faults)
        model.bind_object(OBJ_HISTORY_NUMBERS, read=self._read_history_numbers)
        model.bind_object(OBJ_HISTORY_TIMES, read=self._read_history_times)

    # ------------------------------------------------------------------ contract
    @property
    def fault_present(self) -> bool:
        """ZSW1 bit 3 / statusword bit 3: an unacknowledged fault situation exists."""
        return bool(self.situations[0])

    @property
    def warning_present(self) -> bool:
        """ZSW1 bit 7 / statusword bit 7."""
        return bool(self.warnings)

    def active(self) -> list[str]:
        """Active faults then warnings, as codes ('F501', 'n503')."""
        return [_code(n, warning=False) for n in self.situations[0]] + [_code(n, warning=True) for n in self.warnings]

    def raise_fault(self, code: str, *, persist: bool = False) -> None:
        """Raise a fault or warning now; ``ValueError`` for a code not in the AKD table."""
        fault = _lookup(code)
        assert fault.number is not None
        if fault.is_warning:
            if fault.number not in self.warnings:
                self.warnings.append(fault.number)
                self.changed()
                self._emergency(fault)
            self._keep_cause(fault.code)  # a warning lasts until its cause is cleared
            return
        active = self.situations[0]
        if not active:
            self.counter = (self.counter + 1) & 0xFFFF
        if fault.number not in active and len(active) < FAULTS_PER_SITUATION:
            active.append(fault.number)
            self.history.insert(0, (fault.number, int(self.model.clock)))
            del self.history[HISTORY_LENGTH:]
            self.changed()
            self._emergency(fault)
        if persist:
            self._keep_cause(fault.code)
        self.model.motion.on_fault(fault.code)

    def acknowledge(self) -> bool:
        """Move the active situation into the acknowledged section; False if none is active.

        Faults whose cause persists come straight back as a new situation.
        """
        if not self.situations[0]:
            return False
        self.situations = [[]] + self.situations[: SITUATIONS - 1]
        register = self._register()
        self._queue(_emcy_class()(0x0000, register))
        for code in list(self.persistent):
            fault = _fault_table().by_code(code)
            if fault is not None and not fault.is_warning:
                self.raise_fault(code)
        return True

    def take_emergencies(self) -> list[Emergency]:
        if not self.emergencies:  # the usual case: nothing queued, nothing changes
            return []
        out, self.emergencies = self.emergencies, []
        return out

    # ------------------------------------------------------------------ simulator control
    def arm(self, code: str, after_reads: int, *, persist: bool = False) -> None:
        """Raise ``code`` after the drive answered ``after_reads`` more fault reads (≥ 1)."""
        fault = _lookup(code)
        if after_reads < 1:
            raise ValueError("after_reads must be at least 1")
        self.armed.append({"code": fault.code, "reads": int(after_reads), "persist": bool(persist)})
        self.changed()

    def clear_causes(self) -> list[str]:
        """Remove every persisting cause and every warning (faults stay until acknowledged)."""
        removed = list(self.persistent)
        self.persistent = []
        self.armed = []
        if self.warnings:
            self.warnings = []
            if not self.fault_present:
                self._queue(_emcy_class()(0x0000, self._register()))
        return removed

    def clear_warning(self, code: str) -> None:
        """A warning's condition ended (the watchdog's, on the next command): it leaves 0x2000 and ZSW1 bit 7."""
        fault = _lookup(code)
        if fault.number in self.warnings:
            self.warnings.remove(fault.number)
            self.changed()
            if not self.warnings and not self.fault_present:
                self._queue(_emcy_class()(0x0000, self._register()))
        if fault.code in self.persistent:
            self.persistent.remove(fault.code)
            self.changed()

    def clear_error_field(self) -> None:
        """0x1003:0 = 0 (CiA 301): forget the pre-defined error field."""
        self.error_field = []

    # ------------------------------------------------------------------ internals
    def _keep_cause(self, code: str) -> None:
        if code not in self.persistent:
            self.persistent.append(code)
            self.changed()

    def _register(self) -> int:
        reg = 0
        for number in self.situations[0]:
            fault = _fault_table().by_number(number)
            reg |= error_register_bits(fault.emcy) if fault is not None else 0x01
        return reg

    def _emergency(self, fault: catalog.Fault) -> None:
        assert fault.number is not None
        entry = fault.emcy | ((fault.number & 0xFFFF) << 16)
        self.error_field.insert(0, entry)
        del self.error_field[ERROR_FIELD_LENGTH:]
        self.changed()
        register = self._register()  # warnings set no 0x1001 bits: only faults are errors
        self._queue(_emcy_class()(fault.emcy, register, struct.pack("<H", fault.number & 0xFFFF) + bytes(3)))

    def _queue(self, emcy: Emergency) -> None:
        self.emergencies.append(emcy)
        del self.emergencies[: max(0, len(self.emergencies) - EMCY_QUEUE_LIMIT)]
        self.changed()

    def _counted_read(self) -> None:
        """After answering a fault read: fire armed faults whose count ran out."""
        if not self.armed:
            return
        due = []
        self.changed()  # every armed count goes down
        for item in self.armed:
            item["reads"] -= 1
            if item["reads"] <= 0:
                due.append(item)
        self.armed = [i for i in self.armed if i["reads"] > 0]
        for item in due:
            self.raise_fault(item["code"], persist=item.get("persist", False))

    # PNU views ------------------------------------------------------------------------------
    def _read_counter(self, sub: int, count: int) -> list[int]:
        values = [self.counter]
        self._counted_read()
        return values

    def _buffer(self) -> list[int]:
        flat: list[int] = []
        for situation in self.situations:
            flat.extend(situation + [0] * (FAULTS_PER_SITUATION - len(situation)))
        return flat

    def _read_buffer(self, sub: int, count: int) -> list[int]:
        values = self._buffer()[sub : sub + count]
        self._counted_read()
        return values

    # Object views ---------------------------------------------------------------------------
    def _read_error_register(self, sub: int) -> bytes:
        if sub != 0:
            raise SdoAccessError(0x06090011)
        data = bytes([self._register()])
        self._counted_read()
        return data

    def _read_error_field(self, sub: int) -> bytes:
        if sub == 0:
            data = bytes([len(self.error_field)])
        else:
            data = _u32(self.error_field, sub, ERROR_FIELD_LENGTH)
        self._counted_read()
        return data

    def _write_error_field(self, sub: int, data: bytes) -> None:
        if sub != 0:
            raise SdoAccessError(0x06010002)  # the entries are read-only
        if data != b"\x00":
            raise SdoAccessError(ABORT_VALUE_RANGE)  # only 0 (clear) may be written
        self.clear_error_field()

    def _read_warnings(self, sub: int) -> bytes:
        data = _u32(self.warnings, sub, WARNING_SLOTS)
        self._counted_read()
        return data

    def _read_faults(self, sub: int) -> bytes:
        if sub == 0:
            data = bytes([FAULT_SLOTS])
        elif 1 <= sub <= FAULT_SLOTS:
            active = self.situations[0]
            data = struct.pack("<H", active[sub - 1] if sub - 1 < len(active) else 0)
        else:
            raise SdoAccessError(0x06090011)
        self._counted_read()
        return data

    def _read_history_numbers(self, sub: int) -> bytes:
        data = _u32([n for n, _ in self.history], sub, HISTORY_LENGTH)
        self._counted_read()
        return data

    def _read_history_times(self, sub: int) -> bytes:
        data = _u32([t for _, t in self.history], sub, HISTORY_LENGTH)
        self._counted_read()
        return data

    # ------------------------------------------------------------------ persistence
    def to_state(self) -> dict[str, Any]:
        return {
            "situations": [list(s) for s in self.situations],
            "counter": self.counter,
            "warnings": list(self.warnings),
            "persistent": list(self.persistent),
            "history": [[n, t] for n, t in self.history],
            "error_field": list(self.error_field),
            "emergencies": [[e.error_code, e.error_register, e.data.hex()] for e in self.emergencies],
            "armed": [dict(a) for a in self.armed],
        }

    def load_state(self, state: dict[str, Any]) -> None:
        situations = [[int(n) for n in s][:FAULTS_PER_SITUATION] for s in state.get("situations", [])][:SITUATIONS]
        self.situations = situations + [[] for _ in range(SITUATIONS - len(situations))]
        self.counter = int(state.get("counter", 0)) & 0xFFFF
        self.warnings = [int(n) for n in state.get("warnings", [])]
        self.persistent = [str(c) for c in state.get("persistent", [])]
        self.history = [(int(n), int(t)) for n, t in state.get("history", [])][:HISTORY_LENGTH]
        self.error_field = [int(v) for v in state.get("error_field", [])][:ERROR_FIELD_LENGTH]
        self.emergencies = [_emcy_class()(int(c), int(r), bytes.fromhex(d)) for c, r, d in state.get("emergencies", [])]
        self.armed = [{"code": str(a["code"]), "reads": int(a["reads"]), "persist": bool(a.get("persist"))}
                      for a in state.get("armed", [])]


def _lookup(code: str) -> catalog.Fault:
    fault = _fault_table().by_code(code) if isinstance(code, str) else None
    if fault is None or fault.number is None or not fault.code:
        raise ValueError(f"unknown AKD fault or warning {code!r} (see 'akdctl fault list')")
    return fault


def _code(number: int, *, warning: bool) -> str:
    fault = _fault_table().by_number(number, warning=warning)
    if fault is not None and fault.is_warning == warning:
        return fault.code
    return f"{'n' if warning else 'F'}{number}"


def _fault_table() -> Any:
    """The fault catalogue (``catalog/faults.py``), imported when a fault is raised, looked up or described: a drive
    without faults is read without it (issue 29, cold start)."""
    from akdctl.catalog import faults

    return faults


def _emcy_class() -> "type[Emergency]":
    """The EMCY record class, imported when an emergency is queued or loaded."""
    from akdctl.protocol.emcy import Emergency

    return Emergency
