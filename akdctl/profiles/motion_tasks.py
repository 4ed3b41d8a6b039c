"""How the AKD exposes its motion task table on CoE: object numbers and MT.CNTL bits, for client and simulator.

Why here: ``akdctl task`` (drive/tasks.py) and the simulated drive (sim/task_table.py) must agree on which
object carries which MT parameter; living below both, neither imports the other (docs/fidelity.md F11).

From the AKD ESI (parameter names of the objects): MT.NUM 0x365B, MT.SET 0x3431 (write only), MT.LOAD 0x3432
(write only), MT.CNTL 0x35B9, MT.V 0x6081, MT.ACC 0x6083, MT.DEC 0x6084. Inferred [I]: MT.P ↔ 0x607A (the ESI
names no object for MT.P; profile position "uses motion task 0", EtherCAT manual 5.8, with 0x607A as its target),
and MT.CNTL bit 0 = 1 relative (EtherCAT manual 5.14, FBUS.PARAM05 bit 6: MT.CNTL bit 0 is the DS402
controlword's bit 6, 0 absolute / 1 relative). Task numbers 0..127 [I].
"""

from __future__ import annotations

MT_NUM, MT_SET, MT_LOAD, MT_CNTL = 0x365B, 0x3431, 0x3432, 0x35B9
MT_P, MT_V, MT_ACC, MT_DEC = 0x607A, 0x6081, 0x6083, 0x6084
MAX_TASK = 127
CNTL_RELATIVE = 0x0001
