"""The one-pass record call codec (``pnio_record.record_call_fields``, ``write_ok``, ``read_ok``) against the general
short way it stands for (``plain_record_call``, ``write_res``/``read_res``, ``pack_record_response``): the same
requests recognised, the same fields, byte-equal replies -- for valid requests and for mutated, cut and padded ones."""

from __future__ import annotations

import random
import uuid

from akdctl.protocol import dcerpc, pnio, pnio_record


def _call(rng: random.Random, opnum: int, blocks: bytes, little: bool) -> bytes:
    head = dcerpc.RpcHeader(ptype=dcerpc.PT_REQUEST, object_uuid=pnio.object_uuid(0x100, 1),
                            interface_uuid=pnio.DEVICE_INTERFACE, activity_uuid=uuid.UUID(int=rng.getrandbits(128)),
                            sequence=rng.getrandbits(32), opnum=opnum, serial=rng.getrandbits(16),
                            drep=dcerpc.DREP_LITTLE if little else dcerpc.DREP_BIG)
    return dcerpc.encode_packet(head, pnio.encode_request_args(blocks, little=little))


def _requests(seed: int, count: int) -> list[bytes]:
    rng = random.Random(seed)
    out = []
    for _ in range(count):
        little = rng.random() < 0.5
        ar = uuid.UUID(int=rng.getrandbits(128))
        address = pnio.RecordAddress(api=rng.choice([0x3A00, 0]), slot=rng.choice([1, 3]), subslot=1,
                                     index=rng.choice([0x2F, 0xB02E, 0xAFF0]))
        if rng.random() < 0.5:
            data = bytes(rng.getrandbits(8) for _ in range(rng.choice([0, 1, 10, 240, 241])))
            request = _call(rng, pnio.OP_WRITE, pnio.IODWriteReq(rng.getrandbits(16), ar, address, data).encode(),
                            little)
        else:
            request = _call(rng, rng.choice([pnio.OP_READ, pnio.OP_READ, pnio.OP_READ_IMPLICIT]),
                            pnio.IODReadReq(rng.getrandbits(16), ar, address, rng.choice([240, 4, 0])).encode(), little)
        kind = rng.random()
        if kind < 0.3:
            where = rng.randrange(min(len(request), 170))
            request = request[:where] + bytes([rng.randrange(256)]) + request[where + 1:]
        elif kind < 0.4:
            request = request[:rng.randrange(len(request))]
        elif kind < 0.45:
            request += bytes(rng.randint(1, 4))
        out.append(request)
    return out


def test_record_call_fields_recognise_what_plain_record_call_does() -> None:
    recognised = 0
    for data in _requests(29, 3000):
        plain = pnio_record.plain_record_call(data)
        fields = pnio_record._record_call_fields(data)
        assert (plain is None) == (fields is None), data.hex()
        if plain is None or fields is None:
            continue
        recognised += 1
        little, sequence, opnum, req = plain
        assert fields == (little, data[40:56], sequence, opnum, req.ar,
                          pnio_record.record_address(req.api, req.slot, req.subslot), req.index, req.length)
        shape, shape_sequence, record_sequence = pnio_record.record_call_fields(data)  # type: ignore[misc]
        assert (shape[:2], shape_sequence, shape[2:7]) == (fields[:2], fields[2], fields[3:])
        assert record_sequence == req.seq.to_bytes(2, "big")
        if opnum == pnio.OP_WRITE:
            assert data[164:164 + fields[-1]] == req.data
    assert recognised > 1000


def test_ok_replies_are_the_general_replies() -> None:
    """write_ok/read_ok pack a shape's template (cut from the general reply to its first call): every later call of
    the shape -- another sequence number, record sequence number, boot time, record of another length -- still gets
    the general codecs' bytes."""
    rng = random.Random(7)
    checked = reused = 0
    pnio_record._SHAPES.clear()
    for first in _requests(31, 2000):
        for variant in range(4):
            data = first
            if variant:  # another sequence number and record sequence number: the same shape, its templates kept
                data = first[:64] + rng.getrandbits(32).to_bytes(4, "big") + first[68:106] + \
                    rng.getrandbits(16).to_bytes(2, "big") + first[108:]
            plain = pnio_record.plain_record_call(data)
            fields = pnio_record.record_call_fields(data)
            assert (plain is None) == (fields is None)
            if plain is None or fields is None:
                break
            little, _sequence, opnum, req = plain
            shape, sequence, record_sequence = fields
            reused += bool(shape[8])
            boot = rng.getrandbits(32)
            if opnum == pnio.OP_WRITE:
                expected = pnio_record.pack_record_response(data, little, boot, *pnio_record.write_res(req, pnio.OK))
                assert pnio_record.write_ok(data, shape, sequence, record_sequence, boot) == expected
            else:
                record = bytes(rng.getrandbits(8) for _ in range(rng.choice([0, 4, 12, 240])))
                expected = pnio_record.pack_record_response(data, little, boot, *pnio_record.read_res(req, record))
                assert pnio_record.read_ok(data, shape, sequence, record_sequence, boot, record) == expected
            reply = dcerpc.decode_packet(expected)  # and the general codecs read it back
            assert reply.header.ptype == dcerpc.PT_RESPONSE
            checked += 1
    assert checked > 1500 and reused > 1000


def test_a_shape_seen_before_gives_what_every_check_gives() -> None:
    """record_call_fields keeps the shapes it checked (pnio_record._SHAPES); requests of a kept shape -- their
    sequence numbers changed, cut short, lengthened, a byte anywhere changed -- get what every check gives."""
    rng = random.Random(11)
    hits = 0
    pnio_record._SHAPES.clear()
    for data in _requests(41, 1500):
        for variant in range(6):
            if variant == 1:    # another sequence number and record sequence number: the same shape
                data = data[:64] + rng.getrandbits(32).to_bytes(4, "big") + data[68:106] + \
                    rng.getrandbits(16).to_bytes(2, "big") + data[108:]
            elif variant == 2:  # cut short
                data = data[:rng.randrange(len(data) + 1)]
            elif variant == 3:  # bytes after the body
                data += bytes(rng.randint(1, 3))
            elif variant == 4 and data:  # a byte anywhere
                where = rng.randrange(len(data))
                data = data[:where] + bytes([rng.randrange(256)]) + data[where + 1:]
            key = data[:64] + data[68:106] + data[108:140]
            hits += key in pnio_record._SHAPES
            kept, checked = pnio_record.record_call_fields(data), pnio_record._record_call_fields(data)
            assert (kept is None) == (checked is None), data.hex()
            if kept is not None and checked is not None:
                (little, activity, opnum, ar, address, index, length, _least, _replies), sequence, _record = kept
                assert (little, activity, sequence, opnum, ar, address, index, length) == checked, data.hex()
    assert hits > 1000


def test_booted_templates_pack_the_general_replies() -> None:
    """ok_template_booted (the face's templates, its boot time written in) packs the general codecs' bytes for every
    call of the shape: other sequence numbers, record sequence numbers, records."""
    rng = random.Random(11)
    checked = 0
    for first in _requests(37, 600):
        plain = pnio_record.plain_record_call(first)
        if plain is None:
            continue
        boot = rng.getrandbits(32)
        write = plain[2] == pnio.OP_WRITE
        length = None if write else rng.choice([0, 4, 12, 240])
        pack, head, middle, tail = pnio_record.ok_template_booted(first, length, boot)
        for _ in range(3):
            sequence, record_sequence = rng.getrandbits(32), rng.getrandbits(16).to_bytes(2, "big")
            data = first[:64] + sequence.to_bytes(4, "little" if plain[0] else "big") + first[68:106] + \
                record_sequence + first[108:]
            little, _sequence, _opnum, req = pnio_record.plain_record_call(data)  # type: ignore[misc]
            if write:
                expected = pnio_record.pack_record_response(data, little, boot, *pnio_record.write_res(req, pnio.OK))
                assert pack(head, sequence, middle, record_sequence, tail) == expected
            else:
                record = bytes(rng.getrandbits(8) for _ in range(length or 0))
                expected = pnio_record.pack_record_response(data, little, boot, *pnio_record.read_res(req, record))
                assert pack(head, sequence, middle, record_sequence, tail, record) == expected
            checked += 1
    assert checked > 300
