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
:func:`confirm_write` is the one place a write whose answer went missing is
judged (read back, never written again) for the SDO clients that run the
protocol themselves or drive a library's client transfer by transfer.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

from akdctl.errors import AkdError, NoAnswer, SdoAborted, UnknownOutcome, UsageError

#: The most bytes one SDO upload may bring on any SDO client, whatever the server declares: far above any
#: AKD object (the longest are strings of a few hundred bytes), far below what would hurt the machine.
MAX_UPLOAD = 1 << 20

if TYPE_CHECKING:
    from akdctl.protocol.coe_info import EntryDescription, ObjectDescription
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

    def object_description(self, index: int) -> "ObjectDescription":
        """One object's description (SDO information service): name, object code, max subindex."""
        raise UsageError("this link does not offer the SDO information service (object description)")

    def entry_description(self, index: int, subindex: int) -> "EntryDescription":
        """One entry's description (SDO information service): name, data type, bit length, access."""
        raise UsageError("this link does not offer the SDO information service (entry description)")

    def close(self) -> None:
        """Stop whatever the channel registered on its link (emergency callbacks); safe to call twice."""


class LazyObjectChannel(ObjectChannel):
    """An object channel built on first use, so commands that never use it never import its codecs
    (a PNU-only command over the simulator does not load the CoE codecs).

    It forwards exactly the :class:`ObjectChannel` contract and nothing else: whoever needs more than the
    contract declares it there (with a neutral default), so nothing falls through by name."""

    def __init__(self, build: Callable[[], ObjectChannel]) -> None:
        self._build = build
        self._channel: ObjectChannel | None = None

    @property
    def channel(self) -> ObjectChannel:
        if self._channel is None:
            self._channel = channel = self._build()
            # a poll's uploads go straight to the channel once it is built: no second call per upload
            self.upload = channel.upload  # type: ignore[method-assign]
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

    def object_description(self, index: int) -> "ObjectDescription":
        return self.channel.object_description(index)

    def entry_description(self, index: int, subindex: int) -> "EntryDescription":
        return self.channel.entry_description(index, subindex)

    def close(self) -> None:
        if self._channel is not None:
            self._channel.close()


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


def confirm_write(why: str, data: bytes, read_back: Callable[[], bytes] | None,
                  details: dict[str, object] | None = None) -> None:
    """A write's answer is missing or doubtful: success only if the object reads back ``data``.

    ``why`` says what happened ("no answer to the SDO download to 0x6040:00 within 2 s"); ``read_back``
    reads the object within what is left of the request's time (None: no time left). Anything else is
    :class:`~akdctl.errors.UnknownOutcome`: the drive may or may not have applied the write, and akdctl
    does not send it again -- a repeated controlword edge or command would act twice.
    """
    import logging

    details = {**(details or {}), "written": data.hex()}
    answered = False
    if read_back is None:
        found = "no time was left to read it back"
    else:
        try:
            back = read_back()
        except NoAnswer:
            found = "reading it back got no answer either"
        except AkdError as exc:
            answered = True
            found = f"it cannot be read back ({exc.message})"
        else:
            if _same_value(back, data):
                logging.getLogger("akdctl").info("%s; the object reads back the value written", why)
                return
            answered = True
            found = f"it reads back {back.hex(' ') or 'nothing'} (written: {data.hex(' ')})"
            details["read_back"] = back.hex()
    error = UnknownOutcome(
        f"{why}, and {found}: the drive may or may not have applied it. akdctl does not send a write "
        "twice; check the drive before repeating the command",
        details=details,
    )
    error.unanswered = not answered  # type: ignore[attr-defined]  # how links.Budget counts it
    raise error


def _same_value(back: bytes, written: bytes) -> bool:
    """Whether an object read back holds what was written (an expedited answer may pad to 4 bytes)."""
    if back == written:
        return True
    return len(written) <= 4 and len(back) == 4 and back[: len(written)] == written and not any(back[len(written):])
