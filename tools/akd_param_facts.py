"""The hand-kept fact table of AKD parameters behind ``akdctl/catalog/data/akd_params.tsv``.

Why a table of facts and not a table of rows: the ESI (``tools/gen_akd_params.py`` reads it) gives every name it
carries with its CoE index, type and access; what it does not give -- the class (NV / RW / RO / WO / command), the
value kind and unit, the published range and default, the sign, the CoE float scale, the parameter number ``n``, a
PNU -- is written here once per fact with the key of the source it was read in, and the generator merges both. No
row of a Kollmorgen table is copied: each entry is a handful of numbers and words re-entered from the reference
notes (``shared/reference/akd-parameter-names.md``, ``akd-ascii-channel.md``).

Sources (keys used in the ``source`` column):
  G1   AKD Parameter and Command Reference Guide, Dec 2009 (launch firmware; units/ranges/defaults/CoE boxes)
  ESI  AKD.xml v2.50 (fw M_01-20-00-001): object index, type, access
  S6   AKD EtherCAT manual, Oct 2017, 5.2.1 Float Scaling (IL.KP 3598h 1000:1, MT.P 607Ah 1:1)
  S11  AKD EtherNet/IP manual Dec 2014 p.25 (HOME.MOVE instance 205)
  S12  "Using AKD EtherNet/IP with RSLogix" appendix B rows 1-30
  C4   third-party Modbus register map (reference akd-ascii-channel.md 7): DRV.MOTIONSTAT, IL.FB, MOTOR.TEMP,
       VBUS.VALUE, DRV.FAULT1, VL.KP
  UG   AKD User Guide fieldbus boxes (Modbus register, hence n): VL.FB, VL.CMD, VL.KI, PL.FB, PL.CMD, WS.MODE, ...
  PN   AKD PROFINET manuals (seeds 000/003/004): PNU 930 (operating mode), PNU 1001 (HOME.MODE)
  A1   aakd (GPL, facts only): class of a keyword

Marks: a fact read in a source is [V]; what is inferred is [I] and says so (``marks`` keys ``coe``, ``scale``, ``n``,
``pnu``, ``range``). The float scale of most 0x35xx objects is not in any public excerpt (akd-parameter-names.md
1.4): those rows carry ``scale`` 1000 marked [I] (floats) or 1 marked [I] (integers).
"""

from __future__ import annotations

# Columns of one fact: name, class, kind, unit, min, max, default, CoE ("INDEX:SUB" / "-" none / "" the ESI's),
# CoE type override ("" = the ESI's, sign fixed here), scale, n, PNU, sources, marks, note.
# kind: int, float, bool, string, text (a multi-line read-only report), command.
# scale: "1", "1000", "var" (depends on FBUS.PARAM05 / UNIT.* / 6091h-6092h: read raw only), "" (no CoE).
FACTS: tuple[tuple[str, ...], ...] = (
    # ---- DRV: the drive itself
    ("DRV.OPMODE", "NV", "int", "", "0", "2", "0", "0x35B4:0", "i32", "1", "", "930", "G1 PN", "coe=V scale=V pnu=V", "0 torque, 1 velocity, 2 position"),
    ("DRV.CMDSOURCE", "NV", "int", "", "0", "5", "0", "-", "", "", "", "", "G1", "", "0 service (TCP/IP), 1 fieldbus, 2 gearing, 3 analog, 4 digital, 5 Bode"),
    ("DRV.ACTIVE", "RO", "int", "", "0", "3", "", "-", "", "", "", "", "G1 A1", "", "1 enabled; 3 dynamic braking (aakd)"),
    ("DRV.EN", "CMD", "command", "", "", "", "", "-", "", "", "", "", "G1", "", "software enable"),
    ("DRV.DIS", "CMD", "command", "", "", "", "", "-", "", "", "", "", "G1", "", "software disable (DRV.DISMODE)"),
    ("DRV.STOP", "CMD", "command", "", "", "", "", "", "", "", "", "", "G1 ESI", "coe=V", "stops all motion"),
    ("DRV.CLRFAULTS", "CMD", "command", "", "", "", "", "-", "", "", "", "", "G1", "", "clears the drive's faults"),
    ("DRV.FAULTS", "RO", "text", "", "", "", "", "-", "", "", "", "", "G1 A1", "", "one line per active fault"),
    ("DRV.WARNINGS", "RO", "text", "", "", "", "", "-", "", "", "", "", "G1 A1", "", "one line per active warning"),
    ("DRV.FAULT1", "RO", "int", "", "", "", "", "", "", "", "478", "", "ESI C4", "coe=V n=V", "first active fault number"),
    ("DRV.INFO", "RO", "text", "", "", "", "", "-", "", "", "", "", "G1", "", "drive identity report"),
    ("DRV.VER", "RO", "text", "", "", "", "", "-", "", "", "", "", "G1", "", "firmware and FPGA versions"),
    ("DRV.LIST", "RO", "text", "", "", "", "", "-", "", "", "", "", "G1", "", "the drive's keywords"),
    ("DRV.HELP", "RO", "text", "", "", "", "", "-", "", "", "", "", "G1", "", "min, max, default, actual of a keyword"),
    ("DRV.NVLIST", "RO", "text", "", "", "", "", "-", "", "", "", "", "G1", "", "NV parameters with their RAM values"),
    ("DRV.DIFVAR", "RO", "text", "", "", "", "", "-", "", "", "", "", "A1", "", "parameters that differ from their defaults"),
    ("DRV.NVSAVE", "CMD", "command", "", "", "", "", "0x1010:1", "u32", "", "", "", "G1 ESI", "coe=V", "RAM to non-volatile memory (CoE: 'save' to 1010h:1)"),
    ("DRV.NVLOAD", "WO", "command", "", "", "", "", "-", "", "", "", "", "G1", "", "non-volatile memory to RAM"),
    ("DRV.RSTVAR", "CMD", "command", "", "", "", "", "0x1011:1", "u32", "", "", "", "G1 S6", "coe=V", "RAM to defaults (NV untouched)"),
    ("DRV.NVCHECK", "RO", "int", "", "", "", "", "", "", "1", "522", "", "ESI UG", "coe=V n=V", "checksum of the NV parameters"),
    ("DRV.MOTIONSTAT", "RO", "int", "", "", "", "", "", "", "1", "135", "", "G1 ESI C4", "coe=V n=V", "motion status bits"),
    ("DRV.DISSOURCES", "RO", "int", "", "", "", "", "", "", "1", "", "", "G1 ESI", "coe=V", "why the drive is disabled (bits)"),
    ("DRV.READFORMAT", "RW", "int", "", "10", "16", "10", "-", "", "", "", "", "G1", "", "10 decimal, 16 hexadecimal replies"),
    ("DRV.ACC", "NV", "float", "rpm/s", "1.860", "50000000", "3000", "", "i32", "1000", "", "", "G1 ESI", "coe=V scale=I", "drive acceleration limit"),
    ("DRV.DEC", "NV", "float", "rpm/s", "1.860", "50000000", "3000", "0x3522:0", "i32", "1000", "", "", "G1", "coe=V scale=I", "drive deceleration limit"),
    ("DRV.DISMODE", "NV", "int", "", "0", "3", "0", "-", "", "", "", "", "G1", "", "0 immediate, 1 dyn. brake, 2 ramp, 3 ramp + dyn. brake"),
    ("DRV.NAME", "NV", "string", "", "", "", "No-Name", "", "", "", "", "", "G1 ESI", "coe=V", "the drive's name"),
    ("DRV.ICONT", "RO", "float", "A", "", "", "", "", "", "1000", "132", "", "ESI", "coe=V scale=I n=I", "drive continuous current"),
    ("DRV.IPEAK", "RO", "float", "A", "", "", "", "", "", "1000", "133", "", "ESI", "coe=V scale=I n=I", "drive peak current"),
    # ---- VL: velocity loop
    ("VL.CMD", "RO", "float", "rpm", "", "", "", "0x606B:0", "i32", "var", "426", "", "G1 UG", "coe=V n=V", "velocity command after limits"),
    ("VL.CMDU", "RW", "float", "rpm", "-12000", "12000", "0", "-", "", "", "", "", "G1", "", "service velocity set point"),
    ("VL.FB", "RO", "float", "rpm", "", "", "", "0x3618:0", "i32", "1000", "429", "", "G1 ESI UG", "coe=V scale=I n=V", "velocity feedback"),
    ("VL.KP", "NV", "float", "A/(rad/s)", "0.001", "2147483.008", "1", "0x3548:0", "", "1000", "437", "", "G1 ESI C4", "coe=V scale=I n=V", "velocity loop proportional gain"),
    ("VL.KI", "NV", "float", "Hz", "0", "1000", "160", "0x354D:0", "", "1000", "435", "", "G1 UG", "coe=V scale=I n=V", "velocity loop integral gain"),
    ("VL.LIMITP", "NV", "float", "rpm", "0", "12000", "3000", "0x3622:0", "i32", "1000", "", "", "G1 ESI", "coe=V scale=I", "positive velocity limit"),
    ("VL.LIMITN", "NV", "float", "rpm", "-12000", "0", "-3000", "0x3623:0", "i32", "1000", "", "", "G1 ESI", "coe=V scale=I", "negative velocity limit"),
    ("VL.THRESH", "NV", "float", "rpm", "0", "12000", "", "0x3627:0", "i32", "1000", "", "", "G1", "coe=V scale=I range=I", "overspeed fault threshold"),
    # ---- IL: current loop
    ("IL.FB", "RO", "float", "A", "", "", "", "", "i32", "1000", "217", "", "G1 ESI C4", "coe=V scale=I n=V", "current feedback"),
    ("IL.CMD", "RO", "float", "A", "", "", "", "-", "", "", "", "", "G1", "", "current command"),
    ("IL.CMDU", "RW", "float", "A", "", "", "0", "-", "", "", "", "", "G1", "", "service current set point"),
    ("IL.KP", "NV", "float", "V/A", "0", "2000", "50", "0x3598:0", "i32", "1000", "", "", "G1 S6", "coe=V scale=V", "current loop proportional gain"),
    ("IL.LIMITP", "NV", "float", "A", "", "", "", "0x356E:0", "i32", "1000", "", "", "G1", "coe=V scale=I", "positive current limit"),
    ("IL.LIMITN", "NV", "float", "A", "", "", "", "0x356F:0", "i32", "1000", "", "", "G1", "coe=V scale=I", "negative current limit"),
    # ---- PL: position loop
    ("PL.FB", "RO", "float", "counts", "", "", "", "0x6064:0", "i32", "var", "295", "", "G1 UG", "coe=V n=V", "position feedback (64-bit)"),
    ("PL.CMD", "RO", "float", "counts", "", "", "", "-", "", "", "286", "", "G1 UG", "n=V", "position command (64-bit)"),
    ("PL.ERR", "RO", "float", "counts", "", "", "", "0x60F4:0", "i32", "var", "", "", "G1", "coe=V", "following error"),
    ("PL.KP", "NV", "float", "(rev/s)/rev", "0", "2147483.008", "100", "0x3542:0", "", "1000", "", "", "G1", "coe=V scale=I", "position loop proportional gain"),
    ("PL.KI", "NV", "float", "1/s", "0", "2147483.008", "0", "", "", "1000", "", "", "G1 ESI", "coe=V scale=I", "position loop integral gain"),
    ("PL.ERRFTHRESH", "NV", "float", "counts", "0", "", "0", "0x35C7:0", "", "1000", "", "", "G1", "coe=V scale=I", "following error fault threshold (0 = off)"),
    # ---- MT: motion task working parameters
    ("MT.NUM", "RW", "int", "", "0", "128", "0", "0x365B:0", "", "1", "", "", "G1", "coe=V", "motion task number"),
    ("MT.P", "RW", "float", "counts", "", "", "0", "0x607A:0", "i32", "1", "", "", "G1 S6", "coe=V scale=V", "motion task position"),
    ("MT.V", "RW", "float", "rpm", "0", "12000", "0", "0x6081:0", "u32", "var", "", "", "G1", "coe=V", "motion task velocity"),
    ("MT.ACC", "RW", "float", "rpm/s", "", "", "3000", "0x6083:0", "u32", "var", "", "", "G1", "coe=V", "motion task acceleration"),
    ("MT.DEC", "RW", "float", "rpm/s", "", "", "3000", "0x6084:0", "u32", "var", "", "", "G1", "coe=V", "motion task deceleration"),
    ("MT.CNTL", "RW", "int", "", "0", "4294967295", "0", "0x35B9:0", "", "1", "", "", "G1 ESI", "coe=V", "motion task control bits"),
    ("MT.MOVE", "CMD", "command", "", "", "", "", "-", "", "", "", "", "G1", "", "starts motion task n"),
    ("MT.SET", "CMD", "command", "", "", "", "", "", "", "", "", "", "G1 ESI", "coe=V", "stores task MT.NUM"),
    ("MT.LOAD", "CMD", "command", "", "", "", "", "", "", "", "", "", "G1 ESI", "coe=V", "loads task MT.NUM"),
    ("MT.LIST", "RO", "text", "", "", "", "", "-", "", "", "", "", "G1", "", "the motion task table"),
    # ---- HOME
    ("HOME.MODE", "RW", "int", "", "0", "20", "0", "", "", "1", "204", "1001", "G1 ESI PN", "coe=V n=I pnu=V range=I", "homing procedure"),
    ("HOME.MOVE", "CMD", "command", "", "", "", "", "-", "", "", "205", "", "G1 S11", "n=V", "starts homing"),
    ("HOME.DIR", "NV", "int", "", "0", "1", "1", "", "", "1", "198", "", "G1 ESI", "coe=V n=I", "homing direction"),
    ("HOME.V", "RW", "float", "rpm", "0.001", "12000", "", "0x6099:1", "u32", "var", "", "", "G1", "coe=V", "homing velocity"),
    ("HOME.ACC", "RW", "float", "rpm/s", "", "", "3000", "0x3502:0", "", "1000", "", "", "G1", "coe=V scale=I", "homing acceleration"),
    ("HOME.DEC", "RW", "float", "rpm/s", "", "", "3000", "0x3524:0", "", "1000", "", "", "G1", "coe=V scale=I", "homing deceleration"),
    ("HOME.P", "RW", "float", "counts", "", "", "0", "-", "", "", "", "", "G1", "", "home position"),
    ("HOME.SET", "CMD", "command", "", "", "", "", "", "", "", "", "", "G1 ESI", "coe=V", "sets the home position now"),
    # ---- UNIT
    ("UNIT.PROTARY", "NV", "int", "", "0", "3", "0", "0x3660:0", "", "1", "", "", "G1", "coe=V", "position unit: 0 counts, 1 rad, 2 deg, 3 PIN/POUT"),
    ("UNIT.VROTARY", "NV", "int", "", "0", "3", "0", "0x365F:0", "", "1", "", "", "G1", "coe=V", "velocity unit: 0 rpm, 1 rps, 2 deg/s, 3 (PIN/POUT)/s"),
    ("UNIT.ACCROTARY", "NV", "int", "", "0", "3", "0", "0x3659:0", "", "1", "", "", "G1", "coe=V", "acceleration unit: 0 rpm/s, 1 rps/s, 2 deg/s², 3 (PIN/POUT)/s²"),
    ("UNIT.PIN", "NV", "int", "", "0", "", "100", "0x35CA:0", "", "1", "", "", "G1", "coe=V range=I", "position scaling numerator"),
    ("UNIT.POUT", "NV", "int", "", "0", "", "100", "0x35CB:0", "", "1", "", "", "G1", "coe=V range=I", "position scaling denominator"),
    ("UNIT.PLINEAR", "NV", "int", "", "0", "4", "0", "", "", "1", "392", "", "G1 ESI", "coe=V n=I", "linear position unit"),
    ("UNIT.VLINEAR", "NV", "int", "", "0", "3", "0", "", "", "1", "395", "", "G1 ESI", "coe=V n=I", "linear velocity unit"),
    ("UNIT.ACCLINEAR", "NV", "int", "", "0", "3", "0", "", "", "1", "389", "", "G1 ESI", "coe=V n=I", "linear acceleration unit"),
    # ---- MOTOR
    ("MOTOR.TYPE", "NV", "int", "", "0", "1", "0", "", "", "1", "261", "", "G1 ESI", "coe=V n=I", "0 rotary, 1 linear (2009 values)"),
    ("MOTOR.ICONT", "NV", "float", "A", "", "", "", "0x358E:0", "", "1000", "", "", "G1", "coe=V scale=I", "motor continuous current (2009 guide: mA)"),
    ("MOTOR.IPEAK", "NV", "float", "A", "", "", "", "0x358F:0", "", "1000", "", "", "G1", "coe=V scale=I", "motor peak current (2009 guide: mA)"),
    ("MOTOR.POLES", "NV", "int", "", "0", "128", "6", "", "", "1", "", "", "G1 ESI", "coe=V", "motor poles"),
    ("MOTOR.KT", "NV", "float", "Nm/A", "0.001", "65", "0.1", "", "", "1000", "", "", "G1 ESI", "coe=V scale=I", "torque constant"),
    ("MOTOR.VMAX", "NV", "int", "rpm", "100", "40000", "3000", "", "", "1", "", "", "G1 ESI", "coe=V", "motor maximum velocity"),
    ("MOTOR.INERTIA", "NV", "float", "kg·cm²", "1", "200000", "100", "", "", "1000", "", "", "G1 ESI", "coe=V scale=I", "rotor inertia"),
    ("MOTOR.BRAKE", "NV", "int", "", "0", "1", "0", "0x3587:0", "", "1", "", "", "G1", "coe=V", "brake present"),
    ("MOTOR.AUTOSET", "NV", "int", "", "0", "1", "0", "", "", "1", "", "", "G1 ESI", "coe=V", "motor parameters from the feedback"),
    ("MOTOR.TEMP", "RO", "int", "Ohm", "", "", "", "0x3612:0", "", "1", "258", "", "G1 C4", "coe=V n=V", "motor temperature sensor"),
    ("MOTOR.NAME", "NV", "string", "", "", "", "", "", "", "", "", "", "G1 ESI", "coe=V", "motor name"),
    # ---- feedback, bus, analog, fieldbus
    ("FB1.SELECT", "NV", "int", "", "-1", "41", "-1", "", "i32", "1", "", "", "G1 ESI", "coe=V", "feedback type (-1 auto)"),
    ("FB1.ENCRES", "NV", "int", "counts/rev", "0", "4294967295", "1024", "", "", "1", "", "", "G1 ESI", "coe=V", "encoder resolution"),
    ("FB1.PSCALE", "RW", "int", "bits", "0", "32", "20", "-", "", "", "", "", "G1", "", "fraction bits of the fieldbus position"),
    ("VBUS.VALUE", "RO", "int", "V", "0", "900", "", "0x361A:0", "", "1", "404", "", "G1 C4", "coe=V n=V", "DC bus voltage"),
    ("AIN.CUTOFF", "NV", "float", "Hz", "", "", "", "", "", "1000", "1", "", "ESI S12", "coe=V scale=I n=V", "analog input filter"),
    ("AIN.DEADBAND", "NV", "float", "V", "", "", "", "", "", "1000", "2", "", "ESI S12", "coe=V scale=I n=V", "analog input deadband"),
    ("AIN.ISCALE", "NV", "float", "A/V", "", "", "", "", "", "1000", "3", "", "ESI S12", "coe=V scale=I n=V", "analog current scale"),
    ("AIN.OFFSET", "NV", "float", "V", "", "", "", "", "i32", "1000", "4", "", "ESI S12", "coe=V scale=I n=V", "analog input offset"),
    ("AOUT.ISCALE", "NV", "float", "A/V", "", "", "", "", "", "1000", "10", "", "ESI S12", "coe=V scale=I n=V", "analog output current scale"),
    ("AOUT.MODE", "NV", "int", "", "", "", "", "", "", "1", "11", "", "ESI S12", "coe=V n=V", "analog output mode"),
    ("AOUT.OFFSET", "NV", "float", "V", "", "", "", "", "i32", "1000", "12", "", "ESI S12", "coe=V scale=I n=V", "analog output offset"),
    ("MODBUS.PSCALE", "NV", "int", "", "", "", "", "", "", "1", "490", "", "ESI UG", "coe=V n=V", "Modbus position scaling"),
    ("EIP.POSUNIT", "NV", "int", "", "1", "2147483648", "65536", "-", "", "", "796", "", "UG", "n=V", "EtherNet/IP position unit"),
    ("EIP.PROFUNIT", "NV", "int", "", "1", "2147483648", "65536", "-", "", "", "797", "", "UG", "n=V", "EtherNet/IP profile unit"),
    ("WS.MODE", "NV", "int", "", "", "", "", "", "", "1", "452", "", "ESI UG", "coe=V n=V", "wake-and-shake mode"),
    ("SD.SAVE", "CMD", "command", "", "", "", "", "-", "", "", "844", "", "UG", "n=V", "saves the drive's parameters to the SD card"),
)
