"""The scope's pdo source runs once per bus cycle, so its path through the raw master and the decoder has fast
forms; each is pinned here to the general form it stands for, on the same input, error cases included:

* ``image_reader`` (one struct) reads what ``field_value`` reads, for every layout (a bit field, entries out of
  order, overlapping or repeated, an image too short falls back to it);
* ``PdoSpec.decoder()`` gives the rows ``PdoSpec.decode`` gives;
* ``FrameTemplate.answer`` takes exactly the replies ``FrameTemplate.read`` takes, less our own frame echoed;
  ``stamp_in_place`` builds the frame ``stamp`` builds;
* ``EcatMaster.txrx_cyclic`` returns what ``txrx_template`` returns for the same frames received (the answer
  after our own echo, after a foreign frame, nothing at all), and ``ProcessDataCycle.exchange`` puts the outputs
  asked for in every frame although it stamps them only when they change (a send that failed included).
"""

from __future__ import annotations

import random
import struct

import pytest

from akdctl.catalog.objects import PdoEntry
from akdctl.drive import scope_pdo
from akdctl.drive.ecat_pdo_watch import Layout, field_value, image_reader
from akdctl.drive.scope_trigger import parse_trigger
from akdctl.errors import CommError
from akdctl.protocol import ethercat as ec
from akdctl.transport.ethercat_raw import LOGICAL_BASE, MASTER_MAC, EcatMaster, FrameLost, ProcessDataCycle
from akdctl.transport.trace import Tracer

LAYOUTS = [
    [(0, 32, True), (32, 16, False)],  # 0x6063 and the status word, as the row maps them
    [(32, 16, False), (0, 32, True)],  # out of order
    [(0, 16, False), (0, 16, False)],  # the same entry twice
    [(0, 16, True), (0, 16, False)],  # the same bits, signed and not
    [(0, 32, True), (16, 16, False)],  # overlapping
    [(4, 12, False), (16, 8, True)],  # a bit field
    [(0, 8, True), (24, 16, True), (40, 64, False)],  # gaps, 8 and 64 bits
    [(16, 16, True)],  # one entry behind a gap
    [(0, 1, False), (1, 15, True)],
]


def _general(image: bytes, fields: list[tuple[int, int, bool]]) -> tuple[int, ...]:
    value = int.from_bytes(image, "little")
    return tuple(field_value(value, bit, bits, signed) for bit, bits, signed in fields)


@pytest.mark.parametrize("fields", LAYOUTS)
def test_image_reader_reads_what_field_value_reads(fields: list[tuple[int, int, bool]]) -> None:
    rng = random.Random(29)
    need = max(bit + bits for bit, bits, _s in fields) // 8 + 1
    read, as_float = image_reader(fields), image_reader(fields, float)
    for length in (need - 2, need - 1, need, need + 3):  # shorter than the entries too: the missing bits are 0
        for _ in range(200):
            image = bytes(rng.getrandbits(8) for _ in range(max(0, length)))
            want = _general(image, fields)
            assert tuple(read(image)) == want
            got = as_float(image)
            assert isinstance(got, list) and got == [float(v) for v in want]


TX = Layout([(0x1A00, (PdoEntry(0x606C, 0, 32), PdoEntry(0x6063, 0, 32), PdoEntry(0x6041, 0, 16)))])


@pytest.mark.parametrize("names, trigger", [(["0x6063", "STATUSWORD"], None), (["VL.FB"], "bit:3"),
                                            (["0x6063"], "above:0x606C:5"), (["STATUSWORD", "0x606C", "0x6063"], None)])
def test_the_compiled_decoder_gives_the_rows_decode_gives(names: list[str], trigger: str | None) -> None:
    trig = parse_trigger(trigger)
    columns, width, tslot, sslot = scope_pdo.resolve_columns(TX, names, trig)
    spec = scope_pdo.PdoSpec(columns, width, 0.001, 10, 0, trigger_slot=tslot, status_slot=sslot)
    decode, rng = spec.decoder(), random.Random(7)
    for length in (TX.bytes, TX.bytes - 3, TX.bytes + 2):
        for _ in range(300):
            image = bytes(rng.getrandbits(8) for _ in range(length))
            assert decode(image) == spec.decode(image)


# ---------------------------------------------------------------------- the frame template
def _templates() -> list[ec.FrameTemplate]:
    lrw = [ec.logical_datagram(ec.Cmd.LRW, LOGICAL_BASE, bytes(10))]
    status = lrw + [ec.Datagram(ec.Cmd.FPRD, 0x1001, ec.REG_AL_STATUS, bytes(2))]
    return [ec.FrameTemplate(lrw, MASTER_MAC, answer_from=4), ec.FrameTemplate(lrw, MASTER_MAC),
            ec.FrameTemplate(status, MASTER_MAC, answer_from=4),
            ec.FrameTemplate([ec.Datagram(ec.Cmd.FPRD, 0x1001, 0x0808, bytes(8))], MASTER_MAC)]


def _reply(template: ec.FrameTemplate, index: int, rng: random.Random) -> bytearray:
    """The template's frame as a slave sends it back: another source, data and WKCs filled in, ADP/IRQ moved."""
    frame = bytearray(template.stamp(index))
    frame[6:12] = b"\x03\x01\x01\x01\x01\x01"
    pos = ec.ETH_HEADER + 2
    while pos < template.size:
        length = struct.unpack_from("<H", frame, pos + 6)[0] & 0x7FF
        frame[pos + 2:pos + 4] = bytes((rng.getrandbits(8), rng.getrandbits(8)))  # ADP (counted on the way)
        frame[pos + 10:pos + 10 + length] = bytes(rng.getrandbits(8) for _ in range(length))
        frame[pos + 10 + length:pos + 12 + length] = struct.pack("<H", rng.randrange(4))
        pos += 12 + length
    return frame


def _expected(template: ec.FrameTemplate, buffer: bytearray, index: int, size: int) -> object:
    if buffer[6:12] == MASTER_MAC:
        return None
    got = template.read(buffer, index, size)
    return None if got is None else template.from_answer_from(got)


def test_answer_takes_the_replies_read_takes_less_our_own_frame() -> None:
    rng = random.Random(23)
    for template in _templates():
        for _ in range(40):
            index = rng.randrange(256)
            reply = _reply(template, index, rng)
            cases = [bytearray(reply)]
            for at in range(len(reply)):  # every byte changed once
                bad = bytearray(reply)
                bad[at] = (bad[at] + 1 + rng.randrange(255)) & 0xFF
                cases.append(bad)
            own = bytearray(reply)
            own[6:12] = MASTER_MAC
            cases.append(own)
            for case in cases:
                for size in (len(case), len(case) - 1, len(case) + 5):
                    buffer = bytearray(rng.getrandbits(8) for _ in range(256))  # a receive buffer, stale bytes after
                    buffer[:len(case)] = case
                    for asked in (index, (index + 1) & 0xFF):
                        assert template.answer(buffer, asked, size) == _expected(template, buffer, asked, size)
            assert template.answer(reply, index, len(reply)) is not None  # (the unchanged reply is taken)


def test_stamp_in_place_builds_the_frame_stamp_builds() -> None:
    for template in _templates():
        data = bytes(range(template._data_at[1] - template._data_at[0]))
        assert bytes(template.stamp_in_place(9, data)) == template.stamp(9, data)
        assert bytes(template.stamp_in_place(10)) == template.stamp(10)  # the data stamped last stays
        assert template.stamp_in_place(11) is template.frame
        with pytest.raises(ec.CodecError):
            template.stamp_in_place(12, data + b"\0")


# ---------------------------------------------------------------------- the master's cyclic exchange
class Scripted:
    """A socket: each frame sent queues what ``answers(frame)`` gives; a receive with none queued is the receive
    timeout running out. ``fail_sends`` sends raise OSError."""

    def __init__(self, answers) -> None:  # type: ignore[no-untyped-def]
        self.answers = answers
        self.sent: list[bytes] = []
        self.queue: list[bytes] = []
        self.fail_sends = 0

    def send(self, frame: bytes) -> int:
        if self.fail_sends:
            self.fail_sends -= 1
            raise OSError(100, "Network is down")
        self.sent.append(bytes(frame))
        self.queue.extend(self.answers(bytes(frame)))
        return len(frame)

    def recv_into(self, buffer: bytearray) -> int:
        if not self.queue:
            raise BlockingIOError
        frame = self.queue.pop(0)
        buffer[:len(frame)] = frame
        return len(frame)

    def settimeout(self, value: object) -> None:
        pass

    def setsockopt(self, *option: object) -> None:
        pass

    def close(self) -> None:
        pass


def _answered(frame: bytes, wkc: int = 1, fill: int = 0x5A) -> bytes:
    """The slave's answer to a one-LRW frame: inputs filled behind the outputs, WKC, its own source."""
    out = bytearray(frame)
    out[6:12] = b"\x03\x01\x01\x01\x01\x01"
    length = struct.unpack_from("<H", out, 22)[0] & 0x7FF
    out[26 + 4:26 + length] = bytes([fill]) * (length - 4)
    out[26 + length:28 + length] = struct.pack("<H", wkc)
    return bytes(out)


FOREIGN = ec.encode_frame([ec.Datagram(ec.Cmd.BRD, 0, 0, bytes(2), index=0xEE)], src=b"\x02" * 6)
SCRIPTS = {
    "the answer": lambda f: [_answered(f)],
    "our echo first": lambda f: [f, _answered(f, 2)],
    "a foreign frame first": lambda f: [FOREIGN, _answered(f, 3)],
    "an earlier index first": lambda f: [_answered(f[:17] + bytes([(f[17] - 1) & 0xFF]) + f[18:], 1, 1),
                                         _answered(f, 1, 2)],
    "another command, this index": lambda f: [_answered(f[:16] + bytes([ec.Cmd.LRD]) + f[17:])],  # general decode
    "a short frame": lambda f: [f[:20], _answered(f)],
    "nothing": lambda f: [],
    "only our echo": lambda f: [f],
}


@pytest.mark.parametrize("traced", [False, True])
@pytest.mark.parametrize("script", sorted(SCRIPTS))
def test_txrx_cyclic_returns_what_txrx_template_returns(script: str, traced: bool) -> None:
    outcomes, tracers = [], []
    for cyclic in (True, False):
        sock = Scripted(SCRIPTS[script])
        tracer = Tracer(record=traced)
        tracers.append(tracer)
        master = EcatMaster("pd0", tracer, timeout=0.05, retries=0, sock=sock)  # type: ignore[arg-type]
        template = ec.FrameTemplate([ec.logical_datagram(ec.Cmd.LRW, LOGICAL_BASE, bytes(10))], MASTER_MAC,
                                    answer_from=4)
        try:
            if cyclic:
                outcomes.append(master.txrx_cyclic(template, bytes(10)))
            else:
                outcomes.append(template.from_answer_from(master.txrx_template(template, bytes(10))))
        except FrameLost as exc:
            outcomes.append(("lost", exc.message))
        outcomes.append(sock.sent)
    assert outcomes[0] == outcomes[2] and outcomes[1] == outcomes[3]
    frames = [[(r.direction, r.data) for r in tracer.records] for tracer in tracers]
    assert frames[0] == frames[1] and (len(frames[0]) > 0) == traced  # the same frames traced either way


def test_exchange_sends_the_outputs_asked_for_though_it_stamps_only_changes() -> None:
    sock = Scripted(lambda f: [_answered(f)])
    master = EcatMaster("pd0", Tracer(record=False), timeout=0.05, retries=0, sock=sock)  # type: ignore[arg-type]
    cycle = ProcessDataCycle(master, 0x1001, 4, 6)
    one, two = b"\x01\x02\x03\x04", bytearray(b"\x09\x08\x07\x06")
    asked = [one, one, two, two, one, b"\x01\x02", one, two]
    for outputs in asked:
        assert cycle.exchange(outputs, False) == (b"\x5a" * 6, 1, None)
    sent = [bytes(o).ljust(4, b"\0") for o in asked]
    two[0] = 0x55  # the caller changes its buffer: the next frame carries the change
    cycle.exchange(two, False)
    sent.append(bytes(two))
    assert [frame[26:30] for frame in sock.sent] == sent
    sock.fail_sends = 1
    with pytest.raises(CommError, match="cannot send"):
        cycle.exchange(one, False)  # stamped, not sent
    cycle.exchange(one, False)
    sock.fail_sends = 1
    with pytest.raises(CommError, match="cannot send"):
        cycle.exchange(two, False)
    cycle.exchange(two, False)  # sent now: the frame holds these outputs
    assert [frame[26:30] for frame in sock.sent[-2:]] == [one, bytes(two)]
    assert all(frame[30:36] == bytes(6) for frame in sock.sent)  # the inputs' part goes out as zeros


def test_a_factor_of_one_converts_as_float_does() -> None:
    from akdctl.drive.scope_signals import _scaled

    assert _scaled(1.0) is float  # (float(raw) * 1.0 is float(raw), bit for bit)
    assert _scaled(0.5)(3) == 1.5 and _scaled(1.0)(-7) == -7.0
