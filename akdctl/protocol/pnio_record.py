"""The one shape every PNU read and write has on the wire — a plain PNIO record Write/Read call — read and
answered with one unpack each way.

Why a codec of its own beside :mod:`akdctl.protocol.dcerpc` and :mod:`akdctl.protocol.pnio`: a PNU read is two
RPCs, and decoding each into an ``RpcHeader`` (three UUIDs), an ``IODWriteReq``/``IODReadReq`` and encoding the reply
from objects cost several times what the drive's answer does (issue 15). :func:`plain_record_call` recognises only
requests the general decoders accept (anything else returns None and takes the general path, with every check of
``dcerpc.view_packet``, ``pnio.decode_request_args`` and the record decoders); the replies are the bytes
``dcerpc.encode_packet`` and ``IODWriteRes``/``IODReadRes.encode()`` produce. The simulator's PROFINET face uses it;
tests/test_sim_faces.py holds the two ways together (replies byte-equal to the codecs', the short way's answers
equal to the general path's).
"""

from __future__ import annotations

import functools
import struct
from typing import Any, NamedTuple

from akdctl.protocol import dcerpc, pnio
from akdctl.protocol.pnio import BT_READ_REQ, BT_WRITE_REQ, OK, OP_READ, OP_WRITE

#: The device interface UUID as it appears on the wire, by the request's byte order (True: little endian).
DEVICE_INTERFACE_WIRE = {False: pnio.DEVICE_INTERFACE.bytes, True: pnio.DEVICE_INTERFACE.bytes_le}
_HEAD_TAIL = {False: struct.Struct(">I"), True: struct.Struct("<I")}  # server boot time at byte 56
_LENGTH_FRAGMENT = {False: struct.Struct(">HH"), True: struct.Struct("<HH")}  # body length, fragment: byte 74


def reply_head(data: bytes, little: bool, ptype: int, boot: int, body_length: int) -> bytes:
    """The 80-byte header of a reply to the request ``data``: its header with the reply's type, flags (NOFACK on a
    response), this device's boot time, fragment 0 and the body's length; UUIDs, sequence, opnum, hints and
    data representation stay as the request sent them (``little``: its data representation)."""
    head = bytearray(data[:dcerpc.HEADER_SIZE])
    head[1], head[2], head[3] = ptype, dcerpc.FLAG_NOFACK if ptype == dcerpc.PT_RESPONSE else 0, 0
    _HEAD_TAIL[little].pack_into(head, 56, boot)
    _LENGTH_FRAGMENT[little].pack_into(head, 74, body_length, 0)
    return bytes(head)


# DCE/RPC CL header (drep order) + the NDR request arguments: the fields a plain record call is checked by
_CALL = {order: struct.Struct(order + "B B B 1x B 19x 16s 16s 4x 4x I H 4x H 2x 2x I I I I I")
         for order in (">", "<")}


def plain_record_call(data: bytes) -> tuple[bool, int, int, RecordCall] | None:
    """(little endian, sequence number, opnum, record request) of a datagram of the one shape every PNU read and
    write has - a DCE/RPC v4 request to the device interface, not fragmented, NDR arguments holding exactly one
    IODWriteReq or IODReadReq header (a write's record data after it) - else None, and the general path takes it
    with every check of dcerpc.view_packet, pnio.decode_request_args and the record decoders. This recognises
    only requests those accept, and the face answers them as the general path would."""
    if len(data) < 164 or data[0] != dcerpc.RPC_VERSION or data[1] != dcerpc.PT_REQUEST \
            or data[2] & dcerpc.FLAG_FRAG or data[4] >> 4 > 1:
        return None
    little = data[4] >> 4 == 1
    (_v, _t, _f, _drep, interface, _act, sequence, opnum, length, _args_max, args_length, maximum, offset,
     actual) = _CALL["<" if little else ">"].unpack_from(data)
    if interface != DEVICE_INTERFACE_WIRE[little] or (opnum != OP_WRITE and opnum != OP_READ):
        return None
    body_end = dcerpc.HEADER_SIZE + length
    if body_end > len(data) or offset or actual > maximum or args_length > length - 20 or actual > length - 20:
        return None
    blocks = data[100:100 + args_length]
    req = record_request_plain(blocks, BT_WRITE_REQ if opnum == OP_WRITE else BT_READ_REQ)
    return None if req is None else (little, sequence, opnum, req)


class RecordCall(NamedTuple):
    """A record read/write request as the face needs it (``ar``: the AR UUID's 16 bytes)."""

    seq: int
    ar: bytes
    api: int
    slot: int
    subslot: int
    pad: bytes
    index: int
    length: int  # write: the record data's length; read: the most the client takes
    data: bytes = b""


# BlockHeader (type, length, version) + the record header (seq, AR UUID, API, slot, subslot, padding, index, length)
_RECORD_HEAD = struct.Struct(">HHBBH16sIHH2sHI")
_RECORD_HEAD_LENGTH = 60  # BlockLength of IODWriteReqHeader and IODReadReqHeader (58 bytes after the version)
_RECORD = struct.Struct(">H16sIHH2sHI")  # the record header alone (34 bytes)
_WRITE_RES = pnio.block_header(pnio.BT_WRITE_RES, 58)
_READ_RES = pnio.block_header(pnio.BT_READ_RES, 58)
_NO_ADDITIONAL = bytes(4)  # AdditionalValue1, AdditionalValue2
_PAD2, _PAD16, _PAD20 = bytes(2), bytes(16), bytes(20)
_OK_BYTES = OK.encode()
#: A RecordCall from a plain tuple, without the Python-level ``__new__`` (the hot path builds one per request).
_new_record = functools.partial(tuple.__new__, RecordCall)


def write_res(req: RecordCall, status: pnio.PnioStatus) -> tuple[pnio.PnioStatus, bytes]:
    """IODWriteResHeader: the request's record header, AdditionalValue1/2 = 0, the status, 16 reserved bytes."""
    code = _OK_BYTES if status is OK else status.encode()
    return status, _WRITE_RES + _RECORD.pack(*req[:7], len(req.data)) + _NO_ADDITIONAL + code + _PAD16


def read_res(req: RecordCall, data: bytes) -> tuple[pnio.PnioStatus, bytes]:
    """IODReadResHeader: the request's record header with the data's length, 24 bytes 0; then the data."""
    return OK, _READ_RES + _RECORD.pack(*req[:7], len(data)) + _NO_ADDITIONAL + _PAD20 + data


def record_request(blocks: bytes, block_type: int) -> RecordCall:
    """The request's record header: one unpack when it is the one block it should be, else the general decoder
    (which refuses what does not parse with the same PnioError)."""
    plain = record_request_plain(blocks, block_type)
    if plain is not None:
        return plain
    if block_type == BT_WRITE_REQ:
        write = pnio.IODWriteReq.decode(blocks)
        a = write.address
        return RecordCall(write.seq_number, write.ar_uuid.bytes, a.api, a.slot, a.subslot, b"\0\0", a.index,
                       len(write.data), write.data)
    read = pnio.IODReadReq.decode(blocks)
    a = read.address
    return RecordCall(read.seq_number, read.ar_uuid.bytes, a.api, a.slot, a.subslot, b"\0\0", a.index,
                   read.max_length)


def record_request_plain(blocks: bytes, block_type: int) -> RecordCall | None:
    """The record header when ``blocks`` is exactly that one header block (and a write's data), else None."""
    size = len(blocks)
    if size >= 64:
        btype, blen, vhi, vlo, seq, ar, api, slot, subslot, _pad, index, length = _RECORD_HEAD.unpack_from(blocks)
        if btype == block_type and blen == _RECORD_HEAD_LENGTH:
            if block_type == BT_READ_REQ and size == 64:
                return _new_record((seq, ar, api, slot, subslot, _PAD2, index, length, b""))
            if block_type == BT_WRITE_REQ and size == 64 + length:
                return _new_record((seq, ar, api, slot, subslot, _PAD2, index, length, blocks[64:]))
    return None


# --- the whole response to a plain record call in one step (the simulator's PROFINET face, issue 29) -------------
# The reply header's fields the request gave (version; drep .. activity UUID; interface version .. activity hint;
# serial low, data representation's tail) around the ones a response sets, then PNIOStatus and the NDR array header.
_RESPONSE = {little: struct.Struct(order + "1sBBB52sI14sHH2s4sIIII")
             for little, order in ((False, ">"), (True, "<"))}


def pack_record_response(data: bytes, little: bool, boot: int, status: pnio.PnioStatus, blocks: bytes) -> bytes:
    """The response datagram to the plain record call ``data``: what ``reply_head(data, little, PT_RESPONSE, boot,
    n) + pnio.encode_response_args(status, blocks, little=little)`` writes, in one pack."""
    n = len(blocks)
    return _RESPONSE[little].pack(data[:1], dcerpc.PT_RESPONSE, dcerpc.FLAG_NOFACK, 0, data[4:56], boot,
                                  data[60:74], 20 + n, 0, data[78:80],
                                  _OK_BYTES if status is OK else status.encode(), n, n, 0, n) + blocks


# --- one pass per plain record call (the simulator's PROFINET face, issue 29: a PNU read is two of them) ----------
# Why besides plain_record_call/pack_record_response: those build a RecordCall and take a PnioStatus per call; the
# calls that succeed -- nearly all of a poll -- need neither. The face reads the fields below, answers the OK cases
# with write_ok/read_ok and hands every other case to plain_record_call and the general answer (tests/test_sim_faces.py
# and tests/test_pnio_record_fast.py hold the two ways byte-equal). The OK replies are cut once per shape from the
# general codecs' reply (_template): a call then packs only what differs between the calls of its shape.
#: From byte 0, by the request's data representation (0 big, 1 little endian): interface and activity UUID, sequence,
#: opnum, body length, then the NDR arguments' length, maximum count, offset and actual count.
_FIELDS = (struct.Struct(">24x16s16s8xIH4xH8xIIII"), struct.Struct("<24x16s16s8xIH4xH8xIIII"))
#: From byte 100 (big endian, as every PNIO block): block type and length, the AR UUID, API + slot + subslot as the
#: 8 bytes :func:`record_address` makes, index and record data length (version, sequence and padding skipped).
_FIELDS_RECORD = struct.Struct(">HH4x16s8s2xHI")
_ADDRESS = struct.Struct(">IHH")
_INTERFACES = (DEVICE_INTERFACE_WIRE[False], DEVICE_INTERFACE_WIRE[True])


def record_address(api: int, slot: int, subslot: int) -> bytes:
    """API, slot and subslot as a record header carries them (the ``address`` of :func:`record_call_fields`)."""
    return _ADDRESS.pack(api, slot, subslot)


#: From byte 0, by the request's data representation (0 big, 1 little endian): the bytes the checks below read up to
#: the sequence number, the sequence number, the bytes from it to the record's own sequence number, that (2 bytes,
#: big endian as every PNIO block field: kept as bytes), and the record header's rest up to byte 140.
_PARTS = (struct.Struct(">64sI38s2s32s").unpack_from, struct.Struct("<64sI38s2s32s").unpack_from)
#: A shape of a plain record call: (little endian, activity UUID bytes, opnum, AR UUID bytes, address, index,
#: length, the least datagram length it holds for, its OK replies' templates by record length: _template).
Shape = tuple[bool, bytes, int, bytes, bytes, int, int, int, dict[int, tuple[Any, bytes, bytes, bytes, bytes]]]
#: The shapes of plain record calls seen: every byte the checks below read, but the sequence (64..67), and the
#: record's own sequence number (106..107, not checked) -> its Shape. A client's poll repeats two shapes; the
#: checks' answer depends on nothing else.
_SHAPES: dict[bytes, Shape] = {}
_SHAPES_KEPT = 64


def record_call_fields(data: bytes) -> tuple[Shape, int, bytes] | None:
    """(shape, sequence, record sequence) of a datagram :func:`plain_record_call` accepts (the same checks, no
    RecordCall; a shape seen before is not checked twice), else None. The shape: (little endian, activity UUID
    bytes, opnum, AR UUID bytes, address, index, length, the least datagram length it holds for, reply templates);
    ``address``: API, slot and subslot as :func:`record_address` packs them; ``length``: a write's record data length
    (the data is ``data[164:164 + length]``), a read's most the client takes; the record sequence number: its two
    bytes, as the reply carries them back (:func:`write_ok`, :func:`read_ok`)."""
    if len(data) < 164:
        return None
    head, sequence, middle, record_sequence, tail = _PARTS[data[4] >> 4 & 1](data)
    key = head + middle + tail
    shape = _SHAPES.get(key)
    if shape is not None and len(data) >= shape[7]:
        return shape, sequence, record_sequence
    fields = _record_call_fields(data)
    if fields is None:
        return None
    if len(_SHAPES) >= _SHAPES_KEPT:
        _SHAPES.clear()  # many clients or shapes: start over rather than grow
    little, activity, sequence, opnum, ar, address, index, rlength = fields
    body = _FIELDS[little].unpack_from(data)[4]
    shape = _SHAPES[key] = (little, activity, opnum, ar, address, index, rlength,
                            max(164, dcerpc.HEADER_SIZE + body), {})
    return shape, sequence, record_sequence


def _record_call_fields(data: bytes) -> tuple[bool, bytes, int, int, bytes, bytes, int, int] | None:
    """:func:`record_call_fields`, every check made."""
    if len(data) < 164 or data[0] != dcerpc.RPC_VERSION or data[1] != dcerpc.PT_REQUEST \
            or data[2] & dcerpc.FLAG_FRAG:
        return None
    drep = data[4] >> 4
    if drep > 1:
        return None
    interface, activity, sequence, opnum, length, args_length, maximum, offset, actual = \
        _FIELDS[drep].unpack_from(data)
    if interface != _INTERFACES[drep] or (opnum != OP_WRITE and opnum != OP_READ) or offset \
            or dcerpc.HEADER_SIZE + length > len(data) or actual > maximum or args_length > length - 20 \
            or actual > length - 20:
        return None
    btype, blen, ar, address, index, rlength = _FIELDS_RECORD.unpack_from(data, 100)
    if blen != _RECORD_HEAD_LENGTH:
        return None
    if opnum == OP_WRITE:
        if btype != BT_WRITE_REQ or args_length != 64 + rlength:
            return None
    elif btype != BT_READ_REQ or args_length != 64:
        return None
    return drep == 1, activity, sequence, opnum, ar, address, index, rlength


def write_ok(data: bytes, shape: Shape, sequence: int, record_sequence: bytes, boot: int) -> bytes:
    """The response to the plain Write record call ``data`` (:func:`record_call_fields` gave the rest) that
    succeeded: what ``pack_record_response(data, little, boot, *write_res(req, OK))`` writes, in one pack."""
    template = shape[8].get(-1)
    if template is None:
        template = shape[8][-1] = _template(data, None)
    pack, head, interface, middle, tail = template
    return pack(head, boot, interface, sequence, middle, record_sequence, tail)  # type: ignore[no-any-return]


def read_ok(data: bytes, shape: Shape, sequence: int, record_sequence: bytes, boot: int, record: bytes) -> bytes:
    """The response to the plain Read record call ``data`` (:func:`record_call_fields` gave the rest) answered with
    ``record``: what ``pack_record_response(data, little, boot, *read_res(req, record))`` writes, in one pack."""
    template = shape[8].get(len(record))
    if template is None:
        template = shape[8][len(record)] = _template(data, record)
    pack, head, interface, middle, tail = template
    return pack(head, boot, interface, sequence, middle, record_sequence, tail, record)  # type: ignore[no-any-return]


#: :func:`record_call_fields`' split of a datagram, by its data representation (``data[DREP_BYTE] >> 4 & 1``): the
#: bytes before the sequence number, the sequence number, the bytes up to the record sequence number, that, and the
#: rest of the record header; a shape's key is ``head + middle + tail`` (what a caller that keeps its own memo of
#: shapes looks up before it calls :func:`record_call_fields`).
CALL_PARTS = _PARTS
DREP_BYTE = 4
#: CALL_PARTS by the data representation byte itself: ``CALL_PARTS_BY_DREP[data[DREP_BYTE]]``.
CALL_PARTS_BY_DREP = tuple(_PARTS[drep >> 4 & 1] for drep in range(256))
#: What a CALL_PARTS split (its data representation byte read first) raises for a datagram too short to be split,
#: so too short to be a plain record call.
CallTooShort = (IndexError, struct.error)
#: Where a plain Write call's record data starts (its length is the shape's ``length``).
WRITE_DATA = 164


def ok_template(data: bytes, record_length: int | None) -> tuple[Any, bytes, bytes, bytes, bytes]:
    """The OK reply's template for the plain record call ``data`` (:func:`record_call_fields` accepts it): a Write's
    (``record_length`` None) or a Read's answered with a record of that length. ``pack(head, boot, interface,
    sequence, middle, record_sequence, tail[, record])`` writes what :func:`write_ok`/:func:`read_ok` write."""
    return _template(data, None if record_length is None else bytes(record_length))


def _template(data: bytes, record: bytes | None) -> tuple[Any, bytes, bytes, bytes, bytes]:
    """The OK reply to a shape's calls (a write's; a read's for a record of ``record``'s length) as a pack and the
    bytes around what differs between the calls of the shape -- the boot time (56..59), the sequence number
    (64..67), the record sequence number (106..107) and a read's record: the reply the general codecs write for
    ``data``, cut there. Every other byte of it is one of the bytes the shape's key holds or a constant."""
    plain = plain_record_call(data)
    assert plain is not None  # record_call_fields accepted data: so does plain_record_call (the same checks)
    little, _sequence, _opnum, req = plain
    status, blocks = write_res(req, OK) if record is None else read_res(req, record)
    full = pack_record_response(data, little, 0, status, blocks)
    end = len(full) - (0 if record is None else len(record))
    layout = f"{'<' if little else '>'}56sI4sI38s2s{end - 108}s" + ("" if record is None else f"{len(record)}s")
    return struct.Struct(layout).pack, full[:56], full[60:64], full[68:106], full[108:end]


def ok_template_booted(data: bytes, record_length: int | None, boot: int) -> tuple[Any, bytes, bytes, bytes]:
    """:func:`ok_template` with the device's boot time written in: ``pack(head, sequence, middle, record_sequence,
    tail[, record])`` writes what :func:`write_ok`/:func:`read_ok` write for that ``boot``. Why: a face's boot time is
    fixed, so its replies' first 64 bytes are one constant per shape, and the pack takes two arguments fewer per
    reply (issue 29). Cut from :func:`ok_template`'s, which is cut from the general codecs' reply."""
    _pack, head, interface, middle, tail = ok_template(data, record_length)
    little = data[DREP_BYTE] >> 4 & 1
    first = head + _HEAD_TAIL[bool(little)].pack(boot) + interface
    record = "" if record_length is None else f"{record_length}s"
    layout = f"{'<' if little else '>'}64sI38s2s{len(tail)}s{record}"
    return struct.Struct(layout).pack, first, middle, tail


def write_data_reader(length: int) -> Any:
    """The record data of a plain Write call whose record is ``length`` bytes: ``reader(buffer)`` gives
    ``(data[WRITE_DATA:WRITE_DATA + length],)`` as bytes from any buffer holding the datagram at its start. Why: a
    face that receives into a kept bytearray gets the request's bytes with one unpack, where a slice of the
    bytearray and its copy to bytes cost twice that (issue 29)."""
    return struct.Struct(f"{WRITE_DATA}x{length}s").unpack_from
