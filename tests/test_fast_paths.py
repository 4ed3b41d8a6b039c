"""The simulator's fast paths keep no copy of a wire layout: the codec owns both layouts (issue 22, item 7).

The servers answer the poll's requests (a PNU read, an SDO upload) without message objects; the layouts they pack
are the codec's (``bmp.iter_read_addresses``/``raw_block_layout``/``pack_read_response``,
``coe.pack_expedited_upload_response``), held here equal to the general encoders. The servers' own byte-equality
tests (tests/test_pnu_server.py, tests/test_sdo_server.py) hold the two paths through the servers equal.
"""

from __future__ import annotations

import re
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from akdctl.protocol import bmp, coe

ROOT = Path(__file__).resolve().parent.parent / "akdctl"


def test_the_servers_hold_no_wire_layout() -> None:
    for name in ("sim/pnu_server.py", "sim/sdo_server.py"):
        text = (ROOT / name).read_text(encoding="utf-8")
        assert not re.search(r"struct\.(Struct|pack|unpack)", text), name


@given(st.sampled_from([bmp.Format.BYTE, bmp.Format.WORD, bmp.Format.DWORD]), st.data())
def test_raw_value_blocks_equal_the_general_encoder(fmt: int, data: st.DataObject) -> None:
    count = data.draw(st.integers(1, 20))
    top = (1 << (8 * bmp.format_size(fmt))) - 1
    values = data.draw(st.lists(st.integers(0, top), min_size=count, max_size=count))
    layout = bmp.raw_block_layout(fmt, count)
    assert layout is not None
    assert layout.pack(fmt, count, *values) == bmp.encode_value_block(bmp.ParameterValue(fmt, tuple(values)))


def test_addresses_and_read_response_equal_the_general_codec() -> None:
    addresses = [bmp.ParameterAddress(964, 0, 2), bmp.ParameterAddress(930, 0, 1)]
    request = bmp.encode_request(bmp.ParameterRequest(7, bmp.REQ_READ, 0, tuple(addresses)))
    assert [bmp.ParameterAddress(p, s, c, a) for a, c, p, s in bmp.iter_read_addresses(request, 2)] == addresses
    results = (bmp.ParameterValue(bmp.Format.WORD, (0x100, 1)), bmp.ParameterFailure(0x14, 3))
    blocks = [bmp.encode_value_block(results[0]), bmp.pack_failure_block(0x14, 3)]
    general = bmp.encode_response(bmp.ParameterResponse(7, bmp.RESP_READ_NAK, 0, results))
    assert bmp.pack_read_response(request, blocks, negative=True) == general


@given(st.integers(0, 0xFFFF), st.integers(0, 0xFF), st.binary(min_size=1, max_size=4))
def test_expedited_upload_response_equals_the_general_encoder(index: int, subindex: int, value: bytes) -> None:
    general = coe.encode_sdo(coe.SdoUploadResponse(index, subindex, value, len(value), True))
    assert coe.pack_expedited_upload_response(index, subindex, value) == general
    request = coe.encode_sdo(coe.SdoUploadInitiate(index, subindex))
    assert request[0] == coe.UPLOAD_INITIATE_COMMAND and coe.sdo_address(request) == (index, subindex)


@given(st.integers(0, 0xFFFF), st.integers(0, 7), st.integers(0, 0xFFFF), st.integers(0, 0xFF),
       st.binary(min_size=1, max_size=4))
def test_the_upload_mailbox_in_one_step_equals_the_general_codecs(address: int, counter: int, index: int,
                                                                  subindex: int, value: bytes) -> None:
    """coe.plain_upload_initiate / pack_expedited_upload_mailbox (issue 29) read and write what mailbox.split,
    decode_coe and the expedited encoders do; a request of any other shape is left to the general path."""
    from akdctl.protocol import mailbox as mbx

    assert coe._MAILBOX_TYPE_COE == mbx.MailboxType.COE
    sdo = coe.encode_sdo(coe.SdoUploadInitiate(index, subindex))
    request = mbx.pack(mbx.MailboxType.COE, coe.encode_coe(coe.CoeService.SDO_REQUEST, sdo), address, counter)
    assert coe.plain_upload_initiate(request) == (address, counter, index, subindex)
    mtype, got_counter, got_address, data = mbx.split(request)
    service, _number, payload = coe.decode_coe(data)
    assert (mtype, service, got_counter, got_address) == (mbx.MailboxType.COE, coe.CoeService.SDO_REQUEST, counter,
                                                         address)
    assert coe.sdo_address(payload) == (index, subindex)
    reply = mbx.pack(mbx.MailboxType.COE, coe.coe_header(coe.CoeService.SDO_RESPONSE)
                     + coe.encode_sdo(coe.SdoUploadResponse(index, subindex, value, len(value), True)), address, counter)
    assert coe.pack_expedited_upload_mailbox(address, counter, index, subindex, value) == reply
    for other in (request + b"\0", request[:-1], request[:4] + bytes([request[4] | 1]) + request[5:],
                  request[:5] + bytes([(request[5] & 0xF0) | mbx.MailboxType.FOE]) + request[6:],
                  request[:6] + coe.encode_coe(coe.CoeService.SDO_RESPONSE, sdo),
                  request[:8] + bytes([0x60]) + request[9:]):
        assert coe.plain_upload_initiate(other) is None


@given(st.binary(min_size=80, max_size=120), st.booleans(), st.integers(0, 0xFFFFFFFF),
       st.tuples(st.integers(0, 255), st.integers(0, 255), st.integers(0, 255), st.integers(0, 255)),
       st.binary(max_size=300))
def test_the_record_response_in_one_step_equals_the_general_codecs(data: bytes, little: bool, boot: int,
                                                                   codes: tuple[int, int, int, int],
                                                                   blocks: bytes) -> None:
    """pnio_record.pack_record_response (issue 29) writes what reply_head + pnio.encode_response_args write."""
    from akdctl.protocol import dcerpc, pnio, pnio_record

    for status in (pnio.OK, pnio.PnioStatus(*codes)):
        general = pnio_record.reply_head(data, little, dcerpc.PT_RESPONSE, boot, 20 + len(blocks)) \
            + pnio.encode_response_args(status, blocks, little=little)
        assert pnio_record.pack_record_response(data, little, boot, status, blocks) == general


@given(st.lists(st.tuples(st.sampled_from([0x10, 0x20]), st.integers(1, 20), st.integers(1, 0xFFFF),
                          st.integers(0, 0xFF)), min_size=1, max_size=5))
def test_the_first_read_address_is_what_the_iterator_yields_first(addresses: list[tuple[int, int, int, int]]) -> None:
    request = bmp.encode_request(bmp.ParameterRequest(
        1, bmp.REQ_READ, 0, tuple(bmp.ParameterAddress(p, s, c, a) for a, c, p, s in addresses)))
    assert bmp.first_read_address(request) == next(bmp.iter_read_addresses(request, len(addresses)))
