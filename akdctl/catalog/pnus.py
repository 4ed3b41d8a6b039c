"""The PNUs of the AKD PROFINET manuals (000/004 section 5.6, 003 section 6.6).

Data only. ``type`` is the PROFIdrive data type the value has (U16, S16, U32,
S32, OS = octet string); ``elements`` is the array length for array PNUs
(``None`` for a simple variable). The AKD documents the transfer formats 0x41
byte, 0x42 word and 0x43 double word (SPEC-NOTES 5); ``wire_format`` says which
one a PNU is answered with.

Facts not in the manuals are marked in ``note`` (the simulator needs a value,
a real drive reports its own).
"""

from __future__ import annotations

from functools import cache

from akdctl.protocol.record import Record

# PROFIdrive standard data type codes (identifier bits 0-7) for descriptions.
DATATYPE_CODES = {"S16": 0x03, "S32": 0x04, "U16": 0x06, "U32": 0x07, "OS": 0x0A}
TYPE_BITS = {"S16": 16, "U16": 16, "S32": 32, "U32": 32, "OS": 8}


class PnuInfo(Record):
    """One PROFIdrive parameter as the AKD documents it."""

    __slots__ = ("pnu", "name", "type", "access", "description", "elements", "minimum", "maximum", "default", "unit",
                 "group", "akd_parameter", "note")

    def __init__(self, pnu: int, name: str, type: str, access: str, description: str, elements: int | None = None,
                 minimum: int | None = None, maximum: int | None = None, default: int | tuple[int, ...] = 0,
                 unit: str = "", group: str = "profidrive", akd_parameter: str = "", note: str = "") -> None:
        self.pnu = pnu
        self.name = name
        self.type = type
        self.access = access  # "rw" or "ro"
        self.description = description
        self.elements = elements
        self.minimum = minimum
        self.maximum = maximum
        self.default = default
        self.unit = unit
        self.group = group
        self.akd_parameter = akd_parameter
        self.note = note

    @property
    def signed(self) -> bool:
        return self.type.startswith("S")

    @property
    def bits(self) -> int:
        return TYPE_BITS[self.type]

    @property
    def is_array(self) -> bool:
        return self.elements is not None

    @property
    def length(self) -> int:
        """Number of elements (1 for a simple variable)."""
        return self.elements or 1

    @property
    def writable(self) -> bool:
        return self.access == "rw"

    @property
    def wire_format(self) -> int:
        """The BMP format the AKD answers with: 0x41 byte, 0x42 word, 0x43 double word."""
        return {8: 0x41, 16: 0x42, 32: 0x43}[self.bits]

    def limits(self) -> tuple[int, int]:
        """Allowed element values (the documented limits, else the type's range)."""
        bits = self.bits
        lo = -(1 << (bits - 1)) if self.signed else 0
        hi = (1 << (bits - 1)) - 1 if self.signed else (1 << bits) - 1
        return (self.minimum if self.minimum is not None else lo, self.maximum if self.maximum is not None else hi)

    def default_values(self) -> list[int]:
        if isinstance(self.default, tuple):
            values = list(self.default)
            return values + [0] * (self.length - len(values))
        return [self.default] * self.length


def _p(*args: object, **kwargs: object) -> PnuInfo:
    return PnuInfo(*args, **kwargs)  # type: ignore[arg-type]


# Telegram numbers the AKD offers (PNU 922): 0 free, 1, 7, 9 standard, 350/351 manufacturer.
TELEGRAMS = (0, 1, 7, 9, 350, 351)

_TABLE: tuple[PnuInfo, ...] = (
    # signals (manufacturer table of 5.6; the signal number equals the PNU, 5.8)
    _p(1, "STW1", "U16", "rw", "control word 1 (I/O control word)", group="signal", akd_parameter="control word 1"),
    _p(2, "ZSW1", "U16", "ro", "status word 1 (I/O status word)", group="signal", akd_parameter="status word 1"),
    # STW2/ZSW2/XIST_A travel in telegrams 9 and 351 (5.11.4, 003 6.11.6); 5.8: "The signals are also available
    # in the PNU list. Each signal can be read/write with the same PNU number", 5.6: all can go into telegram 0.
    _p(3, "STW2", "U16", "rw", "control word 2 (bits 12-15 master sign of life)", group="signal",
       note="not in the manual's PNU table; a signal of telegram 9, so a PNU by 5.8 (docs/fidelity.md F7)"),
    _p(4, "ZSW2", "U16", "ro", "status word 2 (bits 12-15 slave sign of life; 0 without clock synchronism)",
       group="signal", note="not in the manual's PNU table; a signal of telegram 9, so a PNU by 5.8 "
                            "(docs/fidelity.md F7)"),
    _p(5, "NSOLL_A", "S16", "rw", "velocity set point (X2, x=15: 2^15 = 12000 rpm)", unit="N2:12000rpm",
       group="signal", akd_parameter="VL.CMD"),
    _p(6, "NIST_A", "S16", "ro", "velocity actual value (X2, x=15: 2^15 = 12000 rpm)", unit="N2:12000rpm",
       group="signal", akd_parameter="VL.FB"),
    _p(28, "XIST_A", "S32", "ro", "position actual value A (counts; 2^PNU1002 per revolution)", unit="counts",
       group="signal", note="not in the manual's PNU table; a signal of telegrams 9 and 351, so a PNU by 5.8 "
                            "(docs/fidelity.md F7)"),
    _p(32, "SATZANW", "U16", "rw", "motion task selection (bit 15 selects MDI)", group="signal", akd_parameter="MT.MOVE"),
    _p(33, "AKTSATZ", "U16", "ro", "actual motion task (bit 15: MDI active)", group="signal", akd_parameter="MT.PARAMS"),
    _p(34, "MDI_TARPOS", "S32", "rw", "MDI target position (counts; 2^PNU1002 per revolution)", unit="counts",
       group="signal", akd_parameter="MT.P"),
    _p(35, "MDI_VELOCITY", "U32", "rw", "MDI velocity (X4, x=32: 2^32 = 12000 rpm)", unit="X4:12000rpm",
       group="signal", akd_parameter="MT.V"),
    _p(36, "MDI_ACC", "U16", "rw", "MDI acceleration (X2, x=16: 2^16 = 50,000,000 rpm/s)", unit="X2:50000000rpm/s",
       group="signal", akd_parameter="MT.ACC"),
    _p(37, "MDI_DEC", "U16", "rw", "MDI deceleration (X2, x=16: 2^16 = 50,000,000 rpm/s)", unit="X2:50000000rpm/s",
       group="signal", akd_parameter="MT.DEC"),
    _p(38, "MDI_MOD", "U16", "rw", "MDI mode (bit 0: 0 relative, 1 absolute)", minimum=0, maximum=1,
       group="signal", akd_parameter="MT.CNTL"),
    _p(52, "ITIST_GLATT", "S16", "ro", "active current (N2: 2^14 = DRV.IPEAK)", unit="N2:DRV.IPEAK",
       group="signal", akd_parameter="IL.FB",
       note="the manual's table says U16, its own example reads -182: signed (SPEC-NOTES 13)"),
    # PROFIdrive parameters (5.6)
    _p(915, "PZD setpoint assignment", "U16", "rw", "DO IO data configuration, set point telegram (signal numbers)",
       elements=10, group="telegram"),
    _p(916, "PZD actual value assignment", "U16", "rw", "DO IO data configuration, actual value telegram (signal numbers)",
       elements=10, group="telegram"),
    _p(922, "Telegram selection", "U16", "rw", "PROFIdrive telegram of the IO connection (0, 1, 7, 9, 350, 351)",
       default=1, group="telegram"),
    _p(923, "Signal list", "U16", "ro", "list of all parameters for signals: element n holds the PNU of signal n",
       elements=53, group="telegram"),
    _p(930, "Operating mode", "U16", "rw", "operating mode (DRV.OPMODE: 0 torque, 1 velocity, 2 position)",
       minimum=0, maximum=2, default=1, akd_parameter="DRV.OPMODE"),
    _p(944, "Fault message counter", "U16", "ro", "incremented with every new fault situation", group="fault"),
    _p(947, "Fault number", "U16", "ro", "fault buffer: 8 situations x 8 fault numbers, situation 0 active",
       elements=64, group="fault"),
    _p(964, "Drive unit identification", "U16", "ro",
       "[0] manufacturer, [1] drive unit type, [2] firmware version, [3] firmware year, [4] firmware day/month",
       elements=5, default=(0x0100, 0x0001, 120, 2013, 1505), group="identity",
       note="values are the simulator's; a real drive reports its own"),
    _p(965, "Profile identification number", "OS", "ro", "profile number 3 (PROFIdrive), version 41 (V4.1)",
       elements=2, default=(3, 41), group="identity"),
    _p(975, "DO identification", "U16", "ro",
       "[0] manufacturer, [1] DU type, [2] version, [3] year, [4] day/month, [5] DO type class, [6] sub-class, [7] DO id",
       elements=8, default=(0x0100, 0x0001, 120, 2013, 1505, 1, 1, 1), group="identity",
       note="values are the simulator's; a real drive reports its own"),
    *(
        _p(n, f"Number list of defined parameters ({n - 979})", "U16", "ro",
           "the implemented PNUs in ascending order, 0 ends the list", elements=0, group="identity")
        for n in range(980, 990)
    ),
    _p(1001, "Homing mode", "U16", "rw", "HOME.MODE: the homing procedure STW1 bit 11 starts", minimum=0, maximum=20,
       default=0, akd_parameter="HOME.MODE"),
    _p(1002, "Singleturn bits", "U16", "rw", "number of singleturn bits of MDI_TARPOS and XIST_A (default 16)",
       minimum=8, maximum=24, default=16, note="range is the simulator's; the manual gives only the default"),
    _p(1004, "Jog v1", "S16", "rw", "jogging set point 1 (velocity, X2 x=15 like NSOLL_A)", unit="N2:12000rpm",
       default=163, group="jog"),
    _p(1005, "Jog v2", "S16", "rw", "jogging set point 2 (velocity, X2 x=15 like NSOLL_A)", unit="N2:12000rpm",
       default=-163, group="jog"),
    _p(1006, "Jog Acc", "U16", "rw", "jogging acceleration (the velocity loop's acceleration ramp)", default=1000,
       group="jog", akd_parameter="DRV.ACC"),
    _p(1007, "Jog Dec", "U16", "rw", "jogging deceleration (the velocity loop's deceleration ramp)", default=1000,
       group="jog", akd_parameter="DRV.DEC"),
)


@cache
def pnu_table() -> dict[int, PnuInfo]:
    """Every catalogued PNU, the number-list PNUs 980..989 sized to hold the list."""
    table = {info.pnu: info for info in _TABLE}
    listed = sorted(p for p in table if not 980 <= p <= 989)
    # 980 holds the whole list plus its 0 terminator; 981..989 hold one 0 each.
    table[980] = table[980].replace(elements=len(listed) + 1, default=tuple(listed) + (0,))
    for n in range(981, 990):
        table[n] = table[n].replace(elements=1, default=(0,))
    return table


def lookup(pnu: int) -> PnuInfo | None:
    return pnu_table().get(pnu)


def by_name(name: str) -> PnuInfo | None:
    """Find a PNU by its signal or parameter name (case-insensitive), e.g. ``STW1``."""
    wanted = name.strip().lower()
    for info in pnu_table().values():
        if info.name.lower() == wanted:
            return info
    return None
