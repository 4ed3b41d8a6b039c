"""The simulated AKD's state: PNU values, object values, and live quantities.

``DriveModel`` stores plain values for every catalogued PNU and object and
checks every access the way the drive does (PROFIdrive error values for PNUs,
CiA 301 abort codes for objects). Live quantities (status words, positions,
the fault buffer, PDO mapping rules) are supplied by *components*: small
classes that register read/write bindings for the PNUs and objects they own
and advance with the virtual clock. The PNU server and SDO server only ever
call :meth:`pnu_read`/:meth:`pnu_write` and :meth:`object_read`/:meth:`object_write`.

State round-trips through :meth:`to_state`/:meth:`from_state` as JSON-able
data so :class:`akdctl.sim.drive.SimDrive` can persist it between CLI
invocations.

Why components are built on first use: every CLI command against the default
target starts a process that loads this model, and most touch one component
(``pnu get 930`` the axis, nothing of the PDO mapping or the FoE files). The
components that move with time (``motion``) are built at once; the others
(:data:`LAZY`: faults, pdo, foe; the recorder) when first named -- a property
(``model.pdo``), :meth:`component`, or an access to a PNU or object they own,
found in :data:`LAZY_PNUS`/:data:`LAZY_OBJECTS` (``tests/test_sim_lazy.py``
fails when that index no longer matches what the components bind). A component
never built keeps its persisted state as loaded and writes it back unchanged.
The motion component itself builds its parts (axis, word machines, task table:
``sim/motion.PARTS``) the same way, so reading the operating mode builds none of
them and a resting axis is not built by the clock.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from akdctl.catalog import pnus as pnu_catalog
from akdctl.sim.component import (
    ABORT_NO_OBJECT,
    ABORT_NO_SUBINDEX,
    ABORT_READ_ONLY,
    ABORT_TOO_LONG,
    ABORT_TOO_SHORT,
    ABORT_WRITE_ONLY,
    PE_BAD_SUBINDEX,
    PE_ILLEGAL_FORMAT,
    PE_IMPERMISSIBLE_PNU,
    PE_LIMIT,
    PE_NO_ARRAY,
    PE_READ_ONLY,
    PE_WRONG_TYPE,
    Component,
)
from akdctl.sim.errors import DamagedState, PnuAccessError, SdoAccessError
from akdctl.sim.motion import MotionComponent

if TYPE_CHECKING:
    from akdctl.sim.faults import FaultComponent
    from akdctl.sim.foe import FoeFiles
    from akdctl.sim.pdo import PdoComponent

STATE_VERSION = 1

# Formats a PNU write may use for each element size (typed formats of the same size included).
_FORMATS_BY_BITS = {8: {0x41, 0x02, 0x05, 0x0A}, 16: {0x42, 0x03, 0x06}, 32: {0x43, 0x04, 0x07}}

PnuReader = Callable[[int, int], list[int]]
PnuWriter = Callable[[int, list[int]], None]
ObjectReader = Callable[[int], bytes]
ObjectWriter = Callable[[int, bytes], None]


class _PnuBinding:
    """A component's reader and/or writer of one PNU (a plain slotted class: no code generated at import)."""

    __slots__ = ("read", "write")

    def __init__(self, read: PnuReader | None, write: PnuWriter | None) -> None:
        self.read = read
        self.write = write


class _ObjectBinding:
    """A component's reader and/or writer of one object index."""

    __slots__ = ("read", "write")

    def __init__(self, read: ObjectReader | None, write: ObjectWriter | None) -> None:
        self.read = read
        self.write = write


#: The components built on first use, in the order they are saved (after ``motion``): name -> (module, class).
LAZY: dict[str, tuple[str, str]] = {
    "faults": ("akdctl.sim.faults", "FaultComponent"),
    "pdo": ("akdctl.sim.pdo", "PdoComponent"),
    "foe": ("akdctl.sim.foe", "FoeFiles"),
}
#: Which lazy component binds a PNU / an object index: an access to one builds its owner first. A copy of what the
#: components' ``__init__`` bind, kept here so finding the owner imports nothing (tests/test_sim_lazy.py checks it).
LAZY_PNUS: dict[int, str] = {915: "pdo", 916: "pdo", 922: "pdo", 923: "pdo", 944: "faults", 947: "faults"}
LAZY_OBJECTS: dict[int, str] = {
    0x1001: "faults", 0x1003: "faults", 0x2000: "faults", 0x2001: "faults", 0x2012: "faults", 0x2013: "faults",
    0x1C12: "pdo", 0x1C13: "pdo", 0x60C2: "pdo",
    **{pdo: "pdo" for pdo in (*range(0x1600, 0x1604), *range(0x1A00, 0x1A04), 0x1701, 0x1702, *range(0x1720, 0x1726),
                              0x1B01, *range(0x1B20, 0x1B27))},
}


class DriveModel:
    """One simulated AKD: every PNU and object, with the drive's access checks."""

    def __init__(self) -> None:
        self.clock = 0.0
        self.time_scale = 1.0  # virtual seconds per wall second (SimDrive sets it; the watchdog counts wall time)
        self.pnu_values: dict[int, list[int]] = {}
        self.object_values: dict[tuple[int, int], bytes] = {}
        # AKD parameters a face keeps that have no PNU or object address (EtherNet/IP's EIP.POSUNIT, EIP.PROFUNIT):
        # kept with the rest, so a write over any face survives a restart (issue 23.11)
        self.named_values: dict[str, int] = {}
        self.writes = 0  # count of accepted writes (tests assert "no write reached the drive")
        # Bumped by every change of persisted state: the stored values here, every component's (component.Tracked);
        # the store saves when it moved (sim/drive.py). The virtual clock is not part of it.
        self.revision = 0
        self._pnu_bindings: dict[int, _PnuBinding] = {}
        # pnu_read_raw's lookups, once per PNU: entry, wire format, value mask, reader, is an array
        self._pnu_shapes: dict[int, tuple[Any, int, int, PnuReader | None, bool]] = {}
        self.pnu_bindings_version = 0  # moved by every bind_pnu: what pnu_read_parts gave holds while it stays
        self._object_bindings: dict[int, _ObjectBinding] = {}
        # moved by every bind_object / bind_object_later: what object_read_parts gave holds while it stays
        self.object_bindings_version = 0
        # Object indices a component binds only once a part of it is built (bind_object_later): index -> builder
        self._object_builders: dict[int, Callable[[], object]] = {}
        # The components, named here as typed handles for each other and for the faces. ``motion`` (the one that
        # moves with time) is built now; the LAZY ones on first use (module doc), each from its persisted state
        # if the loaded state had one (``_pending``).
        self.motion = MotionComponent(self)
        self._built: dict[str, Component] = {"motion": self.motion}
        self._pending: dict[str, dict[str, Any]] = {}
        # Why a lazy component could not be built from its loaded state: the store reports the file corrupt after
        # the request even where a server turned the exception into a refusal (sim/drive.py)
        self.damage: str | None = None
        self._recorder: Any = None  # REC.* (sim/recorder.py), made on first use: most commands never record
        # the components that move with time (the lazy ones keep Component.tick, which does nothing), in tick order
        self._tickers = [self.motion.tick]
        # ... and each one's declaration that a tick now would change nothing but the clock (Component.still)
        self._stills = [self.motion.still]
        # The revision at which every ticking component declared itself still after a step (-1: not proven). While
        # the revision stays there, nothing persisted changed, so a step would still change nothing: advance() moves
        # the clock only (the one place this is decided; tests/test_sim_still.py).
        self._still_at = -1

    # ------------------------------------------------------------------ components
    def _build(self, name: str) -> Any:
        """The lazy component ``name``, built (and given its loaded state) on first use. Building is not a change
        of persisted state: the revision is kept, so a read that builds a component never rewrites the file."""
        comp = self._built.get(name)
        if comp is not None:
            return comp
        import importlib

        module, cls = LAZY[name]
        revision = self.revision
        comp = vars(importlib.import_module(module))[cls](self)
        self._built[name] = comp
        pending = self._pending.pop(name, None)
        if pending is not None:
            try:
                comp.load_state(pending)
                comp.to_state()  # renders every derived value once, as the store does at load (sim/drive.py)
            except Exception as exc:  # noqa: BLE001 - hostile content may fail anywhere; all of it means damaged
                del self._built[name]
                self._pending[name] = pending
                self.damage = f"{name}: {exc or type(exc).__name__}"
                raise DamagedState(f"damaged simulator state: {self.damage}") from None
        self.revision = revision
        return comp

    @property
    def faults(self) -> "FaultComponent":
        return self._build("faults")  # type: ignore[no-any-return]

    @property
    def pdo(self) -> "PdoComponent":
        return self._build("pdo")  # type: ignore[no-any-return]

    @property
    def foe(self) -> "FoeFiles":
        return self._build("foe")  # type: ignore[no-any-return]

    @property
    def components(self) -> list[Component]:
        """Every component, built, in tick and save order (motion, faults, pdo, foe, then the recorder if any)."""
        comps: list[Component] = [self.motion, *(self._build(name) for name in LAZY)]
        if self._recorder is not None:
            comps.append(self._recorder)
        return comps

    # ------------------------------------------------------------------ bindings
    def bind_pnu(self, pnu: int, read: PnuReader | None = None, write: PnuWriter | None = None) -> None:
        """Let a component compute a PNU on read (``read(sub, count)``) and/or act on write
        (``write(sub, values)``); stored values are used for the side left ``None``."""
        self._pnu_bindings[pnu] = _PnuBinding(read, write)
        self._pnu_shapes.pop(pnu, None)
        self.pnu_bindings_version += 1

    def bind_object(self, index: int, read: ObjectReader | None = None, write: ObjectWriter | None = None) -> None:
        """Like :meth:`bind_pnu` for a whole object index (``read(sub)``, ``write(sub, data)``)."""
        self._object_bindings[index] = _ObjectBinding(read, write)
        self.object_bindings_version += 1

    def bind_object_later(self, index: int, build: Callable[[], object]) -> None:
        """An object whose binding a component makes only when the part that owns it is built (the motion task
        table, sim/motion.py): the first access calls ``build``, which binds it, and finds that binding."""
        self._object_builders[index] = build
        self.object_bindings_version += 1

    def component(self, name: str) -> Component | None:
        if name in LAZY:
            return self._build(name)  # type: ignore[no-any-return]
        if name == "recorder":
            return self._recorder  # type: ignore[no-any-return]
        return self._built.get(name)

    def _pnu_binding(self, pnu: int) -> _PnuBinding | None:
        binding = self._pnu_bindings.get(pnu)
        if binding is None and pnu in LAZY_PNUS and LAZY_PNUS[pnu] not in self._built:
            self._build(LAZY_PNUS[pnu])
            binding = self._pnu_bindings.get(pnu)
        return binding

    def _object_binding(self, index: int) -> _ObjectBinding | None:
        binding = self._object_bindings.get(index)
        if binding is None:
            if index in LAZY_OBJECTS and LAZY_OBJECTS[index] not in self._built:
                self._build(LAZY_OBJECTS[index])
            elif index in self._object_builders:
                self._object_builders.pop(index)()
            else:
                return None
            binding = self._object_bindings.get(index)
        return binding

    # ------------------------------------------------------------------ time
    def advance(self, dt: float) -> None:
        """Advance virtual time; components integrate motion, timers, watchdogs.

        Why O(1) at rest: a served drive advances the clock before every request, and a drive at rest (the usual
        poll) has nothing to integrate. After a step, each ticking component declares whether a tick would now
        change anything (:meth:`Component.still`); if none would and no recording runs, the model remembers the
        revision. Every change of persisted state bumps the revision (the revision rule, sim/component.Tracked), so
        while it is unchanged the next step would find the same: only the clock moves."""
        if dt <= 0:
            return
        recorder = self._recorder
        if self._still_at == self.revision and (recorder is None or not recorder.running):
            self.clock += dt
            return
        if recorder is not None and recorder.running:
            recorder.advance(dt, self._step)  # samples the motion at its own instants
            return
        self._step(dt)
        for still in self._stills:
            if not still():
                return
        self._still_at = self.revision

    @property
    def recorder(self) -> Any:
        """The REC.* recorder (:class:`akdctl.sim.recorder.Recorder`), attached on first use."""
        if self._recorder is None:
            from akdctl.sim.recorder import Recorder

            self._recorder = Recorder(self)
            self.revision += 1  # to_state() now carries it (the revision rule, sim/component.Tracked)
        return self._recorder

    def _step(self, dt: float) -> None:
        """One advance of the clock and the components (the recorder splits :meth:`advance` at its samples)."""
        if dt <= 0:
            return
        self.clock += dt
        for tick in self._tickers:
            tick(dt)

    # ------------------------------------------------------------------ PNUs
    def pnu_info(self, pnu: int) -> pnu_catalog.PnuInfo:
        info = pnu_catalog.lookup(pnu)
        if info is None:
            raise PnuAccessError(PE_IMPERMISSIBLE_PNU)
        return info

    def stored_pnu(self, pnu: int) -> list[int]:
        """The stored element values of a PNU (defaults until first written; a read stores nothing)."""
        values = self.pnu_values.get(pnu)
        if values is None:
            return self.pnu_info(pnu).default_values()
        return values

    def set_stored_pnu(self, pnu: int, values: list[int], subindex: int = 0) -> None:
        """Store element values without access checks (components use this)."""
        stored = self.pnu_values.get(pnu)
        if stored is None:
            stored = self.pnu_values[pnu] = self.pnu_info(pnu).default_values()
        stored[subindex : subindex + len(values)] = values
        self.revision += 1

    def _check_range(self, info: pnu_catalog.PnuInfo, subindex: int, count: int) -> None:
        if count < 1:
            raise PnuAccessError(PE_BAD_SUBINDEX, subindex)
        if not info.is_array and (subindex != 0 or count != 1):
            raise PnuAccessError(PE_NO_ARRAY if count != 1 else PE_BAD_SUBINDEX, subindex)
        if subindex + count > info.length:
            raise PnuAccessError(PE_BAD_SUBINDEX, subindex)

    def pnu_read(self, pnu: int, subindex: int, count: int) -> Any:
        """ParameterAccess: read ``count`` elements from ``subindex`` as a BMP ParameterValue."""
        from akdctl.protocol.bmp import ParameterValue

        fmt, values = self.pnu_read_raw(pnu, subindex, count)
        return ParameterValue(fmt, tuple(values))

    def pnu_write(self, pnu: int, subindex: int, value: Any) -> None:
        """ParameterAccess: change elements from ``subindex`` with a BMP ParameterValue."""
        values = list(value.values)
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            raise PnuAccessError(PE_WRONG_TYPE)
        self.pnu_write_raw(pnu, subindex, value.format, values)

    def pnu_describe(self, pnu: int) -> Any:
        """ParameterAccess: the PROFIdrive description (attribute 0x20) built from the catalogue."""
        from akdctl.protocol import bmp

        info = self.pnu_info(pnu)
        dtype = pnu_catalog.DATATYPE_CODES[info.type]
        identifier = dtype | (bmp.ID_ARRAY if info.is_array else 0) | (0 if info.writable else bmp.ID_READ_ONLY)
        identifier |= bmp.ID_NO_STANDARDISATION
        lo, hi = info.limits()
        if info.type == "OS":
            low, high = bytes(4), bytes(4)
        else:
            low, high = bmp.ParameterDescription.limit_bytes(dtype, lo), bmp.ParameterDescription.limit_bytes(dtype, hi)
        return bmp.ParameterDescription(
            identifier=identifier,
            elements=info.length if info.is_array else 0,
            name=info.name[:16],
            low_limit=low,
            high_limit=high,
        )

    def pnu_read_raw(self, pnu: int, subindex: int, count: int) -> tuple[int, list[int]]:
        """Read ``count`` elements from ``subindex``: returns (BMP format, unsigned element values)."""
        shape = self._pnu_shapes.get(pnu)
        if shape is None:
            shape = self._pnu_shape(pnu)
        info, wire_format, mask, read, array = shape
        if subindex or count != 1 or array:  # a plain variable's one element needs no range check
            self._check_range(info, subindex, count)
        if read is not None:
            values = read(subindex, count)
        else:
            values = self.stored_pnu(pnu)[subindex : subindex + count]
        if len(values) == 1:  # the usual read: no comprehension (a function call of its own before Python 3.12)
            return wire_format, [values[0] & mask]
        return wire_format, [v & mask for v in values]

    def pnu_read_parts(self, pnu: int, subindex: int, count: int) -> tuple[int, int, PnuReader] | None:
        """For a read of one element of a PNU a component computes (no array, subindex 0): (wire format, value mask,
        the component's reader), such that ``pnu_read_raw(pnu, 0, 1)`` is ``(format, [reader(0, 1)[0] & mask])``
        whenever the reader returns one value; else None. Why: the PNU server plans the reads a poll repeats and
        takes these once per plan instead of looking them up on every read (issue 29); they hold while
        :attr:`pnu_bindings_version` stays (:meth:`bind_pnu` moves it). Raises what pnu_read_raw raises for an
        unknown PNU."""
        if subindex or count != 1:
            return None
        shape = self._pnu_shapes.get(pnu)
        if shape is None:
            shape = self._pnu_shape(pnu)
        _info, wire_format, mask, read, array = shape
        if read is None or array:
            return None
        return wire_format, mask, read

    def _pnu_shape(self, pnu: int) -> tuple[pnu_catalog.PnuInfo, int, int, PnuReader | None, bool]:
        """What every read of a PNU needs, looked up once: its entry, wire format, value mask and reader."""
        info = self.pnu_info(pnu)
        binding = self._pnu_binding(pnu)
        shape = (info, info.wire_format, (1 << info.bits) - 1, binding.read if binding else None, info.is_array)
        self._pnu_shapes[pnu] = shape
        return shape

    def pnu_value_getter(self, pnu: int, subindex: int, count: int) -> tuple[int, Callable[[], Sequence[int]]]:
        """``(wire format, get)`` of a read of ``count`` elements from ``subindex``: ``get()`` returns the values
        :meth:`pnu_read_raw` returns for it -- read from the stored values or the component's reader at each call,
        so never a stale one -- and raises what it raises while reading; what pnu_read_raw refuses before it reads
        (an unknown PNU, a subindex or count out of range: the catalogue's rule, fixed) is raised here, now.

        Why: a poll repeats the same batch of addresses; the PNU server takes each address's getter once per
        request shape instead of looking up catalogue entry, binding, range and mask on every read (issue 29).
        A getter holds while :attr:`pnu_bindings_version` stays (:meth:`bind_pnu` moves it) -- the server checks;
        tests/test_pnu_batch_plan.py holds it to pnu_read_raw."""
        shape = self._pnu_shapes.get(pnu)
        if shape is None:
            shape = self._pnu_shape(pnu)
        info, wire_format, mask, read, array = shape
        if subindex or count != 1 or array:
            self._check_range(info, subindex, count)
        end = subindex + count

        if read is not None:
            def computed() -> Sequence[int]:
                values = read(subindex, count)
                if len(values) == 1:
                    return [values[0] & mask]
                return [v & mask for v in values]

            return wire_format, computed
        defaults = tuple([v & mask for v in info.default_values()[subindex:end]])
        model = self

        def stored() -> Sequence[int]:
            values = model.pnu_values.get(pnu)
            if values is None:  # never written: the catalogue's default (stored_pnu's rule)
                return defaults
            values = values[subindex:end]
            if len(values) == 1:
                return [values[0] & mask]
            return [v & mask for v in values]

        return wire_format, stored

    def pnu_write_raw(self, pnu: int, subindex: int, fmt: int, raw_values: list[int]) -> None:
        """Change elements from ``subindex`` with unsigned wire values in format ``fmt``."""
        info = self.pnu_info(pnu)
        if not info.writable:
            raise PnuAccessError(PE_READ_ONLY, subindex)
        self._check_range(info, subindex, len(raw_values))
        if fmt not in _FORMATS_BY_BITS[info.bits]:
            raise PnuAccessError(PE_ILLEGAL_FORMAT)
        lo, hi = info.limits()
        values = []
        for offset, raw in enumerate(raw_values):
            value = raw - (1 << info.bits) if info.signed and raw >= 1 << (info.bits - 1) else raw
            if not lo <= value <= hi:
                raise PnuAccessError(PE_LIMIT, subindex + offset)
            values.append(value)
        binding = self._pnu_binding(pnu)
        if binding and binding.write:
            binding.write(subindex, values)
        else:
            self.set_stored_pnu(pnu, values, subindex)
        self.writes += 1
        self.revision += 1

    def signed_pnu(self, pnu: int) -> list[int]:
        """Current element values of a PNU as signed/unsigned per its type (for components and tests)."""
        info = self.pnu_info(pnu)
        _, raw = self.pnu_read_raw(pnu, 0, info.length) if info.length else (0, [])
        if info.signed:
            return [r - (1 << info.bits) if r >= 1 << (info.bits - 1) else r for r in raw]
        return raw

    # ------------------------------------------------------------------ objects
    def object_entry(self, index: int, subindex: int) -> Any:
        from akdctl.catalog import objects as object_catalog

        entry = object_catalog.lookup(index, subindex)
        if entry is None:
            raise SdoAccessError(ABORT_NO_SUBINDEX if object_catalog.subentries(index) else ABORT_NO_OBJECT)
        return entry

    def stored_object(self, index: int, subindex: int) -> bytes:
        data = self.object_values.get((index, subindex))
        if data is None:
            entry = self.object_entry(index, subindex)
            data = _default_bytes(entry)
        return data

    def set_stored_object(self, index: int, subindex: int, data: bytes) -> None:
        self.object_values[(index, subindex)] = bytes(data)
        self.revision += 1

    def object_read(self, index: int, subindex: int) -> bytes:
        """A component's reader if one binds the index, else the stored value or the catalogue's default.

        What the catalogue says of an address (no such object or sub-index, write-only, the default bytes) is
        static data, so it is looked up once per (index, subindex) into :data:`_READ_PLANS`; the binding and the
        stored value are read from this model on every call (a component built later, a value written since)."""
        binding = self._object_bindings.get(index)
        if binding is None and (index in LAZY_OBJECTS or index in self._object_builders):
            binding = self._object_binding(index)  # builds the component or part that binds it
        if binding is not None and binding.read is not None:
            return binding.read(subindex)
        key = (index, subindex)
        plan = _READ_PLANS.get(key)
        if plan is None:
            plan = _read_plan(index, subindex)
        if plan.__class__ is int:
            raise SdoAccessError(plan)
        data = self.object_values.get(key)
        return plan if data is None else data  # type: ignore[return-value]

    def object_read_parts(self, index: int, subindex: int) -> tuple[tuple[int, int], bytes] | None:
        """For an address whose read is its stored value (no component binds its index, none will once built, the
        catalogue lets it be read): the key of :attr:`object_values` and the bytes read when nothing is stored;
        None for any other, whose reads go through :meth:`object_read`.

        Why: a served upload polls the same address, and finding again that nothing binds it was a share of what
        it cost (issue 29). What this gives depends on the bindings (:attr:`object_bindings_version` moves with
        every one made) and static catalogue data; the stored value is read at each use, as object_read does."""
        if index in self._object_bindings or index in LAZY_OBJECTS or index in self._object_builders:
            return None
        key = (index, subindex)
        plan = _READ_PLANS.get(key)
        if plan is None:
            plan = _read_plan(index, subindex)
        if plan.__class__ is int:
            return None
        return key, plan  # type: ignore[return-value]

    def object_write(self, index: int, subindex: int, data: bytes) -> None:
        entry = self.object_entry(index, subindex)
        if entry.access == "ro":
            raise SdoAccessError(ABORT_READ_ONLY)
        size = _entry_size(entry)
        if size is not None and len(data) != size:
            raise SdoAccessError(ABORT_TOO_LONG if len(data) > size else ABORT_TOO_SHORT)
        binding = self._object_binding(index)
        if binding and binding.write:
            binding.write(subindex, bytes(data))
        else:
            self.set_stored_object(index, subindex, data)
        self.writes += 1
        self.revision += 1

    # SDO information service (CoE service 8): the dictionary is the catalogue's (sim/object_info.py)
    def object_indices(self) -> list[int]:
        from akdctl.sim.object_info import object_indices

        return object_indices()

    def object_info(self, index: int) -> Any:
        from akdctl.sim.object_info import object_info

        return object_info(index)

    def object_value(self, index: int, subindex: int) -> int:
        """An integer object's current value (signed per its type), for components and tests."""
        entry = self.object_entry(index, subindex)
        data = self.object_read(index, subindex)
        return int.from_bytes(data, "little", signed=_entry_signed(entry))

    # ------------------------------------------------------------------ files (FoE)
    def foe_read(self, name: str, password: int) -> bytes:
        """FileAccess: a file written before (any password: the AKD's is not documented); FoeRefused otherwise."""
        return self.foe.read(name)

    def foe_write(self, name: str, password: int, data: bytes) -> None:
        """FileAccess: keep ``data`` as file ``name`` (docs/fidelity.md F10)."""
        self.foe.write(name, data)
        self.writes += 1
        self.revision += 1

    def named_value(self, name: str, default: int) -> int:
        """An AKD parameter kept by name (a face's parameter without a PNU or object), ``default`` until written."""
        return self.named_values.get(name, default)

    def set_named_value(self, name: str, value: int) -> None:
        self.named_values[name] = int(value)
        self.writes += 1
        self.revision += 1

    # ------------------------------------------------------------------ persistence
    def to_state(self) -> dict[str, Any]:
        """The persisted state; a component never built gives back the state it was loaded with, unread."""
        components: dict[str, Any] = {"motion": self.motion.to_state()}
        for name in LAZY:
            comp = self._built.get(name)
            if comp is None and name in self._pending:
                components[name] = self._pending[name]
            else:
                components[name] = (comp or self._build(name)).to_state()
        if self._recorder is not None:
            components["recorder"] = self._recorder.to_state()
        return {
            "version": STATE_VERSION,
            "clock": self.clock,
            "writes": self.writes,
            "pnus": {str(k): v for k, v in sorted(self.pnu_values.items())},
            "objects": {f"{i:04X}:{s:02X}": d.hex() for (i, s), d in sorted(self.object_values.items())},
            "named": dict(sorted(self.named_values.items())),
            "components": components,
        }

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> "DriveModel":
        """Rebuild a model; raises ``ValueError`` when the state is not ours or is damaged."""
        if not isinstance(state, dict) or state.get("version") != STATE_VERSION:
            raise ValueError("not an akdctl simulator state (unknown version)")
        model = cls()
        try:
            model.clock = float(state.get("clock", 0.0))
            model.writes = int(state.get("writes", 0))
            for key, values in dict(state.get("pnus", {})).items():
                if not isinstance(values, list) or not all(isinstance(v, int) for v in values):
                    raise ValueError(f"PNU {key}: values must be a list of integers")
                model.pnu_values[int(key)] = list(values)
            for key, hexdata in dict(state.get("objects", {})).items():
                index, _, sub = str(key).partition(":")
                model.object_values[(int(index, 16), int(sub, 16))] = bytes.fromhex(hexdata)
            for name, value in dict(state.get("named", {})).items():
                if not isinstance(value, int) or isinstance(value, bool):
                    raise ValueError(f"parameter {name}: the value must be an integer")
                model.named_values[str(name)] = value
            comp_states = dict(state.get("components", {}))
            model.motion.load_state(dict(comp_states.get("motion", {})))
            for name in LAZY:  # each is built (and its state read) on first use
                model._pending[name] = dict(comp_states.get(name, {}))
            if "recorder" in comp_states:
                model.recorder.load_state(dict(comp_states["recorder"]))
        except (TypeError, AttributeError, KeyError) as exc:
            raise ValueError(f"damaged simulator state: {exc}") from exc
        return model


# Identity of the simulated drive where the ESI gives no default (a real drive reports its own), built on first use:
# the identity record is imported only when an identity object is read (the PNU path never needs it).
_sim_object_defaults: dict[tuple[int, int], bytes] | None = None
_PRESET_KEYS = frozenset({(0x1008, 0), (0x1009, 0), (0x100A, 0), (0x2033, 0), (0x1018, 1), (0x1018, 2), (0x1018, 3),
                          (0x1018, 4), (0x36E8, 0)})  # the keys of sim_object_defaults(), known without building it


def sim_object_defaults() -> dict[tuple[int, int], bytes]:
    global _sim_object_defaults
    if _sim_object_defaults is None:
        from akdctl.sim import identity  # the one identity record (sim/identity.py, issue 23.8)

        _sim_object_defaults = {
            (0x1008, 0): b"AKD",
            (0x1009, 0): identity.HARDWARE_REVISION.encode(),
            (0x100A, 0): f"M_{identity.FIRMWARE}".encode(),
            (0x2033, 0): identity.ORDER_CODE.encode(),  # DRV.MODEL
            (0x1018, 1): (0x6A).to_bytes(4, "little"),  # Kollmorgen's EtherCAT vendor id (ESI)
            (0x1018, 2): (0x00414B44).to_bytes(4, "little"),  # product code "AKD" (ESI)
            # Revision and serial as the simulated ESC's SII reports them (the real AKD's SII dump): one identity
            # over CoE and SII (docs/fidelity.md F3), not the newest ESI revision 0x00260000.
            (0x1018, 3): identity.COE_REVISION.to_bytes(4, "little"),
            (0x1018, 4): identity.SERIAL.to_bytes(4, "little"),
            # FBUS.PARAM04 (synchronization supervision): "EtherCAT drive: enabled (1)" (EtherCAT manual 5.14); the
            # ESI gives 0, the CANopen drive's default. The simulated AKD is an EtherCAT drive (docs/fidelity.md).
            (0x36E8, 0): (1).to_bytes(4, "little"),
        }
    return _sim_object_defaults


def _entry_size(entry: Any) -> int | None:
    """Byte size of a fixed-size object entry; None for strings and octet strings."""
    if entry.short_type in ("vs", "os"):
        return None
    return entry.nbytes


def _entry_signed(entry: Any) -> bool:
    return entry.short_type.startswith("i")


#: What the catalogue makes of a read of a catalogued (index, subindex) without a binding: the abort code (an int)
#: of a write-only entry, else the default bytes. Catalogue data only (static: the catalogue and the simulator's
#: presets never change in a process), so no model's state can make a plan stale; tests/test_fast_paths.py holds
#: the plans equal to object_entry + _default_bytes for every catalogued address.
_READ_PLANS: dict[tuple[int, int], bytes | int] = {}


def _read_plan(index: int, subindex: int) -> bytes | int:
    from akdctl.catalog import objects as object_catalog

    entry = object_catalog.lookup(index, subindex)
    if entry is None:  # not kept: the plans hold the catalogue's entries only, whatever addresses a client sends
        return ABORT_NO_SUBINDEX if object_catalog.subentries(index) else ABORT_NO_OBJECT
    plan = ABORT_WRITE_ONLY if entry.access == "wo" else _default_bytes(entry)
    _READ_PLANS[(index, subindex)] = plan
    return plan


def _default_bytes(entry: Any) -> bytes:
    key = (entry.index, entry.subindex)
    preset = sim_object_defaults().get(key) if key in _PRESET_KEYS else None
    if preset is not None:
        return preset
    size = _entry_size(entry)
    default = entry.default
    if size is None:
        return b""
    if default is None and entry.subindex == 0:
        from akdctl.catalog import objects as object_catalog

        subs = object_catalog.subentries(entry.index)
        if len(subs) > 1:  # a record/array: sub 0 holds the highest sub-index
            default = max(e.subindex for e in subs)
    if entry.short_type == "r32":
        return struct.pack("<f", float(default or 0))
    if entry.short_type == "r64":
        return struct.pack("<d", float(default or 0))
    value = int(default or 0)
    return (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little")
