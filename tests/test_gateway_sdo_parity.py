"""The ``ecat-udp://`` poll's quick way (issue 29, row client-cpu) answers what the general path answers.

* the codec (:class:`akdctl.protocol.gateway_sdo.UploadFrames`): its request datagrams are the layer codecs' bytes,
  and it takes a reply only where ``unwrap_gateway`` + the link's station rule + ``coe.expedited_upload_reply`` take
  it, with the same counter and value, and does take the usual answer (the quick way is really used);
* the client (:meth:`CoeObjectChannel.upload` over a real :class:`GatewayMailboxLink` and a real UDP socket, against
  a scripted gateway answering from the simulated drive's SDO server): for every scenario a client must get right
  (counters echoed, rewritten or absent, an emergency first, duplicates, CoE service 2, losses, silence, a late
  reply, a reply to another station or from address 0, garbage, an abort, a normal and a segmented upload) the
  values, errors, datagrams sent and the counter rules' state equal the general path's (the same uploads inside an
  enclosing request, where ``Budget.lone`` declines), and tracing (which declines the quick way) changes nothing.
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable, Iterator

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.channels.coe_sdo import CoeObjectChannel
from akdctl.errors import AkdError
from akdctl.protocol import coe, gateway_sdo
from akdctl.protocol import mailbox as mbx
from akdctl.protocol.errors import CodecError
from akdctl.sim.drive import factory_model
from akdctl.sim.sdo_server import SdoServer
from akdctl.transport.ethercat_udp import GatewayMailboxLink
from akdctl.transport.trace import Tracer

STATION = 1001


def _general(datagram: bytes, station: int, index: int, subindex: int) -> tuple[int, bytes, bytes] | None:
    """What the general path takes of a datagram on the poll's first look: the link's unwrap and station rule, then
    the channel's one-pass reader."""
    try:
        mailbox = mbx.unwrap_gateway(datagram)
    except CodecError:
        return None
    address = mailbox[2] | mailbox[3] << 8
    if address != station and address:
        return None
    reply = coe.expedited_upload_reply(mailbox, index, subindex)
    return None if reply is None else (reply[0], reply[1], mailbox)


def _answer(station: int, counter: int, index: int, subindex: int, value: bytes) -> bytes:
    return mbx.wrap_gateway(coe.pack_expedited_upload_mailbox(station, counter, index, subindex, value))


def test_the_request_datagrams_are_the_layer_codecs_bytes() -> None:
    for station, index, subindex in ((STATION, 0x1018, 1), (4, 0x6041, 0), (0xFFFF, 0xFFFF, 0xFF), (0, 0, 0)):
        frames = gateway_sdo.UploadFrames(station, index, subindex)
        for counter in range(1, 8):
            assert frames.requests[counter] == mbx.wrap_gateway(
                mbx.pack(mbx.MailboxType.COE, coe.upload_request(index, subindex), station, counter))


@pytest.mark.parametrize(("index", "subindex"), [(0x10000, 0), (-1, 0), (0x1018, 0x100)])
def test_an_address_out_of_range_raises_as_the_general_encoder_does(index: int, subindex: int) -> None:
    with pytest.raises(coe.CoeError):
        coe.upload_request(index, subindex)
    with pytest.raises(coe.CoeError):
        gateway_sdo.UploadFrames(STATION, index, subindex)


@pytest.mark.parametrize("value", [b"\x01", b"\x01\x02", b"\x01\x02\x03", b"\x01\x02\x03\x04"])
def test_the_usual_answer_is_taken(value: bytes) -> None:
    frames = gateway_sdo.UploadFrames(STATION, 0x1018, 1)
    for counter in range(8):
        datagram = _answer(STATION, counter, 0x1018, 1, value)
        assert frames.answer(datagram) == _general(datagram, STATION, 0x1018, 1) == (counter, value, datagram[2:])


@pytest.mark.parametrize("station", [STATION, 0])
def test_every_single_bit_flip_of_the_answer_is_judged_as_the_general_path_judges_it(station: int) -> None:
    frames = gateway_sdo.UploadFrames(station, 0x1018, 1)
    for value in (b"\x01", b"\x01\x02\x03\x04"):
        good = _answer(station, 3, 0x1018, 1, value)
        for bit in range(len(good) * 8):
            flipped = bytearray(good)
            flipped[bit // 8] ^= 1 << bit % 8
            datagram = bytes(flipped)
            general = _general(datagram, station, 0x1018, 1)
            fast = frames.answer(datagram)
            address = datagram[4] | datagram[5] << 8
            assert fast == general or (fast is None and address == 0 != station), (bit, datagram.hex())


@settings(max_examples=500, deadline=None)
@given(st.binary(min_size=0, max_size=24), st.integers(0, 0xFFFF), st.integers(0, 0xFF), st.integers(0, 0xFFFF))
def test_the_one_unpack_check_takes_only_what_the_general_path_takes(tail: bytes, index: int, subindex: int,
                                                                     station: int) -> None:
    frames = gateway_sdo.UploadFrames(station, index, subindex)
    good = _answer(station, 5, index, subindex, tail[:4] or b"\x01")
    mutated = bytearray(good)
    for position, byte in zip(tail[0::2], tail[1::2]):
        mutated[position % len(mutated)] = byte
    for datagram in (tail, good, bytes(mutated), good + tail[:1], good[:-1]):
        fast = frames.answer(datagram)
        general = _general(datagram, station, index, subindex)
        if fast is not None:
            assert fast == general
        elif general is not None:  # declined but taken by the general path: only the cases left to it on purpose
            address = datagram[4] | datagram[5] << 8
            assert len(datagram) != 18 or address == 0 != station, datagram.hex()


# --- the client over a real socket ---------------------------------------------------------------------------------


def _model():
    model = factory_model("gateway-parity")
    model.object_write(0x2032, 0, b"x" * 1500)  # longer than one mailbox: segmented
    model.set_stored_object(0x2033, 0, b"AKD-x")  # a string of 5 bytes: a normal upload
    return model


Script = Callable[[list[bytes], bytes, int, list[bytes]], list[bytes]]


def _with_counter(datagram: bytes, counter: int) -> bytes:
    return datagram[:7] + bytes([(datagram[7] & 0x8F) | counter << 4]) + datagram[8:]


def _late(replies: list[bytes], request: bytes, n: int, held: list[bytes]) -> list[bytes]:
    """Every third request's answer is held back until the next request came (then sent before that one's)."""
    out, held[:] = [*held, *replies], []
    if n % 3 == 1:
        held[:] = out
        return []
    return out


EMERGENCY = mbx.wrap_gateway(mbx.pack(mbx.MailboxType.COE, b"\x00\x10" + bytes(8), STATION, 0))
SCRIPTS: dict[str, Script] = {
    "as served": lambda r, q, n, h: r,
    "counter rewritten": lambda r, q, n, h: [_with_counter(d, n % 7 + 1) for d in r],
    "counter zero": lambda r, q, n, h: [_with_counter(d, 0) for d in r],
    "emergency first": lambda r, q, n, h: [EMERGENCY, *r],
    "duplicated": lambda r, q, n, h: r * 2,
    "service 2": lambda r, q, n, h: [d[:9] + bytes([(d[9] & 0x0F) | 0x20]) + d[10:] for d in r],
    "lost every second": lambda r, q, n, h: r if n % 2 else [],
    "silent": lambda r, q, n, h: [],
    "late": _late,
    "another station first": lambda r, q, n, h: [r[0][:4] + (STATION + 1).to_bytes(2, "little") + r[0][6:], *r],
    "from address 0": lambda r, q, n, h: [d[:4] + b"\x00\x00" + d[6:] for d in r],
    "garbage first": lambda r, q, n, h: [b"\x01", b"\x10\x40" + bytes(16), *r],
    "trailing bytes": lambda r, q, n, h: [d + b"\x00" for d in r],
}
ADDRESSES = [(0x1018, 1), (0x1018, 4), (0x1018, 0), (0x6041, 0), (0x2033, 0), (0x1008, 0), (0x2032, 0), (0x1018, 9),
             (0x7FFF, 0), (0x1018, 1), (0x1018, 1), (0x6041, 0)]


class ScriptedGateway:
    """A UDP gateway in a thread: each request datagram answered by the simulated drive's SDO server, the answers
    rewritten by a script (counters, losses, extra datagrams, late replies)."""

    def __init__(self, script: Script) -> None:
        self.server = SdoServer(_model())
        self.script = script
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.received: list[bytes] = []
        self.held: list[bytes] = []
        self._stop = False
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop:
            try:
                datagram, peer = self.sock.recvfrom(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            self.received.append(datagram)
            replies = [mbx.wrap_gateway(m) for m in self.server.handle(mbx.unwrap_gateway(datagram))]
            for reply in self.script(replies, datagram, len(self.received), self.held):
                self.sock.sendto(reply, peer)

    def close(self) -> None:
        self._stop = True
        self._thread.join(2)
        self.sock.close()


@pytest.fixture
def gateways() -> Iterator[Callable[[Script], ScriptedGateway]]:
    made: list[ScriptedGateway] = []

    def make(script: Script) -> ScriptedGateway:
        made.append(ScriptedGateway(script))
        return made[-1]

    yield make
    for gateway in made:
        gateway.close()


def _outcome(channel: CoeObjectChannel, index: int, subindex: int, general: bool) -> object:
    try:
        if general:  # inside an enclosing request: Budget.lone declines, the general path runs
            with channel.budget.request():
                return channel.upload(index, subindex)
        return channel.upload(index, subindex)
    except AkdError as exc:
        return type(exc).__name__, str(exc)


def _run(make: Callable[[Script], ScriptedGateway], script: Script, general: bool, tracing: bool = False
         ) -> tuple[object, ...]:
    gateway = make(script)
    tracer = Tracer(record=tracing)
    link = GatewayMailboxLink("127.0.0.1", gateway.port, STATION, tracer, timeout=0.3)
    channel = CoeObjectChannel(link, timeout=0.3, retries=1)
    try:
        outcomes = [(_outcome(channel, i, s, general), channel._proven, channel.filter.echoes, channel._stale,
                     channel._counter) for i, s in ADDRESSES]
    finally:
        link.close()
    notes = [(r.direction, r.data, r.note) for r in tracer.records]
    return outcomes, gateway.received, [e.error_code for e in channel.take_emergencies()], notes


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_the_quick_upload_equals_the_general_path(name: str, gateways: Callable[[Script], ScriptedGateway],
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    read = gateway_sdo.UploadFrames.answer
    taken: list[bool] = []

    def counted(self: gateway_sdo.UploadFrames, datagram: bytes) -> tuple[int, bytes, bytes] | None:
        result = read(self, datagram)
        taken.append(result is not None)
        return result

    monkeypatch.setattr(gateway_sdo.UploadFrames, "answer", counted)
    quick = _run(gateways, SCRIPTS[name], general=False)
    if name in ("as served", "counter rewritten", "counter zero"):
        assert taken.count(True) >= 5  # the quick way answered these uploads itself
    assert quick == _run(gateways, SCRIPTS[name], general=True)


@pytest.mark.parametrize("name", ["as served", "emergency first", "another station first"])
def test_tracing_declines_the_quick_way_and_changes_nothing(name: str,
                                                           gateways: Callable[[Script], ScriptedGateway]) -> None:
    traced = _run(gateways, SCRIPTS[name], general=False, tracing=True)
    assert traced[3]  # every datagram traced, with what the link made of it
    assert traced == _run(gateways, SCRIPTS[name], general=True, tracing=True)
    assert traced[:3] == _run(gateways, SCRIPTS[name], general=False)[:3]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 7), st.integers(0, 7), st.sampled_from([b"a", b"b", b"c"]), st.booleans(),
                          st.booleans()), max_size=30), st.booleans())
def test_take_with_the_requests_counter_equals_sent_then_take(steps: list[tuple[int, int, bytes, bool, bool]],
                                                              strict: bool) -> None:
    """ReplyFilter.take(raw, counter, sent) (the quick upload's one call) leaves the filter as sent() then take()
    leave it and answers the same, through any sequence of requests, replies and silences."""
    from akdctl.channels.reply_filter import ReplyFilter

    one, two = ReplyFilter(strict), ReplyFilter(strict)
    for sent, got, content, silence, more in steps:
        raw = content + bytes([got])
        if silence:
            one.sent(sent)
            two.sent(sent)
            one.unanswered()
            two.unanswered()
            continue
        two.sent(sent)
        assert one.take(raw, got, sent) == two.take(raw, got)
        if more:  # a second reply to the same request: take without the counter, on both
            assert one.take(raw, got) == two.take(raw, got)
        assert (list(one._recent), one._sent, one._streak, one._foreign) == \
            (list(two._recent), two._sent, two._streak, two._foreign)
