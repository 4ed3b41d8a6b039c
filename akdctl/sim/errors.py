"""The refusals a simulated drive's servers raise, kept light so the model imports fast.

``PnuAccessError`` carries a PROFIdrive error value (the PNU server turns it
into a negative response); ``SdoAccessError`` carries a CiA 301 abort code (the
SDO servers turn it into an abort); ``RecordRefused`` carries a PROFINET
record-layer Error_Code_1 (the record link or PNIO face refuses the write).
"""

from __future__ import annotations


class PnuAccessError(Exception):
    """The model refuses one parameter access with a PROFIdrive error value (and optional additional info)."""

    def __init__(self, error: int, additional: int | None = None, message: str = "") -> None:
        super().__init__(message or f"PROFIdrive error 0x{error:02X}")
        self.error = error
        self.additional = additional


class SdoAccessError(Exception):
    """Raised by an ObjectAccess to refuse an access with an SDO abort code."""

    def __init__(self, code: int, message: str = "") -> None:
        if not message:
            from akdctl.catalog.texts import sdo_abort_text

            message = sdo_abort_text(code)
        super().__init__(message)
        self.code = code


class RecordRefused(Exception):
    """The parameter manager refuses a record 47 write itself (PDRV V4.2 table 169 Error_Code_1, e.g. 0xB7).

    Raised by :meth:`akdctl.sim.pnu_server.PnuServer.handle` for a request that no base-mode
    response can answer (docs/fidelity.md F1); the record layer in front of it reports it.
    """

    def __init__(self, code1: int, message: str = "") -> None:
        super().__init__(message or f"record write refused (Error_Code_1 0x{code1:02X})")
        self.code1 = code1


class DamagedState(ValueError):
    """A component's persisted state, read when the component is first used (sim/model.py builds the rarely used
    ones lazily), is damaged; the store reports the state file corrupt (sim/drive.py)."""
