"""Issue 23.15: the owner lock is keyed on the normalised address, not on the target's spelling.

``pn://H`` and ``pn://H:34964``, ``?axis=0`` or not, station ``1001`` and ``0x3e9`` were two owners of one axis.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from akdctl.drive import gate
from akdctl.io.owner_lock import OwnerLock
from akdctl.transport.target import split_target


def key(text: str) -> str:
    return gate.owner_key(split_target(text))


@pytest.mark.parametrize("spellings", [
    ("pn://10.0.0.7", "pn://10.0.0.7:34964", "pn://10.0.0.7?axis=0", "pn://10.0.0.7:34964?axis=0&slot=1&subslot=1",
     "pn://10.0.0.7?api=0x3A00", "pn://10.0.0.7?axis=0x0", "PN://10.0.0.7"),
    ("ecat-udp://10.0.0.7/1001", "ecat-udp://10.0.0.7:34980/1001", "ecat-udp://10.0.0.7/0x3e9",
     "ecat-udp://10.0.0.7:34980/0x3E9"),
    ("eip://10.0.0.7", "eip://10.0.0.7:44818"),
    ("can://socketcan/can0/1", "can://socketcan/can0/0x01"),
])
def test_spellings_of_one_axis_share_one_key(spellings: tuple[str, ...]) -> None:
    assert len({key(s) for s in spellings}) == 1, spellings


def test_different_axes_keep_different_keys() -> None:
    assert key("pn://10.0.0.7?axis=1") != key("pn://10.0.0.7")
    assert key("pn://10.0.0.7:34965") != key("pn://10.0.0.7")
    assert key("ecat-udp://10.0.0.7/1002") != key("ecat-udp://10.0.0.7/1001")
    assert key("can://socketcan/can0/2") != key("can://socketcan/can0/1")


def test_a_gated_write_through_another_spelling_is_refused_while_the_axis_is_owned(
        akd_inproc, isolated_env: Path, tmp_path: Path) -> None:
    """Through the real CLI and a PROFINET face: another process owns ``pn://127.0.0.1:PORT?axis=0x0&slot=1``;
    ``pnu set 1=...`` to ``pn://127.0.0.1:PORT`` is refused (exit 4), naming the owner."""
    from akdctl.sim import face_profinet
    from akdctl.sim.drive import SimDrive

    face = face_profinet.from_options(SimDrive("default", tmp_path / "served"), profinet="127.0.0.1:0")
    assert face is not None
    face.start()
    owner = OwnerLock(isolated_env / "owners" / f"{key(f'pn://127.0.0.1:{face.port}?axis=0x0&slot=1')}.lock")
    owner.acquire("akdctl jog 100 --for 10s")
    try:
        code, _, err = akd_inproc("-T", f"pn://127.0.0.1:{face.port}", "-y", "pnu", "set", "1=0x047F")
    finally:
        owner.release()
        face.stop()
    assert code == 4, err
    assert "is in use by pid" in err and "jog 100" in err


def test_a_face_answers_busy_before_the_clients_default_timeout(akd, isolated_env: Path) -> None:
    """Issue 23.15: the faces waited 5 s for the state lock, the client gives up after 2 s; now the face answers
    within FACE_LOCK_TIMEOUT (0.5 s) in its protocol's words ("busy"), and the client reports that answer."""
    import fcntl
    import os

    from tests.harness import SimServer

    with SimServer("--profinet", "127.0.0.1:0") as server:
        assert akd("-T", f"pn://{server.host}:{server.port}", "pnu", "get", "930").returncode == 0
        fd = os.open(isolated_env / "sim-default.lock", os.O_RDWR)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)  # another process holds the simulated drive
            result = akd("-T", f"pn://{server.host}:{server.port}", "pnu", "get", "930", timeout=30)
        finally:
            os.close(fd)
        assert "locked by another process for more than 0.5 s" in server.stderr
    assert result.returncode == 3
    assert "the drive stayed busy" in result.stderr, result.stderr  # the face's own answer arrived in time


@pytest.mark.parametrize("face_option, scheme", [("profinet", "pn"), ("ethernetip", "eip")])
def test_two_spellings_of_one_host_meet_in_the_drives_serial(
        akd_inproc, isolated_env: Path, tmp_path: Path, face_option: str, scheme: str) -> None:
    """Issue 23.15: a name and an address of one host are two address keys; the lock is also keyed on the serial
    the drive reports (I&M0 over PROFINET, CIP Identity attribute 6 over EtherNet/IP). A command owning
    ``SCHEME://127.0.0.1:PORT`` keeps out ``enable`` through ``SCHEME://localhost:PORT`` (exit 4, naming the
    owner), and lets it through once it let go."""
    from akdctl.connection import Connection
    from akdctl.sim import face_ethernetip, face_profinet
    from akdctl.sim.drive import SimDrive
    from akdctl.transport.base import LinkOptions

    module = {"profinet": face_profinet, "ethernetip": face_ethernetip}[face_option]
    face = module.from_options(SimDrive("default", tmp_path / "served"), **{face_option: "127.0.0.1:0"})
    assert face is not None
    face.start()
    try:
        assert key(f"{scheme}://127.0.0.1:{face.port}") != key(f"{scheme}://localhost:{face.port}")
        owner = Connection(split_target(f"{scheme}://127.0.0.1:{face.port}"), LinkOptions())
        owner.own_axis("akdctl jog 100 --for 10s")
        try:
            assert len(list((isolated_env / "owners").glob("serial-*.lock"))) == 1
            code, _, err = akd_inproc("-T", f"{scheme}://localhost:{face.port}", "-y", "enable")
            assert code == 4, err
            assert "is in use by pid" in err and "jog 100" in err
        finally:
            owner.close()
        code, _, err = akd_inproc("-T", f"{scheme}://localhost:{face.port}", "-y", "enable")
        assert code == 0, err
    finally:
        face.stop()
