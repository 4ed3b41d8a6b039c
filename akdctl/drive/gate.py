"""The write gate: which raw writes can power or move the axis, and so need consent like ``enable``.

Why a gate: ``pnu set 1=0x047F`` or ``sdo write 0x6040:0 15`` reach the state
machine without the motion commands' consent. Every raw write path (``pnu set``,
``sdo write``, recipe ``set`` steps) classifies its addresses here, into the
:class:`~akdctl.drive.operation.WritePlan` it builds; the plan's ``needing_consent`` decides what the CLI
(:func:`akdctl.cli.consent.consent_plan`) or the recipe asks. README "Safety model" lists the same addresses.

The gate knows no list of addresses: it asks the catalogue for the *write class* of the row an address
names (catalog/objects.py ``write_class``, ``name_write_class``): every CoE object, PNU and CIP Parameter
instance that carries one AKD name gets that name's class, so ``pnu set 930``, ``sdo write 0x35B4`` (both
DRV.OPMODE) and ``param set DRV.OPMODE=`` are gated alike (:func:`classify_name` serves writes by name).

* always gated — control (the control words), power (DRV.EN, brake release), motion (MT.MOVE, HOME.MOVE) and
  set points (*.CMD, MT.P/V/ACC/DEC/CNTL, DRV.ACC/DEC, the CiA 402 targets and offsets, 0x2071 target current);
* gated while the drive is enabled (or its state cannot be read) — what changes the meaning of the running set
  points: the operating mode (DRV.OPMODE, 0x6060), the command or feedback source (DRV.CMDSOURCE, *.FBSOURCE),
  the telegram / process-data mapping (PNU 915, 916, 922; the CiA 301 PDO areas, 0x1C12, 0x1C13), and MT.LOAD
  (it loads a motion task into the profile-position set points; ``task list|show``).

CIP attributes (``cip set``, ``eip param set|run``): a Parameter object instance by its AKD name as above; the
Position Controller 0x25's attributes carry no AKD name, so their classes are written here (``CIP_PC_CLASSES``:
enable 17 power, load handshake 11 and home move 101 motion, target position/velocity and incremental flag
6, 7, 10 set points, mode 3); the command assembly (0x04/100) is control.

Ownership: whatever passes this gate (a motion, a recipe that moves, a gated raw
write) also owns the target's axis for the rest of the command, so two akdctl
processes never command one axis at once (:func:`owner_key` names the axis;
:func:`akdctl.cli.consent.own_axis` holds it). ``stop``, ``disable`` and ``fault
ack`` only take power away and never wait for an owner.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from akdctl.catalog.pnus import PnuInfo
    from akdctl.connection import Connection

_CONTROL = "the control word powers and moves the axis"
_SETPOINT = "a set point the drive acts on"
_MODE = "the operating mode of an enabled drive changes what its set points mean"
_MAPPING = "the process-data mapping of an enabled drive changes which set points it follows"
_MT_LOAD = "MT.LOAD replaces the profile-position set points 0x607A/0x6081/0x6083/0x6084 of an enabled drive"

#: Why two writes are gated by what they do rather than by an address's class (README "Safety model").
NMT_START = "in OPERATIONAL the node acts on the RPDOs on the bus: a master's controlword and set points"
EVERY_CYCLE = "written to the slave every cycle while it is in OP"

#: Write class (catalog/objects.py WRITE_CLASSES) -> (why it is gated, gated only while the drive is enabled).
CLASS_REASONS: dict[str, tuple[str, bool]] = {
    "control": (_CONTROL, False),
    "power": ("it switches the power stage or releases the brake", False),
    "motion": ("the command starts a motion ('akdctl move|home|task start' supervise it)", False),
    "setpoint": (_SETPOINT, False),
    "mode": (_MODE, True),
    "source": ("the command or feedback source of an enabled drive changes what it follows", True),
    "mapping": (_MAPPING, True),
    "task_load": (_MT_LOAD, True),
}
#: Position Controller 0x25 instance 1 attributes (AKD EtherNet/IP manual appendix A, reference/ethernetip.md 1.8):
#: CIP attributes carry no AKD name, so their classes are written here, once.
CIP_PC_CLASSES: dict[int, tuple[str, str | None]] = {
    17: ("power", "the enable attribute powers the axis"),
    11: ("motion", "the load handshake starts the loaded motion"),
    101: ("motion", "the home move attribute starts homing"),
    6: ("setpoint", None), 7: ("setpoint", None), 10: ("setpoint", None), 3: ("mode", None),
}


@dataclass(frozen=True)
class Gated:
    """One gated address of a write: what it is, why it is gated, whether only while enabled."""

    address: str
    reason: str
    when_enabled: bool = False
    write_class: str = ""

    def text(self) -> str:
        return f"{self.address}: {self.reason}"


def gated_for(label: str, cls: str | None, reason: str | None = None) -> Gated | None:
    """The Gated record of an address of write class ``cls`` (None: not gated)."""
    if cls is None:
        return None
    why, when_enabled = CLASS_REASONS[cls]
    return Gated(label, reason or why, when_enabled=when_enabled, write_class=cls)


def classify_name(name: str, label: str | None = None) -> Gated | None:
    """A write by AKD parameter name (``param set DRV.OPMODE=2``), by the catalogue's classes.

    The name's own class first (catalog/objects.py WRITE_CLASS_RULES); a name the rules do not know is
    classified like the catalogue rows that carry it (every CoE object and PNU of that AKD name).
    """
    from akdctl.catalog import objects, pnus

    label = label or name.strip().upper()
    cls = objects.name_write_class(name)
    if cls is None:
        for entry in objects.by_param(name):
            cls = cls or objects.write_class(entry)
        wanted = name.strip().lower()
        for info in pnus.pnu_table().values():
            if info.akd_parameter.lower() == wanted:
                cls = cls or pnu_write_class(info)
    return gated_for(label, cls)


def pnu_write_class(info: PnuInfo) -> str | None:
    """The write class of one catalogued PNU: the telegram group is mapping; otherwise its AKD name's class,
    else what its name/description says (PNU 1004 "jogging set point 1")."""
    from akdctl.catalog import objects

    if info.access != "rw":
        return None
    if info.group == "telegram":
        return "mapping"
    akd = info.akd_parameter
    return ((objects.name_write_class(akd) if akd else None) or objects.description_write_class(info.name)
            or objects.description_write_class(info.description))


def classify_pnu(pnu: int, name: str = "") -> Gated | None:
    """A PNU write, by the class of the catalogue's row (an uncatalogued PNU is refused by the drive anyway)."""
    from akdctl.catalog import pnus

    label = f"PNU {pnu}" + (f" ({name})" if name else "")
    info = pnus.lookup(pnu)
    return None if info is None else gated_for(label, pnu_write_class(info))


def classify_object(index: int, subindex: int, name: str = "") -> Gated | None:
    """An object write, by the class of the catalogue's row; an object the catalogue lacks by the CiA 301 PDO
    areas, then by the name the caller gives."""
    from akdctl.catalog import objects

    label = f"0x{index:04X}:{subindex}" + (f" ({name})" if name else "")
    entry = objects.lookup(index, subindex)
    if entry is not None:
        return gated_for(label, objects.write_class(entry))
    if objects.is_pdo_communication(index):
        return gated_for(label, "mapping")
    rows = objects.subentries(index)  # a sub-index the table lacks: the object's own class
    cls = next((c for c in (objects.write_class(r) for r in rows) if c), None)
    if cls is None and name:
        cls = objects.name_write_class(name) or objects.description_write_class(name)
    return gated_for(label, cls)


def classify_cip(class_id: int, instance: int, attribute: int, name: str = "") -> Gated | None:
    """A CIP attribute write (explicit messaging), by the same classes as PNUs and objects."""
    from akdctl.catalog.eip_parameters import by_instance
    from akdctl.protocol import cip

    label = f"0x{class_id:02X}/{instance}/{attribute}" + (f" ({name})" if name else "")
    if class_id == cip.POSITION_CONTROLLER and instance == 1 and attribute in CIP_PC_CLASSES:
        cls, reason = CIP_PC_CLASSES[attribute]
        return gated_for(label, cls, reason)
    if class_id == cip.PARAMETER and attribute == 1:
        row = by_instance(instance)
        if row is not None:
            return classify_name(row.name, label)
    if class_id == cip.ASSEMBLY and instance == 100:
        return gated_for(label, "control", "the command assembly powers and moves the axis")
    return None


def needing_consent(gated: Sequence[Gated | None], enabled: bool | None) -> list[Gated]:
    """The gated addresses that need consent now; ``enabled`` None (unknown) counts as enabled. The one rule:
    a write plan (:attr:`akdctl.drive.operation.WritePlan.needing_consent`) and a recipe's steps ask it."""
    return [g for g in gated if g is not None and (not g.when_enabled or enabled is not False)]


def drive_enabled(conn: "Connection") -> bool | None:
    """Is the power stage enabled? Reads only; None when the drive's state cannot be read.

    The one answer to that question for raw writes, recipes and parameter restores.
    """
    from akdctl.errors import AkdError

    try:
        return bool(conn.axis().read_status().enabled)
    except AkdError:
        return None


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


def serial_owner_key(serial: str) -> str:
    """The owner lock's second key: the serial number the drive reports (:func:`akdctl.drive.identity.serial_number`).

    Two spellings of one host (a name and its address) give two :func:`owner_key` keys; the drive's serial is one,
    so a command holds both locks and a second command on the same drive meets one of them (issue 23.15)."""
    return "serial-" + re.sub(r"[^A-Za-z0-9._-]+", "_", serial)[:40] + "-" + hashlib.sha256(serial.encode()).hexdigest()[:8]
