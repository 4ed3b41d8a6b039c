"""Reading a file from an EtherCAT slave by FoE, in the state it is in (PRE-OP or higher): ``ecat foe read``.

Why apart from :mod:`akdctl.drive.firmware`: a read writes nothing and changes no state, so it has no plan and
no consent; it only needs the slave's mailbox. Our raw master speaks FoE with :class:`FoeClient` over the
open mailbox (the slave's error code and text reach the user); ``ecat+soem://`` goes through pysoem.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from akdctl.errors import UsageError

if TYPE_CHECKING:
    from akdctl.channels.foe_client import Progress
    from akdctl.connection import Connection

#: Per-packet timeout, seconds (the AKD ESI's mailbox timeout, 3000 ms).
PACKET_TIMEOUT = 3.0


def read_file(conn: "Connection", name: str, password: int, max_size: int,
              progress: "Progress | None" = None) -> bytes:
    from akdctl.channels.foe_client import FoeClient

    if not name or len(name.encode("latin-1", "replace")) > 255 or "\0" in name:
        raise UsageError(f"FoE file name {name!r} is not usable: 1..255 characters, no NUL")
    transport = conn.transport()
    scheme = getattr(transport, "scheme", "")
    timeout = max(PACKET_TIMEOUT, float(conn.options.timeout))
    if scheme == "ecat+soem":
        return transport.foe_read(name, password, max_size, timeout)  # type: ignore[attr-defined, no-any-return]
    link = getattr(transport, "link", None)
    if scheme != "ecat" or link is None:
        raise UsageError(f"FoE needs akdctl as the EtherCAT master (target ecat://IFNAME[/POS] or "
                         f"ecat+soem://IFNAME[/POS]); {conn.target.display} has no slave mailbox of its own")
    client = FoeClient(link, link.sm0.length, timeout, who=f"slave {transport.position}")  # type: ignore[attr-defined]
    return client.read(name, password, max_size, progress)
