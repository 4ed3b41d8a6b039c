"""The CIP attribute channel: Get/Set_Attribute_Single by class/instance/attribute, and the
Identity object read on top of it.

Why a channel: the EtherNet/IP transport only carries explicit messages (its session is a
:class:`~akdctl.links.MessageLink`); turning a CIP reply's general status into an error in words
and attribute bytes into identity values is protocol meaning, written once here and built by
:class:`akdctl.connection.Connection` over the link (as the PROFIdrive and SDO channels are).
"""

from __future__ import annotations

import struct

from akdctl.errors import CipRefused, MalformedReply
from akdctl.links import MessageLink
from akdctl.protocol import cip
from akdctl.protocol.errors import CodecError


class CipAttributes:
    """The attribute channel: Get/Set_Attribute_Single and what is built on them."""

    def __init__(self, link: MessageLink, label: str) -> None:
        self.link = link
        self.label = label

    def call(self, service: int, path: cip.Path, data: bytes = b"") -> bytes:
        request = cip.Request(service, path.encode(), data)
        response = self.link.request(request)
        if response.status:
            raise self._refused(request, response, path)
        return response.data

    def get(self, class_id: int, instance: int, attribute: int) -> bytes:
        request = cip.get_attribute_single(class_id, instance, attribute)
        response = self.link.request(request)
        if response.status:
            raise self._refused(request, response)
        return response.data

    def _refused(self, request: cip.Request, response: cip.Response, path: cip.Path | None = None) -> CipRefused:
        """The error for a reply with a general status; its words are looked up only when one comes."""
        from akdctl.catalog.texts import cip_status_text

        label = (path or cip.decode_path(request.path)).label
        return CipRefused(f"{self.label}: {request.name} {label} refused: "
                          f"{cip_status_text(response.status, response.extended)}", code=response.status,
                          details={"general_status": response.status, "extended_status": list(response.extended)})

    def set(self, class_id: int, instance: int, attribute: int, data: bytes) -> None:
        """Set_Attribute_Single. A set whose answer never came is an unknown outcome, not "no answer": the
        drive may have applied it (issue 23.22); akdctl does not send it twice and names the read to check."""
        from akdctl.errors import NoAnswer, UnknownOutcome

        try:
            self.call(cip.SET_ATTRIBUTE_SINGLE, cip.Path(class_id, instance, attribute), data)
        except NoAnswer as exc:
            error = UnknownOutcome(
                f"{exc.message}: unknown outcome, the drive may or may not have applied the set; akdctl does not "
                f"send it twice: check with 'akdctl cip get 0x{class_id:02X}/{instance}/{attribute}' before "
                "repeating", code=exc.code, details={**exc.details, "written": data.hex()})
            error.unanswered = True  # type: ignore[attr-defined]  # how links.Budget counts it
            raise error from None

    def identity(self) -> cip.IdentityAttributes:
        """Identity attributes 1-7 by Get_Attribute_Single (the AKD manual names only 0x0E/0x10 [V])."""
        raw = {n: self.get(cip.IDENTITY, 1, n) for n in range(1, 8)}
        try:
            vendor, dtype, code = (struct.unpack("<H", raw[n])[0] for n in (1, 2, 3))
            if len(raw[4]) != 2:
                raise struct.error("revision")
            status = struct.unpack("<H", raw[5])[0]
            serial = struct.unpack("<I", raw[6])[0]
            name = cip.decode_short_string(raw[7])
        except (struct.error, CodecError) as exc:
            raise MalformedReply(f"{self.label}: malformed Identity attribute: {exc}") from None
        return cip.IdentityAttributes(vendor, dtype, code, (raw[4][0], raw[4][1]), status, serial, name)

    def identity_json(self) -> dict[str, object]:
        """Identity object 1/1 attributes 1-7 in JSON-friendly form (for ``akdctl info``)."""
        from akdctl.catalog.texts import cip_vendor_name

        ident = self.identity()
        return {"vendor": ident.vendor, "vendor_name": cip_vendor_name(ident.vendor), "device_type": ident.device_type,
                "product_code": ident.product_code, "revision": f"{ident.revision[0]}.{ident.revision[1]:03d}",
                "status": ident.status, "serial": f"0x{ident.serial:08X}", "product_name": ident.product_name}
