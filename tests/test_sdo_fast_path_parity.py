"""The served simulator's SDO fast paths (issue 29) answer what the general paths answer, byte for byte.

* ``DriveModel.object_read`` takes what the catalogue says of an address from a plan made once per
  (index, subindex) (``model._READ_PLANS``): for every catalogued address it must equal the rule spelled out
  (``object_entry``, the write-only check, the stored value or ``_default_bytes``), and a plan must never serve a
  value the model no longer holds;
* ``SdoServer.handle`` answers a plain upload initiate without message objects: for every kind of answer
  (expedited, normal, segmented and its segments, every abort) it must equal the general decoder/encoder path
  (``_sdo`` -> ``encode_sdo``);
* the gateway face answers a datagram with what the drive answers, wrapped (``mailbox.wrap_gateway``).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akdctl.catalog import objects as object_catalog
from akdctl.channels.coe_sdo import CoeObjectChannel
from akdctl.errors import AkdError
from akdctl.links import MailboxLink
from akdctl.protocol import coe
from akdctl.protocol import mailbox as mbx
from akdctl.protocol.coe import CoeService
from akdctl.sim import model as model_module
from akdctl.sim.drive import factory_model
from akdctl.sim.errors import SdoAccessError
from akdctl.sim.sdo_server import SdoServer, _Request


def _general_read(model: model_module.DriveModel, index: int, subindex: int) -> bytes | int:
    """object_read's rule for an address no component binds, spelled out with the general helpers."""
    try:
        entry = model.object_entry(index, subindex)
    except SdoAccessError as exc:
        return exc.code
    if entry.access == "wo":
        return model_module.ABORT_WRITE_ONLY
    data = model.object_values.get((index, subindex))
    return model_module._default_bytes(entry) if data is None else data


def _read(model: model_module.DriveModel, index: int, subindex: int) -> bytes | int:
    try:
        return model.object_read(index, subindex)
    except SdoAccessError as exc:
        return exc.code


def _unbound(model: model_module.DriveModel, index: int) -> bool:
    return index not in model._object_bindings and index not in model_module.LAZY_OBJECTS \
        and index not in model._object_builders


def test_every_catalogued_read_plan_equals_the_general_rule() -> None:
    model_module._READ_PLANS.clear()
    model = factory_model("parity")
    keys = [k for k in object_catalog.entries() if _unbound(model, k[0])]
    assert len(keys) > 500
    for _round in range(2):  # the first round makes the plans, the second reads them
        for index, subindex in keys:
            assert _read(model, index, subindex) == _general_read(model, index, subindex), (hex(index), subindex)
    assert model_module._READ_PLANS  # the plans were made and used


@pytest.mark.parametrize(("index", "subindex"), [(0x1018, 9), (0x7FFF, 0), (0x1018, 0xFF), (0x0000, 0)])
def test_addresses_outside_the_catalogue_abort_as_before_and_leave_no_plan(index: int, subindex: int) -> None:
    model = factory_model("parity")
    for _ in range(2):
        assert _read(model, index, subindex) == _general_read(model, index, subindex)
    assert (index, subindex) not in model_module._READ_PLANS


def test_a_plan_never_serves_a_stale_value() -> None:
    model = factory_model("parity")
    default = model.object_read(0x6081, 0)  # profile velocity: stored, rw
    model.object_write(0x6081, 0, (1234).to_bytes(4, "little"))
    assert model.object_read(0x6081, 0) == (1234).to_bytes(4, "little") != default
    other = factory_model("other")  # another model: its own values, the same plan
    assert other.object_read(0x6081, 0) == default
    assert model.object_read(0x1018, 4) != other.object_read(0x1018, 4)  # each drive's own serial, stored


def test_a_binding_made_after_the_plan_wins() -> None:
    model = factory_model("parity")
    assert model.object_read(0x6081, 0) == _general_read(model, 0x6081, 0)
    model.bind_object(0x6081, read=lambda sub: b"\x01\x02\x03\x04")
    assert model.object_read(0x6081, 0) == b"\x01\x02\x03\x04"


def test_a_lazily_bound_object_is_read_through_its_component() -> None:
    model = factory_model("parity")
    assert "faults" not in model._built
    model.object_read(0x1001, 0)  # the error register: the fault component binds it
    assert "faults" in model._built and 0x1001 in model._object_bindings


# --- the SDO server: fast path against the general path ---------------------------------------------------------


def _upload_mailbox(index: int, subindex: int, counter: int = 3, address: int = 1001) -> bytes:
    return mbx.pack(mbx.MailboxType.COE, coe.upload_request(index, subindex), address, counter)


def _general_answer(server: SdoServer, mailbox: bytes) -> list[bytes]:
    """What the message path answers: decode_sdo -> _sdo -> encode_sdo, behind the request's header."""
    _mtype, counter, address, data = mbx.split(mailbox)
    answer = server._sdo(data[coe.COE_HEADER_SIZE:])
    assert answer is not None
    service = CoeService.SDO_REQUEST if isinstance(answer, coe.SdoAbort) else CoeService.SDO_RESPONSE
    return [server._reply(_Request(address, counter), service, coe.encode_sdo(answer))]


def _model() -> model_module.DriveModel:
    model = factory_model("parity")
    model.object_write(0x2032, 0, b"x" * 1500)  # DRV.CUSTOMIDENTIFIER: longer than one mailbox (segmented)
    model.set_stored_object(0x2033, 0, b"AKD-x")  # DRV.MODEL (read-only): a string of 5 bytes (normal upload)
    return model


def _pair() -> tuple[SdoServer, SdoServer]:
    """Two servers over two drives in the same state: one answers by its fast path, one by the general path."""
    return SdoServer(_model()), SdoServer(_model())


ADDRESSES = [
    (0x1018, 1), (0x1018, 4), (0x1018, 0), (0x1000, 0), (0x6041, 0), (0x6081, 0), (0x2033, 0), (0x1008, 0),
    (0x2032, 0), (0x1001, 0), (0x1018, 9), (0x7FFF, 0), (0x0002, 0), (0x1026, 1),
]


@pytest.mark.parametrize(("index", "subindex"), ADDRESSES)
def test_the_upload_fast_path_equals_the_general_path(index: int, subindex: int) -> None:
    fast, general = _pair()
    for counter in (1, 5, 7):
        request = _upload_mailbox(index, subindex, counter)
        assert fast.handle(request) == _general_answer(general, request), (hex(index), subindex)


def test_a_segmented_upload_continues_alike_after_either_path() -> None:
    fast, general = _pair()
    request = _upload_mailbox(0x2032, 0)
    assert fast.handle(request) == _general_answer(general, request)
    toggle = segments = 0
    while fast._upload is not None:
        segments += 1
        segment = mbx.pack(mbx.MailboxType.COE, coe.encode_coe(CoeService.SDO_REQUEST,
                                                              coe.encode_sdo(coe.SdoUploadSegment(toggle))), 1001, 4)
        assert fast.handle(segment) == _general_answer(general, segment)
        toggle ^= 1
    assert general._upload is None and segments == 2  # the transfer ended on both after the same segments


def test_an_upload_initiate_ends_a_transfer_in_progress_on_both_paths() -> None:
    fast, general = _pair()
    first = _upload_mailbox(0x2032, 0)
    fast.handle(first)
    _general_answer(general, first)
    again = _upload_mailbox(0x1018, 1)
    assert fast.handle(again) == _general_answer(general, again)
    assert fast._upload is None and general._upload is None


def test_a_model_failure_becomes_the_same_abort_on_both_paths() -> None:
    class Broken:
        def object_read(self, index: int, subindex: int) -> bytes:
            raise RuntimeError("model bug")

        def object_write(self, index: int, subindex: int, data: bytes) -> None:
            raise RuntimeError("model bug")

    fast, general = SdoServer(Broken()), SdoServer(Broken())
    request = _upload_mailbox(0x1018, 1)
    assert fast.handle(request) == _general_answer(general, request)
    assert coe.decode_sdo(fast.handle(request)[0][8:], from_server=True) == coe.SdoAbort(0x1018, 1, coe.ABORT_GENERAL)


def test_a_bytearray_from_a_reader_is_answered_as_bytes() -> None:
    class Reader:
        def __init__(self, value: bytes) -> None:
            self.value = value

        def object_read(self, index: int, subindex: int) -> bytearray:
            return bytearray(self.value)

        def object_write(self, index: int, subindex: int, data: bytes) -> None:
            pass

    for value in (b"\x01", b"\x01\x02\x03\x04", b"12345678", b""):
        fast, general = SdoServer(Reader(value)), SdoServer(Reader(value))  # type: ignore[arg-type]
        request = _upload_mailbox(0x1018, 1)
        assert fast.handle(request) == _general_answer(general, request)


# --- the client: CoeObjectChannel.upload's one pass against its general path ------------------------------------

@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=0, max_size=24), st.integers(0, 0xFFFF), st.integers(0, 0xFF))
def test_the_clients_reply_reader_equals_the_general_decoders(tail: bytes, index: int, subindex: int) -> None:
    """coe.expedited_upload_reply reads what mailbox.split + the CoE header + decode_sdo read, or declines."""
    for mailbox in (tail, _answer(index, subindex, tail[:4] or b"\x01", 5) + tail[4:], _mutated(tail, index, subindex)):
        fast = coe.expedited_upload_reply(mailbox, index, subindex)
        if fast is None:
            continue
        _mtype, counter, _address, data = mbx.split(mailbox)
        assert _mtype == mbx.MailboxType.COE and data[1] >> 4 == CoeService.SDO_RESPONSE
        msg = coe.decode_sdo(data[2:], from_server=True)
        assert isinstance(msg, coe.SdoUploadResponse) and (msg.index, msg.subindex) == (index, subindex)
        assert msg.expedited and fast == (counter, msg.data)


def _answer(index: int, subindex: int, value: bytes, counter: int) -> bytes:
    return coe.pack_expedited_upload_mailbox(1001, counter, index, subindex, value)


def _mutated(tail: bytes, index: int, subindex: int) -> bytes:
    """An expedited answer with some of its bytes replaced by ``tail``'s (command, type, length, service ...)."""
    answer = bytearray(_answer(index, subindex, b"\x01\x02", 3))
    for position, byte in zip(tail[0::2], tail[1::2]):
        answer[position % len(answer)] = byte
    return bytes(answer)


class ScriptedLink(MailboxLink):
    """Answers each request with the replies a script makes of it (counter echoed or not, extra mailboxes)."""

    mailbox_size = 512
    mailbox_address = 1001

    def __init__(self, script: Callable[[bytes, int], list[bytes]]) -> None:
        self.script = script
        self.inbox: deque[bytes] = deque()
        self.sent: list[bytes] = []

    def send(self, mailbox: bytes) -> None:
        self.sent.append(mailbox)
        self.inbox.extend(self.script(mailbox, len(self.sent)))

    def receive(self, timeout: float) -> bytes | None:
        return self.inbox.popleft() if self.inbox else None


def _server_script(server: SdoServer, extra: Callable[[list[bytes], bytes, int], list[bytes]]
                   ) -> Callable[[bytes, int], list[bytes]]:
    def script(mailbox: bytes, n: int) -> list[bytes]:
        return extra(server.handle(mailbox), mailbox, n)
    return script


SCRIPTS = {
    "as served": lambda replies, request, n: replies,
    "counter rewritten": lambda replies, request, n: [r[:5] + bytes([(r[5] & 0x8F) | ((n % 7 + 1) << 4)]) + r[6:]
                                                       for r in replies],
    "counter zero": lambda replies, request, n: [r[:5] + bytes([r[5] & 0x0F]) + r[6:] for r in replies],
    "emergency first": lambda replies, request, n: [coe.pack_expedited_upload_mailbox(0, 0, 0, 0, b"\x00")[:6]
                                                    + b"\x00\x10" + bytes(8), *replies],
    "duplicated": lambda replies, request, n: replies * 2,
    "service 2": lambda replies, request, n: [r[:7] + bytes([(r[7] & 0x0F) | 0x20]) + r[8:] for r in replies],
    "lost every second": lambda replies, request, n: replies if n % 2 else [],
    "silent": lambda replies, request, n: [],
}


def _outcome(channel: CoeObjectChannel, index: int, subindex: int, general: bool) -> object:
    try:
        if general:  # the same request inside an enclosing one: Budget.lone declines, the general path runs
            with channel.budget.request():
                return channel.upload(index, subindex)
        return channel.upload(index, subindex)
    except AkdError as exc:
        return type(exc), str(exc)


@pytest.mark.parametrize("name", sorted(SCRIPTS))
def test_the_clients_one_pass_upload_equals_its_general_path(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Values, errors, the requests sent and the counter rules' state after each upload: the same on both paths."""
    read = coe.expedited_upload_reply
    taken: list[bool] = []
    monkeypatch.setattr(coe, "expedited_upload_reply", lambda *a: taken.append(read(*a) is not None) or read(*a))
    runs = []
    for general in (False, True):
        server = SdoServer(_model())
        link = ScriptedLink(_server_script(server, SCRIPTS[name]))
        channel = CoeObjectChannel(link, timeout=0.05, retries=1)
        outcomes = []
        for index, subindex in [*ADDRESSES, *ADDRESSES[:5]]:
            outcomes.append((_outcome(channel, index, subindex, general), channel._proven, channel.filter.echoes,
                             channel._stale))
        runs.append((outcomes, link.sent, [e.error_code for e in channel.take_emergencies()]))
        if not general and name in ("as served", "counter zero", "counter rewritten"):
            assert taken.count(True) >= 4  # the one pass answered these uploads
    assert runs[0] == runs[1]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 7), st.integers(0, 7), st.sampled_from([b"a", b"b", b"c"]), st.booleans()),
                max_size=30), st.booleans())
def test_the_reply_filters_take_equals_admit_mine_accepted(steps: list[tuple[int, int, bytes, bool]],
                                                          strict: bool) -> None:
    """ReplyFilter.take (the one-pass upload's one call) leaves the filter as admit/mine/accepted leave it and
    answers what they answer, through any sequence of requests, replies and silences."""
    from akdctl.channels.reply_filter import ReplyFilter

    one, three = ReplyFilter(strict), ReplyFilter(strict)
    for sent, got, content, silence in steps:
        raw = content + bytes([got])
        one.sent(sent)
        three.sent(sent)
        if silence:
            one.unanswered()
            three.unanswered()
            continue
        taken = one.take(raw, got)
        expected = three.mine(got) if three.admit(raw, got) else None
        if expected is not None:
            three.accepted(raw, got)
        assert taken == expected
        assert (list(one._recent), one._sent, one._streak, one._foreign) == \
            (list(three._recent), three._sent, three._streak, three._foreign)


class _FailingLink(ScriptedLink):
    def receive(self, timeout: float) -> bytes | None:
        from akdctl.errors import NoAnswer

        raise NoAnswer("the link gave up")


def test_a_link_failure_in_the_one_pass_is_counted_as_in_the_general_path() -> None:
    """The Budget's count of unanswered time is the same whichever path met the link's failure."""
    silent = []
    for general in (False, True):
        channel = CoeObjectChannel(_FailingLink(lambda mailbox, n: []), timeout=0.05, retries=1)
        outcome = _outcome(channel, 0x1018, 1, general)
        silent.append((outcome, channel.budget.silent > 0))
    assert silent[0] == silent[1] and silent[0][1]
