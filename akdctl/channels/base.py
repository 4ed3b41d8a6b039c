"""The two channel contracts the drive layer speaks to.

:class:`ParameterChannel` reads and writes PROFIdrive parameters (PNUs) in
batches; :class:`ObjectChannel` uploads and downloads CANopen/CoE objects.
Both count their round trips (``requests``) so benchmarks and tests can prove
that batching works. Per-parameter refusals come back as
:class:`~akdctl.protocol.profidrive.ParameterFailure` results (a multi-parameter
read can be partly good); link failures raise :class:`akdctl.errors.CommError`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import TYPE_CHECKING

from akdctl.errors import UsageError

if TYPE_CHECKING:
    from akdctl.protocol.emcy import Emergency
    from akdctl.protocol.profidrive import ParameterAddress, ParameterFailure, ParameterValue

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
