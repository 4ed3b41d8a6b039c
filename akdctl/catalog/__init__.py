"""Catalogue data: PNUs, objects, PDOs, faults, abort and error texts (loaded lazily).

Data files are read straight from this package's ``data/`` directory (:func:`data_text`): akdctl is installed as
files (wheel or editable), and ``importlib.resources`` with the zipfile and reader modules it imports cost a cold
start more than reading the file does.
"""

from __future__ import annotations

import os


def data_text(name: str) -> str:
    """The text of ``data/NAME`` of this package (UTF-8)."""
    with open(os.path.join(os.path.dirname(__file__), "data", name), encoding="utf-8") as fh:
        return fh.read()
