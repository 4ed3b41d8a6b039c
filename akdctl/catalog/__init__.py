"""Catalogue data: PNUs, objects, PDOs, faults, abort and error texts (loaded lazily)."""
