"""Raw writes of PNUs and objects: ``pnu set``, ``sdo write`` and the recipe's ``set`` step, planned once.

Why one operation for three callers: each used to write, gate and read back on its
own (three read-back comparisons, two refusal texts, the gated addresses named in the
recipe's validator). Here a request is the already-checked list of
:class:`WriteTarget` (a PNU address with its values, or an object with its type,
value and bytes); :func:`plan` classifies every address through
:mod:`akdctl.drive.gate`, reads the power stage only when a write is gated only
while enabled, and :func:`execute` writes the PNUs in one batched request and the
objects one SDO download each, then reads back through
:func:`akdctl.drive.operation.check_readback` when the plan says ``verify``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from akdctl.drive.operation import PlannedWrite, WritePlan, check_readback, read_enabled
from akdctl.protocol.record import Record

if TYPE_CHECKING:
    from akdctl.connection import Connection
    from akdctl.drive.gate import Gated
    from akdctl.drive.values import PnuSpec


class WriteTarget(Record):
    """One checked write: ``kind`` "pnu" (``spec`` and ``values``) or "object" (``index``, ``subindex``,
    ``dtype``, ``value`` as typed, ``data`` as sent); ``name`` from the catalogue ("" when unknown)."""

    __slots__ = ("kind", "spec", "values", "index", "subindex", "dtype", "value", "data", "name")

    def __init__(self, kind: str, *, spec: "PnuSpec | None" = None, values: Sequence[int] = (), index: int = 0,
                 subindex: int = 0, dtype: str = "", value: Any = None, data: bytes = b"", name: str = "") -> None:
        self.kind = kind
        self.spec = spec
        self.values = list(values)
        self.index = index
        self.subindex = subindex
        self.dtype = dtype
        self.value = value
        self.data = data
        self.name = name

    @property
    def address(self) -> str:
        """How a user reads the address: ``PNU 930 (Operating mode)``, ``0x6060:0 (Modes of operation)``."""
        if self.kind == "pnu":
            assert self.spec is not None
            return f"PNU {self.spec.label}" + (f" ({self.name})" if self.name else "")
        return f"0x{self.index:04X}:{self.subindex}" + (f" ({self.name})" if self.name else "")

    def display(self) -> str:
        if self.kind == "pnu":
            from akdctl.drive.values import pnu_display

            assert self.spec is not None
            return ",".join(pnu_display(self.spec.pnu, self.spec.subindex + i, v) for i, v in enumerate(self.values))
        if isinstance(self.value, (bytes, bytearray)):
            return "0x" + bytes(self.value).hex()
        return str(self.value) + (f" ({self.dtype})" if self.dtype else "")

    def gated(self) -> "Gated | None":
        """The gate's verdict for this address (akdctl.drive.gate, the one classification)."""
        from akdctl.drive import gate

        if self.kind == "pnu":
            assert self.spec is not None
            return gate.classify_pnu(self.spec.pnu, self.name)
        return gate.classify_object(self.index, self.subindex, self.name)


def pnu_target(spec: "PnuSpec", values: Sequence[int]) -> WriteTarget:
    return WriteTarget("pnu", spec=spec, values=values, name=spec.info.name if spec.info is not None else "")


def object_target(index: int, subindex: int, dtype: str, value: Any, data: bytes, name: str = "") -> WriteTarget:
    return WriteTarget("object", index=index, subindex=subindex, dtype=dtype, value=value, data=bytes(data), name=name)


class SetRequest(Record):
    """What to write, in order, and whether to read every value back."""

    __slots__ = ("targets", "verify")

    def __init__(self, targets: Sequence[WriteTarget], verify: bool = False) -> None:
        self.targets = list(targets)
        self.verify = verify

    @property
    def operation(self) -> str:
        """The command's words: "pnu set", "sdo write", or "set" when a recipe step mixes both."""
        kinds = {t.kind for t in self.targets}
        return "pnu set" if kinds == {"pnu"} else "sdo write" if kinds == {"object"} else "set"


def gated(request: SetRequest) -> list["Gated"]:
    """The gated addresses of a request, without the drive (a recipe's consent is asked before it runs)."""
    return [g for g in (t.gated() for t in request.targets) if g is not None]


def plan(conn: "Connection", request: SetRequest) -> WritePlan:
    """The writes in order with the gate's verdict; reads the power stage only when a write depends on it.

    A target without the channel a write needs is refused here, before any consent is asked."""
    kinds = {t.kind for t in request.targets}
    if "pnu" in kinds:
        conn.parameters()
    if "object" in kinds:
        conn.objects()
    writes = [PlannedWrite(t.address, list(t.values) if t.kind == "pnu" else t.data, t.display(), t.gated())
              for t in request.targets]
    return WritePlan(request.operation, conn.target.display, writes, enabled=read_enabled(conn, writes),
                     verify=request.verify, data={"request": request})


def execute(conn: "Connection", plan: WritePlan) -> list[dict[str, Any]]:
    """Write the plan (PNUs in one batched request first, then each object), read back if asked (exit 5)."""
    from akdctl.drive.values import pnu_refused, write_pnus

    request: SetRequest = plan.data["request"]
    pnus = [t for t in request.targets if t.kind == "pnu"]
    done: list[dict[str, Any]] = []
    if pnus:
        results = write_pnus(conn.parameters(), [(_spec(t), t.values) for t in pnus])
        failed = [r for r in results if not r.ok]
        if failed:
            raise pnu_refused(failed[0], "change", more=len(failed) - 1)
        done += [{"address": t.address, "value": t.values if len(t.values) > 1 else t.values[0]} for t in pnus]
    for target in request.targets:
        if target.kind == "object":
            conn.objects().download(target.index, target.subindex, target.data)
            done.append({"address": target.address, "value": _jsonable(target.value), "bytes": target.data.hex()})
    if plan.verify:
        check_readback(read_back(conn, request.targets))
    return done


def read_back(conn: "Connection", targets: Sequence[WriteTarget]) -> list[tuple[str, Any, Any]]:
    """(address, written, read back) for every target: PNUs in one batched read, objects decoded by their type."""
    from akdctl.drive.values import decode, pnu_refused, read_pnus

    pairs: list[tuple[str, Any, Any]] = []
    pnus = [t for t in targets if t.kind == "pnu"]
    if pnus:
        for target, back in zip(pnus, read_pnus(conn.parameters(), [_spec(t) for t in pnus])):
            if not back.ok:
                raise pnu_refused(back, "read")
            pairs.append((target.address, target.values, list(back.values or [])))
    for target in targets:
        if target.kind == "object":
            got = decode(target.dtype, conn.objects().upload(target.index, target.subindex))
            pairs.append((target.address, decode(target.dtype, target.data), got))
    return pairs


def _spec(target: WriteTarget) -> "PnuSpec":
    assert target.spec is not None, "a PNU target always has its address"
    return target.spec


def _jsonable(value: Any) -> Any:
    return "0x" + bytes(value).hex() if isinstance(value, (bytes, bytearray)) else value


__all__ = ["SetRequest", "WriteTarget", "execute", "gated", "object_target", "plan", "pnu_target", "read_back"]
