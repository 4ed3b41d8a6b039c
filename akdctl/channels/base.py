"""The two channel contracts the drive layer speaks to.

:class:`ParameterChannel` reads and writes PROFIdrive parameters (PNUs) in
batches; :class:`ObjectChannel` uploads and downloads CANopen/CoE objects.
Both count their round trips (``requests``) so benchmarks and tests can prove
that batching works. Per-parameter refusals come back as
:class:`~akdctl.protocol.bmp.ParameterFailure` results (a multi-parameter
read can be partly good); link failures raise :class:`akdctl.errors.CommError`.

:func:`sdo_aborted` is the one place an SDO abort code becomes the
:class:`~akdctl.errors.SdoAborted` error, for every SDO client (CoE mailbox,
CANopen, SOEM); the words come from :mod:`akdctl.catalog.texts`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from akdctl.errors import SdoAborted, UsageError

if TYPE_CHECKING:
    from akdctl.protocol.emcy import Emergency
    from akdctl.protocol.bmp import ParameterAddress, ParameterDescription, ParameterFailure, ParameterValue

    ParameterResult = ParameterValue | ParameterFailure


class ParameterChannel(ABC):
    """Batched PROFIdrive base-mode parameter access."""

    requests: int = 0

    @abstractmethod
    def read(self, addresses: Sequence["ParameterAddress"]) -> list["ParameterResult"]:
        """Read every address (split into as few requests as the limits allow);
        one result per address, in order."""

    @abstractmethod
    def write(self, items: Sequence[tuple["ParameterAddress", "ParameterValue"]]) -> list["ParameterFailure | None"]:
        """Change every parameter (batched); ``None`` where the change was accepted."""

    @abstractmethod
    def read_description(self, pnu: int) -> "ParameterDescription":
        """The parameter's PROFIdrive description (attribute 0x20); refusals raise ParameterRefused."""

    def close(self) -> None:
        """Release what the channel holds on its link; safe to call twice."""


class ObjectChannel(ABC):
    """SDO access to the object dictionary (CoE over EtherCAT, CANopen, simulated)."""

    requests: int = 0

    @abstractmethod
    def upload(self, index: int, subindex: int) -> bytes:
        """Read an object's raw little-endian bytes; raises SdoAborted on abort."""

    @abstractmethod
    def download(self, index: int, subindex: int, data: bytes) -> None:
        """Write raw little-endian bytes; raises SdoAborted on abort."""

    def take_emergencies(self) -> list["Emergency"]:
        """Emergencies received since the last call (drained)."""
        return []

    def object_list(self) -> list[int]:
        """Indices of the objects the drive has (SDO information service)."""
        raise UsageError("this link does not offer the SDO information service (object list)")

    def object_description(self, index: int) -> Any:
        """One object's description (SDO information service): name, object code, max subindex."""
        raise UsageError("this link does not offer the SDO information service (object description)")

    def entry_description(self, index: int, subindex: int) -> Any:
        """One entry's description (SDO information service): name, data type, bit length, access."""
        raise UsageError("this link does not offer the SDO information service (entry description)")

    def close(self) -> None:
        """Stop whatever the channel registered on its link (emergency callbacks); safe to call twice."""


class LazyObjectChannel(ObjectChannel):
    """An object channel built on first use, so commands that never use it never import its codecs
    (a PNU-only command over the simulator does not load the CoE codecs)."""

    def __init__(self, build: Callable[[], ObjectChannel]) -> None:
        self._build = build
        self._channel: ObjectChannel | None = None

    @property
    def channel(self) -> ObjectChannel:
        if self._channel is None:
            self._channel = self._build()
        return self._channel

    @property
    def requests(self) -> int:  # type: ignore[override]
        return self._channel.requests if self._channel is not None else 0

    def upload(self, index: int, subindex: int) -> bytes:
        return self.channel.upload(index, subindex)

    def download(self, index: int, subindex: int, data: bytes) -> None:
        self.channel.download(index, subindex, data)

    def take_emergencies(self) -> list["Emergency"]:
        return self.channel.take_emergencies() if self._channel is not None else []

    def object_list(self) -> list[int]:
        return self.channel.object_list()

    def object_description(self, index: int) -> Any:
        return self.channel.object_description(index)

    def entry_description(self, index: int, subindex: int) -> Any:
        return self.channel.entry_description(index, subindex)

    def close(self) -> None:
        if self._channel is not None:
            self._channel.close()

    def __getattr__(self, name: str) -> object:
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self.channel, name)


def sdo_aborted(code: int, what: str, *, where: str | None = None, fallback: Mapping[int, str] | None = None,
                details: dict[str, object] | None = None) -> SdoAborted:
    """The error for an SDO abort: what was asked (``what``: "upload of 0x6041:00"), the code and its
    words from the catalogue. ``fallback`` (the CANopen library's own table) words only the codes the
    catalogue lacks; without it an unknown code names itself. ``where`` names the node when the
    target alone does not."""
    from akdctl.catalog.texts import SDO_ABORT_TEXTS, sdo_abort_text

    code = int(code) & 0xFFFFFFFF
    text = sdo_abort_text(code)
    if code not in SDO_ABORT_TEXTS and fallback is not None and code in fallback:
        text = fallback[code]
    return SdoAborted(
        f"SDO {what} aborted: 0x{code:08X} {text}" + (f" ({where})" if where else ""),
        code=code,
        details={**(details or {}), "abort_code": f"0x{code:08X}", "abort_text": text},
    )


def sdo_what(verb: str, index: int, subindex: int) -> str:
    """"upload of 0x6041:00": how every SDO client names a transfer in its messages."""
    return f"{verb} of 0x{index:04X}:{subindex:02X}"
