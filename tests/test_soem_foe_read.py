"""ecat+soem:// FoE reads with a pysoem that does not report FoE timeouts (up to 1.1.13).

Why: pysoem 1.1.13's ``foe_read`` drops SOEM's result, so a transfer that timed out under load came back as a
whole file of the segments that had arrived; ``akdctl ecat foe read`` then wrote a cut-short file and exited 0
(seen in tests/test_ecat_service_root.py under load). The transport reads twice with such a pysoem and takes the
file only when both reads agree. These tests drive the transport's read with a stand-in slave object (the pysoem
call's contract: bytes, at most the size asked), no interface or root needed.
"""

from __future__ import annotations

import pytest

pysoem = pytest.importorskip("pysoem", reason="pysoem (the akdctl[soem] extra) is not installed")

from akdctl.errors import CommError, DriveError  # noqa: E402
from akdctl.transport import ethercat_soem  # noqa: E402
from akdctl.transport.base import LinkOptions  # noqa: E402
from akdctl.transport.registry import parse_target  # noqa: E402


class _Slave:
    """Answers each foe_read with the next of ``replies`` and records the sizes asked."""

    def __init__(self, *replies: bytes) -> None:
        self.replies = list(replies)
        self.asked: list[int] = []

    def foe_read(self, name: str, password: int, size: int, timeout: int) -> bytes:
        self.asked.append(size)
        return self.replies.pop(0)


def _transport(slave: _Slave) -> ethercat_soem.EthercatSoemTransport:
    transport = ethercat_soem.EthercatSoemTransport(parse_target("ecat+soem://eth9/0"), LinkOptions(timeout=1.0))
    transport.master = type("M", (), {"slaves": [slave]})()
    return transport


@pytest.fixture
def unchecked(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(pysoem, "__version__", "1.1.13", raising=False)


def test_two_equal_reads_give_the_file(unchecked: None) -> None:
    slave = _Slave(b"abc" * 100, b"abc" * 100)
    assert _transport(slave).foe_read("f.bin", 0, 1000, 1.0) == b"abc" * 100
    assert slave.asked == [1001, 1001]


def test_a_cut_short_read_is_a_communication_error(unchecked: None) -> None:
    slave = _Slave(b"x" * 1018, b"x" * 1500)
    with pytest.raises(CommError, match=r"1018 and then 1500 bytes.*pysoem 1\.1\.13"):
        _transport(slave).foe_read("f.bin", 0, 4000, 1.0)


def test_nothing_twice_is_not_taken_for_an_empty_file(unchecked: None) -> None:
    with pytest.raises(CommError, match="gave no data"):
        _transport(_Slave(b"", b"")).foe_read("f.bin", 0, 4000, 1.0)


def test_a_refusal_is_still_the_slaves(unchecked: None) -> None:
    with pytest.raises(DriveError, match="refused it or the file is larger"):
        _transport(_Slave(bytes(4001))).foe_read("f.bin", 0, 4000, 1.0)


def test_a_pysoem_that_reports_timeouts_reads_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(pysoem, "__version__", "1.1.14", raising=False)
    slave = _Slave(b"", b"never asked")
    assert _transport(slave).foe_read("f.bin", 0, 4000, 1.0) == b""
    assert slave.asked == [4001]


@pytest.mark.parametrize(("version", "reported"), [
    ("1.1.13", False), ("1.1.14", True), ("1.2.0", True), ("2.0.0rc1", True), ("1.1.9", False), ("1.1", False),
    ("dev", False), ("1.1.13.post1", False),
])
def test_which_pysoem_reports_foe_timeouts(monkeypatch: pytest.MonkeyPatch, version: str, reported: bool) -> None:
    monkeypatch.setattr(pysoem, "__version__", version, raising=False)
    assert ethercat_soem.foe_result_reported() is reported


def test_the_cli_writes_no_file_and_exits_3(unchecked: None, monkeypatch: pytest.MonkeyPatch, tmp_path,
                                            akd_inproc) -> None:  # type: ignore[no-untyped-def]
    """``akdctl ecat foe read`` through the real CLI: reads that differ leave no file and end with exit 3."""
    slave = _Slave(b"x" * 1018, b"x" * 1500)

    def fake_open(self: ethercat_soem.EthercatSoemTransport) -> None:  # the interface and SOEM left out
        self.master = type("M", (), {"slaves": [slave], "close": lambda self: None})()

    monkeypatch.setattr(ethercat_soem.EthercatSoemTransport, "open", fake_open)
    out = tmp_path / "copy.bin"
    code, _, err = akd_inproc("-T", "ecat+soem://eth9/0", "ecat", "foe", "read", "f.bin", "-o", str(out))
    assert code == 3, err
    assert "FoE read of 'f.bin' through SOEM gave 1018 and then 1500 bytes: a transfer timed out" in err
    assert not out.exists()
