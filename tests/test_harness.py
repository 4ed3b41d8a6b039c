"""The test harness keeps its promises: servers report the port they bound and are reaped, failures to start are
reported at once, the network guard sees traffic aimed off the machine, and loopback namespaces are made and
removed."""

from __future__ import annotations

import socket
import subprocess

import pytest

from tests.harness import SimServer, closed_udp_port
from tests.netns import LoopbackNetns
from tests.watch import Watch


@pytest.mark.parametrize("event, args, flagged", [
    ("socket.connect", ("192.0.2.1", 9), True),
    ("socket.sendto", ("239.74.163.2", 43113), True),        # multicast leaves through the default route
    ("socket.connect", ("127.0.0.1", 9), False),
    ("socket.sendto", ("127.3.2.1", 9), False),
    ("socket.connect", ("localhost", 9), False),
    ("socket.connect", ("gateway.example", 9), True),       # a name: resolved over DNS
    ("socket.bind", ("", 0), True),                          # listening on every interface
    ("socket.bind", ("0.0.0.0", 0), True),
    ("socket.bind", ("127.0.0.1", 0), False),
    ("socket.bind", ("192.0.2.1", 0), False),                # binding sends nothing; sending is checked
])
def test_watch_classifies_inet_events(event: str, args: tuple, flagged: bool) -> None:  # type: ignore[type-arg]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:  # never bound or used: only its family counts
        assert bool(Watch.classify(event, (sock, args))) is flagged


def test_watch_ignores_local_families_and_literal_lookups() -> None:
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        assert Watch.classify("socket.sendto", (sock, "/tmp/x")) is None
    with socket.socket(socket.AF_INET6, socket.SOCK_DGRAM) as sock:
        assert Watch.classify("socket.connect", (sock, ("::1", 9, 0, 0))) is None
        assert Watch.classify("socket.connect", (sock, ("2001:db8::1", 9, 0, 0)))
    assert Watch.classify("socket.getaddrinfo", ("192.168.1.128", None, 0, 0, 0, 0)) is None  # parsed, not looked up
    assert Watch.classify("socket.getaddrinfo", ("localhost", 80, 0, 0, 0, 0)) is None
    assert Watch.classify("socket.getaddrinfo", ("drive.example", 80, 0, 0, 0, 0))
    assert Watch.classify("open", ("/etc/hosts", "r", 0)) is None


def test_watch_hook_sees_a_real_socket() -> None:
    """A UDP connect sends no packet, yet the installed audit hook records where it was aimed."""
    Watch.off_machine.clear()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.connect(("192.0.2.1", 9))  # TEST-NET-1; no route is fine, the audit event comes first
        except OSError:
            pass
    seen = list(Watch.off_machine)
    Watch.off_machine.clear()  # this test's own aim off the machine is the point, not a failure
    assert seen == ["socket.connect ('192.0.2.1', 9)"]


def test_closed_udp_port_bounces() -> None:
    with closed_udp_port() as port, socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(5)
        sock.connect(("127.0.0.1", port))
        sock.send(b"anyone?")
        with pytest.raises(ConnectionRefusedError):
            sock.recv(16)


@pytest.mark.slow
def test_sim_server_reports_the_ports_it_bound_and_is_reaped() -> None:
    with SimServer("--profinet", "127.0.0.1:0", "--ethercat-udp", "127.0.0.1:0", faces=2) as server:
        assert [line.split()[0] for line in server.ready] == ["profinet", "ethercat-udp"]
        pn, gw = server.address_of("profinet"), server.address_of("ethercat-udp")
        assert pn[0] == gw[0] == "127.0.0.1" and 0 not in (pn[1], gw[1]) and pn[1] != gw[1]
        assert server.address == pn
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:  # something really listens there
            probe.settimeout(5)
            probe.sendto(bytes.fromhex("10 50 0a 00 e9 03 00 03 00 20 40 18 10 01 00 00 00 00"), gw)  # station 1001
            assert probe.recv(64)[:2] == bytes.fromhex("10 50")
    assert server.proc is not None and server.proc.returncode is not None  # stopped and waited for
    assert server.stop() == server.proc.returncode  # idempotent


@pytest.mark.slow
def test_sim_server_that_cannot_start_fails_at_once_in_words() -> None:
    with pytest.raises(AssertionError, match=r"exited with 2(.|\n)*cannot listen there"):
        SimServer("--profinet", "300.0.0.1:0").start()


@pytest.mark.slow
def test_sim_server_ready_wait_has_a_deadline() -> None:
    server = SimServer("--profinet", "127.0.0.1:0", ready_timeout=0.01)  # far shorter than interpreter start-up
    with pytest.raises(AssertionError, match="printed no ready line within 0.01 s"):
        server.start()
    assert server.proc is not None and server.proc.returncode is not None


@pytest.mark.root
@pytest.mark.slow
def test_loopback_netns_holds_only_lo_and_is_removed() -> None:
    with LoopbackNetns() as netns:
        assert netns.links() == ["lo"]
        routes = subprocess.run(["ip", "-n", netns.name, "route", "show", "table", "all"], capture_output=True,
                                text=True, timeout=30, check=True).stdout
        assert "224.0.0.0/4 dev lo" in routes and "default" not in routes
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, timeout=30).stdout
    assert netns.name not in listed
