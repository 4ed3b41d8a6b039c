"""The two refusals a simulated drive's model raises, kept light so the model imports fast.

``PnuAccessError`` carries a PROFIdrive error value (the PNU server turns it
into a negative response); ``SdoAccessError`` carries a CiA 301 abort code (the
SDO servers turn it into an abort).
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
