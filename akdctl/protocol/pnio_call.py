"""The client's side of a record access - a Write of the parameter record, then a Read of it - encoded once and
patched per call, and its usual reply read with one unpack.

Why a codec of its own: a PNU read is two RPCs, and building each datagram from the general encoders
(:class:`~akdctl.protocol.dcerpc.RequestTemplate`, :func:`~akdctl.protocol.pnio.encode_request_args`,
:func:`~akdctl.protocol.pnio.write_request` / :func:`~akdctl.protocol.pnio.read_request`) and reading each reply into
an :class:`~akdctl.protocol.dcerpc.RpcView` cost more than the drive's answer (issue 29). :class:`RecordCalls` encodes
the datagrams *with those encoders* once per shape (AR, record address, record length) and then writes only what
changes per call - the DCE/RPC sequence number and the record header's sequence number - at the offsets those encoders
put them; tests/test_pnio_call.py holds every datagram byte-equal to the encoders' (hypothesis).
:func:`plain_response` recognises only the reply the general path (``dcerpc.view_packet``, the activity and sequence
check, ``pnio.decode_response_args``) would accept as the call's answer, and returns what that path returns; anything
else (another packet type, a fragment, a stale or foreign reply, a malformed one) is None and takes the general path.
"""

from __future__ import annotations

import struct
import uuid

from akdctl.protocol import dcerpc, pnio

# Offsets the general encoders write to (dcerpc.RequestTemplate: sequence and opnum at 64, body length at 74;
# encode_request_args: the 20-byte NDR header at 80; write_request/read_request: the block header's 6 bytes, then
# the record header whose sequence number comes first and whose record length comes last).
_SEQUENCE_AT = 64
_BODY_AT = dcerpc.HEADER_SIZE
_NDR_SIZE = 20
_RW_SEQ_AT = _BODY_AT + _NDR_SIZE + pnio.BLOCK_HEADER.size
_Patched = tuple[struct.Struct, bytes, bytes, bytes]


def _patched(head: bytes, middle: bytes, tail: bytes) -> _Patched:
    """A datagram's fixed bytes around its two sequence numbers (DCE/RPC's 32-bit one after ``head``, the record
    header's 16-bit one after ``middle``, both big-endian as akdctl sends) as one Struct: one pack per call."""
    return struct.Struct(f">{len(head)}sI{len(middle)}sH{len(tail)}s"), head, middle, tail

_WRITE_PREFIX = _RW_SEQ_AT + 58  # DCE/RPC header + NDR header + IODWriteReqHeader: what precedes the record data


class RecordCalls:
    """The Write and Read datagrams of one activity to one record of one AR.

    ``template`` is the activity's request header, ``ar`` the AR UUID's 16 bytes, ``read_length`` the most a Read
    takes, ``activity`` the activity's UUID (whose replies :meth:`written` and :meth:`read_data` read). Every datagram
    equals ``template.packet(sequence, opnum, pnio.encode_request_args(write_request(...) or
    read_request(...)))``.
    """

    __slots__ = ("_read", "_write", "_write_length", "_write_shape", "_activity_be", "_activity_le", "_index")

    def __init__(self, template: dcerpc.RequestTemplate, ar: bytes, address: pnio.RecordAddress,
                 read_length: int, activity: uuid.UUID | None = None) -> None:
        #: The activity's UUID as a reply carries it, big- and little-endian (for :meth:`written`/:meth:`read_data`).
        self._activity_be, self._activity_le = (activity.bytes, activity.bytes_le) if activity is not None else (b"", b"")
        self._index = address.index
        read = template.packet(0, pnio.OP_READ, pnio.encode_request_args(pnio.read_request(0, ar, address,
                                                                                             read_length)))
        self._read = _patched(read[:_SEQUENCE_AT], read[_SEQUENCE_AT + 4:_RW_SEQ_AT], read[_RW_SEQ_AT + 2:])
        self._write = _patched(b"", b"", b"")  # made for the first record length written, again when it changes
        self._write_length = -1
        self._write_shape: tuple[dcerpc.RequestTemplate, bytes, pnio.RecordAddress] = (template, ar, address)

    def read(self, sequence: int, rw_seq: int) -> bytes:
        """The Read datagram of call ``sequence`` with record sequence number ``rw_seq``."""
        layout, head, middle, tail = self._read
        return layout.pack(head, sequence, middle, rw_seq, tail)

    def write(self, sequence: int, rw_seq: int, data: bytes) -> bytes:
        """The Write datagram of call ``sequence`` carrying ``data`` with record sequence number ``rw_seq``."""
        if len(data) != self._write_length:
            template, ar, address = self._write_shape
            write = template.packet(0, pnio.OP_WRITE, pnio.encode_request_args(pnio.write_request(0, ar, address,
                                                                                                  data)))
            self._write = _patched(write[:_SEQUENCE_AT], write[_SEQUENCE_AT + 4:_RW_SEQ_AT],
                                   write[_RW_SEQ_AT + 2:_WRITE_PREFIX])
            self._write_length = len(data)
        layout, head, middle, tail = self._write
        return layout.pack(head, sequence, middle, rw_seq, tail) + data

    def written(self, data: bytes | bytearray, size: int, sequence: int) -> bool:
        """Whether ``data[:size]`` (a receive buffer needs no copy) is the usual answer to the Write of call ``sequence``: the reply :func:`plain_response`
        takes, with PNIOStatus OK and blocks that :func:`pnio.write_response` reads with one unpack (its header block
        first) as an OK write - what the general path takes as a done write. False: the general path decides what
        the datagram is (another call's, a refusal, busy, malformed, an unusual block layout)."""
        head = _answer(data, size, sequence, self._activity_be, self._activity_le)
        if head is None or head[0] != _OK or head[1] < _WRITE_RES_SIZE:
            return False
        btype, length, _seq, _index, status = _WRITE_RES.unpack_from(data, _REPLY_SIZE)
        return btype == pnio.BT_WRITE_RES and 60 <= length <= head[1] - 4 and status == _OK

    def read_data(self, data: bytes | bytearray, size: int, sequence: int, rw_seq: int) -> bytes | None:
        """The record data of ``data[:size]`` when it is the usual answer to the Read of call ``sequence`` with record
        sequence number ``rw_seq``: the reply :func:`plain_response` takes, with PNIOStatus OK and blocks that
        :func:`pnio.read_response` reads with one unpack as this record's, ``rw_seq``'s - what the general path
        returns for it. None: the general path decides."""
        head = _answer(data, size, sequence, self._activity_be, self._activity_le)
        if head is None or head[0] != _OK or head[1] < 64:
            return None
        btype, length, seq, index, record_length = _READ_RES.unpack_from(data, _REPLY_SIZE)
        if btype != pnio.BT_READ_RES or length != 60 or 64 + record_length > head[1] or seq != rw_seq \
                or index != self._index:
            return None
        return bytes(data[_REPLY_SIZE + 64:_REPLY_SIZE + 64 + record_length])


# DCE/RPC CL header of a reply (version, type, flags1, drep byte 0; activity; sequence, body length) and the NDR
# response header after it (PNIOStatus, ArgsLength, MaximumCount, Offset, ActualCount), per data representation.
_REPLY = {little: struct.Struct(order + "BBB1xB35x16s8xI6xH4x4sIIII")
          for little, order in ((False, ">"), (True, "<"))}
_REPLY_SIZE = _REPLY[False].size  # 100: the header and the NDR response header
_OK = pnio.OK.encode()
_VERSION, _RESPONSE, _FRAG = dcerpc.RPC_VERSION, dcerpc.PT_RESPONSE, dcerpc.FLAG_FRAG  # (read once per reply)
# The record header block of a Write/Read response (pnio's own one-unpack layouts), read where it follows the reply's
# NDR header
_WRITE_RES, _READ_RES = pnio.WRITE_RES_FIELDS, pnio.READ_RES_FIELDS
_WRITE_RES_SIZE = max(48, _WRITE_RES.size)


def plain_response(data: bytes, sequence: int, activity_be: bytes, activity_le: bytes
                   ) -> tuple[pnio.PnioStatus, bytes] | None:
    """(PNIOStatus, blocks) of an unfragmented DCE/RPC response of our activity to call ``sequence`` whose NDR
    header is consistent - exactly what the general path (``view_packet``, the activity and sequence check,
    ``decode_response_args``) returns for it - else None (the general path decides what the datagram is)."""
    head = _answer(data, len(data), sequence, activity_be, activity_le)
    if head is None:
        return None
    status, length = head
    return (pnio.OK if status == _OK else pnio.PnioStatus(*status)), data[_REPLY_SIZE:_REPLY_SIZE + length]


def _answer(data: bytes | bytearray, size: int, sequence: int, activity_be: bytes, activity_le: bytes
            ) -> tuple[bytes, int] | None:
    """(PNIOStatus bytes, length of the blocks) of a reply ``data[:size]`` that :func:`plain_response` takes, else
    None: the one check."""
    if size < _REPLY_SIZE or data[0] != _VERSION or data[1] != _RESPONSE or data[2] & _FRAG:
        return None
    order = data[4] >> 4
    if order > 1:
        return None
    (_v, _t, _f, _d, activity, seq, body_length, status, length, maximum, offset,
     actual) = _REPLY[order == 1].unpack_from(data)
    if seq != sequence or activity != (activity_le if order else activity_be) \
            or _BODY_AT + body_length > size or body_length < _NDR_SIZE:
        return None
    if offset != 0 or actual > maximum or length > body_length - _NDR_SIZE:
        return None
    return status, length

