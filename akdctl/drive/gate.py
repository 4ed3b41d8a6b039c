"""The write gate: which raw writes can power or move the axis, and so need consent like ``enable``.

Why a gate: ``pnu set 1=0x047F`` or ``sdo write 0x6040:0 15`` reach the state
machine without the motion commands' consent. Every raw write path (``pnu set``,
``sdo write``, recipe ``set`` steps) classifies its addresses here; the caller asks
for consent (:func:`akdctl.cli.consent.require_consent`) when :func:`needing_consent`
returns anything. README "Safety model" lists the same addresses.

* always gated — the control words and the set points the drive acts on:
  PNU 1 (STW1), 5 (NSOLL_A), 32 (SATZANW), 34..38 (MDI_*), 1004..1007 (jog set points
  and ramps); objects 0x6040 (controlword), 0x607A, 0x60FF, 0x6071, 0x60C1 (target
  position/velocity/torque, interpolation set points), 0x60B1/0x60B2 (velocity/torque
  offsets), 0x6081/0x6083/0x6084 (profile velocity and ramps);
* gated while the drive is enabled (or its state cannot be read) — what changes
  the meaning of the running set points: the operating mode (PNU 930, 0x6060) and
  the telegram / process-data mapping (PNU 915, 916, 922; 0x1600..0x17FF,
  0x1A00..0x1BFF, 0x1C12, 0x1C13), and MT.LOAD 0x3432 (it loads a motion task into
  those profile-position set points; ``task list|show``).

CIP attributes (``cip set``, ``eip param set|run``) are classified the same way: the
Position Controller 0x25's enable (17), load handshake (11) and home move (101) are
control, its target position/velocity and incremental flag (6, 7, 10) set points, its
mode (3) gated while enabled; the Parameter object's HOME.MOVE command and the command
assembly (0x04/100) move the axis.

Ownership: whatever passes this gate (a motion, a recipe that moves, a gated raw
write) also owns the target's axis for the rest of the command, so two akdctl
processes never command one axis at once (:func:`owner_key` names the axis;
:func:`akdctl.cli.consent.own_axis` holds it). ``stop``, ``disable`` and ``fault
ack`` only take power away and never wait for an owner.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from typing import Any

_CONTROL = "the control word powers and moves the axis"
_SETPOINT = "a set point the drive acts on"
_MODE = "the operating mode of an enabled drive changes what its set points mean"
_MAPPING = "the process-data mapping of an enabled drive changes which set points it follows"
_MT_LOAD = "MT.LOAD replaces the profile-position set points 0x607A/0x6081/0x6083/0x6084 of an enabled drive"

PNU_ALWAYS: dict[int, str] = {1: _CONTROL, 5: _SETPOINT, 32: _SETPOINT, 34: _SETPOINT, 35: _SETPOINT,
                              36: _SETPOINT, 37: _SETPOINT, 38: _SETPOINT, 1004: _SETPOINT, 1005: _SETPOINT,
                              1006: _SETPOINT, 1007: _SETPOINT}
PNU_WHEN_ENABLED: dict[int, str] = {930: _MODE, 915: _MAPPING, 916: _MAPPING, 922: _MAPPING}
OBJECT_ALWAYS: dict[int, str] = {0x6040: _CONTROL, 0x607A: _SETPOINT, 0x60FF: _SETPOINT, 0x6071: _SETPOINT,
                                 0x60C1: _SETPOINT, 0x60B1: _SETPOINT, 0x60B2: _SETPOINT, 0x6081: _SETPOINT,
                                 0x6083: _SETPOINT, 0x6084: _SETPOINT}
OBJECT_WHEN_ENABLED: dict[int, str] = {0x6060: _MODE, 0x1C12: _MAPPING, 0x1C13: _MAPPING, 0x3432: _MT_LOAD}
MAPPING_RANGES = ((0x1600, 0x17FF), (0x1A00, 0x1BFF))
#: Position Controller 0x25 instance 1 attributes (AKD EtherNet/IP manual appendix A, reference/ethernetip.md 1.8).
CIP_PC_ALWAYS: dict[int, str] = {17: "the enable attribute powers the axis",
                                 11: "the load handshake starts the loaded motion",
                                 101: "the home move attribute starts homing", 6: _SETPOINT, 7: _SETPOINT,
                                 10: _SETPOINT}
CIP_PC_WHEN_ENABLED: dict[int, str] = {3: _MODE}


@dataclass(frozen=True)
class Gated:
    """One gated address of a write: what it is, why it is gated, whether only while enabled."""

    address: str
    reason: str
    when_enabled: bool = False

    def text(self) -> str:
        return f"{self.address}: {self.reason}"


def classify_pnu(pnu: int, name: str = "") -> Gated | None:
    label = f"PNU {pnu}" + (f" ({name})" if name else "")
    if pnu in PNU_ALWAYS:
        return Gated(label, PNU_ALWAYS[pnu])
    if pnu in PNU_WHEN_ENABLED:
        return Gated(label, PNU_WHEN_ENABLED[pnu], when_enabled=True)
    return None


def classify_object(index: int, subindex: int, name: str = "") -> Gated | None:
    label = f"0x{index:04X}:{subindex}" + (f" ({name})" if name else "")
    if index in OBJECT_ALWAYS:
        return Gated(label, OBJECT_ALWAYS[index])
    if index in OBJECT_WHEN_ENABLED or any(lo <= index <= hi for lo, hi in MAPPING_RANGES):
        return Gated(label, OBJECT_WHEN_ENABLED.get(index, _MAPPING), when_enabled=True)
    return None


def classify_cip(class_id: int, instance: int, attribute: int, name: str = "") -> Gated | None:
    """A CIP attribute write (explicit messaging), by the same rules as PNUs and objects."""
    from akdctl.catalog.eip_parameters import by_name
    from akdctl.protocol import cip

    label = f"0x{class_id:02X}/{instance}/{attribute}" + (f" ({name})" if name else "")
    if class_id == cip.POSITION_CONTROLLER and instance == 1:
        if attribute in CIP_PC_ALWAYS:
            return Gated(label, CIP_PC_ALWAYS[attribute])
        if attribute in CIP_PC_WHEN_ENABLED:
            return Gated(label, CIP_PC_WHEN_ENABLED[attribute], when_enabled=True)
    home_move = by_name("HOME.MOVE")
    if class_id == cip.PARAMETER and home_move is not None and instance == home_move.instance and attribute == 1:
        return Gated(label, "the HOME.MOVE command starts homing ('akdctl home' supervises it)")
    if class_id == cip.ASSEMBLY and instance == 100:
        return Gated(label, "the command assembly powers and moves the axis")
    return None


def needing_consent(gated: list[Gated | None], enabled: bool | None) -> list[Gated]:
    """The gated addresses that need consent now; ``enabled`` None (unknown) counts as enabled."""
    return [g for g in gated if g is not None and (not g.when_enabled or enabled is not False)]


def drive_enabled(conn: Any) -> bool | None:
    """Is the power stage enabled? Reads only; None when the drive's state cannot be read.

    The one answer to that question for raw writes, recipes and parameter restores.
    """
    from akdctl.errors import AkdError

    try:
        return bool(conn.axis().read_status().enabled)
    except AkdError:
        return None


def consent_action(needing: list[Gated]) -> str:
    """The consent prompt's words for a gated write."""
    return "write " + "; ".join(g.text() for g in needing)


def check_write(conn: Any, gated: list[Gated | None], consent: Any, given: bool = False) -> None:
    """Ask ``consent(action)`` when a write touches gated addresses (the drive's state read only if it matters).

    ``given``: consent was already given (``--yes``), so nothing needs to be read or asked.
    """
    present = [g for g in gated if g is not None]
    if not present or given:
        return
    enabled = drive_enabled(conn) if any(g.when_enabled for g in present) else None
    needing = needing_consent(present, enabled)
    if needing:
        consent(consent_action(needing))


#: The port a scheme uses when the target names none (README "Targets"): spelled out or not, one axis.
_DEFAULT_PORTS = {"pn": 34964, "ecat-udp": 34980, "eip": 44818}
#: Query values that select the default (pn: slot 1, subslot 1, API 0x3A00, axis 0), as _number() spells them.
_DEFAULT_QUERY = {"pn": {"slot": "1", "subslot": "1", "api": str(0x3A00), "axis": "0"}}


def _number(text: str) -> str:
    """A decimal or 0x-hex number in its decimal spelling; any other text unchanged."""
    try:
        return str(int(text, 0)) if text.strip() else text
    except ValueError:
        return text


#: Schemes that reach the same drive by another route share one owner name.
_SAME_DRIVE = {"ecat+soem": "ecat"}


def owner_key(target: Any) -> str:
    """A file-name-safe name for the axis a target addresses (the owner lock's key).

    What selects the drive counts (scheme, host, port, path, the PROFINET ``axis``/``slot``);
    options that only change how it is spoken to (``drive=``, ``timeout``, ``bitrate``) do not,
    so ``sim`` and ``sim?drive=cia402`` are one axis. The address is normalised first (issue 23.15):
    a default port or query value spelled out or left away, and a number in hex or decimal
    (station ``1001`` or ``0x3e9``, ``?axis=0``) give one key. Two spellings of one host (a name
    and its address) are still two keys: the lock cannot know they meet.
    """
    scheme = _SAME_DRIVE.get(target.scheme, target.scheme)
    if scheme == "sim":
        who = f"sim/{target.host or 'default'}"
    else:
        port = "" if target.port in (None, _DEFAULT_PORTS.get(scheme)) else str(target.port)
        defaults = _DEFAULT_QUERY.get(scheme, {})
        extra = ""
        for key in ("slot", "subslot", "axis", "api"):
            if key in target.query:
                value = _number(target.query[key])
                if value != defaults.get(key):
                    extra += f"&{key}={value}"
        path = "/".join(_number(part) for part in target.path.strip("/").split("/"))
        who = f"{scheme}/{target.host.lower()}:{port}/{path}{extra}"
    readable = re.sub(r"[^A-Za-z0-9._-]+", "_", who).strip("_")[:80]
    return f"{readable}-{hashlib.sha256(who.encode()).hexdigest()[:12]}"
