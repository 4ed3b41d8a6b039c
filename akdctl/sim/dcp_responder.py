"""The simulated AKD's DCP responder: answers identify, get, set (name, IP) and signal on a raw socket.

Started by the PROFINET face with ``--dcp IFNAME`` so that discovery and
naming can be tested against real Ethernet frames (e.g. across a veth pair
between two network namespaces) without a drive.
"""

from __future__ import annotations

import select
import socket
import threading
from typing import Any

from akdctl.errors import UsageError
from akdctl.io.raw_socket import open_raw_socket
from akdctl.protocol import dcp
from akdctl.protocol.errors import CodecError


class DcpResponder:
    """Device side of DCP on one interface; the station data lives in the face."""

    def __init__(self, face: Any, iface: str) -> None:
        self.face = face
        self.iface = iface
        try:
            with open(f"/sys/class/net/{iface}/address") as fh:
                self.mac = dcp.mac_bytes(fh.read().strip())
        except (OSError, CodecError):
            raise UsageError(f"--dcp {iface}: no such network interface") from None
        self.station = dcp.Station(mac=dcp.mac_text(self.mac), name=face.station_name, ip=self._ip_of(iface),
                                   netmask="255.255.255.0", gateway="0.0.0.0", vendor_id=face.vendor_id,
                                   device_id=face.device_id, role=0x01, family="AKD", ip_set=True)
        self.blinks = 0
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    @staticmethod
    def _ip_of(iface: str) -> str:
        try:
            import fcntl
            import struct

            probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                packed = fcntl.ioctl(probe.fileno(), 0x8915, struct.pack("256s", iface.encode()[:15]))  # SIOCGIFADDR
            finally:
                probe.close()
            return socket.inet_ntoa(packed[20:24])
        except OSError:
            return "0.0.0.0"

    def start(self) -> None:
        sock = open_raw_socket(self.iface, dcp.ETHERTYPE, f"--dcp {self.iface}")
        self._sock = sock
        self._thread = threading.Thread(target=self._run, name="dcp-responder", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _run(self) -> None:
        assert self._sock is not None
        while not self._stop.is_set():
            ready, _, _ = select.select([self._sock], [], [], 0.2)
            if not ready:
                continue
            try:
                frame = self._sock.recv(65535)
                dst, src, payload = dcp.split_ethernet(frame)
                pdu = dcp.DcpPdu.decode(payload)
            except (OSError, CodecError):
                continue
            if src == self.mac or pdu.service_type != dcp.TYPE_REQUEST:
                continue
            try:
                reply = self.answer(dst, pdu)
            except CodecError:
                continue
            if reply is not None:
                try:
                    self._sock.send(dcp.ethernet(src, self.mac, reply.encode()).ljust(60, b"\0"))
                except OSError:
                    pass

    def answer(self, dst: bytes, pdu: dcp.DcpPdu) -> dcp.DcpPdu | None:
        """The response to one request, or None if it is not for us."""
        st = self.station
        if pdu.frame_id == dcp.FRAME_IDENTIFY_REQ and pdu.service_id == dcp.SERVICE_IDENTIFY:
            if dst not in (dcp.IDENTIFY_MULTICAST, self.mac):
                return None
            for block in pdu.blocks:
                if block.key == dcp.OPT_NAME and block.data.rstrip(b"\0").decode("ascii", "replace") != st.name:
                    return None
                if block.key == dcp.OPT_DEVICE_ID and block.data[:4] != bytes.fromhex(
                        f"{st.vendor_id or 0:04x}{st.device_id or 0:04x}"):
                    return None
            return dcp.DcpPdu(dcp.FRAME_IDENTIFY_RES, dcp.SERVICE_IDENTIFY, dcp.TYPE_RESPONSE, pdu.xid,
                              dcp.station_blocks(st))
        if pdu.frame_id != dcp.FRAME_GET_SET or dst != self.mac:
            return None
        if pdu.service_id == dcp.SERVICE_GET:
            blocks: list[dcp.Block] = []
            for block in pdu.blocks:
                wanted = dcp.station_blocks(st, block.key)
                blocks.extend(wanted or (dcp.control_response(block.key, 2),))
            return dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_GET, dcp.TYPE_RESPONSE, pdu.xid, tuple(blocks))
        if pdu.service_id == dcp.SERVICE_SET:
            results = []
            for block in pdu.blocks:
                results.append(dcp.control_response(block.key, self._set(block)))
            return dcp.DcpPdu(dcp.FRAME_GET_SET, dcp.SERVICE_SET, dcp.TYPE_RESPONSE, pdu.xid, tuple(results))
        return dcp.DcpPdu(pdu.frame_id, pdu.service_id, dcp.TYPE_NOT_SUPPORTED, pdu.xid)

    def _set(self, block: dcp.Block) -> int:
        """Apply one set block; returns the DCP block error (0 = ok)."""
        value = block.data[2:]
        st = self.station
        if block.key == dcp.OPT_NAME:
            name = value.rstrip(b"\0").decode("ascii", "replace")
            if name and not dcp.valid_station_name(name):
                return 5
            st.name = name
            self.face.station_name = name
            return 0
        if block.key == dcp.OPT_IP:
            if len(value) < 12:
                return 5
            st.ip, st.netmask, st.gateway = (socket.inet_ntoa(value[i:i + 4]) for i in (0, 4, 8))
            return 0
        if block.key == dcp.OPT_SIGNAL:
            self.blinks += 1
            return 0
        if block.key in (dcp.OPT_CONTROL_START, dcp.OPT_CONTROL_STOP):
            return 0
        return 1 if block.option not in (1, 2, 5) else 2
