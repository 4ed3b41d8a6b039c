"""Channels: PNU parameter access and SDO object access, independent of the link under them."""
