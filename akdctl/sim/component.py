"""What a simulated-drive component is, how its persisted state says it changed, and the access-error codes
components and the model raise.

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

_MISSING = object()


class Tracked:
    """Persisted state that counts its changes: the one rule behind "save only when something changed".

    The rule (docs/internals.md, "The revision rule"): **whatever changes what ``to_state()``
    returns bumps a revision.** Two ways, both here:

    * an assignment to a name in ``FIELDS`` or ``PERSISTED`` bumps it by itself (``__setattr__`` compares with
      the old value, so a tick that writes the same 0.0 again at rest changes nothing);
    * a change *inside* a container (a list appended, a dict item set) cannot be seen that way: the method that
      makes it calls :meth:`changed`.

    ``changed`` bumps this object's ``revision`` and the drive model's (``DriveModel.revision``), so the store
    decides whether to save by comparing one integer - the cost does not grow with the state.
    ``tests/test_sim_revision.py`` runs every kind of request and fails when ``to_state()`` changed while the
    revision did not.
    """

    FIELDS: tuple[str, ...] = ()  # persisted attributes (FieldState saves exactly these)
    PERSISTED: tuple[str, ...] = ()  # further persisted attributes a component's own to_state() saves
    _TRACKED: frozenset[str] = frozenset()
    revision = 0  # this object's changes (the class default until the first one)

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        cls._TRACKED = frozenset(cls.FIELDS) | frozenset(cls.PERSISTED)

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        """A new object with an ordinary (combined) ``__dict__`` from the start.

        Why: :meth:`__setattr__` and :meth:`changed` reach ``self.__dict__``, which turns CPython 3.11's inline
        attribute values into a *split* dict; its specialised attribute load (LOAD_ATTR_WITH_HINT) then misses on
        every read and takes the generic path -- ~300 machine instructions per ``self.x`` of a component, on every
        served request (issue 29: ``self.mode`` and ``self.since_access`` on a PNU 930 read). A combined dict is
        what the specialised load expects; behaviour is the same."""
        self = super().__new__(cls)
        object.__setattr__(self, "__dict__", {})
        return self

    def _model_of(self) -> "DriveModel | None":
        raise NotImplementedError

    def changed(self) -> None:
        """Persisted state changed in a way an assignment to a field does not show (a container's content)."""
        self.__dict__["revision"] = self.revision + 1
        model = self._model_of()
        if model is not None:
            model.revision += 1

    def __setattr__(self, name: str, value: Any) -> None:
        if name in self._TRACKED:
            old = self.__dict__.get(name, _MISSING)
            if old is not value and (old is _MISSING or old != value or type(old) is not type(value)):
                self.changed()
        object.__setattr__(self, name, value)


class Component(Tracked):
    """Base for a model component: owns some PNUs/objects and some state.

    Subclasses set ``name`` (the key of their state), register bindings in
    ``__init__`` and may override :meth:`tick`, :meth:`to_state`, :meth:`load_state`.
    Their persisted state follows :class:`Tracked`'s rule: fields in ``FIELDS``, :meth:`changed` for the rest.
    """

    name = "component"

    def __init__(self, model: "DriveModel") -> None:
        self.model = model

    def _model_of(self) -> "DriveModel | None":
        return self.__dict__.get("model")

    def tick(self, dt: float) -> None:
        """Advance by ``dt`` seconds of virtual time."""

    def still(self) -> bool:
        """Whether a :meth:`tick` now, of any length, would change nothing (the model then moves only its clock
        until the revision moves: ``DriveModel.advance``). A component that overrides :meth:`tick` says when."""
        return True

    def to_state(self) -> dict[str, Any]:
        return {}

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore what :meth:`to_state` returned (may be missing keys after an upgrade)."""


class FieldState(Tracked):
    """State kept as named attributes and persisted as a flat dict of them (``FIELDS``).

    Why: the motion component's parts (power stage, word machines, axis) each own
    some of the fields of one persisted ``motion`` state; each lists its names
    once and shares this one way to save and restore them. A part belongs to a component (``owner``, given
    by :meth:`__init__`): its changes count as the component's.
    """

    def __init__(self, owner: "Tracked | None") -> None:
        self.__dict__["owner"] = owner

    def _model_of(self) -> "DriveModel | None":
        owner = self.__dict__.get("owner")
        return owner._model_of() if owner is not None else None

    def changed(self) -> None:
        Tracked.changed(self)
        owner = self.__dict__.get("owner")
        if owner is not None:
            owner.__dict__["revision"] = owner.revision + 1

    def to_state(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in self.FIELDS}

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore the fields present in ``state`` (a missing one keeps its default)."""
        for name in self.FIELDS:
            if name in state:
                setattr(self, name, state[name])
