"""The ground floor shared by ``drive/`` (the client) and ``sim/`` (the simulated drive).

Why a package of its own: the meaning of a status or control word bit and the
normalisation of a velocity are the same rule for the tool that sends a word and
for the simulator that answers it. Living here, below both, neither has to import
the other to agree. Modules here import nothing of akdctl but ``protocol/``.
"""
