"""``ecat+soem://IFNAME[/POSITION]``: EtherCAT through pysoem (SOEM), the optional extra ``akdctl[soem]``.

For sites that trust SOEM's master more than our pure-Python one, or need its
speed. SOEM does its own framing, so frames are not seen by ``--trace`` /
``--pcap`` here (capture the interface with tshark instead). The transport offers
the pysoem slave as its SDO client; :mod:`akdctl.channels.soem_sdo` maps SDO
aborts and lost mailboxes onto akdctl's errors, missing privileges are mapped here.
"""

from __future__ import annotations

import contextlib
from typing import Any

from akdctl.errors import NoAnswer, UsageError
from akdctl.links import SoemSdoClient
from akdctl.transport.base import LinkOptions, Transport
from akdctl.io.raw_socket import CAP_HINT
from akdctl.transport.ethercat_raw import interface_name
from akdctl.transport.target import Target


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
        self.sdo_client = SoemSdoClient(master.slaves[position], self.target.display)

    def close(self) -> None:
        self.sdo_client = None
        if self.master is not None:
            with contextlib.suppress(Exception):
                self.master.close()
            self.master = None
