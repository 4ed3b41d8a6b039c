"""``ecat+soem://IFNAME[/POSITION]``: EtherCAT through pysoem (SOEM), the optional extra ``akdctl[soem]``.

For sites that trust SOEM's master more than our pure-Python one, or need its
speed. SOEM does its own framing, so frames are not seen by ``--trace`` /
``--pcap`` here (capture the interface with tshark instead); SDO aborts, lost
mailboxes and missing privileges are mapped onto akdctl's errors.
"""

from __future__ import annotations

import contextlib
from typing import Any

from akdctl.channels.base import ObjectChannel
from akdctl.errors import CommError, MalformedReply, NoAnswer, SdoAborted, UsageError
from akdctl.transport.base import LinkOptions, Transport
from akdctl.io.raw_socket import CAP_HINT
from akdctl.transport.ethercat_raw import interface_name
from akdctl.transport.target import Target


def _abort_text(code: int) -> str:
    from akdctl.catalog.texts import sdo_abort_text as abort_text

    return abort_text(code)


class SoemObjectChannel(ObjectChannel):
    """SDO upload/download through a pysoem slave object."""

    def __init__(self, slave: Any, pysoem: Any, where: str) -> None:
        self.slave, self.pysoem, self.where = slave, pysoem, where

    def _call(self, what: str, index: int, subindex: int, fn: Any, *args: Any) -> Any:
        p = self.pysoem
        self.requests += 1
        try:
            return fn(index, subindex, *args)
        except p.SdoError as exc:
            code = int(getattr(exc, "abort_code", 0))
            raise SdoAborted(f"SDO {what} of 0x{index:04X}:{subindex:02X} aborted: 0x{code:08X} {_abort_text(code)}",
                             code=code, target=self.where) from None
        except p.WkcError:
            raise NoAnswer(f"no answer to SDO {what} of 0x{index:04X}:{subindex:02X} (working counter)",
                           target=self.where) from None
        except p.MailboxError as exc:
            raise CommError(f"mailbox error on SDO {what} of 0x{index:04X}:{subindex:02X}: {exc}",
                            target=self.where) from None
        except p.PacketError as exc:
            raise MalformedReply(f"unexpected reply to SDO {what} of 0x{index:04X}:{subindex:02X}: {exc}",
                                 target=self.where) from None

    def upload(self, index: int, subindex: int) -> bytes:
        return bytes(self._call("upload", index, subindex, self.slave.sdo_read))

    def download(self, index: int, subindex: int, data: bytes) -> None:
        self._call("download", index, subindex, self.slave.sdo_write, bytes(data))


class EthercatSoemTransport(Transport):
    scheme = "ecat+soem"

    def __init__(self, target: Target, options: LinkOptions) -> None:
        super().__init__(target, options)
        self.master: Any = None

    def open(self) -> None:
        import pysoem

        ifname = interface_name(self.target)
        parts = self.target.path_parts
        position = int(parts[0], 0) if parts else 0
        master = pysoem.Master()
        try:
            master.open(ifname)
        except ConnectionError:
            raise UsageError(f"ecat+soem://{ifname}: cannot open the interface: it needs CAP_NET_RAW ({CAP_HINT}) "
                             "and must exist") from None
        self.master = master
        micro = int(self.options.timeout * 1e6)
        for attr in ("sdo_read_timeout", "sdo_write_timeout"):
            with contextlib.suppress(AttributeError, TypeError, ValueError):
                setattr(master, attr, micro)
        count = master.config_init()
        if count <= 0:
            raise NoAnswer(f"no EtherCAT slave answered on {ifname} (SOEM config_init found none)")
        if position >= count:
            raise UsageError(f"target {self.target.raw!r}: no slave at position {position} "
                             f"({count} slave{'s' if count != 1 else ''} found, positions 0..{count - 1})")
        self.objects = SoemObjectChannel(master.slaves[position], pysoem, self.target.display)

    def close(self) -> None:
        if self.master is not None:
            with contextlib.suppress(Exception):
                self.master.close()
            self.master = None
