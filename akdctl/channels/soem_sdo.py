"""SoemObjectChannel: the ObjectChannel over a pysoem slave's own SDO client (``ecat+soem://``).

SOEM already runs the CoE SDO protocol (and its own framing), so this adapter only
counts transfers and turns pysoem's exceptions into akdctl's errors: an abort
through :func:`~akdctl.channels.base.sdo_aborted`, a missing working counter as
:class:`~akdctl.errors.NoAnswer`, mailbox and packet errors as communication errors.
An upload is bounded by pysoem's read buffer (256 bytes unless a size is given): SOEM
stops there, so no hostile slave can make it grow; its waits are the transport's
``sdo_read_timeout``/``sdo_write_timeout``, set from ``--timeout``.
"""

from __future__ import annotations

from typing import Any

from akdctl.channels.base import ObjectChannel, sdo_aborted, sdo_what
from akdctl.errors import CommError, MalformedReply, NoAnswer


class SoemObjectChannel(ObjectChannel):
    """SDO upload/download through a pysoem slave object."""

    def __init__(self, slave: Any, where: str, pysoem: Any = None) -> None:
        if pysoem is None:
            import pysoem as module

            pysoem = module
        self.slave, self.pysoem, self.where = slave, pysoem, where
        self.requests = 0

    def _call(self, verb: str, index: int, subindex: int, fn: Any, *args: Any) -> Any:
        p = self.pysoem
        what = sdo_what(verb, index, subindex)
        self.requests += 1
        try:
            return fn(index, subindex, *args)
        except p.SdoError as exc:
            raise sdo_aborted(int(getattr(exc, "abort_code", 0)), what).with_target(self.where) from None
        except p.WkcError:
            raise NoAnswer(f"no answer to SDO {what} (working counter)", target=self.where) from None
        except p.MailboxError as exc:
            raise CommError(f"mailbox error on SDO {what}: {exc}", target=self.where) from None
        except p.PacketError as exc:
            raise MalformedReply(f"unexpected reply to SDO {what}: {exc}", target=self.where) from None

    def upload(self, index: int, subindex: int) -> bytes:
        return bytes(self._call("upload", index, subindex, self.slave.sdo_read))

    def download(self, index: int, subindex: int, data: bytes) -> None:
        self._call("download", index, subindex, self.slave.sdo_write, bytes(data))
