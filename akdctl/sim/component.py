"""What a simulated-drive component is, and the access-error codes components and the model raise.

Why a module of its own: the model (``sim/model.py``) lists its components by
import, and every component needs the base class and the codes; living here,
below both, neither has to import the other at load time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from akdctl.sim.model import DriveModel

# PROFIdrive error values the model raises (profidrive_reference.md).
PE_IMPERMISSIBLE_PNU = 0x00
PE_READ_ONLY = 0x01
PE_LIMIT = 0x02
PE_BAD_SUBINDEX = 0x03
PE_NO_ARRAY = 0x04
PE_WRONG_TYPE = 0x05
PE_NO_DESCRIPTION = 0x09
PE_OPERATING_STATE = 0x11
PE_VALUE_IMPERMISSIBLE = 0x14
PE_ILLEGAL_FORMAT = 0x17
PE_VALUE_COUNT = 0x18

# CiA 301 / ETG.1000.6 abort codes the model raises.
ABORT_UNSUPPORTED_ACCESS = 0x06010000
ABORT_WRITE_ONLY = 0x06010001
ABORT_READ_ONLY = 0x06010002
ABORT_NO_OBJECT = 0x06020000
ABORT_TYPE_LENGTH = 0x06070010
ABORT_TOO_LONG = 0x06070012
ABORT_TOO_SHORT = 0x06070013
ABORT_NO_SUBINDEX = 0x06090011
ABORT_VALUE_RANGE = 0x06090030
ABORT_VALUE_HIGH = 0x06090031
ABORT_VALUE_LOW = 0x06090032
ABORT_DEVICE_STATE = 0x08000022



class Component:
    """Base for a model component: owns some PNUs/objects and some state.

    Subclasses set ``name`` (the key of their state), register bindings in
    ``__init__`` and may override :meth:`tick`, :meth:`to_state`, :meth:`load_state`.
    """

    name = "component"

    def __init__(self, model: "DriveModel") -> None:
        self.model = model

    def tick(self, dt: float) -> None:
        """Advance by ``dt`` seconds of virtual time."""

    def to_state(self) -> dict[str, Any]:
        return {}

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`to_state` returned (may be missing keys after an upgrade)."""
