"""``--pcap FILE``: write every traced frame as a classic pcap capture (LINKTYPE_ETHERNET).

Transports trace the bytes they put on the wire *above* the socket (a UDP
payload, an EtherCAT frame body); Wireshark and tshark need whole Ethernet
frames. So this sink synthesises the lower headers from the record's ``meta``:

* ``{"proto": "udp", "src": (ip, port), "dst": (ip, port)}``: Ethernet + IPv4
  (or IPv6) + UDP with correct checksums around ``data``;
* ``{"proto": "tcp", "src": ..., "dst": ...}``: Ethernet + IPv4 + TCP (one data segment, sequence
  numbers counted per direction) around ``data`` (EtherNet/IP encapsulation);
* ``{"proto": "ethernet", "ethertype": T[, "src_mac": b6, "dst_mac": b6]}``: an
  Ethernet header in front of ``data``;
* ``{"proto": "ethernet"}`` without an EtherType: ``data`` is already a whole frame.
* ``{"proto": "can", "can_id": N, "extended": bool, "remote": bool}`` (``can://``): a SocketCAN frame
  (LINKTYPE_CAN_SOCKETCAN: the CAN ID with its flags big-endian, the length, 8 data bytes). A pcap file has one
  link type, written in its header before the first frame is known: the header says Ethernet, and when the first
  frame written is a CAN frame the link type is changed in place to CAN (a capture is one command's, on one
  transport). A frame of the other kind than the file's is counted in ``skipped``. tshark decodes the CANopen
  SDOs with ``-d can.subdissector,canopen`` (Wireshark does not guess CANopen from an identifier).

* ``{"proto": "sim"}`` (the in-process simulated drive, which has no wire): the
  bytes it exchanged are put in the frames a real drive would carry them in
  (:class:`SimWire`) — PROFIdrive blocks as PNIO record Write requests and Read
  responses over UDP on 127.0.0.1, CoE mailboxes as EtherCAT FPWR/FPRD datagrams
  to station 0x1001's mailbox sync managers (0x1800 / 0x1C00). The addresses,
  AR and sequence numbers are synthetic; the payload is byte for byte what the
  simulator was sent and answered, and tshark dissects it.

Records without usable meta are counted in ``skipped`` and left out. Every frame is flushed at once, so a
capture cut short by a crash or Ctrl-C still opens.
"""

from __future__ import annotations

import ipaddress
import os
import socket
import struct
import threading
from typing import BinaryIO

from akdctl.errors import UsageError
from akdctl.transport.trace import TraceRecord

PCAP_MAGIC = 0xA1B2C3D4
LINKTYPE_ETHERNET = 1
LINKTYPE_CAN_SOCKETCAN = 227
CAN_EFF_FLAG = 0x80000000  # extended (29-bit) identifier
CAN_RTR_FLAG = 0x40000000  # remote transmission request
SNAPLEN = 262144
ETHERTYPE_IPV4 = 0x0800
ETHERTYPE_IPV6 = 0x86DD


def internet_checksum(data: bytes) -> int:
    """RFC 1071 ones'-complement sum, as IPv4 and UDP use it."""
    if len(data) % 2:
        data += b"\0"
    total = sum(struct.unpack(f"!{len(data) // 2}H", data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def _address(value: object) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    text = str(value)
    try:
        return ipaddress.ip_address(text.split("%")[0])
    except ValueError:
        pass
    try:
        return ipaddress.ip_address(socket.gethostbyname(text))
    except (OSError, UnicodeError):
        return ipaddress.IPv4Address("0.0.0.0")


def _mac_for(ip: ipaddress.IPv4Address | ipaddress.IPv6Address) -> bytes:
    """A stable, locally administered MAC per IP, so conversations look right in Wireshark."""
    return b"\x02\x00" + ip.packed[-4:]


def udp_frame(src: tuple[object, int], dst: tuple[object, int], payload: bytes, ident: int = 0) -> bytes:
    """Ethernet/IP/UDP around ``payload`` with valid IP and UDP checksums."""
    sip, dip = _address(src[0]), _address(dst[0])
    sport, dport = int(src[1]) & 0xFFFF, int(dst[1]) & 0xFFFF
    if sip.version != dip.version:   # mixed families cannot share one IP header; map both to v6
        sip = ipaddress.IPv6Address(f"::ffff:{sip}") if sip.version == 4 else sip
        dip = ipaddress.IPv6Address(f"::ffff:{dip}") if dip.version == 4 else dip
    ulen = 8 + len(payload)
    if sip.version == 4:
        pseudo = sip.packed + dip.packed + struct.pack("!BBH", 0, socket.IPPROTO_UDP, ulen)
    else:
        pseudo = sip.packed + dip.packed + struct.pack("!I3xB", ulen, socket.IPPROTO_UDP)
    udp_sum = internet_checksum(pseudo + struct.pack("!HHHH", sport, dport, ulen, 0) + payload) or 0xFFFF
    udp = struct.pack("!HHHH", sport, dport, ulen, udp_sum) + payload
    if sip.version == 4:
        head = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), ident & 0xFFFF, 0x4000, 64,
                           socket.IPPROTO_UDP, 0, sip.packed, dip.packed)
        head = head[:10] + struct.pack("!H", internet_checksum(head)) + head[12:]
        ethertype = ETHERTYPE_IPV4
    else:
        head = struct.pack("!IHBB16s16s", 0x60000000, len(udp), socket.IPPROTO_UDP, 64, sip.packed, dip.packed)
        ethertype = ETHERTYPE_IPV6
    return _mac_for(dip) + _mac_for(sip) + struct.pack("!H", ethertype) + head + udp


def tcp_frame(src: tuple[object, int], dst: tuple[object, int], payload: bytes, seq: int, ack: int,
              ident: int = 0) -> bytes:
    """Ethernet/IPv4/TCP (PSH+ACK) around ``payload`` with valid checksums (EtherNet/IP explicit messaging)."""
    sip, dip = _address(src[0]), _address(dst[0])
    if sip.version != 4 or dip.version != 4:
        sip, dip = ipaddress.IPv4Address("0.0.0.0"), ipaddress.IPv4Address("0.0.0.0")
    sport, dport = int(src[1]) & 0xFFFF, int(dst[1]) & 0xFFFF
    head = struct.pack("!HHIIBBHHH", sport, dport, seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, 5 << 4, 0x18, 65535, 0, 0)
    pseudo = sip.packed + dip.packed + struct.pack("!BBH", 0, socket.IPPROTO_TCP, len(head) + len(payload))
    tcp_sum = internet_checksum(pseudo + head + payload)
    tcp = head[:16] + struct.pack("!H", tcp_sum) + head[18:] + payload
    ip = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(tcp), ident & 0xFFFF, 0x4000, 64, socket.IPPROTO_TCP, 0,
                     sip.packed, dip.packed)
    ip = ip[:10] + struct.pack("!H", internet_checksum(ip)) + ip[12:]
    return _mac_for(dip) + _mac_for(sip) + struct.pack("!H", ETHERTYPE_IPV4) + ip + tcp


class SimWire:
    """The frames a real link would have carried for the simulated drive's records (module docstring).

    Why synthesise rather than refuse: ``--pcap`` on the simulator is how a technician learns what the
    tool will send to a real drive, and Wireshark only decodes whole frames. One direction per record,
    so a PROFIdrive exchange is a Write request (the request block) and a Read response (the answer).
    """

    CLIENT = ("127.0.0.1", 49152)
    DEVICE = ("127.0.0.1", 34964)
    STATION = 0x1001
    SM_WRITE, SM_READ = 0x1800, 0x1C00

    def __init__(self) -> None:
        import uuid

        from akdctl.protocol import pnio

        self.ar = uuid.UUID("00000000-0000-4000-8000-0000000000a1")  # synthetic, constant: captures compare
        self.activity = uuid.UUID("00000000-0000-4000-8000-0000000000a2")
        self.read_activity = uuid.UUID("00000000-0000-4000-8000-0000000000a3")
        self.object = pnio.object_uuid(0x0100, 0x0001)
        self.sequence = 0

    def frame(self, record: TraceRecord) -> tuple[str, bytes] | None:
        """(kind, payload): ``("udp", datagram)`` or ``("ecat", frame)``; None for other layers."""
        if record.layer == "bmp":
            return "udp", self._pnio(record.direction == "tx", record.data)
        if record.layer == "mailbox":
            return "ecat", self._ecat(record.direction == "tx", record.data)
        return None

    def _pnio(self, request: bool, block: bytes) -> bytes:
        from akdctl.protocol import dcerpc, pnio

        if request:
            self.sequence = (self.sequence + 1) & 0xFFFFFFFF
            body = pnio.encode_request_args(pnio.IODWriteReq(self.sequence, self.ar, pnio.RecordAddress(),
                                                             block).encode())
        else:
            body = pnio.encode_response_args(pnio.OK, pnio.IODReadRes(self.sequence, self.ar, pnio.RecordAddress(),
                                                                      block).encode())
        # The answer travels in a Read response; on its own activity, so Wireshark does not pair it with the
        # Write request (a real client sends a Read request in between, which has no bytes of its own here).
        header = dcerpc.RpcHeader(ptype=dcerpc.PT_REQUEST if request else dcerpc.PT_RESPONSE,
                                  object_uuid=self.object, interface_uuid=pnio.DEVICE_INTERFACE,
                                  activity_uuid=self.activity if request else self.read_activity,
                                  sequence=self.sequence,
                                  opnum=pnio.OP_WRITE if request else pnio.OP_READ, flags1=dcerpc.FLAG_IDEMPOTENT)
        return dcerpc.encode_packet(header, body)

    def _ecat(self, to_slave: bool, mailbox: bytes) -> bytes:
        from akdctl.protocol import ethercat

        datagram = ethercat.Datagram(ethercat.Cmd.FPWR if to_slave else ethercat.Cmd.FPRD, self.STATION,
                                     self.SM_WRITE if to_slave else self.SM_READ, bytes(mailbox), wkc=1)
        return ethercat.encode_frame([datagram], b"\x02\x00\x00\x00\x00\x01")


def can_frame(can_id: int, data: bytes, extended: bool = False, remote: bool = False) -> bytes:
    """A LINKTYPE_CAN_SOCKETCAN packet: ID and flags (big-endian), length, 3 reserved bytes, 8 data bytes."""
    ident = (can_id & (0x1FFFFFFF if extended else 0x7FF)) | (CAN_EFF_FLAG if extended else 0) | (
        CAN_RTR_FLAG if remote else 0)
    payload = bytes(data[:8])
    return struct.pack("!IB3x", ident, len(payload)) + payload.ljust(8, b"\0")


class PcapWriter:
    """A pcap file that grows one flushed frame at a time. Use ``write`` as a tracer sink."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        from pathlib import Path

        from akdctl.io.atomic import require_directory

        require_directory(Path(path))  # the rule for every file akdctl writes (io/atomic.py); open() honours the umask
        try:
            self._file: BinaryIO | None = open(path, "wb")
        except OSError as exc:
            raise UsageError(f"cannot write the capture file {os.fspath(path)!r}: {exc.strerror}") from None
        self.path = os.fspath(path)
        self.frames = 0
        self.skipped = 0
        self._ident = 0
        self._tcp_seq: dict[tuple[str, int, str, int], int] = {}
        self._sim_wire: SimWire | None = None
        self._lock = threading.Lock()
        self.link_type = LINKTYPE_ETHERNET
        self._file.write(struct.pack("<IHHiIII", PCAP_MAGIC, 2, 4, 0, 0, SNAPLEN, LINKTYPE_ETHERNET))
        self._file.flush()

    def frame_bytes(self, record: TraceRecord) -> bytes | None:
        """The Ethernet frame for a record (a SocketCAN frame for ``proto`` "can"), or ``None`` if it has no wire
        form."""
        meta = record.meta
        proto = meta.get("proto")
        if proto == "can" and isinstance(meta.get("can_id"), int):
            return can_frame(int(meta["can_id"]), record.data, bool(meta.get("extended")),  # type: ignore[call-overload]
                             bool(meta.get("remote")))
        if proto == "udp" and isinstance(meta.get("src"), (tuple, list)) and isinstance(meta.get("dst"), (tuple, list)):
            self._ident = (self._ident + 1) & 0xFFFF
            return udp_frame(meta["src"], meta["dst"], record.data, self._ident)  # type: ignore[arg-type]
        if proto == "tcp" and isinstance(meta.get("src"), (tuple, list)) and isinstance(meta.get("dst"), (tuple, list)):
            src, dst = meta["src"], meta["dst"]  # type: ignore[index]
            key = (str(src[0]), int(src[1]), str(dst[0]), int(dst[1]))
            back = (key[2], key[3], key[0], key[1])
            seq = self._tcp_seq.setdefault(key, 1)
            self._tcp_seq[key] = seq + len(record.data)
            self._ident = (self._ident + 1) & 0xFFFF
            return tcp_frame(src, dst, record.data, seq, self._tcp_seq.get(back, 1), self._ident)  # type: ignore[arg-type]
        if proto == "sim":
            wire = self._sim_wire = self._sim_wire or SimWire()
            made = wire.frame(record)
            if made is None:
                return None
            kind, payload = made
            if kind == "ecat":
                return payload
            self._ident = (self._ident + 1) & 0xFFFF
            src, dst = (wire.CLIENT, wire.DEVICE) if record.direction == "tx" else (wire.DEVICE, wire.CLIENT)
            return udp_frame(src, dst, payload, self._ident)
        if proto == "ethernet":
            ethertype = meta.get("ethertype")
            if ethertype is None:
                return record.data if len(record.data) >= 14 else None
            dst = bytes(meta.get("dst_mac") or b"\xff" * 6)  # type: ignore[arg-type]
            src = bytes(meta.get("src_mac") or b"\x02\x00\x00\x00\x00\x01")  # type: ignore[arg-type]
            return dst[:6].ljust(6, b"\0") + src[:6].ljust(6, b"\0") + struct.pack("!H", int(ethertype)) + record.data  # type: ignore[call-overload]
        return None

    def write(self, record: TraceRecord) -> None:
        frame = self.frame_bytes(record)
        with self._lock:
            if self._file is None:
                return
            if frame is None or not self._link_type_for(record.meta.get("proto") == "can"):
                self.skipped += 1
                return
            seconds = int(record.time)
            micros = int(round((record.time - seconds) * 1e6))
            if micros >= 1_000_000:
                seconds, micros = seconds + 1, micros - 1_000_000
            kept = frame[:SNAPLEN]
            self._file.write(struct.pack("<IIII", seconds, micros, len(kept), len(frame)) + kept)
            self._file.flush()
            self.frames += 1

    def _link_type_for(self, can: bool) -> bool:
        """Whether a frame of this kind fits the file; the first frame decides (CAN: the header is rewritten)."""
        wanted = LINKTYPE_CAN_SOCKETCAN if can else LINKTYPE_ETHERNET
        if wanted == self.link_type:
            return True
        if self.frames or self._file is None:
            return False
        try:
            self._file.seek(20)
            self._file.write(struct.pack("<I", wanted))
            self._file.seek(0, os.SEEK_END)
        except (OSError, ValueError):
            return False  # not seekable (a pipe): the header stays Ethernet and CAN frames are skipped
        self.link_type = wanted
        return True

    def close(self) -> None:
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None

    def __enter__(self) -> "PcapWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
