"""Issue 23.8: one simulated drive, one identity, whichever face is asked.

Before, PROFINET's I&M0 said AKD-P00306-NBPN-0000 / SIM0001 / V1.13, CoE said M_01-20-00-001 / 2575499411, the CIP
Identity object AKD-P00306-NBEI-0000 / 0x00AD0001 / 1.18. Every face now derives from ``sim/identity.py``: the test
serves the drive on PROFINET, the ETG.8200 gateway and EtherNet/IP and asks each face through ``akdctl info``, and
checks the raw slave's SII image (its face needs a raw interface) and PNU 964.
"""

from __future__ import annotations

import json

import pytest

from akdctl.sim import identity
from tests.harness import SimServer


@pytest.mark.slow
def test_every_face_reports_the_one_identity(akd) -> None:
    with SimServer("--profinet", "127.0.0.1:0", "--ethercat-udp", "127.0.0.1:0", "--ethernetip", "127.0.0.1:0",
                   "--eip-io-port", "0", faces=3) as server:
        targets = {
            "profinet": "pn://{}:{}".format(*server.address_of("profinet")),
            "ethercat": "ecat-udp://{}:{}/1001".format(*server.address_of("ethercat-udp")),
            # "ethernetip HOST:PORT (class-1 I/O on udp ...)": the TCP address is the line's second word
            "ethernetip": "eip://" + next(line.split()[1] for line in server.ready if line.startswith("ethernetip")),
        }
        seen = {}
        for face, target in targets.items():
            result = akd("-T", target, "--json", "info", timeout=60)
            assert result.returncode == 0, (face, result.stderr)
            seen[face] = json.loads(result.stdout)
    summaries = {face: (d["summary"]["model"], d["summary"]["serial"], d["summary"]["firmware"])
                 for face, d in seen.items()}
    assert set(summaries.values()) == {(identity.ORDER_CODE, str(identity.SERIAL), "1.20")}, summaries
    # each protocol's own spelling of the same facts
    assert seen["profinet"]["im0"]["order_id"] == identity.ORDER_CODE
    assert seen["profinet"]["im0"]["software_revision"] == "V1.20.0"
    assert seen["profinet"]["profidrive"]["drive_unit"]["software_version"] == "1.20"  # PNU 964[2]
    assert seen["ethercat"]["canopen"]["software_version"] == f"M_{identity.FIRMWARE}"
    assert seen["ethercat"]["canopen"]["serial"] == identity.SERIAL
    assert seen["ethercat"]["canopen"]["hardware_version"] == identity.HARDWARE_REVISION
    assert seen["ethernetip"]["cip_identity"]["serial"] == f"0x{identity.SERIAL:08X}"
    assert seen["ethernetip"]["cip_identity"]["product_name"] == identity.ORDER_CODE


def test_the_raw_slaves_sii_carries_the_same_identity() -> None:
    from akdctl.protocol.sii import build_sii, parse_sii
    from akdctl.sim.face_ethercat_raw import sim_sii_image

    decoded = parse_sii(build_sii(sim_sii_image()))  # the bytes the slave's EEPROM serves, read back
    assert decoded.serial == identity.SERIAL and decoded.revision == identity.COE_REVISION
    categories = dict(decoded.categories)
    assert categories[0x0800].rstrip(b"\0").decode() == identity.ORDER_CODE
    assert categories[0x0801].rstrip(b"\0").decode() == identity.FIRMWARE


def test_the_preset_keys_are_the_defaults_keys() -> None:
    from akdctl.sim import model

    assert model._PRESET_KEYS == set(model.sim_object_defaults())


@pytest.mark.slow
def test_a_named_drive_reports_its_own_serial_on_every_face(akd) -> None:
    """A simulated drive other than 'default' has its own serial (0x1018:4, ``serial_for``); PROFINET's I&M0 and the
    CIP Identity object report that one too, not the record's."""
    from akdctl.sim.drive import serial_for

    with SimServer("--name", "axis2", "--profinet", "127.0.0.1:0", "--ethernetip", "127.0.0.1:0",
                   "--eip-io-port", "0", faces=2) as server:
        pn = "pn://{}:{}".format(*server.address_of("profinet"))
        eip = "eip://" + next(line.split()[1] for line in server.ready if line.startswith("ethernetip"))
        serials = {json.loads(akd("-T", t, "--json", "info", timeout=60).stdout)["summary"]["serial"] for t in (pn, eip)}
    assert serials == {str(serial_for("axis2"))} and serial_for("axis2") != identity.SERIAL
