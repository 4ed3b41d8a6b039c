"""A support bundle names the drive as ``info`` does: who it is in words first, then each identity value with its
hex form and words (``256 (0x100, Kollmorgen)``), on the page and in ``support show``; a status value the drive does
not report (homed, outside position mode) says so instead of an empty cell."""

from __future__ import annotations

from akdctl.drive import bundle_report

DATA = {
    "identity": {"profidrive": {"drive_unit": {"manufacturer": 256, "drive_unit_type": 1, "software_version": "1.20",
                                               "firmware_date": "15.05.2013"},
                                "profile": {"number": 3, "version": "4.1", "name": "PROFIdrive"}},
                 "canopen": {"vendor_id": 106, "serial": 2575499411, "device_name": "AKD"}},
    "status": {"state": "S4", "homed": None, "standstill": True},
}


def test_the_identity_section_starts_with_the_drive_in_words() -> None:
    pairs = bundle_report.identity(DATA).pairs
    assert pairs[:4] == [("vendor", "Kollmorgen"), ("model", "AKD"), ("firmware", "1.20"),
                         ("serial", "2575499411")]
    shown = dict(pairs)
    assert shown["profidrive.drive_unit.manufacturer"] == "256 (0x100, Kollmorgen)"
    assert shown["canopen.vendor_id"] == "106 (0x6A, Kollmorgen)"
    assert shown["profidrive.profile.name"] == "PROFIdrive"


def test_an_identity_from_elsewhere_is_shown_without_words_rather_than_refused() -> None:
    pairs = dict(bundle_report.identity({"identity": {"canopen": {"vendor_id": "x", "serial": None}}}).pairs)
    assert pairs["canopen.vendor_id"] == "x" and pairs["canopen.serial"] == ""


def test_a_status_value_the_drive_does_not_report_says_so() -> None:
    shown = dict(bundle_report.status(DATA).pairs)
    assert shown["homed"] == "not reported" and shown["standstill"] == "yes"
