"""The simulated AKD's CIP objects, acting on the same simulated drive as every other face.

Why a translation layer and not a second axis: an AKD has one power stage, and the simulator
keeps one (``sim/motion.py``). The Position Controller object and the I/O assemblies here turn
CIP requests into the CiA 402 object accesses of that one model (controlword 0x6040, mode 0x6060,
targets 0x607A/0x60FF/0x6081, homing 0x6098), inside a ``SimDrive`` transaction, so ``akdctl
status`` over any other face sees what an EtherNet/IP client did.

What is verified and what is inferred (reference/ethernetip.md; [I] = inferred, unverified):

* Parameter object 0x0F, attributes 1 value / 5 type / 6 length, the AKD manual's error codes
  0x0E / 0x14 / 0x08 / 0x16 / 0x09 [V]; instances modelled: EIP.POSUNIT 796, EIP.PROFUNIT 797
  (default 65536), HOME.MOVE 205 (a command: a 1-byte Set runs it) [V].
* Position Controller 0x25 attributes of appendix A [V]; 12 on-target, 13 actual position and
  14 actual velocity follow the ODVA position-controller profile [I]. Positions are scaled so that
  EIP.POSUNIT counts make one revolution and velocities so that EIP.PROFUNIT counts/s make one rev/s [I].
* Supervisor 0x24 attributes 1, 2, 3 (axis number) and 5 (general fault) [I: ODVA/Moog/Yaskawa].
* Identity, TCP/IP 0xF5, Ethernet Link 0xF6, Message Router: the standard CIP sets [I: no AKD tables].
* I/O: assemblies 100 (config, 0 B), 101 (command, 64 B, run/idle header [I instance]), 102
  (response, 64 B) and the Load/Start -> Load Complete handshake [V]; command types 1/5/6/7/8 [V].
  Status word 1 carries only bits 7 Enabled and 2 In Position [V] plus 3 General Fault and 0 In
  Motion [I]; bit 5 "Homed" [I] is left clear because the manual's own example shows 0x84 for an
  enabled axis about to take a position command, which must be homed [M-11].

The unknown-class answer is 0x16 as the AKD manual says (OpENer answers 0x05; clients accept both).
"""

from __future__ import annotations

import struct
import threading
from dataclasses import dataclass
from typing import Any

from akdctl.catalog import eip_parameters
from akdctl.protocol import akd_assembly as asm
from akdctl.protocol import cip
from akdctl.protocol.errors import CodecError
from akdctl.sim.errors import SdoAccessError

CIA_COUNTS = 65536
DEFAULT_UNIT = 65536
SIM_RATED_MA = 3000                      # the simulated motor's rated current (for response type 5)
HOMING_METHODS = {0: 35, 1: 17, 2: 1, 3: 19, 4: 3, 5: 34}   # AKD HOME.MODE -> a CiA 402 method of the same procedure
PC_MODES = {0: 1, 1: 3, 2: 4}            # Position Controller mode -> 0x6060
PC_ATTRS = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 17, 25, 58, 100, 101)
SUPERVISOR_ATTRS = (1, 2, 3, 5)

# simulated-model refusals (CiA 301 aborts) in CIP words
_ABORT_TO_CIP = {0x08000022: cip.DEVICE_STATE_CONFLICT, 0x06090030: cip.INVALID_ATTRIBUTE_VALUE,
                 0x06090031: cip.INVALID_ATTRIBUTE_VALUE, 0x06090032: cip.INVALID_ATTRIBUTE_VALUE}


class CipRefusal(Exception):
    def __init__(self, status: int, extended: tuple[int, ...] = ()) -> None:
        super().__init__(f"CIP status 0x{status:02X}")
        self.status = status
        self.extended = extended


@dataclass
class IdentitySettings:
    """What the Identity object and ListIdentity report; configurable (no public AKD EDS, [I])."""

    vendor: int = 452                    # "Kollmorgen" in pycomm3's vendor table [I]
    device_type: int = 0x10              # position controller [I]
    product_code: int = 1                # [I]
    revision: tuple[int, int] = (1, 18)
    serial: int = 0x00AD0001
    product_name: str = "AKD-P00306-NBEI-0000 (simulated)"

    @classmethod
    def parse(cls, text: str | None) -> "IdentitySettings":
        from akdctl.errors import UsageError

        settings = cls()
        if not text:
            return settings
        for item in text.split(","):
            key, sep, value = item.strip().partition("=")
            try:
                if key == "name" and sep:
                    settings.product_name = value
                elif key in ("vendor", "device_type", "product_code", "serial") and sep:
                    setattr(settings, key, int(value, 0))
                elif key == "revision" and sep:
                    major, _, minor = value.partition(".")
                    settings.revision = (int(major), int(minor or "0"))
                else:
                    raise ValueError(item)
            except ValueError:
                raise UsageError(f"--eip-identity {text!r}: expected vendor=N,device_type=N,product_code=N,"
                                 "revision=MAJOR.MINOR,serial=N,name=TEXT") from None
        return settings


@dataclass
class _PcState:
    """Position Controller attributes that live in the EtherNet/IP interface (volatile, per face)."""

    target_position: int = 0
    target_velocity: int = 0
    acceleration: int = 0
    deceleration: int = 0
    incremental: bool = False
    handshake: bool = False
    load_complete: bool = False
    torque: int = 0
    home_mode: int = 0
    posunit: int = DEFAULT_UNIT
    profunit: int = DEFAULT_UNIT


@dataclass
class IoState:
    last_control: int | None = None
    load_complete: bool = False
    error: asm.CommandError | None = None


class CipDevice:
    """Answers CIP explicit requests and I/O cycles; one lock serialises every access to the drive."""

    def __init__(self, drive: Any, identity: IdentitySettings | None = None,
                 address: tuple[str, int] = ("127.0.0.1", 44818)) -> None:
        self.drive = drive
        self.identity = identity or IdentitySettings()
        self.address = address
        self.lock = threading.RLock()
        self.pc = _PcState()
        self.io = IoState()
        self.requests = 0

    # ================================================================ explicit messages
    def handle(self, message: bytes) -> bytes:
        """One Message Router request -> its reply bytes. Never raises."""
        try:
            req = cip.Request.decode(message)
        except CodecError:
            service = message[0] & 0x7F if message else 0
            return cip.Response(service, cip.PATH_SEGMENT_ERROR).encode()
        try:
            path = cip.decode_path(req.path)
        except CodecError:
            return cip.Response(req.service, cip.PATH_SEGMENT_ERROR).encode()
        try:
            with self.lock:
                self.requests += 1
                data = self._dispatch(req.service, path, req.data)
            return cip.Response(req.service, cip.SUCCESS, (), data).encode()
        except CipRefusal as exc:
            return cip.Response(req.service, exc.status, exc.extended).encode()
        except Exception:  # noqa: BLE001 - a face survives any per-request error
            return cip.Response(req.service, cip.DEVICE_STATE_CONFLICT).encode()

    def _dispatch(self, service: int, path: cip.Path, data: bytes) -> bytes:
        handlers = {cip.IDENTITY: self._identity, cip.MESSAGE_ROUTER: self._router,
                    cip.PARAMETER: self._parameter, cip.POSITION_CONTROLLER: self._position_controller,
                    cip.POSITION_CONTROLLER_SUPERVISOR: self._supervisor, cip.TCPIP: self._tcpip,
                    cip.ETHERNET_LINK: self._ethernet_link, cip.ASSEMBLY: self._assembly}
        handler = handlers.get(path.class_id)
        if handler is None:
            raise CipRefusal(cip.OBJECT_DOES_NOT_EXIST)
        if service not in (cip.GET_ATTRIBUTE_SINGLE, cip.SET_ATTRIBUTE_SINGLE, cip.GET_ATTRIBUTES_ALL):
            raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)
        return handler(service, path, data)

    @staticmethod
    def _single(service: int, path: cip.Path, attrs: dict[int, bytes], settable: dict[int, Any] | None = None,
                data: bytes = b"") -> bytes:
        if path.instance != 1:
            raise CipRefusal(cip.OBJECT_DOES_NOT_EXIST)
        if service == cip.GET_ATTRIBUTES_ALL:
            raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)
        if path.attribute is None or path.attribute not in attrs:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)
        if service == cip.GET_ATTRIBUTE_SINGLE:
            return attrs[path.attribute]
        setter = (settable or {}).get(path.attribute)
        if setter is None:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SETTABLE)
        size = len(attrs[path.attribute])
        if len(data) < size:
            raise CipRefusal(cip.NOT_ENOUGH_DATA)
        if len(data) > size:
            raise CipRefusal(cip.TOO_MUCH_DATA)
        setter(data)
        return b""

    # ---------------------------------------------------------------- standard objects
    def identity_attributes(self) -> cip.IdentityAttributes:
        ident = self.identity
        # CIP Identity status word (standard meaning; what an AKD sets is not documented [I]): bit 2 configured,
        # bits 4-7 extended status (3 = no I/O connection, 6 = an I/O connection in run), bit 10 major
        # recoverable fault while the drive reports a fault
        status = 0x0004 | (0x0060 if self.io.last_control is not None else 0x0030) | (0x0400 if self._fault() else 0)
        return cip.IdentityAttributes(ident.vendor, ident.device_type, ident.product_code, ident.revision,
                                      status, ident.serial, ident.product_name)

    def _identity(self, service: int, path: cip.Path, data: bytes) -> bytes:
        attrs = self.identity_attributes()
        if service == cip.GET_ATTRIBUTES_ALL:
            if path.instance != 1 or path.attribute is not None:
                raise CipRefusal(cip.OBJECT_DOES_NOT_EXIST if path.instance != 1 else cip.INVALID_PARAMETER)
            return attrs.encode()
        values = {1: struct.pack("<H", attrs.vendor), 2: struct.pack("<H", attrs.device_type),
                  3: struct.pack("<H", attrs.product_code), 4: bytes(attrs.revision),
                  5: struct.pack("<H", attrs.status), 6: struct.pack("<I", attrs.serial),
                  7: cip.short_string(attrs.product_name)}
        if service == cip.SET_ATTRIBUTE_SINGLE and path.attribute in values:
            raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)   # as OpENer answers a Set on Identity
        return self._single(service, path, values)

    def _router(self, service: int, path: cip.Path, data: bytes) -> bytes:
        classes = (cip.IDENTITY, cip.MESSAGE_ROUTER, cip.ASSEMBLY, cip.CONNECTION_MANAGER, cip.PARAMETER,
                   cip.POSITION_CONTROLLER_SUPERVISOR, cip.POSITION_CONTROLLER, cip.TCPIP, cip.ETHERNET_LINK)
        return self._single(service, path, {1: struct.pack(f"<H{len(classes)}H", len(classes), *classes)})

    def _tcpip(self, service: int, path: cip.Path, data: bytes) -> bytes:
        import ipaddress

        host = self.address[0]
        try:
            ip = int(ipaddress.IPv4Address(host))
        except ValueError:
            ip = 0
        config = struct.pack("<IIIII", ip, 0xFFFFFF00, 0, 0, 0) + struct.pack("<H", 0)
        return self._single(service, path, {1: struct.pack("<I", 1), 2: struct.pack("<I", 0x14),
                                            3: struct.pack("<I", 0), 4: bytes.fromhex("0200 20F6 2401"),
                                            5: config, 6: struct.pack("<H", 0)})

    def _ethernet_link(self, service: int, path: cip.Path, data: bytes) -> bytes:
        return self._single(service, path, {1: struct.pack("<I", 100), 2: struct.pack("<I", 0x0F),
                                            3: bytes.fromhex("02 00 00 00 AD 01")})

    def _assembly(self, service: int, path: cip.Path, data: bytes) -> bytes:
        if path.instance not in (asm.CONFIG_INSTANCE, asm.OUTPUT_INSTANCE, asm.INPUT_INSTANCE):
            raise CipRefusal(cip.OBJECT_DOES_NOT_EXIST)
        if service != cip.GET_ATTRIBUTE_SINGLE:
            raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)
        if path.attribute != 3:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)
        if path.instance == asm.CONFIG_INSTANCE:
            return b""
        if path.instance == asm.INPUT_INSTANCE:
            return self._response_assembly(None).encode()
        return bytes(asm.ASSEMBLY_SIZE)

    # ---------------------------------------------------------------- Parameter object 0x0F
    def _parameter(self, service: int, path: cip.Path, data: bytes) -> bytes:
        if service == cip.GET_ATTRIBUTES_ALL:
            raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)
        instance = path.instance or 0
        modelled = {eip_parameters.by_name(name).instance: key  # type: ignore[union-attr]
                    for name, key in (("EIP.POSUNIT", "posunit"), ("EIP.PROFUNIT", "profunit"), ("HOME.MOVE", "home"))}
        if instance not in modelled:
            return self._named_parameter(service, path, data, instance)
        command = modelled[instance] == "home"
        attrs = {1: b"\x00" if command else struct.pack("<I", getattr(self.pc, modelled[instance])),
                 5: bytes([0xC6 if command else 0xC8]), 6: bytes([1 if command else 4])}
        if path.attribute not in attrs:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)
        if service == cip.GET_ATTRIBUTE_SINGLE:
            return attrs[path.attribute]   # reading a command does not run it [M-26]
        if path.attribute != 1:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SETTABLE)
        if len(data) != len(attrs[1]):
            raise CipRefusal(cip.NOT_ENOUGH_DATA if len(data) < len(attrs[1]) else cip.TOO_MUCH_DATA)
        if command:
            self._start_homing()
            return b""
        value = struct.unpack("<I", data)[0]
        if not 1 <= value <= 1 << 31:        # range 0..2^31 [M-21]; 0 would divide by zero
            raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
        setattr(self.pc, modelled[instance], value)
        return b""

    def _named_parameter(self, service: int, path: cip.Path, data: bytes, instance: int) -> bytes:
        """Any other catalogue parameter with a number ``n``: served from the one drive model by name
        (:mod:`akdctl.sim.akd_params`), 4 bytes, floats x1000 (issue 24)."""
        from akdctl.sim import akd_params as store

        row = store.by_number(instance)
        if row is None or row.is_command or row.kind in ("text", "string"):
            raise CipRefusal(cip.OBJECT_DOES_NOT_EXIST)
        signed = row.kind == "float" or not row.coe_type.startswith("u")
        if path.attribute in (5, 6):
            if service != cip.GET_ATTRIBUTE_SINGLE:
                raise CipRefusal(cip.ATTRIBUTE_NOT_SETTABLE)
            return bytes([0xC4 if signed else 0xC8]) if path.attribute == 5 else b"\x04"
        if path.attribute != 1:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)
        with self._model() as model:
            try:
                if service == cip.GET_ATTRIBUTE_SINGLE:
                    return (store.wire(model, row) & 0xFFFFFFFF).to_bytes(4, "little")
                if len(data) != 4:
                    raise CipRefusal(cip.NOT_ENOUGH_DATA if len(data) < 4 else cip.TOO_MUCH_DATA)
                store.write_wire(model, row, int.from_bytes(data, "little", signed=signed))
            except store.ParamError:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE) from None
        return b""

    # ---------------------------------------------------------------- model access
    def _model(self) -> Any:
        return self.drive.transaction()

    def _fault(self) -> bool:
        with self._model() as model:
            return bool(model.object_value(0x6041, 0) & 0x08)

    def _write(self, model: Any, index: int, fmt: str, value: int) -> None:
        try:
            model.object_write(index, 0, struct.pack(fmt, value))
        except SdoAccessError as exc:
            raise CipRefusal(_ABORT_TO_CIP.get(exc.code, cip.OBJECT_STATE_CONFLICT)) from None

    def _cia_pos(self, eip: int) -> int:
        return round(eip * CIA_COUNTS / self.pc.posunit)

    def _cia_vel(self, eip: int) -> int:
        return round(eip * CIA_COUNTS / self.pc.profunit)

    def _eip_pos(self, cia: int) -> int:
        return _clamp32(round(cia * self.pc.posunit / CIA_COUNTS))

    def _eip_vel(self, cia: int) -> int:
        return _clamp32(round(cia * self.pc.profunit / CIA_COUNTS))

    def _ensure_mode(self, model: Any, cia_mode: int) -> None:
        if model.object_value(0x6061, 0) != cia_mode:
            self._write(model, 0x6060, "<b", cia_mode)

    def _enable(self, on: bool) -> None:
        with self._model() as model:
            state = model.object_value(0x6041, 0) & 0x6F
            if on:
                if model.object_value(0x6041, 0) & 0x08:
                    raise CipRefusal(cip.DEVICE_STATE_CONFLICT)
                if state != 0x27:
                    for word in (0x06, 0x07, 0x0F):
                        self._write(model, 0x6040, "<H", word)
            else:
                self._write(model, 0x6040, "<H", 0x06)

    def _enabled(self, model: Any) -> bool:
        return model.object_value(0x6041, 0) & 0x6F == 0x27

    def _start_homing(self) -> None:
        with self._model() as model:
            if not self._enabled(model):
                raise CipRefusal(cip.DEVICE_STATE_CONFLICT)
            method = HOMING_METHODS.get(self.pc.home_mode)
            if method is None:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
            self._ensure_mode(model, 6)
            self._write(model, 0x6098, "<b", method)
            self._write(model, 0x6040, "<H", 0x0F)
            self._write(model, 0x6040, "<H", 0x1F)

    def _load(self, kind: int, *, target: int | None = None, velocity: int | None = None,
              acceleration: int = 0, deceleration: int = 0, relative: bool = False) -> None:
        """Load (and start) one command on the one axis: 'position', 'velocity' or 'torque'."""
        with self._model() as model:
            if not self._enabled(model):
                raise CipRefusal(cip.DEVICE_STATE_CONFLICT)
            axis = model.motion.axis
            if kind == asm.CMD_TORQUE:
                self.pc.torque = 0 if target is None else target
                return
            if kind in (asm.CMD_VELOCITY_SETPOINT, asm.CMD_JOG_MOVE):
                self._ensure_mode(model, 3)
                if acceleration:
                    self._write(model, 0x6083, "<I", abs(self._cia_vel(acceleration)))
                    self._write(model, 0x6084, "<I", abs(self._cia_vel(deceleration or acceleration)))
                self._write(model, 0x60FF, "<i", _clamp32(self._cia_vel(velocity or 0)))
                self._write(model, 0x6040, "<H", 0x0F)
                return
            if not axis.homed:
                raise CipRefusal(cip.DEVICE_STATE_CONFLICT)   # must be homed before position moves [M-11]
            self._ensure_mode(model, 1)
            # type 1 carries no velocity: the attribute-7 target velocity, else the simulator's 1 rev/s
            speed = velocity or self.pc.target_velocity or self.pc.profunit
            self._write(model, 0x607A, "<i", _clamp32(self._cia_pos(target or 0)))
            self._write(model, 0x6081, "<I", min(0xFFFFFFFF, abs(self._cia_vel(speed))))
            self._write(model, 0x6083, "<I", abs(self._cia_vel(acceleration or self.pc.acceleration)))
            self._write(model, 0x6084, "<I", abs(self._cia_vel(deceleration or self.pc.deceleration)))
            base = 0x0F | 0x20 | (0x40 if relative else 0)
            self._write(model, 0x6040, "<H", base)
            self._write(model, 0x6040, "<H", base | 0x10)
            if not model.object_value(0x6041, 0) & 0x1000:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)      # outside the software limits
            self._write(model, 0x6040, "<H", base)

    # ---------------------------------------------------------------- Position Controller 0x25
    def _snapshot(self) -> dict[str, Any]:
        with self._model() as model:
            word = model.object_value(0x6041, 0)
            mode = model.object_value(0x6061, 0)
            axis = model.motion.axis
            return {"word": word, "mode": mode, "enabled": word & 0x6F == 0x27, "fault": bool(word & 0x08),
                    "position": model.object_value(0x6064, 0), "velocity": model.object_value(0x606C, 0),
                    "homed": axis.homed, "homing": axis.homing is not None, "activity": axis.activity,
                    "task": axis.task is not None, "at_rest": axis.standstill,
                    "current": model.object_value(0x6077, 0)}

    def _pc_mode(self, cia_mode: int) -> int:
        return {1: 0, 3: 1, 4: 2, 6: 0}.get(cia_mode, 0)

    def _position_controller(self, service: int, path: cip.Path, data: bytes) -> bytes:
        snap = self._snapshot()
        pc = self.pc
        on_target = snap["enabled"] and snap["at_rest"] and not snap["task"] and not snap["homing"]
        values = {1: bytes([len(PC_ATTRS)]), 2: bytes(PC_ATTRS), 3: bytes([self._pc_mode(snap["mode"])]),
                  4: struct.pack("<i", _clamp32(pc.posunit)), 5: struct.pack("<i", _clamp32(pc.profunit)),
                  6: struct.pack("<i", pc.target_position), 7: struct.pack("<i", pc.target_velocity),
                  8: struct.pack("<i", pc.acceleration), 9: struct.pack("<i", pc.deceleration),
                  10: bytes([pc.incremental]), 11: bytes([pc.handshake]), 12: bytes([on_target]),
                  13: struct.pack("<i", self._eip_pos(snap["position"])),
                  14: struct.pack("<i", self._eip_vel(snap["velocity"])), 17: bytes([snap["enabled"]]),
                  25: struct.pack("<i", pc.torque), 58: bytes([pc.load_complete]),
                  100: struct.pack("<h", pc.home_mode), 101: b"\x00"}

        def i32(name: str) -> Any:
            return lambda raw: setattr(pc, name, struct.unpack("<i", raw)[0])

        def units(name: str) -> Any:
            def set_units(raw: bytes) -> None:
                value = struct.unpack("<i", raw)[0]
                if value <= 0:
                    raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
                setattr(pc, name, value)
            return set_units

        def set_mode(raw: bytes) -> None:
            if raw[0] not in PC_MODES:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
            with self._model() as model:
                self._ensure_mode(model, PC_MODES[raw[0]])

        def set_bool(name: str) -> Any:
            def setter(raw: bytes) -> None:
                if raw[0] > 1:
                    raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
                setattr(pc, name, bool(raw[0]))
            return setter

        def set_handshake(raw: bytes) -> None:
            if raw[0] > 1:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
            rising = raw[0] and not pc.handshake
            pc.handshake = bool(raw[0])
            if not raw[0]:
                pc.load_complete = False
                return
            if rising:
                kind = {0: asm.CMD_POSITION_MOVE, 1: asm.CMD_VELOCITY_SETPOINT, 2: asm.CMD_TORQUE}[
                    self._pc_mode(snap["mode"])]
                self._load(kind, target=pc.torque if kind == asm.CMD_TORQUE else pc.target_position,
                           velocity=pc.target_velocity, relative=pc.incremental)
                pc.load_complete = True

        def set_enable(raw: bytes) -> None:
            if raw[0] > 1:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
            self._enable(bool(raw[0]))

        def set_home_mode(raw: bytes) -> None:
            value = struct.unpack("<h", raw)[0]
            if value not in HOMING_METHODS:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
            pc.home_mode = value

        def home_move(raw: bytes) -> None:
            if raw[0]:
                self._start_homing()

        setters = {3: set_mode, 4: units("posunit"), 5: units("profunit"), 6: i32("target_position"),
                   7: i32("target_velocity"), 8: i32("acceleration"), 9: i32("deceleration"),
                   10: set_bool("incremental"), 11: set_handshake, 17: set_enable, 25: i32("torque"),
                   100: set_home_mode, 101: home_move}
        if service == cip.GET_ATTRIBUTE_SINGLE and path.attribute == 101:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)   # Set only [M-37]
        return self._single(service, path, values, setters, data)

    def _supervisor(self, service: int, path: cip.Path, data: bytes) -> bytes:
        snap = self._snapshot()
        return self._single(service, path, {1: bytes([len(SUPERVISOR_ATTRS)]), 2: bytes(SUPERVISOR_ATTRS),
                                            3: b"\x01", 5: bytes([snap["fault"]])})

    # ================================================================ I/O assemblies
    def _response_assembly(self, command: asm.Command | None) -> asm.Response:
        snap = self._snapshot()
        status1 = 0
        if snap["enabled"]:
            status1 |= asm.ST1_ENABLED
            if snap["at_rest"] and not snap["task"] and not snap["homing"]:
                status1 |= asm.ST1_IN_POSITION
        if snap["fault"]:
            status1 |= asm.ST1_GENERAL_FAULT
        if not snap["at_rest"]:
            status1 |= asm.ST1_IN_MOTION
        status2 = asm.ST2_LOAD_COMPLETE if self.io.load_complete else 0
        motionstat = (1 if snap["task"] else 0) | (0b110 if snap["homed"] else 0) | (0b1000 if snap["homing"] else 0)
        rtype = command.response_type if command is not None else asm.RSP_NONE
        value = round(snap["current"] * SIM_RATED_MA / 1000) if rtype == asm.RSP_TORQUE else 0
        return asm.Response(status1=status1, status2=status2, response_axis=command.response_axis if command else 1,
                            response_type=rtype, data=asm.value_data(value),
                            actual_position=self._eip_pos(snap["position"]),
                            actual_velocity=self._eip_vel(snap["velocity"]), motion_status=motionstat,
                            attribute_to_get=command.attribute_to_get if command else 0)

    def io_cycle(self, raw: bytes) -> bytes:
        """One consumed command assembly -> the response assembly to produce. Never raises."""
        with self.lock:
            try:
                command = asm.Command.decode(raw)
            except CodecError:
                return self._response_assembly(None).encode()
            io = self.io
            previous = io.last_control if io.last_control is not None else 0
            io.last_control = command.control
            try:
                self._apply_control(command, previous)
            except CipRefusal:
                pass
            except Exception:  # noqa: BLE001
                pass
            if command.flag(asm.CTL_LOAD_START) and not previous & asm.CTL_LOAD_START:
                try:
                    self._io_load(command)
                    io.load_complete, io.error = True, None
                except CipRefusal as exc:
                    io.error = asm.CommandError(exc.status, asm.ADDITIONAL_CODE, 0, 0)
                except Exception:  # noqa: BLE001
                    io.error = asm.CommandError(cip.DEVICE_STATE_CONFLICT, asm.ADDITIONAL_CODE, 0, 0)
            elif not command.flag(asm.CTL_LOAD_START):
                io.load_complete, io.error = False, None
            response = self._response_assembly(command)
            if io.error is not None:
                response = asm.error_response(response, command, io.error.code, io.error.additional)
            return response.encode()

    def _apply_control(self, command: asm.Command, previous: int) -> None:
        enable = command.flag(asm.CTL_ENABLE)
        with self._model() as model:
            enabled = self._enabled(model)
            if not enable:
                if enabled:
                    self._write(model, 0x6040, "<H", 0x06)     # fieldbus requested disable (DISSOURCES bit 6)
                return
            if command.flag(asm.CTL_HARD_STOP) and not previous & asm.CTL_HARD_STOP and enabled:
                self._write(model, 0x6040, "<H", 0x0B)         # quick stop; Enable must be cycled
                return
            halt = 0x100 if command.flag(asm.CTL_SMOOTH_STOP) else 0
            if command.flag(asm.CTL_SMOOTH_STOP) != bool(previous & asm.CTL_SMOOTH_STOP) and enabled:
                self._write(model, 0x6040, "<H", 0x0F | halt)
        if enable and not previous & asm.CTL_ENABLE and not enabled:
            self._enable(True)

    def _io_load(self, command: asm.Command) -> None:
        kind = command.command_type
        relative = command.flag(asm.CTL_RELATIVE)
        if command.command_axis != 1:
            raise CipRefusal(cip.INVALID_PARAMETER)
        if kind == asm.CMD_TARGET_POSITION:
            self._load(kind, target=command.data, relative=relative)
        elif kind == asm.CMD_POSITION_MOVE:
            self._load(kind, target=command.position, velocity=command.velocity, acceleration=command.acceleration,
                       deceleration=command.deceleration, relative=relative)
        elif kind == asm.CMD_JOG_MOVE:
            speed = abs(command.velocity) * (1 if command.flag(asm.CTL_DIRECTION) else -1)
            self._load(kind, velocity=speed, acceleration=command.acceleration, deceleration=command.deceleration)
        elif kind == asm.CMD_VELOCITY_SETPOINT:
            self._load(kind, velocity=command.data)
        elif kind == asm.CMD_TORQUE:
            self._load(kind, target=command.data)
        else:
            raise CipRefusal(cip.INVALID_PARAMETER)

    def io_closed(self) -> None:
        """The I/O connection ended (Forward_Close or timeout): the Enable bit is gone, so disable."""
        with self.lock:
            self.io = IoState()
            try:
                self._enable(False)
            except Exception:  # noqa: BLE001
                pass


def _clamp32(value: int) -> int:
    return max(-(1 << 31), min((1 << 31) - 1, int(value)))
