"""A simulated EtherCAT Slave Controller (ESC): the register space a master
talks to, processing datagrams exactly as the silicon would.

Only what a master needs to bring an AKD to PRE-OP and use its mailbox:
station address (0x0010), DL status, AL control/status/status code
(0x0120/0x0130/0x0134) with the AKD's state machine and its two error codes
(0x0011 invalid requested state change, 0x0017 invalid sync manager
configuration - AKD EtherCAT manual 5.3.3, SPEC-NOTES 22), the SII EEPROM
interface (0x0500-0x050F), sync managers (0x0800+) with mailbox semantics
(full/empty, write to a full mailbox and read of an empty one are not counted
in the working counter, the repeat request/acknowledge handshake) and the
mailbox buffers SM0 0x1800 / SM1 0x1C00.

The ESC is pure: :meth:`Esc.process` takes the datagrams of a frame and
returns them as they leave the slave (data filled in, WKC incremented, ADP
incremented for auto-increment and broadcast commands). Mailbox requests are
handed to whoever calls :meth:`take_request` (the face's worker thread, so a
slow SDO never delays a frame) and replies come back through :meth:`post_replies`
-- except the requests :attr:`Esc.quick` picks (reads answered from memory),
which the caller of :meth:`process` takes with :meth:`take_quick` once the
frame has gone back: no thread hand-off, no frame waiting for an application
thread to be scheduled.
"""

from __future__ import annotations

import struct
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from akdctl.protocol import ethercat as ec
from akdctl.protocol.sii import SiiImage, build_sii, crc8

RAM_SIZE = 0x10000
NUM_SM = 8
NUM_FMMU = 3  # as REG_TYPE reports (0x0004)
#: SM watchdog registers and their power-on values (ESC datasheet: divider 2498 -> 100 us units, process-data
#: watchdog 1000 units -> 100 ms).
REG_WD_PD_TIME = 0x0420
WD_DIVIDER_DEFAULT = 2498
WD_PD_TIME_DEFAULT = 1000
SM_CONTROL_WATCHDOG = 0x40
MBX_MIN = 40  # smallest mailbox the AKD accepts (ESI Sm MinSize)
_SM_END = ec.REG_SM0 + ec.SM_STRIDE * NUM_SM

# ECAT-read-only register bytes (writes by the master are ignored there)
_READ_ONLY = [(0x0000, 0x000F), (0x0012, 0x0013), (0x0110, 0x0111), (0x0130, 0x0135), (0x0140, 0x0141),
              (0x0220, 0x0223), (0x0501, 0x0501)]


@dataclass
class _MailboxSm:
    """Run-time state of one mailbox sync manager (beyond its register block)."""

    full: bool = False
    last: bytes = b""  # last buffer content handed to the master (for the repeat request)


@dataclass
class EscStats:
    frames: int = 0
    mailbox_requests: int = 0
    mailbox_replies: int = 0
    repeats: int = 0
    denied: int = 0
    dropped: int = 0


@dataclass
class Esc:
    """One slave controller with an SII image and an AL state machine."""

    sii: SiiImage
    mailbox_sizes: tuple[int, int] = (0, 0)
    stats: EscStats = field(default_factory=EscStats)

    def __post_init__(self) -> None:
        self.mem = bytearray(RAM_SIZE)
        self.eeprom = bytearray(build_sii(self.sii))
        self._lock = threading.RLock()
        self._requests: deque[bytes] = deque()
        self._replies: deque[bytes] = deque()
        self._have_request = threading.Condition(self._lock)
        self._sm = [_MailboxSm() for _ in range(NUM_SM)]
        #: () -> (RxPDO bytes, TxPDO bytes) of the current mapping, for the P -> S SM length check
        self.process_sizes: Callable[[], tuple[int, int]] | None = None
        self.drop_next_reply = False  # fault injection: the frame that reads the next reply is lost
        self.eeprom_writes: list[int] = []  # words the master wrote, for the face's application to act on
        self.inputs_read = 0  # input process data frames served
        self.outputs_written = 0  # output process data frames taken (the application and the SM watchdog watch it)
        self.lost_frame = False  # set by process(): the face must not send this frame back
        #: Requests (the whole SM0 buffer) the caller of process() answers itself through take_quick(), when no
        #: earlier request is still with the application (replies keep the requests' order); None: none.
        self.quick: Callable[[bytes], bool] | None = None
        self._quick: deque[bytes] = deque()
        self._owed = 0  # requests handed to the application whose replies it has not posted yet
        self._sm_regs = bytearray()  # the SM registers the mailbox layout below was derived from
        self._layout: tuple[tuple[int, int, int, bool], ...] = ()
        self.reset()

    # ------------------------------------------------------------------ power-on state
    def reset(self) -> None:
        with self._lock:
            self.mem[:] = bytes(RAM_SIZE)
            struct.pack_into("<BBHBBBB", self.mem, ec.REG_TYPE, 0x04, 0x01, 0x0100, 3, NUM_SM, 8, 0x0F)
            struct.pack_into("<H", self.mem, ec.REG_FEATURES, 0x01CC)
            # Power-on: the ESC loads its configuration area (words 0-7) from the EEPROM, the station alias
            # (word 4) into 0x0012 among it -- only when the CRC in word 7 is right (ESC datasheet, reference
            # foe-alias-recorder.md B); a wrong CRC leaves the alias 0 and shows the checksum error in 0x0502.
            crc_ok = crc8(bytes(self.eeprom[0:14])) == self.eeprom[14]
            alias = struct.unpack_from("<H", self.eeprom, 8)[0] if crc_ok else 0
            struct.pack_into("<H", self.mem, ec.REG_STATION_ALIAS, alias)
            struct.pack_into("<H", self.mem, ec.REG_WD_DIVIDER, WD_DIVIDER_DEFAULT)
            struct.pack_into("<H", self.mem, REG_WD_PD_TIME, WD_PD_TIME_DEFAULT)
            # DL status: PDI operational, link on port 0, port 0 open with communication, ports 1-3 closed
            struct.pack_into("<H", self.mem, ec.REG_DL_STATUS, 0x0001 | 0x0010 | 0x0200 | 0x0400 | 0x1000 | 0x4000)
            struct.pack_into("<H", self.mem, ec.REG_AL_STATUS, ec.AlState.INIT)
            struct.pack_into("<H", self.mem, ec.REG_PDI_CONTROL, self.sii.pdi_control)
            struct.pack_into("<H", self.mem, ec.REG_EEP_CONTROL,
                             ec.EEP_READ_8_BYTES | (0 if crc_ok else ec.EEP_ERROR_CHECKSUM))
            self._requests.clear()
            self._replies.clear()
            self._quick.clear()
            self._owed = 0
            self._sm = [_MailboxSm() for _ in range(NUM_SM)]

    # ------------------------------------------------------------------ small accessors
    def u16(self, addr: int) -> int:
        return struct.unpack_from("<H", self.mem, addr)[0]

    def _set_u16(self, addr: int, value: int) -> None:
        struct.pack_into("<H", self.mem, addr, value & 0xFFFF)

    @property
    def station(self) -> int:
        return self.u16(ec.REG_STATION_ADDR)

    @property
    def al_status(self) -> int:
        return self.u16(ec.REG_AL_STATUS)

    @property
    def al_code(self) -> int:
        return self.u16(ec.REG_AL_STATUS_CODE)

    def sync_manager(self, n: int) -> ec.SyncManager:
        base = ec.REG_SM0 + ec.SM_STRIDE * n
        return ec.SyncManager.decode(bytes(self.mem[base : base + 8]))

    def _sm_status_addr(self, n: int) -> int:
        return ec.REG_SM0 + ec.SM_STRIDE * n + 5

    def _mailbox_enabled(self, n: int) -> bool:
        sm = self.sync_manager(n)
        return sm.enabled and sm.is_mailbox and sm.length > 0

    def _set_full(self, n: int, full: bool) -> None:
        self._sm[n].full = full
        addr = self._sm_status_addr(n)
        status = self.mem[addr] = (self.mem[addr] | ec.SM_STATUS_MAILBOX_FULL) if full else (
            self.mem[addr] & ~ec.SM_STATUS_MAILBOX_FULL & 0xFF)
        if len(self._sm_regs) == _SM_END - ec.REG_SM0:
            self._sm_regs[addr - ec.REG_SM0] = status  # the layout does not depend on it: no decode for it

    def _mailboxes_active(self) -> bool:
        return (self.al_status & 0x0F) in (ec.AlState.PREOP, ec.AlState.SAFEOP, ec.AlState.OP, ec.AlState.BOOT)

    # ------------------------------------------------------------------ frame processing
    def process(self, datagrams: list[ec.Datagram]) -> list[ec.Datagram]:
        """Process every datagram of a frame in place (and return them)."""
        with self._lock:
            self.stats.frames += 1
            self.lost_frame = False
            for d in datagrams:
                self._process_one(d)
            return datagrams

    def _process_one(self, d: ec.Datagram) -> None:
        cmd = d.cmd
        if cmd in ec.AUTO_INCREMENT_CMDS:
            addressed = d.adp == 0
            d.adp = (d.adp + 1) & 0xFFFF
        elif cmd in ec.CONFIGURED_CMDS:
            addressed = d.adp == self.station
        elif cmd in ec.BROADCAST_CMDS:
            addressed = True
            d.adp = (d.adp + 1) & 0xFFFF
        elif cmd in ec.LOGICAL_CMDS:
            self._process_logical(d)
            return
        else:
            return  # NOP (and unknown commands): nothing
        if not addressed:
            return
        ado, n = d.ado, len(d.data)
        if ado + n > RAM_SIZE:
            return
        if cmd in ec.READ_CMDS:
            data = self._read(ado, n)
            if data is None:
                self.stats.denied += 1
                return
            if cmd in ec.BROADCAST_CMDS:
                data = bytes(a | b for a, b in zip(d.data, data))
            d.data = data
            d.wkc = (d.wkc + 1) & 0xFFFF
        elif cmd in ec.WRITE_CMDS:
            if self._write(ado, d.data):
                d.wkc = (d.wkc + 1) & 0xFFFF
            else:
                self.stats.denied += 1
        else:  # read-write: the old content goes back, the new is written
            old = self._read(ado, n)
            if old is None:
                return
            wrote = self._write(ado, d.data)
            d.data = old
            d.wkc = (d.wkc + (3 if wrote else 1)) & 0xFFFF

    # ------------------------------------------------------------------ logical addressing (FMMUs)
    def fmmus(self) -> list[tuple[int, int, int, int]]:
        """The active FMMUs: (logical start, length, physical start, type bits: 1 read, 2 write).

        Byte granularity only: the AKD's process data is whole bytes (SPEC-NOTES 18 keeps totals even),
        and every master maps it byte-aligned; start/stop bits are not evaluated."""
        out = []
        for i in range(NUM_FMMU):
            base = ec.REG_FMMU0 + 16 * i
            logical, length, _sb, _eb, physical, _pb, kind, active = struct.unpack_from("<IHBBHBBB", self.mem, base)
            if active & 0x01 and length and kind & 0x03:
                out.append((logical, length, physical, kind & 0x03))
        return out

    def _pd_area_ok(self, physical: int, length: int, write: bool) -> bool:
        """An FMMU's physical area must lie in an enabled process-data SM of the right direction; outputs
        count only in OP (the AKD's application takes them then; in SAFE-OP the output SM is not yet
        served, so LRW shows WKC 1 there and 3 in OP -- what a master expects of one slave)."""
        state = self.al_status & 0x0F
        if state not in (ec.AlState.SAFEOP, ec.AlState.OP) or (write and state != ec.AlState.OP):
            return False
        for i in range(NUM_SM):
            sm = self.sync_manager(i)
            if (sm.enabled and not sm.is_mailbox and sm.writes_to_slave == write
                    and sm.start <= physical and physical + length <= sm.start + sm.length):
                return True
        return False

    def _process_logical(self, d: ec.Datagram) -> None:
        start, n = d.logical, len(d.data)
        data = bytearray(d.data)
        read = wrote = False
        for logical, length, physical, kind in self.fmmus():
            lo, hi = max(start, logical), min(start + n, logical + length)
            if lo >= hi:
                continue
            phys = physical + (lo - logical)
            size = hi - lo
            if kind & 0x01 and d.cmd in (ec.Cmd.LRD, ec.Cmd.LRW) and self._pd_area_ok(phys, size, write=False):
                data[lo - start:hi - start] = self.mem[phys:phys + size]
                read = True
            if kind & 0x02 and d.cmd in (ec.Cmd.LWR, ec.Cmd.LRW) and self._pd_area_ok(phys, size, write=True):
                self.mem[phys:phys + size] = d.data[lo - start:hi - start]
                wrote = True
        if wrote:
            self.outputs_written += 1
        if read:
            self.inputs_read += 1
        d.data = bytes(data)
        d.wkc = (d.wkc + (1 if read else 0) + (2 if wrote else 0)) & 0xFFFF

    def process_image(self, write: bool) -> bytes:
        """The bytes of the enabled process-data SM of one direction (``write``: outputs, SM2)."""
        with self._lock:
            for i in range(NUM_SM):
                sm = self.sync_manager(i)
                if sm.enabled and not sm.is_mailbox and sm.writes_to_slave == write and sm.length:
                    return bytes(self.mem[sm.start:sm.start + sm.length])
            return b""

    def set_inputs(self, data: bytes) -> None:
        """The application's inputs (TxPDO) into the input SM's buffer, as far as it reaches."""
        with self._lock:
            for i in range(NUM_SM):
                sm = self.sync_manager(i)
                if sm.enabled and not sm.is_mailbox and not sm.writes_to_slave and sm.length:
                    chunk = bytes(data[:sm.length])
                    self.mem[sm.start:sm.start + len(chunk)] = chunk
                    return

    def _mailboxes(self) -> tuple[tuple[int, int, int, bool], ...]:
        """(n, start, length, written by the master) of every enabled mailbox SM, as its registers say now.

        Why not decode the SMs each time: every mailbox access asked for them, eight SyncManager objects a
        time, a dozen times per SDO. One comparison of the SM register block tells whether anything changed
        since (whoever wrote it: the master, or a test writing ``mem``; :meth:`_set_full` keeps the status
        bytes it changes itself in step, so a mailbox turning full or empty costs no new decode)."""
        regs = self.mem[ec.REG_SM0:_SM_END]
        if regs != self._sm_regs:
            self._sm_regs = regs
            self._layout = tuple((i, sm.start, sm.length, sm.writes_to_slave)
                                 for i, sm in ((i, self.sync_manager(i)) for i in range(NUM_SM))
                                 if sm.enabled and sm.is_mailbox)
        return self._layout

    def _mailbox_sm_at(self, addr: int, n: int) -> tuple[int, int, int, bool] | None:
        """The enabled mailbox SM whose buffer overlaps [addr, addr+n)."""
        for sm in self._mailboxes():
            _i, start, length, _writes = sm
            if length and addr < start + length and start < addr + n:
                return sm
        return None

    def _read(self, addr: int, n: int) -> bytes | None:
        found = self._mailbox_sm_at(addr, n) if addr >= 0x1000 else None
        if found is not None:
            i, start, length, writes = found
            if writes or not self._sm[i].full:
                return None  # reading an empty read-mailbox (or the write mailbox) is denied: WKC unchanged
            data = bytes(self.mem[addr : addr + n])
            if addr + n >= start + length:  # the last byte was read: the buffer is the master's now
                self._sm[i].last = bytes(self.mem[start : start + length])
                self._set_full(i, False)
                self.stats.mailbox_replies += 1
                if self.drop_next_reply:
                    self.drop_next_reply = False
                    self.lost_frame = True
                    self.stats.dropped += 1
                self._load_reply()
            return data
        return bytes(self.mem[addr : addr + n])

    def _write(self, addr: int, data: bytes) -> bool:
        n = len(data)
        if addr >= 0x1000:
            found = self._mailbox_sm_at(addr, n)
            if found is not None:
                i, start, length, writes = found
                if not writes or self._sm[i].full or not self._mailboxes_active():
                    return False
                self.mem[addr : addr + n] = data
                if addr + n >= start + length:
                    self._set_full(i, True)
                    raw = bytes(self.mem[start : start + length])
                    self.stats.mailbox_requests += 1
                    if self.quick is not None and not self._owed and self.quick(raw):
                        self._quick.append(raw)
                    else:
                        self._requests.append(raw)
                        self._owed += 1
                        self._have_request.notify_all()
                return True
            self.mem[addr : addr + n] = data
            return True
        old = bytes(self.mem[addr : addr + n])
        for pos in range(n):
            a = addr + pos
            if not any(lo <= a <= hi for lo, hi in _READ_ONLY) and not self._sm_read_only(a):
                self.mem[a] = data[pos]
        self._after_write(addr, n, old)
        return True

    @staticmethod
    def _sm_read_only(a: int) -> bool:
        return ec.REG_SM0 <= a < ec.REG_SM0 + ec.SM_STRIDE * NUM_SM and (a - ec.REG_SM0) % ec.SM_STRIDE in (5, 7)

    def _touches(self, addr: int, n: int, reg: int, size: int = 1) -> bool:
        return addr < reg + size and reg < addr + n

    def _after_write(self, addr: int, n: int, old: bytes) -> None:
        if self._touches(addr, n, ec.REG_EEP_CONTROL, 2):
            self._eeprom_command()
        for i in range(NUM_SM):
            act = ec.REG_SM0 + ec.SM_STRIDE * i + 6
            if self._touches(addr, n, act):
                before = old[act - addr]
                self._activate_changed(i, before, self.mem[act])
        if self._touches(addr, n, ec.REG_AL_CONTROL, 2):
            self._al_control(self.u16(ec.REG_AL_CONTROL))

    # ------------------------------------------------------------------ SII EEPROM interface
    def _eeprom_command(self) -> None:
        ctl = self.u16(ec.REG_EEP_CONTROL)
        cmd = ctl & 0x0700
        (word,) = struct.unpack_from("<I", self.mem, ec.REG_EEP_ADDRESS)
        status = ec.EEP_READ_8_BYTES
        if cmd == ec.EEP_CMD_READ:
            start = word * 2
            chunk = bytes(self.eeprom[start : start + 8]) if start < len(self.eeprom) else b""
            self.mem[ec.REG_EEP_DATA : ec.REG_EEP_DATA + 8] = chunk.ljust(8, b"\xff")
        elif cmd == ec.EEP_CMD_WRITE:
            if not ctl & 0x0001:  # write enable must be set in the same access
                status |= ec.EEP_ERROR_WRITE_ENABLE
            elif word * 2 + 2 <= len(self.eeprom):
                self.eeprom[word * 2 : word * 2 + 2] = self.mem[ec.REG_EEP_DATA : ec.REG_EEP_DATA + 2]
                self.eeprom_writes.append(word)
            else:
                status |= ec.EEP_ERROR_ACK
        elif cmd == ec.EEP_CMD_RELOAD:
            self.mem[ec.REG_STATION_ALIAS : ec.REG_STATION_ALIAS + 2] = self.eeprom[8:10]
        self._set_u16(ec.REG_EEP_CONTROL, status)  # command done at once: busy never set

    # ------------------------------------------------------------------ sync manager activation / repeat
    def _activate_changed(self, i: int, before: int, after: int) -> None:
        if (before ^ after) & ec.SM_ACTIVATE_ENABLE:
            self._set_full(i, False)
            self._sm[i].last = b""
        if (before ^ after) & ec.SM_ACTIVATE_REPEAT and after & ec.SM_ACTIVATE_ENABLE:
            sm = self.sync_manager(i)
            if not sm.writes_to_slave and self._sm[i].last and not self._sm[i].full:
                # repeat request: put the last reply back (the application's job, done at once here)
                self.mem[sm.start : sm.start + len(self._sm[i].last)] = self._sm[i].last
                self._set_full(i, True)
                self.stats.repeats += 1
            pdi = ec.REG_SM0 + ec.SM_STRIDE * i + 7
            self.mem[pdi] = (self.mem[pdi] & ~ec.SM_PDI_REPEAT_ACK & 0xFF) | (after & ec.SM_ACTIVATE_REPEAT)

    # ------------------------------------------------------------------ AL state machine (AKD rules)
    def _al_control(self, ctl: int) -> None:
        requested, ack = ctl & 0x0F, bool(ctl & ec.AL_ERROR_FLAG)
        status = self.al_status
        current, error = status & 0x0F, bool(status & ec.AL_ERROR_FLAG)
        if error and not ack and requested >= current:
            return  # an error must be acknowledged before going on (a step down is always allowed)
        if requested == current:
            self._set_al(current, 0)
            return
        code = self._transition_error(current, requested)
        if code:
            self._set_al(current | ec.AL_ERROR_FLAG, code)
            return
        if requested == ec.AlState.INIT or (current == ec.AlState.INIT and requested == ec.AlState.PREOP):
            self._clear_mailboxes()
        self._set_al(requested, 0)

    def _transition_error(self, current: int, requested: int) -> int:
        S = ec.AlState
        if requested not in (S.INIT, S.PREOP, S.BOOT, S.SAFEOP, S.OP):
            return 0x0011
        if requested == S.INIT:
            return 0
        if requested == S.BOOT:
            return self._check_mailbox_sms(boot=True) if current == S.INIT else 0x0011
        if current == S.BOOT:
            return 0x0011
        if requested == S.PREOP:
            return self._check_mailbox_sms() if current == S.INIT else 0
        if requested == S.SAFEOP:
            if current == S.INIT:
                return 0x0011
            return self._check_process_sms() if current == S.PREOP else 0
        # OP
        return 0 if current == S.SAFEOP else 0x0011

    def watchdog_expired(self) -> None:
        """The process-data watchdog ran out in OP: SAFE-OP with the error flag, AL status code 0x001B [I]
        (see :class:`akdctl.sim.face_ethercat_raw.ProcessData`)."""
        with self._lock:
            if (self.al_status & 0x0F) == ec.AlState.OP:
                self._set_al(ec.AlState.SAFEOP | ec.AL_ERROR_FLAG, 0x001B)

    def follow_al_state(self, state: int) -> None:
        """Enter AL state ``state`` because the drive behind the ESC is in it (the application side).

        The face calls this when the drive model's AL state changed outside the
        master's AL control (another process, a test), so that AL status 0x0130
        always shows the one AL state the model acts on. Leaving for INIT clears
        the mailboxes as an AL-control transition to INIT does.
        """
        with self._lock:
            if (self.al_status & 0x0F) == state and not self.al_status & ec.AL_ERROR_FLAG:
                return
            if state == ec.AlState.INIT:
                self._clear_mailboxes()
            self._set_al(state, 0)

    def _check_mailbox_sms(self, boot: bool = False) -> int:
        """I -> P: SM0/SM1 must be the AKD's standard mailboxes (start address and a sane length);
        I -> B: the bootstrap mailboxes the SII declares (words 0x14-0x17), as SOEM's firm_update and
        pysoem's amend_mbx program them (reference foe-alias-recorder.md A2/A3)."""
        sii = self.sii
        if boot:
            rx_start, rx, tx_start, tx = sii.boot_rx_offset, sii.boot_rx_size, sii.boot_tx_offset, sii.boot_tx_size
        else:
            rx_start, rx, tx_start, tx = sii.std_rx_offset, sii.std_rx_size, sii.std_tx_offset, sii.std_tx_size
        rx = rx or self.mailbox_sizes[0]
        tx = tx or self.mailbox_sizes[1]
        sm0, sm1 = self.sync_manager(0), self.sync_manager(1)
        ok = (sm0.start == rx_start and MBX_MIN <= sm0.length <= rx and sm0.is_mailbox
              and sm0.writes_to_slave and sm0.enabled
              and sm1.start == tx_start and MBX_MIN <= sm1.length <= tx and sm1.is_mailbox
              and not sm1.writes_to_slave and sm1.enabled)
        return 0 if ok else 0x0017

    def _check_process_sms(self) -> int:
        """P -> S: process-data SMs, where enabled, at the AKD's addresses 0x1100/0x1140 and exactly as long
        as the assigned PDOs (issue 23 item 9: the manual's 0x0017 "invalid sync manager configuration"
        covers both; ETG.1000.6 SM checks do the same). :attr:`process_sizes` tells the lengths the drive's
        current mapping needs (rx bytes, tx bytes); without one (a bare ESC) only the addresses are checked.
        A disabled SM is not checked: a master that exchanges no process data may still go to SAFE-OP/OP
        (a real AKD then raises its fieldbus fault; the simulator does not)."""
        sizes = self.process_sizes() if self.process_sizes is not None else None
        for n, start in ((2, 0x1100), (3, 0x1140)):
            sm = self.sync_manager(n)
            if not sm.enabled:
                continue
            if sm.start != start or sm.is_mailbox:
                return 0x0017
            if sizes is not None and sm.length != sizes[n - 2]:
                return 0x0017
        return 0

    def _set_al(self, status: int, code: int) -> None:
        self._set_u16(ec.REG_AL_STATUS, status)
        self._set_u16(ec.REG_AL_STATUS_CODE, code)

    def _clear_mailboxes(self) -> None:
        self._requests.clear()
        self._replies.clear()
        self._quick.clear()
        self._owed = 0
        for i in range(NUM_SM):
            self._set_full(i, False)
            self._sm[i].last = b""

    # ------------------------------------------------------------------ mailbox application side
    def take_request(self, timeout: float) -> bytes | None:
        """The next mailbox the master wrote to SM0 (the PDI reading it empties SM0)."""
        with self._lock:
            if not self._requests:
                self._have_request.wait(timeout)
            if not self._requests:
                return None
            return self._taken(self._requests.popleft())

    def take_quick(self) -> bytes | None:
        """The next request :attr:`quick` picked (None: none waiting); answer it with :meth:`post_quick_replies`."""
        with self._lock:
            return self._taken(self._quick.popleft()) if self._quick else None

    def _taken(self, raw: bytes) -> bytes:
        """The PDI has read SM0: it is empty again; the mailbox without the buffer's tail."""
        for i, _start, _length, writes in self._mailboxes():
            if writes:
                self._set_full(i, False)
        length = struct.unpack_from("<H", raw)[0] if len(raw) >= 2 else 0
        return raw[: min(len(raw), 6 + length)]

    def post_replies(self, replies: list[bytes], drop: bool = False) -> None:
        """The application's replies to a request it took (none: it had none): queued for SM1; ``drop`` loses
        the frame that carries the first one to the master."""
        with self._lock:
            if self._owed:
                self._owed -= 1
            self._post(replies, drop)

    def post_quick_replies(self, replies: list[bytes], drop: bool = False) -> None:
        """:meth:`post_replies` for a request taken with :meth:`take_quick`."""
        with self._lock:
            self._post(replies, drop)

    def _post(self, replies: list[bytes], drop: bool) -> None:
        if not self._mailboxes_active():
            return
        if drop and replies:
            self.drop_next_reply = True
        self._replies.extend(replies)
        self._load_reply()

    def _load_reply(self) -> None:
        for i, start, length, writes in self._mailboxes():
            if not writes and length:
                if self._sm[i].full or not self._replies:
                    return
                reply = self._replies.popleft()[:length]
                self.mem[start : start + length] = reply.ljust(length, b"\0")
                self._set_full(i, True)
                return


def watchdog_seconds(esc: Esc) -> float | None:
    """The process-data watchdog time the master programmed (None: disabled -- time 0 or no SM with the
    watchdog bit). Units: (divider + 2) x 40 ns, as the ESC counts them."""
    divider = esc.u16(ec.REG_WD_DIVIDER)
    units = esc.u16(REG_WD_PD_TIME)
    if not units:
        return None
    armed = any(sm.enabled and not sm.is_mailbox and sm.writes_to_slave and sm.control & SM_CONTROL_WATCHDOG
                for sm in (esc.sync_manager(i) for i in range(NUM_SM)))
    return units * (divider + 2) * 40e-9 if armed else None
