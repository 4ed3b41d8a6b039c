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

Layout: one class per CIP object (:mod:`akdctl.sim.cip_objects`), the one axis they act on
(:mod:`akdctl.sim.cip_axis`), and here the device that routes requests to them and runs the I/O handshake.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

from akdctl.protocol import akd_assembly as asm
from akdctl.protocol import cip
from akdctl.protocol.errors import CodecError
from akdctl.sim.cip_axis import AxisBridge, CipRefusal, PcState
from akdctl.sim import identity as _identity
from akdctl.sim.cip_objects import OBJECTS, CipObject, IdentityObject
from akdctl.sim.drive import SimStateError
from akdctl.sim.face import request_failed


@dataclass
class IdentitySettings:
    """What the Identity object and ListIdentity report; configurable (no public AKD EDS, [I])."""

    vendor: int = 452                    # "Kollmorgen" in pycomm3's vendor table [I]
    device_type: int = 0x10              # position controller [I]
    product_code: int = 1                # [I]
    # Revision, serial and name from the drive's one identity record (sim/identity.py, issue 23.8).
    revision: tuple[int, int] = field(default_factory=lambda: _identity.firmware_numbers()[:2])
    serial: int | None = None            # None: the drive's own (0x1018:4), as every face reports it
    product_name: str = _identity.ORDER_CODE

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
        self.pc = PcState()
        self.io = IoState()
        self.axis = AxisBridge(drive, self.pc)
        self.objects: dict[int, CipObject] = {cls.class_id: cls(self) for cls in OBJECTS}
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
                self.axis.load_units()
                data = self._dispatch(req.service, path, req.data)
            return cip.Response(req.service, cip.SUCCESS, (), data).encode()
        except CipRefusal as exc:
            return cip.Response(req.service, exc.status, exc.extended).encode()
        except SimStateError as exc:  # the drive cannot keep what it was told: "resource unavailable" (issue 23.11)
            request_failed("ethernetip", exc)
            return cip.Response(req.service, cip.RESOURCE_UNAVAILABLE).encode()
        except Exception:  # noqa: BLE001 - a face survives any per-request error
            return cip.Response(req.service, cip.DEVICE_STATE_CONFLICT).encode()

    def _dispatch(self, service: int, path: cip.Path, data: bytes) -> bytes:
        target = self.objects.get(path.class_id)
        if target is None:
            raise CipRefusal(cip.OBJECT_DOES_NOT_EXIST)
        if service not in (cip.GET_ATTRIBUTE_SINGLE, cip.SET_ATTRIBUTE_SINGLE, cip.GET_ATTRIBUTES_ALL):
            raise CipRefusal(cip.SERVICE_NOT_SUPPORTED)
        return target.request(service, path, data)

    def identity_attributes(self) -> cip.IdentityAttributes:
        """What the Identity object and ListIdentity report now."""
        identity = self.objects[cip.IDENTITY]
        assert isinstance(identity, IdentityObject)
        return identity.identity_attributes()

    # ================================================================ I/O assemblies
    def response_assembly(self, command: asm.Command | None) -> asm.Response:
        """The 64-byte response assembly for ``command`` (None: no command yet)."""
        axis = self.axis
        snap = axis.snapshot()
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
        value = snap["current_ma"] if rtype == asm.RSP_TORQUE else 0  # the actual current of 0x2077 (issue 23.7)
        return asm.Response(status1=status1, status2=status2, response_axis=command.response_axis if command else 1,
                            response_type=rtype, data=asm.value_data(value),
                            actual_position=axis.eip_pos(snap["position"]),
                            actual_velocity=axis.eip_vel(snap["velocity"]), motion_status=motionstat,
                            attribute_to_get=command.attribute_to_get if command else 0)

    def io_cycle(self, raw: bytes) -> bytes:
        """One consumed command assembly -> the response assembly to produce. Never raises."""
        with self.lock:
            try:
                command = asm.Command.decode(raw)
            except CodecError:
                return self.response_assembly(None).encode()
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
            response = self.response_assembly(command)
            if io.error is not None:
                response = asm.error_response(response, command, io.error.code, io.error.additional)
            return response.encode()

    def _apply_control(self, command: asm.Command, previous: int) -> None:
        enable = command.flag(asm.CTL_ENABLE)
        axis = self.axis
        with axis.model() as model:
            enabled = axis.enabled(model)
            if not enable:
                if enabled:
                    axis.write(model, 0x6040, "<H", 0x06)     # fieldbus requested disable (DISSOURCES bit 6)
                return
            if command.flag(asm.CTL_HARD_STOP) and not previous & asm.CTL_HARD_STOP and enabled:
                axis.write(model, 0x6040, "<H", 0x0B)         # quick stop; Enable must be cycled
                return
            halt = 0x100 if command.flag(asm.CTL_SMOOTH_STOP) else 0
            if command.flag(asm.CTL_SMOOTH_STOP) != bool(previous & asm.CTL_SMOOTH_STOP) and enabled:
                axis.write(model, 0x6040, "<H", 0x0F | halt)
        if enable and not previous & asm.CTL_ENABLE and not enabled:
            axis.enable(True)

    def _io_load(self, command: asm.Command) -> None:
        kind = command.command_type
        relative = command.flag(asm.CTL_RELATIVE)
        if command.command_axis != 1:
            raise CipRefusal(cip.INVALID_PARAMETER)
        if kind == asm.CMD_TARGET_POSITION:
            self.axis.load(kind, target=command.data, relative=relative)
        elif kind == asm.CMD_POSITION_MOVE:
            self.axis.load(kind, target=command.position, velocity=command.velocity, acceleration=command.acceleration,
                       deceleration=command.deceleration, relative=relative)
        elif kind == asm.CMD_JOG_MOVE:
            speed = abs(command.velocity) * (1 if command.flag(asm.CTL_DIRECTION) else -1)
            self.axis.load(kind, velocity=speed, acceleration=command.acceleration, deceleration=command.deceleration)
        elif kind == asm.CMD_VELOCITY_SETPOINT:
            self.axis.load(kind, velocity=command.data)
        elif kind == asm.CMD_TORQUE:
            self.axis.load(kind, target=command.data)
        else:
            raise CipRefusal(cip.INVALID_PARAMETER)

    def io_closed(self) -> None:
        """The I/O connection ended (Forward_Close or timeout): the Enable bit is gone, so disable."""
        with self.lock:
            self.io = IoState()
            try:
                self.axis.enable(False)
            except Exception:  # noqa: BLE001
                pass
