"""One command through the AKD's I/O assemblies: the Load/Start -> Load Complete handshake [V, M-16].

The sequence of the manual's example (seed 002, SPEC-NOTES 24):

1. command assembly with the command type and data, Enable = 1, Load/Start = 0;
2. wait for a response with Enabled = 1 and Load Complete = 0 (the drive is ready for data);
3. set Load/Start (a 0 -> 1 edge is what loads the data);
4. wait for Load Complete = 1, or for response type 0x14 (error code, additional code, echo);
5. clear Load/Start; the drive clears Load Complete.

Steps 4-5 follow the manual's text; the page with their example bytes was not readable [I for the bytes].
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

from akdctl.errors import DriveError, Interrupted, NoAnswer, SafetyRefusal, UsageError
from akdctl.protocol import akd_assembly as asm

if TYPE_CHECKING:
    from akdctl.connection import Connection


@dataclass
class HandshakeResult:
    sent: list[bytes]          # command assemblies in the order they were set
    seen: list[bytes]          # the response assembly each step waited for
    response: asm.Response


def run_command(io: object, command: asm.Command, timeout: float = 2.0) -> HandshakeResult:
    """Load ``command`` (its Load/Start bit is managed here) and return when the drive took it."""
    from akdctl.catalog.texts import cip_status_text

    idle = replace(command, control=(command.control | asm.CTL_ENABLE) & ~asm.CTL_LOAD_START)
    load = replace(idle, control=idle.control | asm.CTL_LOAD_START)
    sent, seen = [idle.encode()], []
    io.set_output(idle)  # type: ignore[attr-defined]
    # step 2: Enabled (enabling takes 300-350 ms on a drive) and Load Complete = 0
    ready = io.wait_input(lambda r: bool(r.status1 & asm.ST1_ENABLED) and not r.load_complete  # type: ignore[attr-defined]
                          and r.response_type != asm.RSP_ERROR, "Enabled with Load Complete = 0", timeout)
    seen.append(ready.encode())
    io.set_output(load)  # type: ignore[attr-defined]
    sent.append(load.encode())
    done = io.wait_input(lambda r: r.load_complete or r.response_type == asm.RSP_ERROR,  # type: ignore[attr-defined]
                         "Load Complete = 1", timeout)
    seen.append(done.encode())
    io.set_output(idle)  # type: ignore[attr-defined]
    sent.append(idle.encode())
    error = done.error
    if error is not None:
        from akdctl.protocol import cip

        hint = ""
        if error.code == cip.DEVICE_STATE_CONFLICT and command.command_type in (asm.CMD_TARGET_POSITION,
                                                                                 asm.CMD_POSITION_MOVE):
            hint = ("; the AKD runs position commands only on a homed axis [M-11]: run 'akdctl home' first "
                    "(a jog or velocity command does not home it)")
        raise DriveError(f"the drive refused the {asm.COMMAND_TYPES.get(command.command_type, 'command')} "
                         f"(response type 0x14): {cip_status_text(error.code)}, additional code "
                         f"0x{error.additional:02X}{hint}", code=error.code,
                         details={"error_code": error.code, "additional_code": error.additional,
                                  "echo": f"{error.echo_command:02X} {error.echo_response:02X}"})
    cleared = io.wait_input(lambda r: not r.load_complete, "Load Complete = 0 after Load/Start = 0",  # type: ignore[attr-defined]
                            timeout)
    seen.append(cleared.encode())
    return HandshakeResult(sent, seen, done)


# ====================================================================== eip io: plan -> consent -> execute
#: ``eip io TYPE`` -> command type of the command assembly [V, M-12].
IO_TYPES = {"position": asm.CMD_TARGET_POSITION, "torque": asm.CMD_TORQUE, "move": asm.CMD_POSITION_MOVE,
            "jog": asm.CMD_JOG_MOVE, "velocity": asm.CMD_VELOCITY_SETPOINT}
#: The types the tool ends (after --for); position and move end by themselves.
TIMED = ("jog", "velocity", "torque")
#: The longest a dead tool may leave an I/O motion running (README "Safety model"): the drive keeps the last
#: command until the connection times out, RPI x the timeout multiplier (CIP: 4 << code, code 0..7). Other
#: transports bound the same through the drive's watchdog.
MAX_CONNECTION_TIMEOUT_S = 0.5
#: How long an interrupted I/O motion is given to reach standstill before the connection is closed anyway.
STOP_WAIT_S = 10.0


def timeout_multiplier(rpi_ms: float) -> int:
    """The largest CIP timeout multiplier code whose timeout (RPI x 4 << code) stays within
    :data:`MAX_CONNECTION_TIMEOUT_S` (the most tolerant of a late packet); SafetyRefusal when even x4 exceeds it."""
    rpi_s = rpi_ms / 1000.0
    if not rpi_s * 4 <= MAX_CONNECTION_TIMEOUT_S:
        raise SafetyRefusal(f"refusing: --rpi {rpi_ms:g} ms: the drive would keep the axis moving for "
                            f"{rpi_s * 4:g} s (RPI x 4, the smallest timeout multiplier) after the tool dies; "
                            f"motion over I/O is bounded to {MAX_CONNECTION_TIMEOUT_S:g} s, so the RPI must be at "
                            f"most {MAX_CONNECTION_TIMEOUT_S / 4 * 1000:g} ms")
    code = 0
    while code < 7 and rpi_s * (4 << (code + 1)) <= MAX_CONNECTION_TIMEOUT_S:
        code += 1
    return code


@dataclass
class IoRequest:
    """``eip io`` as the user typed it: raw EIP.POSUNIT / EIP.PROFUNIT values, the connection's RPI."""

    kind: str
    value: int
    velocity: int | None = None
    accel: int = 0
    decel: int = 0
    relative: bool = False
    hold_s: float | None = None
    rpi_ms: float = 20.0
    io_port: int = 2222
    local_port: int = 0


@dataclass
class IoPlan:
    """An accepted I/O command: the command assembly, the connection's timeout multiplier, what was checked."""

    request: IoRequest
    target: str
    command: asm.Command
    multiplier: int
    connection_timeout_s: float
    hold_s: float | None
    rpm: float | None
    end_rev: float | None
    notes: list[str] = field(default_factory=list)

    @property
    def consent_text(self) -> str:
        r = self.request
        return (f"run an I/O {r.kind} command ({r.value}, command type 0x{IO_TYPES[r.kind]:02X}) over a class-1 "
                f"connection akdctl opens; when the connection ends the drive sees Enable drop and disables the axis")

    def lines(self) -> list[str]:
        r = self.request
        out = [f"eip io on {self.target}: I/O {r.kind} command type 0x{IO_TYPES[r.kind]:02X}, value {r.value}"
               + (f", for {self.hold_s:g} s" if self.hold_s is not None else ""),
               f"connection: RPI {r.rpi_ms:g} ms, timeout multiplier x{4 << self.multiplier}: a dead tool leaves "
               f"the axis running at most {self.connection_timeout_s:g} s"]
        if self.rpm is not None:
            out.append(f"velocity {self.rpm:.6g} rpm as executed")
        if self.end_rev is not None:
            out.append(f"ends at {self.end_rev:.4f} rev")
        return out + self.notes

    def to_json(self) -> dict[str, Any]:
        return {"type": self.request.kind, "command_type": IO_TYPES[self.request.kind], "value": self.request.value,
                "hold_s": self.hold_s, "rpi_ms": self.request.rpi_ms, "timeout_multiplier": 4 << self.multiplier,
                "connection_timeout_s": self.connection_timeout_s, "rpm": self.rpm, "end_rev": self.end_rev,
                "command": self.command.encode().hex(" ")}


def plan(conn: "Connection", request: IoRequest) -> IoPlan:
    """Every check of a planned motion, on the raw values this command sends; reads the drive, writes nothing.

    The jog-duration bound and the profile's limits (velocity, acceleration, travel, max_jog_duration) are the
    planner's own rules (drive/motion_plan.py); the connection's timeout is bounded here."""
    from akdctl.drive import motion_plan
    from akdctl.drive.axis.cip import CipAxis

    r = request
    if r.kind not in IO_TYPES:
        raise UsageError(f"unknown I/O command {r.kind!r}: expected one of {', '.join(IO_TYPES)}")
    limits = motion_plan.limits_of(conn)
    hold = None
    if r.kind in TIMED:
        if r.hold_s is None:
            raise UsageError(f"eip io {r.kind} needs --for SECONDS, so the motion is bounded")
        hold = motion_plan.check_duration(limits, r.hold_s, f"eip io {r.kind} --for",
                                          "'eip io move' ends by itself")
    elif r.hold_s is not None:
        raise UsageError(f"--for bounds jog, velocity and torque; an I/O {r.kind} ends by itself")
    if r.kind == "move" and not r.velocity:
        raise UsageError("eip io move needs --velocity (EIP.PROFUNIT units per second)")
    multiplier = timeout_multiplier(r.rpi_ms)
    axis = CipAxis(conn.cip(), timeout=conn.options.timeout, target=conn.target.display)
    posunit, profunit = axis.units()
    speed = r.value if r.kind in ("jog", "velocity") else (r.velocity or 0)
    rpm = speed * 60.0 / profunit if speed else None
    end_rev = None
    if r.kind in ("position", "move"):
        status = axis.read_status()
        if r.relative:
            end_rev = None if status.position_rev is None else status.position_rev + r.value / posunit
        else:
            end_rev = r.value / posunit
        if end_rev is None and limits.get("travel"):
            raise SafetyRefusal("refusing: the profile limits travel but this link cannot read the position")
    motion_plan.check_executed_limits(conn, rpm=rpm, acc_rpm_s=max(r.accel, r.decel) * 60.0 / profunit
                                      if (r.accel or r.decel) else None, end_rev=end_rev,
                                      executed_by="the I/O assembly")
    direction = asm.CTL_DIRECTION if r.kind in ("jog", "velocity") and r.value >= 0 else 0   # velocity mode [M-12]
    control = asm.CTL_ENABLE | (asm.CTL_RELATIVE if r.relative else 0) | direction
    command = asm.Command(control=control, command_type=IO_TYPES[r.kind],
                          data=r.value if r.kind in ("position", "velocity", "torque") else 0,
                          position=r.value if r.kind == "move" else 0,
                          velocity=(r.velocity or 0) if r.kind == "move" else abs(r.value) if r.kind == "jog" else 0,
                          acceleration=r.accel, deceleration=r.decel)
    rpi_s = r.rpi_ms / 1000.0
    return IoPlan(r, conn.target.display, command, multiplier, rpi_s * (4 << multiplier), hold, rpm, end_rev)


def _standstill(r: asm.Response) -> bool:
    return r.actual_velocity == 0 and not r.status1 & asm.ST1_IN_MOTION


def execute(conn: "Connection", accepted: IoPlan, stop: Callable[[], bool]) -> dict[str, Any]:
    """Open the I/O connection, run the handshake, hold or wait for In Position, close.

    ``stop()`` true (SIGINT/TERM/HUP): Smooth Stop is commanded and the axis watched until standstill
    (at most :data:`STOP_WAIT_S`) before the connection closes; Interrupted then says whether it stopped.
    The Run bit is set only while a command is meant: before the handshake and after the motion the drive gets
    Idle data."""
    from akdctl.drive.polling import pause_unless_stopped

    r = accepted.request
    io = conn.io_connection(rpi_ms=r.rpi_ms, port=r.io_port, local_port=r.local_port,
                            timeout_multiplier=accepted.multiplier)
    with io:
        if io.connection_timeout_s > MAX_CONNECTION_TIMEOUT_S + 1e-9:  # the drive raised our RPI (its API)
            raise SafetyRefusal(f"refusing: the drive accepted the I/O connection with a timeout of "
                                f"{io.connection_timeout_s:g} s, more than {MAX_CONNECTION_TIMEOUT_S:g} s; "
                                "nothing was commanded")
        result = run_command(io, accepted.command, timeout=conn.options.timeout)
        if accepted.hold_s is not None:
            pause_unless_stopped(accepted.hold_s, stop)
            final = io.wait_input(lambda resp: True, "a response", conn.options.timeout)
        else:
            final = io.wait_input(lambda resp: stop() or (bool(resp.status1 & asm.ST1_IN_POSITION)
                                                          and not resp.status1 & asm.ST1_IN_MOTION), "In Position",
                                  timeout=max(conn.options.timeout, 60.0))
        if stop():
            raise Interrupted(f"interrupted during the I/O {r.kind} command; {_stop_and_wait(io, accepted)}")
        if accepted.hold_s is not None:
            # the tool ends a timed motion: stop it and see standstill before the connection (and Enable) ends
            words = _stop_and_wait(io, accepted)
            if not words.startswith("the axis stopped"):
                raise DriveError(f"the I/O {r.kind} did not end: {words}")
            final = io.wait_input(lambda resp: True, "a response", conn.options.timeout)
        io.idle()
        stats = io.stats
    return {"target": accepted.target, "type": r.kind, "command_type": IO_TYPES[r.kind], "value": r.value,
            "sent": [b.hex(" ") for b in result.sent], "responses": [b.hex(" ") for b in result.seen],
            "final": final.encode().hex(" "), "actual_position": final.actual_position,
            "actual_velocity": final.actual_velocity, "produced": stats.produced, "consumed": stats.consumed,
            "connection_timeout_s": accepted.connection_timeout_s,
            "connection": "closed (the drive disables the axis)"}


def _stop_and_wait(io: Any, accepted: IoPlan) -> str:
    """Smooth Stop (Enable kept, so the drive decelerates on its ramp), wait for standstill, then leave a zero
    set point behind (a velocity or torque command of 0): the drive must not resume the old set point when the
    next connection enables it. Never raises; says what happened."""
    stopping = replace(accepted.command, control=(accepted.command.control | asm.CTL_SMOOTH_STOP)
                       & ~asm.CTL_LOAD_START)
    io.set_output(stopping)
    try:
        io.wait_input(_standstill, "standstill", STOP_WAIT_S)
    except (NoAnswer, DriveError) as exc:
        return (f"could not confirm standstill within {STOP_WAIT_S:g} s ({exc}); the connection is closed, so the "
                "drive disables the axis")
    words = "the axis stopped; the connection is closed, so the drive disables the axis"
    if accepted.request.kind in TIMED:
        kind = asm.CMD_TORQUE if accepted.request.kind == "torque" else asm.CMD_VELOCITY_SETPOINT
        zero = asm.Command(control=(accepted.command.control & ~asm.CTL_LOAD_START) | asm.CTL_SMOOTH_STOP,
                           command_type=kind, data=0)
        try:
            run_command(io, zero, timeout=STOP_WAIT_S)
        except (NoAnswer, DriveError) as exc:
            words += f" (the drive did not take a zero set point: {exc})"
    return words
