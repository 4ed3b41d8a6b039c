"""DCP: codec vectors and fuzz, the simulator's responder logic, and (as root) real frames between two
network namespaces with pnio-dcp and akdctl as clients."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.protocol import dcp
from akdctl.protocol.errors import CodecError
from tests.harness import CliResult, SimServer, akdctl_env, run_akdctl
from tests.netns import VethPair


def test_identify_request_vector() -> None:
    pdu = dcp.DcpPdu(dcp.FRAME_IDENTIFY_REQ, dcp.SERVICE_IDENTIFY, dcp.TYPE_REQUEST, 0x01020304,
                     (dcp.Block(*dcp.OPT_ALL),), response_delay=1)
    assert pdu.encode() == bytes.fromhex("FEFE 05 00 01020304 0001 0004 FF FF 0000")
    assert dcp.DcpPdu.decode(pdu.encode()) == pdu


def test_odd_block_is_padded() -> None:
    pdu = dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_SET, dcp.TYPE_REQUEST, 7, (dcp.Block(2, 2, b"\0\x01akd"),
                                                                             dcp.Block(5, 3, b"\0\0\x01\0")))
    raw = pdu.encode()
    assert raw[10:12] == (4 + 5 + 1 + 4 + 4).to_bytes(2, "big")
    assert dcp.DcpPdu.decode(raw).blocks == pdu.blocks


def test_station_blocks_round_trip() -> None:
    st_in = dcp.Station(mac="02:00:00:00:00:01", name="akd-axis1", ip="10.0.0.5", netmask="255.255.255.0",
                        gateway="10.0.0.1", vendor_id=0x0100, device_id=0x0001, role=1, family="AKD", ip_set=True)
    blocks = dcp.station_blocks(st_in)
    back = dcp.station_from_blocks(bytes.fromhex("020000000001"), blocks)
    assert back == st_in and back.role_text == "IO device"
    assert back.to_json()["vendor_id"] == "0x0100"


@given(st.binary(max_size=120))
def test_fuzz_decode_only_codec_error(data: bytes) -> None:
    try:
        pdu = dcp.DcpPdu.decode(data)
        dcp.station_from_blocks(bytes(6), pdu.blocks)
    except CodecError:
        pass
    try:
        dcp.split_ethernet(data)
    except CodecError:
        pass


@given(xid=st.integers(0, 2**32 - 1),
       blocks=st.lists(st.tuples(st.integers(0, 255), st.integers(0, 255), st.binary(max_size=40)), max_size=5))
def test_pdu_round_trip(xid: int, blocks) -> None:
    pdu = dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_GET, dcp.TYPE_RESPONSE, xid,
                     tuple(dcp.Block(*b) for b in blocks))
    assert dcp.DcpPdu.decode(pdu.encode()) == pdu


def test_station_names() -> None:
    assert dcp.valid_station_name("akd-axis1") and dcp.valid_station_name("line1.akd-2")
    for bad in ("AKD", "-akd", "akd_1", "", "a" * 64, "port-001"):
        assert not dcp.valid_station_name(bad)


class _Face:
    station_name = "akd-sim"
    vendor_id = 0x0100
    device_id = 0x0001


def test_responder_logic_without_sockets(monkeypatch) -> None:
    from akdctl.sim import dcp_responder

    monkeypatch.setattr(dcp_responder.DcpResponder, "__init__", lambda self, face, iface: None)
    r = dcp_responder.DcpResponder(_Face(), "x")
    r.face, r.mac, r.blinks = _Face(), bytes.fromhex("020000000099"), 0
    r.station = dcp.Station(mac="02:00:00:00:00:99", name="akd-sim", ip="10.1.1.1", netmask="255.0.0.0",
                            vendor_id=0x100, device_id=1, role=1, ip_set=True)
    ident = dcp.DcpPdu(dcp.FRAME_IDENTIFY_REQ, dcp.SERVICE_IDENTIFY, dcp.TYPE_REQUEST, 5, (dcp.Block(*dcp.OPT_ALL),))
    reply = r.answer(dcp.IDENTIFY_MULTICAST, ident)
    assert reply is not None and reply.frame_id == dcp.FRAME_IDENTIFY_RES and reply.xid == 5
    assert dcp.station_from_blocks(r.mac, reply.blocks).name == "akd-sim"
    other = dcp.DcpPdu(dcp.FRAME_IDENTIFY_REQ, dcp.SERVICE_IDENTIFY, dcp.TYPE_REQUEST, 6,
                       (dcp.Block(*dcp.OPT_NAME, b"someone-else"),))
    assert r.answer(dcp.IDENTIFY_MULTICAST, other) is None
    set_name = dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_SET, dcp.TYPE_REQUEST, 7,
                          (dcp.Block(*dcp.OPT_NAME, b"\0\x01akd-new"),))
    reply = r.answer(r.mac, set_name)
    assert reply is not None and reply.blocks[0].data == bytes((2, 2, 0)) and r.station.name == "akd-new"
    bad = dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_SET, dcp.TYPE_REQUEST, 8,
                     (dcp.Block(*dcp.OPT_NAME, b"\0\x01Bad_Name"),))
    assert r.answer(r.mac, bad).blocks[0].data[2] == 5
    blink = dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_SET, dcp.TYPE_REQUEST, 9,
                       (dcp.Block(*dcp.OPT_SIGNAL, b"\0\0\x01\0"),))
    assert r.answer(r.mac, blink).blocks[0].data[2] == 0 and r.blinks == 1
    assert r.answer(bytes(6), blink) is None          # unicast for someone else


# ------------------------------------------------------------- real frames between namespaces

def _need_root() -> None:
    reason = None
    if os.geteuid() != 0:
        reason = "needs root for network namespaces and raw sockets"
    elif shutil.which("ip") is None:
        reason = "needs iproute2 ('ip')"
    if reason:
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI must run this test: {reason}")
        pytest.skip(reason)


PNIO_DCP_CLIENT = textwrap.dedent("""
    import json, sys
    from pnio_dcp import DCP
    dcp = DCP(sys.argv[1])
    dcp.identify_all_timeout = 1
    dcp.default_timeout = 2
    found = dcp.identify_all(timeout=1)
    out = {"found": [[d.name_of_station, d.MAC, d.IP, d.family] for d in found]}
    mac = found[0].MAC
    out["set_name"] = int(dcp.set_name_of_station(mac, "akd-axis1", store_permanent=False).code)
    out["set_ip"] = int(dcp.set_ip_address(mac, ["10.77.0.1", "255.255.255.0", "0.0.0.0"], store_permanent=False).code)
    out["blink"] = int(dcp.blink(mac).code)
    out["name_after"] = dcp.get_name_of_station(mac)
    print(json.dumps(out))
""")


@pytest.mark.root
@pytest.mark.slow
def test_dcp_between_namespaces() -> None:
    _need_root()
    pytest.importorskip("pnio_dcp", reason="pnio-dcp is not installed")
    with VethPair(address_a="10.77.0.2/24", address_b="10.77.0.1/24") as pair, \
            SimServer("--profinet", "10.77.0.1:0", "--dcp", pair.if_b, "--pn-station", "akd-sim",
                      netns=pair.b) as server:
        cli_ns, cli_if = pair.a, pair.if_a
        host, port = server.address
        assert host == "10.77.0.1", server.ready

        # pnio-dcp, an independent client, finds, names, addresses and blinks the simulated device
        result = subprocess.run(["ip", "netns", "exec", cli_ns, sys.executable, "-c", PNIO_DCP_CLIENT, "10.77.0.2"],
                                capture_output=True, text=True, timeout=60, env=akdctl_env())
        assert result.returncode == 0, result.stderr
        out = json.loads(result.stdout.strip().splitlines()[-1])
        assert out["found"] and out["found"][0][0] == "akd-sim" and out["found"][0][2] == "10.77.0.1"
        assert out["set_name"] == 0 and out["set_ip"] == 0 and out["blink"] == 0
        assert out["name_after"] == "akd-axis1"

        def cli(*argv: str) -> CliResult:
            return run_akdctl("--timeout", "1", *argv, netns=cli_ns)

        scan = cli("--json", "pn", "scan", "--iface", cli_if)
        assert scan.returncode == 0, scan.stderr
        devices = json.loads(scan.stdout)["devices"]
        assert devices[0]["name"] == "akd-axis1" and devices[0]["vendor_id"] == "0x0100"
        assert devices[0]["role"] == "IO device"
        assert cli("pn", "blink", "--iface", cli_if, "akd-axis1").returncode == 0
        dry = cli("--json", "pn", "set-name", "--iface", cli_if, "akd-axis1", "akd-axis2", "--dry-run")
        assert dry.returncode == 0, dry.stderr
        write = json.loads(dry.stdout)["plan"]["writes"][0]
        assert write["address"] == f"{devices[0]['mac']} station name" and "now 'akd-axis1'" in write["value"]
        assert json.loads(cli("--json", "pn", "scan", "--iface", cli_if).stdout)["devices"][0]["name"] == "akd-axis1"
        renamed = cli("pn", "set-name", "--iface", cli_if, "akd-axis1", "akd-axis2", "--temporary")
        assert renamed.returncode == 0, renamed.stderr
        dry_ip = cli("--json", "pn", "set-ip", "--iface", cli_if, "akd-axis2", "10.77.0.9", "--dry-run")
        assert dry_ip.returncode == 0, dry_ip.stderr
        write = json.loads(dry_ip.stdout)["plan"]["writes"][0]
        assert write["raw"] == ["10.77.0.9", "255.255.255.0", "0.0.0.0"] and "(now 10.77.0.1)" in write["value"]
        assert cli("pn", "set-ip", "--iface", cli_if, "akd-axis2", "10.77.0.1").returncode == 0
        assert cli("pn", "set-name", "--iface", cli_if, "akd-axis2", "Bad_Name").returncode == 2
        assert "temporary: the device forgets it" in renamed.stderr
        missing = cli("pn", "blink", "--iface", cli_if, "no-such-drive")
        assert missing.returncode == 3 and "no PROFINET device" in missing.stderr
        # a target by station name, resolved through DCP, then PNIO RPC over UDP across the veth pair
        got = cli("-T", f"pn://akd-axis2:{port}?iface={cli_if}", "pnu", "get", "930")
        assert got.returncode == 0, got.stderr
        assert "Operating mode" in got.stdout


def test_get_request_is_option_pairs() -> None:
    pdu = dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_GET, dcp.TYPE_REQUEST, 1, (dcp.Block(*dcp.OPT_NAME),))
    assert pdu.encode() == bytes.fromhex("FEFD 03 00 00000001 0000 0002 02 02")
    assert dcp.DcpPdu.decode(pdu.encode()) == pdu
