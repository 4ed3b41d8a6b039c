"""The simulated AKD against the EtherCAT manual ``001`` (edition H; issue 16 items 7-11).

Each test quotes the statement it checks; rulings of our own are docs/fidelity.md F1..; SPEC-NOTES numbers are
named where a test relies on one. The CLI runs in process (``akd_inproc``), the simulator over its real codecs.
"""

from __future__ import annotations

import json

from akdctl.profiles import statusword as sw


def _json(akd_inproc, *args: str) -> dict:
    code, out, err = akd_inproc("--json", *args)
    assert code == 0, (args, code, err)
    return json.loads(out)


# ---------------------------------------------------------------------------------------------------- item 7
def test_supported_drive_modes_lists_the_manuals_modes(akd_inproc) -> None:
    """``001`` 5.8 "Supported Operation Modes": profile velocity "0x6060Sub0 Data: 3", interpolated position "7",
    homing "6", profile position "1", torque "4", cyclic synchronous position "8" (SPEC-NOTES 20). CiA 402 0x6502
    "supported drive modes" has bit n-1 for mode n: 1, 3, 4, 6, 7, 8 -> bits 0, 2, 3, 5, 6, 7 = 0xED."""
    data = _json(akd_inproc, "sdo", "read", "0x6502")
    assert data["value"] == 0xED
    assert sw.drive_modes_of_word(data["value"]) == [1, 3, 4, 6, 7, 8]
    for mode in sw.drive_modes_of_word(data["value"]):                # every listed mode is accepted by 0x6060
        assert akd_inproc("--yes", "sdo", "write", "0x6060", "i8", str(mode))[0] == 0
    assert akd_inproc("--yes", "sdo", "write", "0x6060", "i8", "2")[0] == 1   # velocity (vl) is not listed: refused


# ---------------------------------------------------------------------------------------------------- item 9
def test_fbus_param04_defaults_to_1_on_the_ethercat_drive(akd_inproc) -> None:
    """``001`` 5.14: "FBUS.PARAM04: This parameter enables (1) or disables(0) the synchronization supervision ...
    Default values for this parameter are as follows: CANopen drive: disabled (0) EtherCAT drive: enabled (1)".
    The ESI (0x36E8 default 0) is overridden: the simulated AKD is an EtherCAT drive."""
    assert _json(akd_inproc, "sdo", "read", "0x36E8")["value"] == 1


# ---------------------------------------------------------------------------------------------------- item 10
def test_one_identity_over_coe_and_sii(akd_inproc) -> None:
    """``001`` 5.15: "AKD has a built-in emulated EEPROM. This EEPROM can be read by the EtherCAT master to get some
    information about drive properties"; the identity it holds (vendor, product code, revision, serial) is the one
    0x1018 reports. docs/fidelity.md F3: the real AKD's SII dump (``reference/akd_sii_eeprom_dump``) says revision
    0x00000002, so CoE 0x1018:3 says 0x00000002 too."""
    from akdctl.protocol.sii import akd_sii_image, parse_sii
    from akdctl.sim.esc import Esc

    values = [_json(akd_inproc, "sdo", "read", f"0x1018:{sub}")["value"] for sub in (1, 2, 3, 4)]
    image = akd_sii_image()
    assert values == [image.vendor_id, image.product_code, image.revision, image.serial]
    assert values[2] == 0x00000002
    eeprom = parse_sii(bytes(Esc(image).eeprom))                   # the bytes the simulated ESC serves
    assert (eeprom.vendor_id, eeprom.product_code, eeprom.revision, eeprom.serial) == tuple(values)
