"""PcapWriter: classic pcap, synthesised Ethernet/IPv4/UDP with valid checksums, readable by scapy."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.transport.pcap import PcapWriter, internet_checksum, udp_frame
from akdctl.transport.trace import TraceRecord, Tracer


def test_internet_checksum_vector() -> None:
    # RFC 1071 example words
    assert internet_checksum(bytes.fromhex("0001f203f4f5f6f7")) == 0x220D


def test_udp_frame_headers_and_checksums() -> None:
    frame = udp_frame(("127.0.0.1", 50000), ("127.0.0.2", 34964), b"hello")
    assert frame[12:14] == b"\x08\x00"
    ip = frame[14:34]
    assert ip[0] == 0x45 and ip[9] == 17 and struct.unpack("!H", ip[2:4])[0] == 20 + 8 + 5
    assert internet_checksum(ip) == 0                   # a correct header sums to zero
    udp = frame[34:]
    assert struct.unpack("!HHH", udp[:6]) == (50000, 34964, 13) and udp[8:] == b"hello"
    pseudo = ip[12:20] + struct.pack("!BBH", 0, 17, 13)
    assert internet_checksum(pseudo + udp) == 0


@given(payload=st.binary(max_size=600), sport=st.integers(0, 65535), dport=st.integers(0, 65535))
def test_udp_frame_checksums_always_valid(payload: bytes, sport: int, dport: int) -> None:
    frame = udp_frame(("10.0.0.1", sport), ("192.168.0.10", dport), payload)
    assert internet_checksum(frame[14:34]) == 0
    pseudo = frame[26:34] + struct.pack("!BBH", 0, 17, 8 + len(payload))
    assert internet_checksum(pseudo + frame[34:]) == 0


def test_writer_file_is_readable_after_each_frame(tmp_path) -> None:
    path = tmp_path / "cap.pcap"
    tracer = Tracer()
    writer = PcapWriter(path)
    tracer.add_sink(writer.write)
    try:
        tracer.frame("tx", "pnio-rpc", b"\x04\x00" + bytes(78),
                     meta={"proto": "udp", "src": ("127.0.0.1", 40000), "dst": ("127.0.0.1", 34964)})
        # flushed per frame: readable while the writer is still open
        raw = path.read_bytes()
        assert struct.unpack("<IHHiIII", raw[:24]) == (0xA1B2C3D4, 2, 4, 0, 0, 262144, 1)
        _, _, incl, orig = struct.unpack("<IIII", raw[24:40])
        assert incl == orig == 14 + 20 + 8 + 80
        tracer.frame("rx", "ecat", b"\x0e\x10" + bytes(14),
                     meta={"proto": "ethernet", "ethertype": 0x88A4, "src_mac": b"\x02" * 6, "dst_mac": b"\xff" * 6})
        tracer.frame("tx", "bmp", b"\x01\x01", meta={})          # no wire form: skipped
    finally:
        writer.close()
    writer.close()    # twice is fine
    assert writer.frames == 2 and writer.skipped == 1
    scapy_all = pytest.importorskip("scapy.all", reason="scapy is not installed")
    packets = scapy_all.rdpcap(str(path))
    assert len(packets) == 2
    assert packets[0][scapy_all.UDP].dport == 34964 and packets[0][scapy_all.IP].src == "127.0.0.1"
    assert packets[1][scapy_all.Ether].type == 0x88A4


def test_unwritable_path_is_usage_error(tmp_path) -> None:
    from akdctl.errors import UsageError

    with pytest.raises(UsageError):
        PcapWriter(tmp_path / "no" / "such" / "dir" / "x.pcap")


def test_record_timestamps(tmp_path) -> None:
    with PcapWriter(tmp_path / "t.pcap") as writer:
        writer.write(TraceRecord(1700000000.9999999, "tx", "pnio-rpc", b"x",
                                 meta={"proto": "udp", "src": ("::1", 1), "dst": ("::1", 2)}))
    raw = (tmp_path / "t.pcap").read_bytes()
    sec, usec = struct.unpack("<II", raw[24:32])
    assert usec < 1_000_000 and sec in (1700000000, 1700000001)
    assert raw[40 + 12:40 + 14] == b"\x86\xdd"
