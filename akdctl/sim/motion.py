"""The simulated AKD's axis as a model component: one power stage, two word machines, one axis.

Why this module: an AKD has one power stage and one axis. PROFIdrive
(STW1/ZSW1, PNU 1/2) and CiA 402 (0x6040/0x6041) are two views of the same
state, so the component keeps the one state (``power_states``), lets either
word machine drive it (``stw1_machine``, ``cia402_machine``), moves the one
axis (``kinematics``) and binds all of it to the drive model's PNUs and
objects. Everything about *how* the words are read or the axis moves lives in
those modules; this one holds what they share: the power stage transitions,
the fault reaction, the drive parameters the axis asks for, and the watchdog.

Bounded motion (the drive-side watchdog): every access to a PNU or object this
component owns feeds a watchdog. When no access arrived for ``watchdog_s``
seconds of *wall* time (the virtual equivalent is ``watchdog_s × time scale``),
the drive ramps the axis to standstill on its own, raises the simulator's
warning n990 (ZSW1/statusword bit 7, 0x2000, an emergency), aborts the running traversing task and forgets the
level-triggered commands (jog bits, velocity set point) until the next control
word or set point write. A tool that dies (kill -9) or loses its link therefore
never leaves the simulated axis moving. ``watchdog_s = 0`` disables it.

The watchdog and "target reached": the aborted task was *not* completed, so
ZSW1 bit 10 (position mode) and CiA 402 statusword bit 10 (profile position)
stay clear short of its target (:attr:`Kinematics.at_target`). A
``move --no-wait`` therefore outlives its tool by at most ``watchdog_s`` of
wall time unless something keeps talking to the drive, and never reads as
arrived at the wrong position afterwards (docs/simulator.md).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akdctl.profiles import units
from akdctl.profiles.motion_tasks import MT_LOAD, MT_NUM, MT_SET
from akdctl.profiles.units import CIA_COUNTS_PER_REV
from akdctl.sim.component import ABORT_NO_SUBINDEX, ABORT_VALUE_RANGE, Component, FieldState
from akdctl.sim.errors import SdoAccessError
from akdctl.sim.power_states import CIA_WORD, ENABLED, FAULT, FAULT_REACTION, POWERED, QUICK_STOP, SOD

if TYPE_CHECKING:
    from akdctl.sim.cia402_machine import Cia402Machine
    from akdctl.sim.kinematics import Kinematics
    from akdctl.sim.model import DriveModel
    from akdctl.sim.stw1_machine import Stw1Machine
    from akdctl.sim.task_table import TaskTable

DEFAULT_FE_WINDOW_REV = 0.5  # ZSW1 bit 8 / SW bit 13 window when 0x6065 is 0
DEFAULT_WATCHDOG_S = 1.0
#: The simulated drive's peak current (DRV.IPEAK, Arms): the AKD x00606 size the identity record names
#: (6 A continuous, 18 A peak; [I] from Kollmorgen's catalogue, not from the seeds).
SIM_PEAK_CURRENT_A = 18.0
#: The warning the watchdog raises: a simulator-only number (catalog/data/faults.csv marks it so); a real AKD has
#: no watchdog on acyclic access, hence no warning for it (docs/fidelity.md F4).
WATCHDOG_WARNING = "n990"

#: The component's parts, built on first use (issue 29, cold start: ``pnu get 930`` reads the mode, which is the
#: component's own field, and needs no axis): name -> (module, class, the fields the part persists). The fields are a
#: copy of each class's ``FIELDS``, kept here so writing back a part never built imports nothing
#: (tests/test_sim_lazy.py fails when they differ). Listed in save order.
PARTS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "pd": ("akdctl.sim.stw1_machine", "Stw1Machine", ("stw1", "plc_control_allowed", "aktsatz", "frozen_vel")),
    "cia": ("akdctl.sim.cia402_machine", "Cia402Machine", ("controlword", "quick_stop_code")),
    "tasks": ("akdctl.sim.task_table", "TaskTable", ("tasks", "mt_num")),
    "axis": ("akdctl.sim.kinematics", "Kinematics", (
        "pos", "vel", "acc_now", "offset", "gen", "activity", "task", "task_paused", "last_target", "task_ack",
        "homed", "homing", "homing_error", "homing_done", "internal_limit")),
}

#: The objects the task table binds when it is built (MT.NUM, MT.LOAD, MT.SET; the numbers are profiles/motion_tasks).
TASK_TABLE_OBJECTS = (MT_NUM, MT_LOAD, MT_SET)


class MotionComponent(Component):
    """Power stage, word machines and axis of the simulated drive (contract: docs/internals.md)."""

    name = "motion"
    FIELDS = ("state", "stopping_to", "mode", "watchdog_s", "since_access", "watchdog_tripped", "quick_stop_option",
              "enabling_words")
    PERSISTED = ("last_writer",)

    def __init__(self, model: "DriveModel") -> None:
        super().__init__(model)
        self.state = SOD
        self.stopping_to: str | None = None  # state to enter when a ramp stop reaches standstill
        self.mode = 3  # 0x6060 (3 profile velocity ↔ PNU 930 = 1, the PNU's documented default)
        self.watchdog_s = DEFAULT_WATCHDOG_S
        self.since_access = 0.0
        self.watchdog_tripped = False
        self.quick_stop_option = 2  # the option code of the quick stop in progress (0x605A when CiA 402 began it)
        self.enabling_words = 0  # control words with "enable operation" received (tests: none without consent)
        self.last_writer = "pd"  # "pd" or "cia": whose ramps and homing speeds apply
        # The parts (PARTS) built so far, and the persisted state they are built from (from load_state; empty for
        # a new drive, whose parts start at their defaults)
        self._parts: dict[str, Any] = {}
        self._loaded: dict[str, Any] = {}
        self._bind()

    # ================================================================== parts, built on first use
    def _part(self, name: str) -> Any:
        """The part ``name``, built and given the loaded state on first use. Building is no change of persisted
        state (the part holds what the file held), so the model's and this component's revisions are kept: a read
        that builds a part never rewrites the file."""
        part = self._parts.get(name)
        if part is not None:
            return part
        import importlib

        module, cls, _ = PARTS[name]
        model = self.model
        revision, own = model.revision, self.revision
        part = vars(importlib.import_module(module))[cls](self)
        self._parts[name] = part
        part.load_state(self._loaded)
        if name == "tasks":
            part.bind()
        model.revision = revision
        self.__dict__["revision"] = own
        return part

    @property
    def axis(self) -> "Kinematics":
        return self._parts.get("axis") or self._part("axis")  # type: ignore[no-any-return]

    @property
    def pd(self) -> "Stw1Machine":
        return self._parts.get("pd") or self._part("pd")  # type: ignore[no-any-return]

    @property
    def cia(self) -> "Cia402Machine":
        return self._parts.get("cia") or self._part("cia")  # type: ignore[no-any-return]

    @property
    def tasks(self) -> "TaskTable":
        return self._parts.get("tasks") or self._part("tasks")  # type: ignore[no-any-return]

    def _resting_unbuilt_axis(self) -> bool:
        """The axis was never built and its loaded state has nothing to integrate (no velocity, no acceleration,
        no set point generator): a tick need not build it. Anything else builds it and asks it."""
        loaded = self._loaded
        return ("axis" not in self._parts and loaded.get("gen") is None and not loaded.get("vel")
                and not loaded.get("acc_now"))

    # ================================================================== contract
    @property
    def standstill(self) -> bool:
        return self.axis.standstill

    @property
    def position_counts(self) -> int:
        return self._position_counts(self.axis.pos, self.axis.offset)

    def _position_counts(self, pos: float, offset: float) -> int:
        return round((pos + offset) * self.counts_per_rev)

    @property
    def velocity_rpm(self) -> float:
        return _rpm(self.axis.vel)

    def on_fault(self, code: str) -> None:
        """A fault was raised: react at once (fault reaction = quick stop, then power off)."""
        if code.lower().startswith("n"):
            return
        from akdctl.sim.kinematics import COAST_RPM_S, QUICK_STOP_RPM_S

        axis = self.axis
        axis.abort_tasks(error=True)
        self.pd.frozen_vel = None
        if self.state in (ENABLED, QUICK_STOP) and not axis.at_rest():
            self.state = FAULT_REACTION
            axis.ramp_to_zero(QUICK_STOP_RPM_S, "fault")
        else:
            self.state = FAULT
            if not axis.at_rest():
                axis.ramp_to_zero(COAST_RPM_S, "coast")
        self.stopping_to = None

    # ================================================================== shared by both word machines
    @property
    def counts_per_rev(self) -> int:
        return 1 << self.model.stored_pnu(1002)[0]

    @property
    def opmode(self) -> int:
        """PNU 930 (DRV.OPMODE) derived from the CiA 402 mode."""
        return self._opmode()

    def _opmode(self) -> int:
        return _OPMODE.get(self.mode, 2)

    def set_opmode(self, value: int) -> bool:
        """DRV.OPMODE written, by PNU 930 or its object 35B4h (0 torque, 1 velocity, 2 position; the caller checked
        the range): the one rule of both. False, and nothing changed, unless the axis stands still and is not homing;
        a different mode drops the kept motion task. Each caller answers a refusal in its own protocol."""
        axis = self.axis
        if not axis.at_rest() or axis.homing is not None:
            return False
        if OPMODE_TO_CIA[value] != self.mode and self._opmode() != value:
            axis.forget_task()
            self.mode = OPMODE_TO_CIA[value]
        self.model.set_stored_pnu(930, [value])
        return True

    @property
    def fault_present(self) -> bool:
        return bool(self.model.faults.fault_present)

    @property
    def warning_present(self) -> bool:
        return bool(self.model.faults.warning_present) or self.watchdog_tripped

    def clear_watchdog(self) -> None:
        """A new command (control word, set point, acknowledge): the watchdog's stop and its warning end."""
        if self.watchdog_tripped:
            self.watchdog_tripped = False
            self.model.faults.clear_warning(WATCHDOG_WARNING)

    def feed(self, writer: str | None = None) -> None:
        """An access to the axis: feed the watchdog; a control word write also says whose ramps apply."""
        if self.since_access:
            self.since_access = 0.0
        if writer is not None:
            self.last_writer = writer

    def acknowledge(self) -> None:
        self.model.faults.acknowledge()
        self.clear_watchdog()
        if self.state in (FAULT, FAULT_REACTION) and not self.fault_present and self.axis.at_rest():
            self.state = SOD
            self.axis.activity = "idle"

    def apply_control_word(self, old: int, new: int, general: Callable[[int], None],
                           mode_bits: Callable[[int, int], None]) -> None:
        """The order both word machines share once a word is honoured (and acknowledge handled): no transition
        in fault; the general state transitions; then, in operation, the mode-specific bits."""
        if self.state in (FAULT, FAULT_REACTION):
            return
        general(new)
        if self.state == ENABLED and self.stopping_to is None:
            mode_bits(old, new)

    def coast_off(self) -> None:
        """OFF2 / disable voltage: pulses off, a moving motor coasts down, switch on disabled."""
        if self.state in (ENABLED, QUICK_STOP) and not self.axis.at_rest():
            from akdctl.sim.kinematics import COAST_RPM_S

            self.axis.abort_tasks()
            self.axis.ramp_to_zero(COAST_RPM_S, "coast")
        self.state, self.stopping_to = SOD, None

    def enable_blocked(self) -> bool:
        """A cause outside the control word keeps the power stage off: a disable source injected into
        DRV.DISSOURCES (``sim set``: hardware enable low, in-rush, ...) or STO low (warning n602)."""
        return bool(self.injected_dissources()) or 602 in self.model.faults.warnings

    def injected_dissources(self) -> int:
        return int.from_bytes(self.model.stored_object(0x3443, 0), "little") & ~0b11

    def dissources(self) -> int:
        """DRV.DISSOURCES as the simulator shows it: bit 0 while not enabled (software disable), bit 1 while a
        fault is present, plus the injected bits (reference/akd-ascii-channel.md, bits [G1]/[A1])."""
        value = self.injected_dissources()
        if self.state != ENABLED:
            value |= 1
        if self.fault_present:
            value |= 2
        return value

    def enter_enabled(self) -> None:
        if self.enable_blocked():
            return  # the drive stays where it was, as a real AKD with its enable input low does
        self.state = ENABLED
        self.stopping_to = None
        self.axis.internal_limit = False
        self.axis.homing_error = False if self.axis.homing is None else self.axis.homing_error

    def leave_enabled(self, to: str) -> None:
        """Disable operation / shut down from ENABLED: brake along the ramp, then enter ``to``."""
        self.axis.abort_tasks()
        self.stopping_to = to
        if self.axis.at_rest():
            self.state, self.stopping_to = to, None
        else:
            self.axis.stop_motion(quick=False, activity="stop")

    def stop_complete(self) -> None:
        """A stop ramp reached standstill (:class:`KinematicsHost`): the power stage takes its next state."""
        if self.state == FAULT_REACTION:
            self.state = FAULT
        elif self.state == QUICK_STOP:
            if self.quick_stop_option not in (5, 6, 7, 8):
                self.state = SOD  # options 5..8 stay in quick stop active
        elif self.stopping_to is not None and self.state == ENABLED:
            self.state = self.stopping_to
        self.stopping_to = None

    # ================================================================== drive parameters (KinematicsHost)
    def _obj(self, index: int, sub: int = 0) -> int:
        return self.model.object_value(index, sub)

    def soft_limits(self) -> tuple[float, float] | None:
        """Software position limits 0x607D (physical rev); None when both are 0 (disabled)."""
        lo, hi = self._obj(0x607D, 1), self._obj(0x607D, 2)
        if lo == 0 and hi == 0:
            return None
        return lo / CIA_COUNTS_PER_REV - self.axis.offset, hi / CIA_COUNTS_PER_REV - self.axis.offset

    def fe_window(self) -> float:
        window = self._obj(0x6065)
        return window / CIA_COUNTS_PER_REV if window else DEFAULT_FE_WINDOW_REV

    def ramp_dec_rpm_s(self) -> float:
        from akdctl.sim.kinematics import DEFAULT_RAMP_RPM_S

        dec = self.model.signed_pnu(1007)[0] if self.last_writer == "pd" \
            else self._obj(0x6084) * 60.0 / CIA_COUNTS_PER_REV
        return float(dec) if dec > 0 else DEFAULT_RAMP_RPM_S

    def homing_profile(self) -> tuple[float, float, float]:
        from akdctl.sim.kinematics import DEFAULT_RAMP_RPM_S, HOMING_FAST_RPM, HOMING_SLOW_RPM, rpm_s

        if self.last_writer == "cia":
            fast, slow = self._obj(0x6099, 1) / CIA_COUNTS_PER_REV, self._obj(0x6099, 2) / CIA_COUNTS_PER_REV
            acc = self._obj(0x609A) / CIA_COUNTS_PER_REV
        else:
            fast = slow = acc = 0.0
        return fast or HOMING_FAST_RPM / 60.0, slow or HOMING_SLOW_RPM / 60.0, acc or rpm_s(DEFAULT_RAMP_RPM_S)

    def home_offset_rev(self) -> float:
        return self._obj(0x607C) / CIA_COUNTS_PER_REV

    # ================================================================== time
    def tick(self, dt: float) -> None:
        faults = self.model.faults
        if faults.fault_present and self.state not in (FAULT, FAULT_REACTION):
            codes = [c for c in faults.active() if not c.lower().startswith("n")]
            self.on_fault(codes[0] if codes else "F0")
        if self._resting_unbuilt_axis():  # at rest, nothing to integrate (as below) without building the axis
            if self.since_access:
                self.since_access = 0.0
            return
        axis = self.axis
        if axis.at_rest():
            # The watchdog only guards motion; a resting axis keeps a constant state, so an idle
            # drive's state file need not be rewritten on every read (SimDrive saves on change).
            if self.since_access:
                self.since_access = 0.0
            if not (axis.vel or axis.acc_now):
                return  # nothing moves, nothing to integrate
        elif self.watchdog_s > 0 and axis.activity not in _stopping():
            threshold = self.watchdog_s * float(self.model.time_scale or 1.0)
            remaining = threshold - self.since_access
            if dt > remaining:
                before = max(0.0, remaining)
                axis.integrate(before)
                self._watchdog_trip()
                self.since_access += before
                dt -= before
        if not axis.at_rest():
            self.since_access += dt
        axis.integrate(dt)

    def still(self) -> bool:
        """A tick would change nothing, whatever its length: no fault waiting for its reaction, the watchdog not
        counting, the axis at rest with nothing to integrate (built or not) -- :meth:`tick`'s early returns."""
        if self.since_access:
            return False
        if self.state not in (FAULT, FAULT_REACTION) and self.model.faults.fault_present:
            return False
        if self._resting_unbuilt_axis():
            return True
        axis = self.axis
        return axis.at_rest() and not (axis.vel or axis.acc_now)

    def _watchdog_trip(self) -> None:
        """No request for ``watchdog_s`` wall seconds while moving: ramp to standstill on our own, and say why
        with the simulator's own warning (ZSW1/statusword bit 7, 0x2000, an EMCY; docs/fidelity.md F4)."""
        self.watchdog_tripped = True
        self.model.faults.raise_fault(WATCHDOG_WARNING)
        self.pd.frozen_vel = None
        self.axis.abort_tasks(error=True)
        self.axis.stop_motion(quick=False, activity="stop")

    # ================================================================== bindings
    def _bind(self) -> None:
        # The parts are named through self at each call (they are built on first use), never held here.
        m = self.model

        def pnu_reader(func: Any) -> Any:
            def read(sub: int, count: int) -> list[int]:
                if self.since_access:  # feed()'s test first: a poll's reads find the watchdog fed (one call less)
                    self.feed()
                return [func()]
            return read

        m.bind_pnu(1, read=pnu_reader(lambda: self.pd.stw1),
                   write=lambda sub, values: self.pd.write_stw1(sub, values))
        m.bind_pnu(2, read=pnu_reader(lambda: self.pd.zsw1()))
        m.bind_pnu(5, write=lambda sub, values: self.pd.write_nsoll(sub, values))
        m.bind_pnu(6, read=pnu_reader(lambda: units.rpm_to_x(max(-12000.0, min(12000.0, self.velocity_rpm)), 15)))
        m.bind_pnu(4, read=pnu_reader(lambda: 0))  # ZSW2: no clock synchronism, so no slave sign of life
        m.bind_pnu(28, read=pnu_reader(lambda: _clamp32(self.position_counts)))  # XIST_A, 2^PNU1002 per rev
        m.bind_pnu(33, read=pnu_reader(lambda: self.pd.aktsatz))
        m.bind_pnu(52, read=pnu_reader(lambda: round(self._current_fraction() * (1 << 14))))
        m.bind_pnu(930, read=pnu_reader(self._opmode),
                   write=lambda sub, values: self.pd.write_opmode(sub, values))

        def obj_reader(fmt: str, func: Any) -> Any:
            def read(sub: int) -> bytes:
                if sub != 0:
                    raise SdoAccessError(ABORT_NO_SUBINDEX)
                self.feed()
                return struct.pack(fmt, func())
            return read

        def counts(rev: float) -> int:
            return _clamp32(round(rev * CIA_COUNTS_PER_REV))

        m.bind_object(0x6040, read=obj_reader("<H", lambda: self.cia.controlword),
                      write=lambda sub, data: self.cia.write_controlword(sub, data))
        m.bind_object(0x6041, read=obj_reader("<H", lambda: self.cia.statusword()))
        m.bind_object(0x6060, read=obj_reader("<b", lambda: self.mode),
                      write=lambda sub, data: self.cia.write_mode(sub, data))
        m.bind_object(0x6061, read=obj_reader("<b", lambda: self.mode))
        m.bind_object(0x6063, read=obj_reader("<i", lambda: counts(self.axis.pos + self.axis.offset)))
        m.bind_object(0x6064, read=obj_reader("<i", lambda: counts(self.axis.pos + self.axis.offset)))
        m.bind_object(0x606C, read=obj_reader("<i", lambda: counts(self.axis.vel)))
        m.bind_object(0x606B, read=obj_reader("<i", lambda: counts(self.axis.vel)))  # velocity demand (VL.CMD)
        m.bind_object(0x6077, read=obj_reader("<h", lambda: round(self._current_fraction() * 1000)))
        m.bind_object(0x60F4, read=obj_reader("<i", lambda: counts(self.axis.following_error)))
        # The AKD names of the same actual values (issue 23.7): one live value, every address of it.
        # VL.FB is 3618h *and* 606Ch [V reference/akd-parameter-names.md, G1]: the same reader.
        m.bind_object(0x3618, read=obj_reader("<i", lambda: counts(self.axis.vel)))
        # DRV.OPMODE is 35B4h and PNU 930 [V reference/akd-parameter-names.md]: one operating mode, so the object
        # reads and writes what PNU 930 does (a stored copy read 0 beside PNU 930's 1 on a factory drive)
        m.bind_object(0x35B4, read=obj_reader("<I", self._opmode),
                      write=lambda sub, data: self.cia.write_opmode_object(sub, data))
        # HOME.MODE is 50CBh and "available also via PNU 1001" [V reference/akd-parameter-names.md, section 3]: the
        # object is the PNU's stored value, not a second copy of it
        m.bind_object(0x50CB, read=obj_reader("<I", lambda: self.model.stored_pnu(1001)[0]),
                      write=self._write_home_mode_object)
        # Actual current: 2077h is scaled in mA [V seed 001, "Actual Current 0x2077 sub 0, 32 bit, scaled in mA"];
        # IL.FB 3558h in the 1000:1 float scaling of the AKD's CoE objects [I: its own scale row was not read].
        m.bind_object(0x2077, read=obj_reader("<i", self.current_ma))
        m.bind_object(0x3558, read=obj_reader("<i", self.current_ma))
        # PL.ERR is the following error 60F4h shows [I: same quantity, same counts assumed].
        m.bind_object(0x35C5, read=obj_reader("<i", lambda: counts(self.axis.following_error)))
        m.bind_object(0x5084, read=obj_reader("<I", lambda: round(SIM_PEAK_CURRENT_A * 1000)))  # DRV.IPEAK, 1000:1 [I]
        m.bind_object(0x60FC, read=obj_reader("<i", lambda: counts(self.axis.demand + self.axis.offset)))
        m.bind_object(0x60FF, write=lambda sub, data: self.cia.write_target_velocity(sub, data))
        # torque mode (4), interpolated position (7), profile position (1) and CSP (8)
        m.bind_object(0x6071, write=lambda sub, data: self.cia.write_target_torque(sub, data))
        m.bind_object(0x60C1, write=lambda sub, data: self.cia.write_ip_setpoint(sub, data))
        m.bind_object(0x607A, write=lambda sub, data: self.cia.write_target_position(sub, data))
        m.bind_object(0x605A, read=lambda sub: self.cia.read_quick_stop_code(sub),
                      write=lambda sub, data: self.cia.write_quick_stop_code(sub, data))
        # 0x6502 lists the modes 0x6060 accepts (EtherCAT manual 5.8 table: 1, 3, 4, 6, 7, 8)
        m.bind_object(0x6502, read=obj_reader("<I", _drive_modes_word))
        m.bind_object(0x3443, read=obj_reader("<H", self.dissources))
        # The task table binds its own objects (sim/task_table.py) when built; these are the ones it binds
        # (tests/test_sim_lazy.py checks it), so the first access to one builds it
        for index in TASK_TABLE_OBJECTS:
            m.bind_object_later(index, lambda: self.tasks)

    def _write_home_mode_object(self, sub: int, data: bytes) -> None:
        """HOME.MODE by 50CBh (UDINT): stored as PNU 1001, within the PNU's range, as a PNU 1001 write stores it."""
        if sub != 0:
            raise SdoAccessError(ABORT_NO_SUBINDEX)
        value = struct.unpack("<I", data)[0]
        low, high = self.model.pnu_info(1001).limits()
        if not low <= value <= high:
            raise SdoAccessError(ABORT_VALUE_RANGE)
        self.model.set_stored_pnu(1001, [value])

    def current_ma(self) -> int:
        """The actual current in mA (signed, as a fraction of the simulated drive's peak current)."""
        return round(self._current_fraction() * SIM_PEAK_CURRENT_A * 1000)

    def _current_fraction(self) -> float:
        """A plausible current: acceleration torque plus a little friction, as a fraction of peak."""
        if self.state not in POWERED:
            return 0.0
        return self.axis.torque_fraction()

    # ================================================================== persistence
    def to_state(self) -> dict[str, Any]:
        """One flat dict (the keys of the state files written before the split, so old files load)."""
        data = FieldState.to_state(self)
        loaded = self._loaded
        for name, (_, _, fields) in PARTS.items():  # a part never built writes back what it was loaded with
            part = self._parts.get(name)
            if part is None and all(key in loaded for key in fields):
                data.update((key, loaded[key]) for key in fields)
            else:
                data.update((part or self._part(name)).to_state())
        data["last_writer"] = self.last_writer
        # for `sim show`; ignored on load
        data["position_counts"] = self._position_counts(data["pos"], data["offset"])
        data["velocity_rpm"] = round(_rpm(data["vel"]), 6)
        return data

    def load_state(self, state: dict[str, Any]) -> None:
        FieldState.load_state(self, state)
        self._loaded = state
        for part in self._parts.values():
            part.load_state(state)
        if state.get("last_writer") in ("pd", "cia"):
            self.last_writer = state["last_writer"]
        if self.state not in CIA_WORD:
            raise ValueError(f"motion state {self.state!r} is not a drive state")


_OPMODE = {4: 0, 3: 1}  # CiA 402 mode -> DRV.OPMODE (torque 0, velocity 1, any position mode 2)
#: DRV.OPMODE (PNU 930, 35B4h) -> the CiA 402 mode of the one axis (0 torque, 1 velocity, 2 profile position).
OPMODE_TO_CIA = {0: 4, 1: 3, 2: 1}


def _clamp32(value: int) -> int:
    return max(-(1 << 31), min((1 << 31) - 1, value))


def _stopping() -> tuple[str, ...]:
    from akdctl.sim.kinematics import STOPPING

    return STOPPING


def _drive_modes_word() -> int:
    """0x6502: the modes the CiA 402 machine accepts, as the object's bit field."""
    from akdctl.profiles import statusword as sw
    from akdctl.sim.cia402_machine import MODES

    return sw.drive_modes_word(MODES)


def _rpm(rev_s: float) -> float:
    return rev_s * 60.0
