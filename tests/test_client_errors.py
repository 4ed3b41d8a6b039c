"""Issue 14, the clients' items: a clear line and the right exit code instead of an internal error or a wait.

* every python-can interface's import/open failure is one line, exit 3 (kvaser without CANlib: NameError);
* an unknown target query key (``pn://HOST?slott=2``) is exit 2 naming the key and the valid ones;
* an SDO timeout to a CANopen node whose heartbeat says STOPPED names that state.
(The ETG.8200 timeout message and pn:// on ICMP port unreachable: tests/test_ecat_udp_lossy.py, test_pn_deadline.py.)
"""

from __future__ import annotations

import pytest

from akdctl.errors import AkdError, CommError, UsageError
from akdctl.transport.registry import BUILTIN, parse_target
from tests.harness import SimServer, run_akdctl

can = pytest.importorskip("can")

#: Interfaces that open a real bus or reach the network: not tried in process.
NOT_TRIED = {"udp_multicast", "virtual", "socketcand"}


@pytest.mark.slow  # some backends look for their library with ctypes.util.find_library (ldconfig, gcc)
@pytest.mark.parametrize("interface", sorted(set(can.VALID_INTERFACES) - NOT_TRIED))
def test_every_python_can_interface_fails_as_one_akdctl_error(interface: str) -> None:
    from akdctl.io.canbus import BusConfig, open_bus

    try:
        bus = open_bus(BusConfig(interface, "0"))
    except AkdError as exc:
        assert isinstance(exc, (CommError, UsageError))
        assert interface in exc.message and "\n" not in exc.message
    else:  # an adapter that exists here: nothing to report
        bus.shutdown()


@pytest.mark.parametrize("raw, key, hint", [
    ("pn://10.0.0.5?slott=2", "slott", "did you mean 'slot'"),
    ("ecat-udp://10.0.0.5/1001?mailbx=1024", "mailbx", "did you mean 'mailbox'"),
    ("sim?drvie=cia402", "drvie", "did you mean 'drive'"),
    ("eip://10.0.0.5?slot=1", "slot", "eip:// takes drive"),
    ("ecat://eth0/0?timeout=1", "timeout", "ecat:// takes drive"),
])
def test_unknown_query_key_is_a_usage_error(raw: str, key: str, hint: str) -> None:
    with pytest.raises(UsageError) as info:
        parse_target(raw)
    assert f"unknown query key {key!r}" in info.value.message and hint in info.value.message


def test_known_query_keys_and_can_pass_through() -> None:
    parse_target("pn://10.0.0.5?slot=1&subslot=1&api=0x3A00&index=47&axis=0&ar_timeout=50&drive=profidrive")
    parse_target("ecat-udp://10.0.0.5/1001?mailbox=1024&drive=cia402")
    parse_target("can://socketcan/can0/2?bitrate=500000&block=1&receive_own_messages=1")  # python-can's options
    assert BUILTIN["can"].query is None


@pytest.mark.slow
def test_cli_kvaser_without_its_library_is_one_line_exit_3() -> None:
    result = run_akdctl("-T", "can://kvaser/0/1", "info")
    if result.returncode == 0:
        pytest.skip("a Kvaser adapter and CANlib are installed here")
    assert result.returncode == 3, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("akdctl: error:") and "kvaser" in lines[0], result.stderr
    assert "internal error" not in result.stderr


@pytest.mark.slow
def test_cli_unknown_query_key_is_exit_2() -> None:
    result = run_akdctl("-T", "pn://127.0.0.1?slott=2", "pnu", "get", "930")
    assert result.returncode == 2
    assert "unknown query key 'slott'" in result.stderr and "slot, subslot" in result.stderr


@pytest.mark.slow
def test_cli_sdo_timeout_to_a_stopped_node_names_the_nmt_state(tmp_path) -> None:  # noqa: ANN001
    link = tmp_path / "slcan-tty"
    with SimServer("--can", f"slcan-pty:{link}:2") as _server:
        target = f"can://slcan/{link.as_posix().replace('/', '%2F')}/2?sleep_after_open=0"
        assert run_akdctl("-T", target, "sdo", "write", "0x1017:0", "100").returncode == 0  # heartbeat 100 ms
        assert run_akdctl("-T", target, "can", "nmt", "stop").returncode == 0
        result = run_akdctl("-T", target, "--timeout", "0.5", "sdo", "read", "0x1018:1")
        assert result.returncode == 3, result.stderr
        assert "NMT state STOPPED" in result.stderr, result.stderr
        assert run_akdctl("-T", target, "can", "nmt", "preop").returncode == 0
        assert run_akdctl("-T", target, "sdo", "read", "0x1018:1").returncode == 0
