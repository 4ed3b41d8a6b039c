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

from dataclasses import dataclass, replace

from akdctl.errors import DriveError
from akdctl.protocol import akd_assembly as asm


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
        raise DriveError(f"the drive refused the {asm.COMMAND_TYPES.get(command.command_type, 'command')} "
                         f"(response type 0x14): {cip_status_text(error.code)}, additional code "
                         f"0x{error.additional:02X}", code=error.code,
                         details={"error_code": error.code, "additional_code": error.additional,
                                  "echo": f"{error.echo_command:02X} {error.echo_response:02X}"})
    cleared = io.wait_input(lambda r: not r.load_complete, "Load Complete = 0 after Load/Start = 0",  # type: ignore[attr-defined]
                            timeout)
    seen.append(cleared.encode())
    return HandshakeResult(sent, seen, done)
