"""An SDO upload through an ETG.8200 mailbox gateway as whole datagrams: the request pre-encoded per object and
counter, the usual (expedited) answer checked in one unpack. The ``ecat-udp://`` client's poll (issue 29, row
client-cpu).

Why a codec of its own: a poll of one object sends the same 18-byte datagram every time but for the mailbox counter
(1..7), and its usual answer differs from one pattern only in the counter, the value and bits a client does not
check. Packing the request layer by layer (CoE request, mailbox header, gateway header) and reading the answer layer
by layer (gateway header, mailbox header, CoE and SDO headers) was most of the client's own CPU per upload. Nothing
here is a new layout: the datagrams are made by the layer codecs (:func:`coe.upload_request`, :func:`mailbox.pack`,
:func:`mailbox.wrap_gateway`), the answer's pattern by :func:`coe.expedited_upload_pattern` behind the gateway header
:func:`mailbox.wrap_gateway` writes. :meth:`UploadFrames.answer` takes exactly what ``mailbox.unwrap_gateway``, the
gateway link's station rule and :func:`coe.expedited_upload_reply` take together -- except an answer sent from
address 0 or with bytes after the mailbox, which it leaves to the general path -- and declines everything else
(tests/test_gateway_sdo_parity.py holds both equal).
"""

from __future__ import annotations

import struct

from akdctl.protocol import coe, mailbox

#: The first 16 bytes of a datagram as two little-endian words, so that one unpack and two masked compares check
#: every header field at once (a view of the bytes, not a layout: the fields' places are the codecs').
_WORDS = struct.Struct("<QQ")
#: The gateway header's bits ``unwrap_gateway`` reads: type (bits 12-15) and the 11-bit length (bit 11 is not read).
_GATEWAY_MASK = 0xF7FF
_GATEWAY_HEADER_SIZE = mailbox.GATEWAY_HEADER_SIZE
_unpack = _WORDS.unpack_from


class UploadFrames:
    """The datagrams of an upload initiate of ``index:subindex`` at ``station`` (one per mailbox counter 1..7) and
    the check of its expedited answer. Built once per object by the client; immutable."""

    __slots__ = ("_command", "_end", "_expected", "_expected2", "_first", "_mask", "_mask2", "requests")

    def __init__(self, station: int, index: int, subindex: int) -> None:
        body = coe.upload_request(index, subindex)   # raises CoeError for an index or subindex out of range
        #: ``requests[counter]``: the whole datagram with that mailbox counter (index 0 unused: 0 means "none").
        self.requests: tuple[bytes, ...] = (b"",) + tuple(
            mailbox.wrap_gateway(mailbox.pack(mailbox.MailboxType.COE, body, station, counter))
            for counter in range(1, 8))
        pattern, mask, value_at = coe.expedited_upload_pattern(station, index, subindex)
        mailbox_size = value_at + 4   # the expedited value's four bytes end the mailbox
        gateway = mailbox.wrap_gateway(bytes(mailbox_size))[:mailbox.GATEWAY_HEADER_SIZE]
        gateway_mask = _GATEWAY_MASK.to_bytes(mailbox.GATEWAY_HEADER_SIZE, "little")
        tail = _WORDS.size - len(gateway) - len(pattern)   # the value's first bytes in the second word: not checked
        self._expected, self._expected2 = _WORDS.unpack(gateway + pattern + bytes(tail))
        self._mask, self._mask2 = _WORDS.unpack(gateway_mask + mask + bytes(tail))
        self._first = len(gateway) + value_at        # where the value starts in the datagram
        self._command = self._first - 4              # the SDO command byte: index (2) and subindex (1) follow it
        self._end = self._first + 4                  # the datagram's whole length

    def answer(self, datagram: bytes) -> tuple[int, bytes, bytes] | None:
        """(mailbox counter, value, the mailbox) when ``datagram`` is exactly the expedited answer to this upload;
        None for anything else (another object or station, a normal or segmented answer, an abort, an emergency,
        CoE service 2, a mailbox error, a malformed frame): the general path reads those."""
        end = self._end
        if len(datagram) != end:
            return None
        first, second = _unpack(datagram)
        if first & self._mask != self._expected or second & self._mask2 != self._expected2:
            return None
        command = datagram[self._command]
        return (first >> 60 & 0x07, datagram[self._first:end - (command >> 2 & 0x03) if command & 0x01 else end],
                datagram[_GATEWAY_HEADER_SIZE:])
