"""Transports: move request/response bytes to a drive (simulated, PROFINET, EtherCAT, CANopen)."""
