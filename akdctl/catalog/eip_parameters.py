"""AKD Parameter object (class 0x0F) instances: name -> instance, each row with its source.

The instance number of every AKD parameter is in appendix B of the AKD EtherNet/IP manual and in
the "Fieldbus Information" box of each parameter's webhelp page (reference/ethernetip.md 1.9).
Only rows read in a cited source are listed; a name not here is refused locally rather than
guessed (the instance table is roughly alphabetical, so a guess would address another parameter).

``kind``: "int" (plain integer), "float" (x1000 integer on the wire, [M-25]), "position"
(scaled by EIP.POSUNIT), "velocity" (scaled by EIP.PROFUNIT) or "command" (a Set of attribute 1
with one byte runs it; reading does not, [M-26]). ``size`` is the byte length where the source
gives it; the client reads attribute 6 before every write anyway.
"""

from __future__ import annotations

from dataclasses import dataclass

RSL_74 = "https://www.easymanua.ls/kollmorgen/akd/manual/226937?p=74"       # appendix B, rev H [RSL-74]
M_26 = "https://manualshive.com/ru/manual/kollmorgen/akd-series/1990719?page=26"
POSUNIT_PAGE = "http://webhelp.kollmorgen.com/AKD/English/Content/CommandParamRefGuide/EIP/EIP.POSUNIT.htm"
PROFUNIT_PAGE = "http://webhelp.kollmorgen.com/AKD/English/Content/CommandParamRefGuide/EIP/EIP.PROFUNIT.htm"


@dataclass(frozen=True)
class EipParameter:
    name: str
    instance: int
    kind: str
    size: int | None
    source: str


PARAMETERS: tuple[EipParameter, ...] = (
    EipParameter("AIN.CUTOFF", 1, "float", 4, RSL_74),
    EipParameter("AIN.DEADBAND", 2, "float", 4, RSL_74),
    EipParameter("AIN.ISCALE", 3, "float", 4, RSL_74),
    EipParameter("AIN.OFFSET", 4, "float", 2, RSL_74),
    EipParameter("AIN.PSCALE", 5, "position", 8, RSL_74),
    EipParameter("AIN.VALUE", 7, "float", 4, RSL_74),
    EipParameter("AIN.VSCALE", 8, "velocity", 4, RSL_74),
    EipParameter("AIN.ZERO", 9, "command", 1, RSL_74),
    EipParameter("AOUT.ISCALE", 10, "float", 4, RSL_74),
    EipParameter("AOUT.MODE", 11, "int", 2, RSL_74),
    EipParameter("AOUT.OFFSET", 12, "float", 4, RSL_74),
    EipParameter("AOUT.PSCALE", 13, "position", 8, RSL_74),
    EipParameter("BODE.EXCITEGAP", 20, "int", 1, RSL_74),
    EipParameter("HOME.MOVE", 205, "command", 1, M_26),
    EipParameter("EIP.POSUNIT", 796, "int", 4, POSUNIT_PAGE),
    EipParameter("EIP.PROFUNIT", 797, "int", 4, PROFUNIT_PAGE),
)

_BY_NAME = {p.name: p for p in PARAMETERS}
_BY_INSTANCE = {p.instance: p for p in PARAMETERS}


def by_name(name: str) -> EipParameter | None:
    return _BY_NAME.get(name.strip().upper())


def by_instance(instance: int) -> EipParameter | None:
    return _BY_INSTANCE.get(instance)
