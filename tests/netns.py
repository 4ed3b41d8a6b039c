"""Network namespaces for tests that need a network of their own: no packet of theirs reaches a real NIC.

:class:`LoopbackNetns` is one namespace with only ``lo`` (multicast routed to it) - for buses such as python-can's
``udp_multicast`` that would otherwise go out of the default-route interface.  :class:`VethPair` is two namespaces
joined by a veth pair - a private wire for raw Ethernet (EtherCAT, PROFINET DCP).  Both need root (tests using them
carry ``@pytest.mark.root``), have unique names, and are removed on exit even when the test failed.  Run processes
inside with ``run_akdctl(..., netns=ns.name)`` / ``SimServer(..., netns=ns.name)`` from :mod:`tests.harness`.
"""

from __future__ import annotations

import os
import subprocess
import uuid
from pathlib import Path

from tests.harness import wait_until


def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30, check=True)


class LoopbackNetns:
    """A network namespace with only ``lo`` (up, with a multicast route), so multicast never reaches a real NIC.

    Needs root (tests using it carry ``@pytest.mark.root``).  Removed on exit even when the test failed; a name is
    unique per instance so parallel runs do not collide.  ``created`` lists every namespace made in this process
    (a :class:`VethPair`'s two as well), so a test can check that a fixture really made one and the session can
    check that none outlived its test (:func:`leftover_namespaces`).
    """

    created: list[str] = []

    def __init__(self, prefix: str = "akdt") -> None:
        self.name = f"{prefix}{uuid.uuid4().hex[:8]}"

    def __enter__(self) -> LoopbackNetns:
        _ip("netns", "add", self.name)
        try:
            _ip("-n", self.name, "link", "set", "lo", "up")
            _ip("-n", self.name, "route", "add", "224.0.0.0/4", "dev", "lo")
        except BaseException:
            self.delete()
            raise
        LoopbackNetns.created.append(self.name)
        return self

    def __exit__(self, *exc: object) -> None:
        self.delete()

    def delete(self) -> None:
        subprocess.run(["ip", "netns", "delete", self.name], capture_output=True, timeout=30)

    @property
    def path(self) -> Path:
        return Path("/run/netns") / self.name

    def links(self) -> list[str]:
        """Names of the network interfaces inside the namespace."""
        out = _ip("-n", self.name, "-o", "link", "show").stdout
        return [line.split(":")[1].strip() for line in out.splitlines()]

    def holds(self, pid: int) -> bool:
        """Whether process *pid* runs in this namespace (same inode as the namespace's bind mount)."""
        ns = os.stat(f"/proc/{pid}/ns/net")
        mine = os.stat(self.path)
        return (ns.st_dev, ns.st_ino) == (mine.st_dev, mine.st_ino)


class VethPair:
    """Two network namespaces joined by a veth pair - a private wire for raw Ethernet (EtherCAT, DCP) - with ``lo``
    up in both; ready once both ends carry frames.  Side ``a`` (``if_a``) is the client's, ``b`` (``if_b``) the
    device's; *address_a*/*address_b* give the ends IPv4 addresses (``10.77.0.2/24``).  Needs root; removed on exit
    even when the test failed (deleting a namespace deletes its end, and so the pair)."""

    def __init__(self, address_a: str | None = None, address_b: str | None = None) -> None:
        tag = uuid.uuid4().hex[:6]
        self.a, self.b = f"akdA{tag}", f"akdB{tag}"
        LoopbackNetns.created.extend((self.a, self.b))  # registered before `ip netns add`: a half-made pair counts
        self.if_a, self.if_b = f"ea{tag}", f"eb{tag}"
        self.addresses = {self.a: address_a, self.b: address_b}

    def __enter__(self) -> VethPair:
        try:
            _ip("netns", "add", self.a)
            _ip("netns", "add", self.b)
            _ip("link", "add", self.if_a, "type", "veth", "peer", "name", self.if_b)
            for ns, ifname in ((self.a, self.if_a), (self.b, self.if_b)):
                _ip("link", "set", ifname, "netns", ns)
                if self.addresses[ns]:
                    _ip("-n", ns, "addr", "add", str(self.addresses[ns]), "dev", ifname)
                _ip("-n", ns, "link", "set", ifname, "up")
                _ip("-n", ns, "link", "set", "lo", "up")
            wait_until(self.is_up, "both veth ends to carry frames", timeout=10)
        except BaseException:
            self.delete()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.delete()

    def delete(self) -> None:
        for ns in (self.a, self.b):
            subprocess.run(["ip", "netns", "delete", ns], capture_output=True, timeout=30)
        subprocess.run(["ip", "link", "delete", self.if_a], capture_output=True, timeout=30)  # if never moved

    def is_up(self) -> bool:
        """Whether both ends report operstate UP (a frame sent earlier may be lost)."""
        return all("state UP" in _ip("-n", ns, "-o", "link", "show", "dev", ifname).stdout
                   for ns, ifname in ((self.a, self.if_a), (self.b, self.if_b)))


def leftover_namespaces() -> list[str]:
    """Namespaces this process made (``LoopbackNetns.created``) that still exist - a test that did not clean up.

    Read from ``/run/netns`` (where ``ip netns add`` mounts them), so it costs nothing when no test made one."""
    if not LoopbackNetns.created:
        return []
    run = Path("/run/netns")
    present = {entry.name for entry in run.iterdir()} if run.is_dir() else set()
    return sorted(present & set(LoopbackNetns.created))


def delete_namespace(name: str) -> None:
    """Remove namespace *name* (best effort: used to clear up after a test that leaked one)."""
    subprocess.run(["ip", "netns", "delete", name], capture_output=True, timeout=30, check=False)
