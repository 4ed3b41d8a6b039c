"""The simulated AKD's CIP objects, one class per object (as ``DriveModel`` has components).

Why one class each: nine objects with fourteen setters in one class, the setters as closures built anew on
every request, hid which attribute does what. Each object here answers Get/Set on its instances from a table
of attributes; settable attributes name a method (or a plain Position Controller field), built once. What is
verified and what is inferred is listed in :mod:`akdctl.sim.cip_device` ([I] = inferred, unverified).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, ClassVar

from akdctl.catalog import eip_parameters
from akdctl.protocol import akd_assembly as asm
from akdctl.protocol import cip
from akdctl.sim import identity as _identity
from akdctl.sim.cip_axis import HOMING_METHODS, CipRefusal, clamp32

if TYPE_CHECKING:
    from akdctl.sim.cip_device import CipDevice

PC_ATTRS = (1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 17, 25, 58, 100, 101)
SUPERVISOR_ATTRS = (1, 2, 3, 5)
FAULT1_INSTANCE = 478  # DRV.FAULT1 in the Parameter object [I] (reference/ethernetip.md 1.9, EIP.RSPMAP ids)

Setter = Callable[[bytes], None]


class CipObject:
    """One CIP object class of the device: answers Get/Set(/Get_Attributes_All) on its instances."""

    class_id: ClassVar[int]

    def __init__(self, device: "CipDevice") -> None:
        self.device = device

    def request(self, service: int, path: cip.Path, data: bytes) -> bytes:
        return single(service, path, self.attributes(), self.setters(), data)

    def attributes(self) -> dict[int, bytes]:
        """Instance 1's attributes, encoded."""
        raise NotImplementedError

    def setters(self) -> dict[int, Setter]:
        """The settable attributes of instance 1 (none by default)."""
        return {}


def single(service: int, path: cip.Path, attrs: dict[int, bytes], setters: dict[int, Setter] | None = None,
           data: bytes = b"") -> bytes:
    """Get/Set_Attribute_Single on instance 1 of an object whose attributes are ``attrs``."""
    if path.instance != 1:
        raise CipRefusal(cip.OBJECT_DOES_NOT_EXIST)
    if service == cip.GET_ATTRIBUTES_ALL:
        raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)
    if path.attribute is None or path.attribute not in attrs:
        raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)
    if service == cip.GET_ATTRIBUTE_SINGLE:
        return attrs[path.attribute]
    setter = (setters or {}).get(path.attribute)
    if setter is None:
        raise CipRefusal(cip.ATTRIBUTE_NOT_SETTABLE)
    size = len(attrs[path.attribute])
    if len(data) < size:
        raise CipRefusal(cip.NOT_ENOUGH_DATA)
    if len(data) > size:
        raise CipRefusal(cip.TOO_MUCH_DATA)
    setter(data)
    return b""


class IdentityObject(CipObject):
    """Identity 0x01: the standard attributes [I: no AKD table]; Set is refused as OpENer refuses it."""

    class_id = cip.IDENTITY

    def identity_attributes(self) -> cip.IdentityAttributes:
        ident = self.device.identity
        # CIP Identity status word (standard meaning; what an AKD sets is not documented [I]): bit 2 configured,
        # bits 4-7 extended status (3 = no I/O connection, 6 = an I/O connection in run), bit 10 major
        # recoverable fault while the drive reports a fault
        io_running = self.device.io.last_control is not None
        status = 0x0004 | (0x0060 if io_running else 0x0030) | (0x0400 if self.device.axis.fault() else 0)
        serial = ident.serial if ident.serial is not None else _identity.serial_of(self.device.drive)
        return cip.IdentityAttributes(ident.vendor, ident.device_type, ident.product_code, ident.revision,
                                      status, serial, ident.product_name)

    def request(self, service: int, path: cip.Path, data: bytes) -> bytes:
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
        return single(service, path, values)


class MessageRouterObject(CipObject):
    """Message Router 0x02: attribute 1 lists the object classes the device implements."""

    class_id = cip.MESSAGE_ROUTER
    CLASSES = (cip.IDENTITY, cip.MESSAGE_ROUTER, cip.ASSEMBLY, cip.CONNECTION_MANAGER, cip.PARAMETER,
               cip.POSITION_CONTROLLER_SUPERVISOR, cip.POSITION_CONTROLLER, cip.TCPIP, cip.ETHERNET_LINK)

    def attributes(self) -> dict[int, bytes]:
        return {1: struct.pack(f"<H{len(self.CLASSES)}H", len(self.CLASSES), *self.CLASSES)}


class TcpIpObject(CipObject):
    """TCP/IP Interface 0xF5 [I: the standard set]: the face's bound address, static configuration."""

    class_id = cip.TCPIP

    def attributes(self) -> dict[int, bytes]:
        import ipaddress

        try:
            ip = int(ipaddress.IPv4Address(self.device.address[0]))
        except ValueError:
            ip = 0
        config = struct.pack("<IIIII", ip, 0xFFFFFF00, 0, 0, 0) + struct.pack("<H", 0)
        return {1: struct.pack("<I", 1), 2: struct.pack("<I", 0x14), 3: struct.pack("<I", 0),
                4: bytes.fromhex("0200 20F6 2401"), 5: config, 6: struct.pack("<H", 0)}


class EthernetLinkObject(CipObject):
    """Ethernet Link 0xF6 [I: the standard set]: 100 Mbit/s full duplex, the simulator's MAC."""

    class_id = cip.ETHERNET_LINK

    def attributes(self) -> dict[int, bytes]:
        return {1: struct.pack("<I", 100), 2: struct.pack("<I", 0x0F), 3: bytes.fromhex("02 00 00 00 AD 01")}


class AssemblyObject(CipObject):
    """Assembly 0x04: configuration 100 (empty), command 101 and response 102 (64 bytes each) [V]."""

    class_id = cip.ASSEMBLY

    def request(self, service: int, path: cip.Path, data: bytes) -> bytes:
        if path.instance not in (asm.CONFIG_INSTANCE, asm.OUTPUT_INSTANCE, asm.INPUT_INSTANCE):
            raise CipRefusal(cip.OBJECT_DOES_NOT_EXIST)
        if service != cip.GET_ATTRIBUTE_SINGLE:
            raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)
        if path.attribute != 3:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)
        if path.instance == asm.CONFIG_INSTANCE:
            return b""
        if path.instance == asm.INPUT_INSTANCE:
            return self.device.response_assembly(None).encode()
        return bytes(asm.ASSEMBLY_SIZE)


class ParameterObject(CipObject):
    """Parameter 0x0F [V]: EIP.POSUNIT, EIP.PROFUNIT (value, type 0xC8, 4 bytes) and HOME.MOVE (a command:
    a 1-byte Set runs it; reading it does not [M-26]); range 1..2^31 for the units [M-21]."""

    class_id = cip.PARAMETER
    _MODELLED = (("EIP.POSUNIT", "posunit"), ("EIP.PROFUNIT", "profunit"), ("HOME.MOVE", "home"))

    def __init__(self, device: "CipDevice") -> None:
        super().__init__(device)
        self.instances: dict[int, str] = {}
        for name, key in self._MODELLED:
            parameter = eip_parameters.by_name(name)
            assert parameter is not None, name
            self.instances[parameter.instance] = key

    def request(self, service: int, path: cip.Path, data: bytes) -> bytes:
        if service == cip.GET_ATTRIBUTES_ALL:
            raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)
        if path.instance == FAULT1_INSTANCE:
            return self._fault1(service, path)
        key = self.instances.get(path.instance or 0)
        if key is None:
            return self._named_parameter(service, path, data, path.instance or 0)
        pc = self.device.pc
        command = key == "home"
        value = 0 if command else (pc.posunit if key == "posunit" else pc.profunit)
        attrs = {1: b"\x00" if command else struct.pack("<I", value),
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
            self.device.axis.start_homing()
            return b""
        units = struct.unpack("<I", data)[0]
        if not 1 <= units <= 1 << 31:        # range 0..2^31 [M-21]; 0 would divide by zero
            raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
        self.device.axis.save_unit(key, units)
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
        with self.device.axis.model() as model:
            try:
                if service == cip.GET_ATTRIBUTE_SINGLE:
                    return (store.wire(model, row) & 0xFFFFFFFF).to_bytes(4, "little")
                if len(data) != 4:
                    raise CipRefusal(cip.NOT_ENOUGH_DATA if len(data) < 4 else cip.TOO_MUCH_DATA)
                store.write_wire(model, row, int.from_bytes(data, "little", signed=signed))
            except store.ParamError:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE) from None
        return b""

    def _fault1(self, service: int, path: cip.Path) -> bytes:
        """DRV.FAULT1 (the first active fault number, 0 for none) at instance 478 [I: its EIP.RSPMAP id, M-34;
        no source states the Parameter-object instance], read-only, 2-byte integer."""
        with self.device.axis.model() as model:
            active = model.faults.situations[0]
            number = active[0] if active else 0
        attrs = {1: struct.pack("<H", number), 5: bytes([0xC7]), 6: bytes([2])}
        if path.attribute not in attrs:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)
        if service != cip.GET_ATTRIBUTE_SINGLE:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SETTABLE)
        return attrs[path.attribute]


class PositionControllerObject(CipObject):
    """Position Controller 0x25 (appendix A [V]; 12 on-target, 13 actual position, 14 actual velocity follow
    the ODVA profile [I]). Plain fields are set from :data:`FIELDS`; the rest have a method each."""

    class_id = cip.POSITION_CONTROLLER
    #: attribute -> (encoding, PcState field): set by storing the value ("units" must be positive).
    FIELDS: ClassVar[dict[int, tuple[str, str]]] = {
        4: ("units", "posunit"), 5: ("units", "profunit"), 6: ("i32", "target_position"),
        7: ("i32", "target_velocity"), 8: ("i32", "acceleration"), 9: ("i32", "deceleration"),
        10: ("bool", "incremental"), 25: ("i32", "torque")}

    def __init__(self, device: "CipDevice") -> None:
        super().__init__(device)
        self._setters: dict[int, Setter] = {
            **{attribute: partial(self.set_field, *self.FIELDS[attribute]) for attribute in self.FIELDS},
            3: self.set_mode, 11: self.set_handshake, 17: self.set_enable, 100: self.set_home_mode,
            101: self.home_move}

    def request(self, service: int, path: cip.Path, data: bytes) -> bytes:
        if service == cip.GET_ATTRIBUTE_SINGLE and path.attribute == 101:
            raise CipRefusal(cip.ATTRIBUTE_NOT_SUPPORTED)   # Set only [M-37]
        return super().request(service, path, data)

    def attributes(self) -> dict[int, bytes]:
        axis, pc = self.device.axis, self.device.pc
        snap = axis.snapshot()
        on_target = snap["enabled"] and snap["at_rest"] and not snap["task"] and not snap["homing"]
        return {1: bytes([len(PC_ATTRS)]), 2: bytes(PC_ATTRS), 3: bytes([axis.pc_mode(snap["mode"])]),
                4: struct.pack("<i", clamp32(pc.posunit)), 5: struct.pack("<i", clamp32(pc.profunit)),
                6: struct.pack("<i", pc.target_position), 7: struct.pack("<i", pc.target_velocity),
                8: struct.pack("<i", pc.acceleration), 9: struct.pack("<i", pc.deceleration),
                10: bytes([pc.incremental]), 11: bytes([pc.handshake]), 12: bytes([on_target]),
                13: struct.pack("<i", axis.eip_pos(snap["position"])),
                14: struct.pack("<i", axis.eip_vel(snap["velocity"])), 17: bytes([snap["enabled"]]),
                25: struct.pack("<i", pc.torque), 58: bytes([pc.load_complete]),
                100: struct.pack("<h", pc.home_mode), 101: b"\x00"}

    def setters(self) -> dict[int, Setter]:
        return self._setters

    def set_field(self, encoding: str, name: str, raw: bytes) -> None:
        value: int | bool
        if encoding == "bool":
            if raw[0] > 1:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
            value = bool(raw[0])
        else:
            value = struct.unpack("<i", raw)[0]
            if encoding == "units" and value <= 0:
                raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
        setattr(self.device.pc, name, value)

    def set_mode(self, raw: bytes) -> None:
        self.device.axis.set_mode(raw[0])

    def set_handshake(self, raw: bytes) -> None:
        """Attribute 11: a rising edge loads the command of the current mode (Load Complete, attribute 58)."""
        pc, axis = self.device.pc, self.device.axis
        if raw[0] > 1:
            raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
        rising = raw[0] and not pc.handshake
        pc.handshake = bool(raw[0])
        if not raw[0]:
            pc.load_complete = False
            return
        if rising:
            kind = {0: asm.CMD_POSITION_MOVE, 1: asm.CMD_VELOCITY_SETPOINT, 2: asm.CMD_TORQUE}[
                axis.pc_mode(axis.snapshot()["mode"])]
            axis.load(kind, target=pc.torque if kind == asm.CMD_TORQUE else pc.target_position,
                      velocity=pc.target_velocity, relative=pc.incremental)
            pc.load_complete = True

    def set_enable(self, raw: bytes) -> None:
        if raw[0] > 1:
            raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
        self.device.axis.enable(bool(raw[0]))

    def set_home_mode(self, raw: bytes) -> None:
        value = struct.unpack("<h", raw)[0]
        if value not in HOMING_METHODS:
            raise CipRefusal(cip.INVALID_ATTRIBUTE_VALUE)
        self.device.pc.home_mode = value

    def home_move(self, raw: bytes) -> None:
        if raw[0]:
            self.device.axis.start_homing()


class SupervisorObject(CipObject):
    """Position Controller Supervisor 0x24: attributes 1, 2, 3 (axis number) and 5 (general fault)
    [I: ODVA/Moog/Yaskawa]."""

    class_id = cip.POSITION_CONTROLLER_SUPERVISOR

    def attributes(self) -> dict[int, bytes]:
        snap = self.device.axis.snapshot()
        return {1: bytes([len(SUPERVISOR_ATTRS)]), 2: bytes(SUPERVISOR_ATTRS), 3: b"\x01", 5: bytes([snap["fault"]])}


#: Every object the device implements, in the Message Router's order.
OBJECTS: tuple[type[CipObject], ...] = (IdentityObject, MessageRouterObject, AssemblyObject, ParameterObject,
                                        SupervisorObject, PositionControllerObject, TcpIpObject, EthernetLinkObject)
