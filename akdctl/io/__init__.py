"""Operating-system I/O that both the tool (``transport/``, ``drive/``) and the simulator (``sim/``) need.

Why a package of its own: a raw Ethernet socket, a python-can bus's teardown and a
crash-safe file write each had one copy per user, and the copies drifted (other
error wording, one fsync missing). One copy each lives here, below ``transport/``
and ``sim/``, so neither has to import the other. Modules here import only
``akdctl.errors`` and the standard library (python-can lazily).
"""
