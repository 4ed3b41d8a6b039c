"""The axis: one interface for enable/disable/stop/acknowledge/jog/home/move/status on both profiles.

Why one implementation: every command that moves or powers the axis (``enable``,
``move``, ``fault ack``, recipes) goes through :func:`open_axis`, so the safety
checks (fault present, control not honoured, controlword overridden by process
data, not homed) and the stop-on-error behaviour exist exactly once.

* :class:`ProfidriveAxis` speaks PNUs: STW1/ZSW1 (PNU 1/2) and the general state
  machine S1..S5 (SPEC-NOTES 6/7), jog with STW1 bits 8/9 and PNU 1004..1007
  (note 8), homing with STW1 bit 11 (note 9), MDI positioning with SATZANW bit 15,
  MDI_* PNU 34..38 and the ZSW1 bit 12 handshake (note 12), units per note 13.
* :class:`Cia402Axis` speaks objects: controlword/statusword (EtherCAT manual 5.4),
  profile position (1) with the bit 4 / bit 12 handshake, profile velocity (3) for
  jog, homing (6, 0x6098, statusword bits 10/12/13). Modes 7/8 need a cyclic set
  point stream and are refused acyclically. Scaling assumed: 65536 counts per
  revolution, counts/s, counts/s² (the simulator's; set a real drive alike).

Every wait polls with a deadline (how often: :mod:`akdctl.drive.polling`); nothing here sleeps unbounded.
"""

from akdctl.drive.axis.base import (
    Axis,
    AxisStatus,
    JogSpec,
    MotionScales,
    MoveSpec,
    Scale,
)

__all__ = ["Axis", "AxisStatus", "JogSpec", "MotionScales", "MoveSpec", "Scale"]
