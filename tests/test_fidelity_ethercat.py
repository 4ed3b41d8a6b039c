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


# ---------------------------------------------------------------------------------------------------- item 8
def test_cycle_time_grid_and_minimum_are_the_drives_refusals(akd_inproc) -> None:
    """``001`` 5.9: "The FBUS.SAMPLEPERIOD parameter is counted in multiples of 62.5us microseconds within the
    device"; 5.10: "Position ≥ 0.25 ms (≥ 250 μs) / Velocity ≥ 0.25 ms / Torque ≥ 0.25 ms" (SPEC-NOTES 20).
    docs/fidelity.md F5: the simulated drive aborts a 0x60C2 write off the 62.5 µs grid with 0x06090030 and one
    below 250 µs with 0x06090032, also when akdctl's own check is skipped with --force."""
    code, _, err = akd_inproc("--yes", "pdo", "map", "--cycle-time", "300us")
    assert code == 2 and "not a multiple of 62.5 us" in err                 # akdctl's check, nothing written
    code, _, err = akd_inproc("--yes", "pdo", "map", "--cycle-time", "300us", "--force")
    assert code == 1 and "0x06090030" in err                                 # the drive's own refusal
    code, _, err = akd_inproc("--yes", "pdo", "map", "--cycle-time", "125us", "--force")
    assert code == 1 and "0x06090032" in err
    assert _json(akd_inproc, "sdo", "read", "0x60C2:2")["value"] == -3       # the refused exponent was not stored
    assert akd_inproc("--yes", "pdo", "map", "--cycle-time", "250us")[0] == 0
    assert akd_inproc("--yes", "pdo", "map", "--cycle-time", "2ms")[0] == 0  # the ESI's InitCmd value (2, -3)


def test_cycle_time_rule_in_the_simulators_bytes() -> None:
    """The same rule at the SDO server: expedited downloads of 0x60C2:02 answered with the abort frames."""
    from akdctl.protocol import coe
    from akdctl.sim.model import DriveModel
    from akdctl.sim.sdo_server import SdoServer

    server = SdoServer(DriveModel())

    def download(sub: int, value: int) -> object:
        request = coe.SdoDownloadInitiate(0x60C2, sub, value.to_bytes(1, "little", signed=True), 1, True)
        return _sdo_answer(server, request)

    assert isinstance(download(1, 3), coe.SdoDownloadResponse)               # 3 ms: on the grid
    assert download(2, -4) == coe.SdoAbort(0x60C2, 2, 0x06090030)            # 300 µs: off the 62.5 µs grid
    assert isinstance(download(1, 25), coe.SdoDownloadResponse)
    assert isinstance(download(2, -5), coe.SdoDownloadResponse)              # 250 µs: the minimum
    assert download(1, 12) == coe.SdoAbort(0x60C2, 1, 0x06090032)            # 120 µs: below 250 µs


def _sdo_answer(server: object, request: object) -> object:
    from akdctl.protocol import coe
    from akdctl.protocol import mailbox as mbx

    data = coe.encode_coe(coe.CoeService.SDO_REQUEST, coe.encode_sdo(request))
    replies = server.handle(mbx.encode_mailbox(mbx.Mailbox(mbx.MailboxType.COE, data, counter=1)))
    _, _, payload = coe.decode_coe(mbx.decode_mailbox(replies[-1]).data)
    return coe.decode_sdo(payload, from_server=True)


def test_cycle_time_rule_and_write_order() -> None:
    """profiles/units.py holds the one rule (simulator and ``pdo map`` both use it) and the write order that keeps
    every intermediate pair valid (docs/fidelity.md F5)."""
    from akdctl.profiles import units

    assert units.cycle_time_problem(2, -3) is None and units.cycle_time_problem(5, -4) is None   # 2 ms, 500 µs
    assert units.cycle_time_problem(4, -4) == units.CYCLE_OFF_GRID                               # 400 µs: 6.4 ticks
    assert units.cycle_time_problem(200, -6) == units.CYCLE_TOO_SHORT                            # 200 µs
    assert units.cycle_time_problem(0, -3) == units.CYCLE_TOO_SHORT
    assert units.cycle_time_write_order((2, -3), (25, -5)) == (1, 2)    # the manual's order from the ESI default
    assert units.cycle_time_write_order((25, -5), (2, -3)) == (2, 1)    # 20 µs in between would be refused


# ---------------------------------------------------------------------------------------------------- item 11
def _foe(link, frame):
    """One FoE frame to the simulated drive's mailbox; the decoded FoE reply, or None."""
    from akdctl.protocol import foe
    from akdctl.protocol import mailbox as mbx

    link.send(mbx.encode_mailbox(mbx.Mailbox(mbx.MailboxType.FOE, foe.encode_foe(frame), counter=2)))
    raw = link.receive(0.1)
    if raw is None:
        return None
    reply = mbx.decode_mailbox(raw)
    assert reply.type == mbx.MailboxType.FOE and reply.counter == 2
    return foe.decode_foe(reply.data)


def test_foe_write_and_read_back() -> None:
    """``001`` 4.6.3: "Downloading a new firmware in the drive must be performed using File over EtherCAT (FoE)";
    the real AKD's SII advertises FoE (mailbox protocols 0x0E = EoE | CoE | FoE, ``reference/akd_sii_eeprom_dump``).
    docs/fidelity.md F10: the simulated drive implements FoE read and write (ETG.1000.6) and keeps the file."""
    from akdctl.protocol import foe
    from akdctl.protocol.sii import akd_sii_image
    from akdctl.sim.drive import SimDrive
    from akdctl.transport.sim import SimMailboxLink

    assert akd_sii_image().mailbox_protocols & 0x08                      # FoE is advertised ...
    link = SimMailboxLink(SimDrive("foe"))
    size = link.mailbox_size - 6 - 6                                      # data per packet
    image = bytes(range(256)) * 5                                         # 1280 bytes: 3 packets of 502 at most
    assert _foe(link, foe.write_request("akd_fw.i00")) == foe.ack(0)      # ... and answered
    packets = [image[i:i + size] for i in range(0, len(image), size)]
    for number, chunk in enumerate(packets, start=1):
        assert _foe(link, foe.data_packet(number, chunk)) == foe.ack(number)
    link = SimMailboxLink(SimDrive("foe"))                                # a later session: the file persists
    received = b""
    reply = _foe(link, foe.read_request("akd_fw.i00"))
    while reply is not None:
        assert reply.opcode == foe.FoeOpcode.DATA
        received += reply.data
        reply = _foe(link, foe.ack(reply.value))
    assert received == image


def test_foe_refusals_are_foe_errors() -> None:
    """ETG.1000.6 FoE error codes: an unknown file is 0x8001 "Not found", a packet out of order 0x8005."""
    from akdctl.catalog.texts import foe_error_text
    from akdctl.protocol import foe
    from akdctl.sim.drive import SimDrive
    from akdctl.transport.sim import SimMailboxLink

    link = SimMailboxLink(SimDrive("foe-err"))
    reply = _foe(link, foe.read_request("missing.bin"))
    assert reply.opcode == foe.FoeOpcode.ERROR and reply.value == foe.ERR_NOT_FOUND
    assert foe_error_text(reply.value) == "Not found"
    assert _foe(link, foe.write_request("x.bin")) == foe.ack(0)
    reply = _foe(link, foe.data_packet(2, b"late"))
    assert reply.opcode == foe.FoeOpcode.ERROR and reply.value == foe.ERR_PACKET_NUMBER
    reply = _foe(link, foe.data_packet(1, b"no transfer any more"))
    assert reply.opcode == foe.FoeOpcode.ERROR and reply.value == foe.ERR_ILLEGAL
