"""DCP client on a raw Linux socket: find, name, address and blink PROFINET devices.

Why not the ``pnio-dcp`` package for this: its identify result keeps only name,
MAC, IP and device family (it drops the DeviceID block with vendor/device ID and
the DeviceRole block, which ``akdctl pn scan`` must show), and it picks the
network card by the card's IPv4 address, which a commissioning laptop on a
fresh drive network often does not have. The tests use ``pnio-dcp`` as an
independent client against the simulator's DCP responder instead.

Needs CAP_NET_RAW (root); every wait is bounded by ``timeout``.
"""

from __future__ import annotations

import random
import select
import socket
import time

from akdctl.errors import CommError, DriveError, NoAnswer, UsageError
from akdctl.io.raw_socket import open_raw_socket
from akdctl.protocol import dcp
from akdctl.protocol.errors import CodecError


def interface_mac(iface: str) -> bytes:
    try:
        with open(f"/sys/class/net/{iface}/address") as fh:
            return dcp.mac_bytes(fh.read().strip())
    except (OSError, CodecError):
        raise UsageError(f"network interface {iface!r} not found (see 'ip link')") from None


class DcpClient:
    """One raw socket on one interface; one transaction (Xid) per request."""

    def __init__(self, iface: str, timeout: float = 2.0, tracer=None) -> None:  # type: ignore[no-untyped-def]
        if not hasattr(socket, "AF_PACKET"):
            raise UsageError("DCP needs raw Ethernet sockets (Linux)")
        self.iface = iface
        self.timeout = timeout
        self.tracer = tracer
        self.mac = interface_mac(iface)
        self.sock = open_raw_socket(iface, dcp.ETHERTYPE, f"DCP on {iface}")
        self.xid = random.getrandbits(32)

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> "DcpClient":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _trace(self, direction: str, frame: bytes) -> None:
        if self.tracer is not None:
            self.tracer.frame(direction, "dcp", frame, meta={"proto": "ethernet"})

    def _send(self, dst: bytes, pdu: dcp.DcpPdu) -> None:
        frame = dcp.ethernet(dst, self.mac, pdu.encode())
        frame = frame.ljust(60, b"\0")          # minimum Ethernet frame
        self._trace("tx", frame)
        self.sock.send(frame)

    def _responses(self, deadline: float, first_only: bool):  # type: ignore[no-untyped-def]
        while True:
            wait = deadline - time.monotonic()
            if wait <= 0:
                return
            ready, _, _ = select.select([self.sock], [], [], wait)
            if not ready:
                return
            frame = self.sock.recv(65535)
            try:
                dst, src, payload = dcp.split_ethernet(frame)
                pdu = dcp.DcpPdu.decode(payload)
            except CodecError:
                continue
            if dst != self.mac or pdu.xid != self.xid or pdu.service_type == dcp.TYPE_REQUEST:
                continue
            self._trace("rx", frame)
            yield src, pdu
            if first_only:
                return

    def identify(self, name: str | None = None, timeout: float | None = None) -> list[dcp.Station]:
        """All stations that answer within ``timeout`` (or only the one named ``name``)."""
        self.xid = (self.xid + 1) & 0xFFFFFFFF
        block = dcp.Block(*dcp.OPT_NAME, name.encode("ascii")) if name else dcp.Block(*dcp.OPT_ALL)
        self._send(dcp.IDENTIFY_MULTICAST, dcp.DcpPdu(dcp.FRAME_IDENTIFY_REQ, dcp.SERVICE_IDENTIFY,
                                                      dcp.TYPE_REQUEST, self.xid, (block,), response_delay=1))
        found: dict[str, dcp.Station] = {}
        wait = self.timeout if timeout is None else timeout
        for src, pdu in self._responses(time.monotonic() + wait, first_only=bool(name)):
            if pdu.frame_id == dcp.FRAME_IDENTIFY_RES:
                station = dcp.station_from_blocks(src, pdu.blocks)
                found[station.mac] = station
        return sorted(found.values(), key=lambda s: (s.name, s.mac))

    def set(self, mac: bytes, option: tuple[int, int], value: bytes, qualifier: int) -> None:
        """A DCP Set; raises DriveError with the block error in words if the device refuses."""
        self.xid = (self.xid + 1) & 0xFFFFFFFF
        data = qualifier.to_bytes(2, "big") + value
        self._send(mac, dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_SET, dcp.TYPE_REQUEST, self.xid,
                                   (dcp.Block(*option, data),)))
        for _src, pdu in self._responses(time.monotonic() + self.timeout, first_only=True):
            for block in pdu.blocks:
                if block.key == dcp.OPT_CONTROL_RESPONSE and len(block.data) >= 3:
                    error = block.data[2]
                    if error:
                        raise DriveError(f"{dcp.mac_text(mac)} refuses DCP set {option[0]}/{option[1]}: "
                                         f"{dcp.BLOCK_ERRORS.get(error, f'error {error}')}", code=error)
                    return
            if pdu.service_type == dcp.TYPE_NOT_SUPPORTED:
                raise DriveError(f"{dcp.mac_text(mac)} does not support DCP set {option[0]}/{option[1]}")
            raise CommError(f"{dcp.mac_text(mac)}: DCP set response without a control block")
        raise NoAnswer(f"no DCP answer from {dcp.mac_text(mac)} on {self.iface} within {self.timeout:g} s")

    def set_name(self, mac: bytes, name: str, permanent: bool = True) -> None:
        if not dcp.valid_station_name(name):
            raise UsageError(f"{name!r} is not a valid PROFINET station name (lower-case letters, digits, '-', "
                             "dot-separated labels of up to 63 characters)")
        self.set(mac, dcp.OPT_NAME, name.encode("ascii"), int(permanent))

    def set_ip(self, mac: bytes, ip: str, netmask: str, gateway: str, permanent: bool = True) -> None:
        try:
            packed = b"".join(socket.inet_aton(x) for x in (ip, netmask, gateway))
        except OSError:
            raise UsageError(f"bad IPv4 settings {ip}/{netmask} via {gateway}") from None
        self.set(mac, dcp.OPT_IP, packed, int(permanent))

    def blink(self, mac: bytes) -> None:
        self.set(mac, dcp.OPT_SIGNAL, b"\x01\x00", 0)


def find_station(client: DcpClient, who: str) -> dcp.Station:
    """A station by MAC address or station name."""
    try:
        mac = dcp.mac_bytes(who)
    except CodecError:
        mac = None
    stations = client.identify(None if mac else who)
    for st in stations:
        if (mac and st.mac == dcp.mac_text(mac)) or st.name == who:
            return st
    raise NoAnswer(f"no PROFINET device {who!r} answered DCP identify on {client.iface} within {client.timeout:g} s")


def resolve_station(name: str, iface: str, timeout: float) -> str:
    """The IP address of the station called ``name`` (for ``pn://NAME?iface=IF``)."""
    with DcpClient(iface, timeout) as client:
        st = find_station(client, name)
    if not st.ip or st.ip == "0.0.0.0":
        raise UsageError(f"station {name!r} ({st.mac}) has no IP address; set one with "
                         f"'akdctl pn set-ip --iface {iface} {name} IP'")
    return st.ip


