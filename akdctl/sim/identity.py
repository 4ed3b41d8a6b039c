"""The simulated AKD's one identity record: every face derives what it reports from it.

Why one record: the simulated drive used to report three serial numbers, firmware versions and models
depending on the face asked (issue 23.8: PROFINET I&M0 / PNU 964, CoE 0x1018/0x100A and the SII, the CIP
Identity object), which a real drive never does. The values come from the one real AKD the project has data
of, its SII EEPROM dump (reference/akd_sii_eeprom_dump.decoded.txt): order code, firmware string and serial
number. How each protocol spells them is the face's business (``face_profinet.im0``, ``model.sim_object_defaults``,
``cip_device.IdentitySettings``, ``face_ethercat_raw``'s SII image); the facts are here, once.
"""

from __future__ import annotations

#: The order code (model) the real drive's SII carries in its category 0x0800.
ORDER_CODE = "AKD-P00606-NBCC-E000"
#: The firmware version the SII carries in its category 0x0801 (CoE 0x100A spells it "M_" + this).
FIRMWARE = "01-20-00-003"
#: The serial number (SII word 0x0E, CoE 0x1018:4).
SERIAL = 2575499411
#: The hardware revision letter (the order code's "E000"; CoE 0x1009).
HARDWARE_REVISION = "E"
#: CoE 0x1018:3 and the SII's revision number (the real dump's, not the newest ESI revision 0x00260000).
COE_REVISION = 0x00000002


def firmware_numbers() -> tuple[int, int, int, int]:
    """The firmware version as numbers: "01-20-00-003" -> (1, 20, 0, 3)."""
    major, minor, patch, build = (int(part) for part in FIRMWARE.split("-"))
    return major, minor, patch, build


def hardware_revision_number() -> int:
    """The hardware revision letter as a number for fields that hold one (I&M0): A = 1 ... E = 5 ([I]: the AKD's
    own I&M0 encoding of its revision letter is not in the seeds)."""
    return ord(HARDWARE_REVISION) - ord("A") + 1


def serial_of(drive: object) -> int:
    """The serial number a face reports for ``drive``: its own 0x1018:4 (``SimDrive.serial``; every simulated drive
    but 'default' has its own), the record's for a stand-in without one (a face built on a test double)."""
    reader = getattr(drive, "serial", None)
    return int(reader()) if callable(reader) else SERIAL
