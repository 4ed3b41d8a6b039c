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
        count = _config_init(master, self.options.timeout)
        if count <= 0:
            raise NoAnswer(f"no EtherCAT slave answered on {ifname} within {self.options.timeout:g} s "
                           "(SOEM config_init found none)")
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

    # ------------------------------------------------------------------ FoE through SOEM (firmware, files)
    # SOEM does the framing; what it cannot tell is the slave's FoE error code: pysoem raises nothing for a FoE
    # ERR reply (SOEM issue #76; seen here: a refused read returns its unfilled buffer). So a refusal is
    # reported with SOEM's own result and the advice to use ecat:// for the slave's words.

    @property
    def position(self) -> int:
        parts = self.target.path_parts
        return int(parts[0], 0) if parts else 0

    def _slave(self) -> Any:
        if self.master is None:
            raise UsageError("ecat+soem: the link is not open")
        return self.master.slaves[self.position]

    def foe_read(self, name: str, password: int, max_size: int, timeout: float) -> bytes:
        """The file, checked as far as the installed pysoem lets us.

        pysoem up to 1.1.13 drops SOEM's result of ``ecx_FOEread``: a transfer whose mailbox receive timed out
        comes back as success holding what arrived before (nothing, or whole segments), indistinguishable from a
        file of that length (fixed upstream after 1.1.13, pysoem commit 6b6b741). With such a pysoem the file is
        read twice and taken only when both reads agree and are not empty; anything else is a communication error
        that names the cause, never a cut-short file written as if whole (tests/test_soem_foe_read.py)."""
        from akdctl.errors import CommError

        first = self._foe_read_once(name, password, max_size, timeout)
        if foe_result_reported():
            return first
        second = self._foe_read_once(name, password, max_size, timeout)
        version = _pysoem_version()
        if first != second:
            raise CommError(f"FoE read of {name!r} through SOEM gave {len(first)} and then {len(second)} bytes: a "
                            f"transfer timed out, and pysoem {version} does not say which (ecat:// does)")
        if not first:
            raise CommError(f"FoE read of {name!r} through SOEM gave no data: a transfer timed out or the file is "
                            f"empty, and pysoem {version} cannot tell which (ecat:// can)")
        return first

    def _foe_read_once(self, name: str, password: int, max_size: int, timeout: float) -> bytes:
        from akdctl.errors import DriveError

        data = bytes(self._slave().foe_read(name, password, max_size + 1, int(timeout * 1e6)))
        if len(data) > max_size:
            raise DriveError(f"FoE read of {name!r} through SOEM: the slave refused it or the file is larger than "
                             f"{max_size} bytes (SOEM does not pass on the slave's FoE error; ecat:// shows it)")
        return data

    def foe_write_in_boot(self, name: str, data: bytes, password: int, timeout: float, restart_timeout: float,
                          progress: Any = None) -> dict[str, Any]:
        """SOEM's firm_update sequence: INIT, SM0/SM1 = the SII's bootstrap mailbox (amend_mbx), BOOT,
        foe_write, INIT, then config_init until the slave answers again in INIT; back in PRE-OP for CoE."""
        import time

        import pysoem

        from akdctl.errors import DriveError

        slave = self._slave()
        micro = int(max(timeout, 1.0) * 1e6)
        slave.state = pysoem.INIT_STATE
        slave.write_state()
        if slave.state_check(pysoem.INIT_STATE, micro) != pysoem.INIT_STATE:
            raise NoAnswer(f"ecat+soem: slave {self.position} did not reach INIT")
        rx = int.from_bytes(slave.eeprom_read(pysoem.SiiOffset.BOOT_RX_MBX), "little")
        tx = int.from_bytes(slave.eeprom_read(pysoem.SiiOffset.BOOT_TX_MBX), "little")
        if not rx >> 16 or not tx >> 16:
            raise UsageError(f"slave {self.position} declares no bootstrap mailbox in its SII: it cannot take a file")
        slave.amend_mbx("out", rx & 0xFFFF, rx >> 16)
        slave.amend_mbx("in", tx & 0xFFFF, tx >> 16)
        slave.state = pysoem.BOOT_STATE
        slave.write_state()
        if slave.state_check(pysoem.BOOT_STATE, micro) != pysoem.BOOT_STATE:
            raise DriveError(f"ecat+soem: slave {self.position} refused BOOT (AL status code 0x{slave.al_status:04X})")
        try:
            result = slave.foe_write(name, password, bytes(data), micro)
        except Exception as exc:  # noqa: BLE001 - pysoem raises its own classes (mailbox, FoE, packet errors)
            result = -1
            why = str(exc)
        else:
            why = ""
        if progress is not None and result > 0:
            progress(len(data), len(data))  # pysoem offers no per-packet hook
        start = time.monotonic()
        slave.state = pysoem.INIT_STATE
        with contextlib.suppress(Exception):
            slave.write_state()
        if result <= 0:
            raise DriveError(f"FoE write of {name!r} through SOEM failed (SOEM result {result}{'; ' + why if why else ''}); "
                             "SOEM does not pass on the slave's FoE error: ecat:// shows its code and words")
        deadline = start + restart_timeout
        while True:
            time.sleep(0.2)
            with contextlib.suppress(Exception):
                if self.master.config_init() > self.position:
                    break
            if time.monotonic() > deadline:
                raise NoAnswer(f"the drive did not answer again within {restart_timeout:g} s after leaving BOOT")
        restart_s = time.monotonic() - start
        slave = self._slave()
        slave.state = pysoem.PREOP_STATE
        slave.write_state()
        slave.state_check(pysoem.PREOP_STATE, micro)
        self.sdo_client = SoemSdoClient(slave, self.target.display)
        return {"packets": None, "packet_bytes": None, "busy": None, "restart_s": restart_s}

    def open_mailbox(self) -> None:
        """Already in PRE-OP after :meth:`foe_write_in_boot` (the raw transport's counterpart re-opens it)."""


def _config_init(master: Any, timeout: float) -> int:
    """SOEM's ``config_init``, repeated while it finds no slave and ``timeout`` (``--timeout``) is not over.

    Why: one ``config_init`` waits only SOEM's own few milliseconds per frame; a slave that answers later (a busy
    link, a simulated drive on a loaded machine) is then "no slave", while the command was told to wait
    ``--timeout`` for its drive. Repeating is harmless: it only counts and reads the slaves."""
    import time

    deadline = time.monotonic() + timeout
    while True:
        count = int(master.config_init())
        if count > 0 or time.monotonic() >= deadline:
            return count
        time.sleep(0.05)


#: The first pysoem release after the FoE read's result check was merged (pysoem commit 6b6b741, after 1.1.13).
FOE_RESULT_CHECKED_FROM = (1, 1, 14)


def _pysoem_version() -> str:
    import pysoem

    return str(getattr(pysoem, "__version__", "?"))


def foe_result_reported() -> bool:
    """Whether the installed pysoem raises when SOEM's FoE read fails (a timeout included) instead of returning
    the part that arrived; an unknown version counts as not."""
    import re

    found = re.match(r"(\d+)\.(\d+)\.(\d+)", _pysoem_version())
    return found is not None and tuple(int(n) for n in found.groups()) >= FOE_RESULT_CHECKED_FROM
