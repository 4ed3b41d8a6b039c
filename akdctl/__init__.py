"""akdctl: commissioning and diagnostics for Kollmorgen AKD servo drives.

The package is layered (see ARCHITECTURE in the README): ``protocol`` holds pure
codecs, ``transport`` moves bytes, ``drive`` gives them meaning, ``catalog`` is
data, ``sim`` is the simulated drive and ``cli`` is the click front end.
Nothing here imports heavy modules at package import time, so that
``akdctl --help`` starts fast.
"""

__version__ = "0.1.0"
