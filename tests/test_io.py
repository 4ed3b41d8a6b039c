"""The one copy of each OS helper (akdctl/io): atomic writes, raw sockets, CAN bus teardown."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from akdctl.errors import UsageError
from akdctl.io import atomic, canbus, raw_socket


def test_atomic_write_replaces_whole_or_not_at_all(tmp_path: Path) -> None:
    target = tmp_path / "state.json"
    atomic.write_atomic(target, "old")
    with pytest.raises(RuntimeError), atomic.atomic_open(target) as fh:
        fh.write("half of the new")
        raise RuntimeError("interrupted")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["state.json"]  # no temporary file left behind
    atomic.write_atomic(target, b"new")
    assert target.read_bytes() == b"new"


def test_user_file_error_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(UsageError) as info:
        atomic.write_user_file(tmp_path / "missing-dir" / "x.json", "{}")
    assert str(info.value).startswith(f"cannot write {tmp_path / 'missing-dir' / 'x.json'}: ") and "\n" not in str(info.value)


def test_raw_socket_refusal_names_who_and_what_to_do(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*_args: object, **_kw: object) -> socket.socket:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(raw_socket.socket, "socket", refuse)
    with pytest.raises(UsageError) as info:
        raw_socket.open_raw_socket("veth0", 0x88A4, "--ethercat-raw veth0")
    assert str(info.value) == f"--ethercat-raw veth0 needs CAP_NET_RAW: {raw_socket.CAP_HINT}"


class _Part:
    def __init__(self, fail: bool = False) -> None:
        self.calls: list[str] = []
        self.fail = fail

    def disconnect(self) -> None:
        self.calls.append("disconnect")
        if self.fail:
            raise OSError("already gone")

    def shutdown(self) -> None:
        self.calls.append("shutdown")


def test_close_bus_stops_the_network_first_and_shuts_a_bare_bus_down() -> None:
    network, bus = _Part(), _Part()
    canbus.close_bus(network, bus)  # type: ignore[arg-type]
    assert network.calls == ["disconnect"] and bus.calls == []  # disconnect shut the bus down itself
    broken, bus = _Part(fail=True), _Part()
    canbus.close_bus(broken, bus)  # type: ignore[arg-type]
    assert bus.calls == ["shutdown"]
    canbus.close_bus(None, None)


def test_open_bus_unknown_interface_is_a_usage_error() -> None:
    with pytest.raises(UsageError) as info:
        canbus.open_bus(canbus.BusConfig("no-such-interface", "x"))
    assert "unknown python-can interface 'no-such-interface'" in str(info.value)


# --- the one fault-injection syntax of the simulator's faces ------------------------------------------------------
def test_injection_specs_share_one_syntax_and_one_error() -> None:
    import pytest

    from akdctl.errors import UsageError
    from akdctl.sim.ecat_inject import Injector
    from akdctl.sim.face_ethernetip import Injection as EipInjection
    from akdctl.sim.face_profinet import Injection as PnInjection

    pn = PnInjection.parse("drop=3,dup=4,delay=5:0.3,rxdrop=7")
    assert (pn.drop, pn.dup, pn.delay, pn.delay_s, pn.rxdrop) == (3, 4, 5, 0.3, 7)
    eip = EipInjection.parse("close=2,status=4:0x0E,delay=3")
    assert (eip.close, eip.status, eip.status_code, eip.delay, eip.delay_s) == (2, 4, 0x0E, 3, 0.5)
    assert Injector.parse("drop,abort=5").every == {"drop": 1, "abort": 5}
    for parse, text, words in ((PnInjection.parse, "drop=x", "--pn-inject 'drop=x': 'drop=x' needs a whole number"),
                               (EipInjection.parse, "status=2:0x100", "--eip-inject: status=N:0x100 is out of range"),
                               (Injector.parse, "zap=1", "--ecat-inject 'zap=1': unknown fault 'zap'"),
                               (PnInjection.parse, "drop=0", "N must be at least 1"),
                               (PnInjection.parse, "dup=2:1", "dup takes no ':' value")):
        with pytest.raises(UsageError) as info:
            parse(text)
        assert words in info.value.message, info.value.message
