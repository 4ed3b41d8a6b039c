"""`akdctl sim serve --ethercat-raw IFNAME`: a simulated AKD as an EtherCAT
slave on a raw interface (AF_PACKET, EtherType 0x88A4).

Frames from a master are processed by the simulated ESC (:mod:`akdctl.sim.esc`)
and sent back out of the same interface, as the last slave of a line closes
the ring. A worker thread plays the drive's application: it takes each mailbox
the master wrote to SM0, lets the drive's SDO server answer it and queues the
replies for SM1, so frames never wait for a write, an FoE transfer or an SDO
information request. SDO uploads are answered by the frame thread itself,
right after the frame that brought them has gone back (:func:`quick_request`):
a read costs the drive tens of microseconds, while handing it to another thread
cost a thread wake-up and a GIL hand-off per request (server CPU per upload
about halved, context switches from ~9 to ~2.5 per upload), and the master's
next poll finds the reply instead of an empty SM1. Any EtherCAT master (pysoem,
TwinCAT, our own ``ecat://``) can run against it; on a veth pair this is how CI
tests interoperability.
"""

from __future__ import annotations

import contextlib
import dataclasses
import socket
import struct
import threading
import time
from typing import Any

from akdctl.io.raw_socket import open_raw_socket
from akdctl.protocol import coe, ethercat as ec, mailbox as mbx
from akdctl.protocol.errors import CodecError
from akdctl.protocol.mailbox import ERR_UNSUPPORTED_PROTOCOL, MailboxType
from akdctl.protocol.sii import SiiImage, akd_sii_image
from akdctl.sim.drive import SimDrive
from akdctl.sim.ecat_inject import Injector, failure_reply, mailbox_error_reply, sdo_abort_reply, warm_up
from akdctl.sim.esc import Esc, watchdog_seconds
from akdctl.sim.face import Face, FaceOption, request_failed
from akdctl.sim.pdo import AL_STATE_CODES, apply_outputs, image_size, sample_inputs


SIM_MAILBOX = 512

#: FBUS.PARAM03, the AKD's configured station alias (seed 001 5.14; reference foe-alias-recorder.md B).
ALIAS_OBJECT = 0x36E7

#: Mailbox protocols the simulated slave advertises in SII word 0x1C: CoE and FoE. The real AKD's SII (and its
#: ESI's <EoE>) advertise EoE as well (0x0E); the simulator does not implement EoE -- the AKD EtherCAT manual
#: itself lists type 2 as "Reserved: Ethernet over EtherCAT" (seed 001, mailbox header byte 5) -- so it does
#: not advertise it, and answers an EoE mailbox "unsupported protocol" (issue 23 item 9; docs/fidelity.md F10).
SIM_MAILBOX_PROTOCOLS = 0x000C

#: Seconds the simulated drive is silent after BOOT -> INIT, while it "restarts" with the downloaded file
#: [I]: the real AKD's restart time is not published; its ESI allows 50 s for back-to-INIT.
REBOOT_SECONDS = 1.0

#: FBUS.PARAM04, synchronization supervision (seed 001 5.14), and the frames it may miss.
SYNC_SUPERVISION = 0x36E8
SYNC_LOST_FRAMES = 7

#: How often the application copies process data between the ESC and the drive model (free run), seconds.
CYCLE_SECONDS = 0.004


OPTIONS = (
    FaceOption("--ethercat-raw", "ethercat_raw", metavar="IFNAME",
               help="Be an EtherCAT slave (simulated AKD ESC) on this raw interface (needs CAP_NET_RAW)."),
    FaceOption("--ecat-raw-inject", "ecat_raw_inject", metavar="drop=N,mbxerr=N,abort=N",
               help="Raw slave fault injection: lose the frame carrying every N-th reply, "
                    "answer with a mailbox error or an SDO abort."),
    FaceOption("--ecat-serial", "ecat_serial", type=int, metavar="N",
               help="Serial number the raw slave's SII reports."),
    FaceOption("--ecat-foe-busy", "ecat_foe_busy", type=int, metavar="N",
               help="In BOOT, answer each FoE data packet N times with BUSY before taking it (a drive busy flashing)."),
)


class SlaveWorker:
    """The drive application behind the ESC's mailbox: SDO server + fault injection (run on a thread of its
    face, :meth:`serve`, until the face stops).

    ``foe_busy``: in BOOT, each FoE DATA packet is answered that many times with BUSY (done/entire = the
    packets so far) before the drive takes it -- ETG.1000.6's way for a slave that is still flashing; a master
    must send the same packet again (SOEM, IgH and akdctl do). Off by default: whether and when the AKD answers
    BUSY is not public [I]."""

    def __init__(self, esc: Esc, drive: SimDrive, injector: Injector, foe_busy: int = 0) -> None:
        from akdctl.sim.mailbox_repeat import MailboxRepeats

        self.esc, self.drive, self.injector = esc, drive, injector
        self.repeats = MailboxRepeats()  # the ESC's one mailbox: a repeated counter is not executed twice
        self.foe_busy = max(0, foe_busy)
        self._busy_left: tuple[int, int] | None = None  # (packet number, BUSY answers still to give)

    def serve(self, stop: threading.Event) -> None:
        while not stop.is_set():
            request = self.esc.take_request(0.2)
            if request is None:
                continue
            replies: tuple[list[bytes], bool] = ([], False)
            try:
                replies = self.answer(request)
            except Exception as exc:  # noqa: BLE001 - the application must outlive any one mailbox
                request_failed("ethercat-raw", exc)
            self.esc.post_replies(*replies)  # even none: the ESC counts the request as answered

    def answer_quick(self) -> None:
        """Answer the requests the ESC left to the frame thread (:func:`quick_request`), in their order."""
        esc = self.esc
        while (request := esc.take_quick()) is not None:
            try:
                esc.post_quick_replies(*self.answer(request))
            except Exception as exc:  # noqa: BLE001 - the slave must outlive any one mailbox
                request_failed("ethercat-raw", exc)

    def answer(self, request: bytes) -> tuple[list[bytes], bool]:
        """The replies to one mailbox and whether injection loses them; never raises."""
        fault = self.injector.decide()
        try:
            if (self.esc.al_status & 0x0F) == ec.AlState.BOOT and not _is_foe(request):
                # In BOOT only FoE is available (reference foe-alias-recorder.md A1: KAS help "Bootstrap ...
                # Only FoE protocol available"): anything else is a mailbox protocol the state does not serve.
                return [mailbox_error_reply(request, ERR_UNSUPPORTED_PROTOCOL)], False
            busy = self._busy(request)
            if busy is not None:
                return [busy], False
            if fault == "mbxerr":
                return [mailbox_error_reply(request)], False
            if fault == "abort" and (abort := sdo_abort_reply(request)) is not None:
                return [abort], False
            return self.repeats.answer("sm0", request, self.drive.handle_mailbox), fault == "drop"
        except CodecError:
            with contextlib.suppress(CodecError):
                return [mailbox_error_reply(request, 1)], False  # syntax of the mailbox protocol header wrong
            return [], False
        except Exception as exc:  # noqa: BLE001 - the slave must keep running; the master sees an abort
            request_failed("ethercat-raw", exc)
            return failure_reply(request), False

    def _busy(self, request: bytes) -> bytes | None:
        """A BUSY reply to a FoE DATA packet in BOOT while this packet's BUSY answers last, else None."""
        if not self.foe_busy or (self.esc.al_status & 0x0F) != ec.AlState.BOOT or not _is_foe(request):
            return None
        from akdctl.protocol import foe
        from akdctl.protocol import mailbox as mbx

        _type, counter, address, data = mbx.split(request)
        frame = foe.decode_foe(data)
        if frame.opcode != foe.FoeOpcode.DATA:
            return None
        number, left = self._busy_left if self._busy_left and self._busy_left[0] == frame.value else (
            frame.value, self.foe_busy)
        if left <= 0:
            self._busy_left = None
            return None
        self._busy_left = (number, left - 1)
        return mbx.pack(mbx.MailboxType.FOE, foe.encode_foe(foe.busy(number - 1, number)), address, counter)


class AlStateBinding:
    """Keeps the ESC's AL state and the drive model's AL state one state.

    Why: the master drives the AL state through the ESC's registers, but the
    model's rules depend on it (PDO mapping only in PRE-OP, SPEC-NOTES 18; an SDO
    controlword has no effect in OP while the controlword is mapped in an assigned
    RxPDO, SPEC-NOTES 23). A transition the master makes is written to the model;
    a change made to the model from elsewhere (another process, ``sim`` commands,
    a test) is shown in AL status 0x0130 before the master reads it. Only frames
    that touch the AL registers (0x0120-0x0135) cost a model transaction.

    At power-on the slave is in INIT, so building the binding puts the model in
    INIT; :meth:`leave_bus` returns it to PRE-OP when the face stops (no master,
    no process data: the state the in-process links assume).
    """

    FIRST, LAST = ec.REG_AL_CONTROL, ec.REG_AL_STATUS_CODE + 1

    def __init__(self, esc: Esc, drive: SimDrive) -> None:
        self.esc, self.drive = esc, drive
        self.known = esc.al_status & 0x0F
        self._write_model(self.known)

    def touches(self, datagrams: list[ec.Datagram]) -> bool:
        return any(d.ado <= self.LAST and self.FIRST <= d.ado + len(d.data) for d in datagrams)

    def pull(self) -> None:
        """Model -> ESC, when someone other than the master changed the model's AL state."""
        with self.drive.transaction() as model:
            name = model.pdo.al_state
        state = AL_STATE_CODES[name]
        if state != self.known:
            self.esc.follow_al_state(state)
            self.known = state

    def push(self) -> None:
        """ESC -> model, when the master's AL control moved the ESC."""
        state = self.esc.al_status & 0x0F
        if state != self.known and state in AL_STATE_CODES.values():
            self._write_model(state)
            self.known = state

    def leave_bus(self) -> None:
        self._write_model(ec.AlState.PREOP)
        self.known = ec.AlState.PREOP

    def _write_model(self, state: int) -> None:
        with self.drive.transaction() as model:
            model.pdo.set_al_state(state)


def quick_request(raw: bytes) -> bool:
    """Whether the frame thread answers this SM0 buffer itself: a CoE SDO upload (initiate or segment), which
    the drive answers from its model in memory. Writes (they may save the state file), FoE and SDO information
    go to the application thread, so no frame waits for them. The cost: a frame arriving while a read is
    answered waits for it (tens of microseconds; longer only while another process holds the drive's lock)."""
    try:
        mtype, _counter, _address, data = mbx.split(raw)
    except CodecError:
        return False
    return mtype == MailboxType.COE and coe.is_upload_request(data)


def _is_foe(request: bytes) -> bool:
    return len(request) >= 6 and request[5] & 0x0F == MailboxType.FOE


class ProcessData:
    """The drive's cyclic task behind SM2/SM3: outputs into the model in OP, inputs out of it in SAFE-OP/OP,
    and the SM watchdog.

    Why a free-running thread and not per frame: a real slave's application runs on its own cycle and the
    ESC's buffered sync managers decouple it from the master's frames; a frame never waits for the model.
    The watchdog: in OP, with the output SM's watchdog bit set and a non-zero time (0x0400/0x0420), no
    output write for that long takes the slave to SAFE-OP + ERROR with AL status code 0x001B "sync manager
    watchdog" (ETG.1000.6 code) [I]: SPEC-NOTES 22 lists the codes the manual names for the AKD, and this
    one is not among them; the manual does not say which code the AKD reports on a watchdog.
    """

    def __init__(self, esc: Esc, drive: SimDrive, on_watchdog: Any) -> None:
        self.esc, self.drive, self.on_watchdog = esc, drive, on_watchdog
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.cycles = 0
        self.expired = 0
        self.f125 = 0
        self.interval: float | None = None  # observed period of the master's output frames, seconds
        self.sync_lost = False
        self._fresh_at = 0.0
        self._served = -1

    def start(self) -> None:
        """Run on a thread of its own (tests; the face runs :meth:`serve` on one of its threads instead)."""
        self._thread = threading.Thread(target=self.serve, args=(self._stop,), name="ecat-raw-pd", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)

    def serve(self, stop: threading.Event) -> None:
        """The cyclic task, every :data:`CYCLE_SECONDS` until ``stop`` is set."""
        seen, last = -1, time.monotonic()
        said = ""
        while not stop.wait(CYCLE_SECONDS):
            state = self.esc.al_status & 0x0F
            if state not in (ec.AlState.SAFEOP, ec.AlState.OP) or self.esc.al_status & ec.AL_ERROR_FLAG:
                seen, last = self.esc.outputs_written, time.monotonic()
                self.interval, self._fresh_at = None, 0.0  # a new OP measures the master's period anew
                continue
            try:
                seen, last = self.cycle(state, seen, last)
                said = ""
            except Exception as exc:  # noqa: BLE001 - the cyclic task must outlive one bad cycle
                if str(exc) != said:  # once per cause, not every 4 ms
                    said = str(exc)
                    request_failed("ethercat-raw", exc)

    def cycle(self, state: int, seen: int, last: float) -> tuple[int, float]:
        """One application cycle; (outputs frames seen, time of the last fresh output frame).

        The model is touched only when a master exchanged process data since the last cycle, so a master that
        died does not keep the drive's own watchdog fed (docs/fidelity.md F4)."""
        now = time.monotonic()
        written, served = self.esc.outputs_written, self.esc.inputs_read
        fresh = written != seen
        if fresh:
            if self._fresh_at:
                gap = now - self._fresh_at
                self.interval = gap if self.interval is None else 0.8 * self.interval + 0.2 * gap
            self._fresh_at = now
            self.sync_lost = False
        if state == ec.AlState.OP and not fresh:
            limit = watchdog_seconds(self.esc)
            if limit is not None and now - last > limit:
                self.expired += 1
                self.on_watchdog()
                return written, now
            if self.interval is not None and not self.sync_lost and \
                    now - last > max(SYNC_LOST_FRAMES * self.interval, 3 * CYCLE_SECONDS):
                self.sync_lost = True
                self._supervise_sync()
        if not fresh and served == self._served:
            return written, last
        self._served = served
        outputs = self.esc.process_image(write=True) if state == ec.AlState.OP and fresh else None
        with self.drive.transaction() as model:
            if outputs:
                apply_outputs(model, outputs)
            inputs = sample_inputs(model)
        self.esc.set_inputs(inputs)
        self.cycles += 1
        return written, (now if fresh else last)

    def _supervise_sync(self) -> None:
        """Seed 001 5.14: with FBUS.PARAM04 = 1, "when more than ... seven EtherCAT frames have not been received
        and the drive is enabled, fault F125 ("Synchronization lost") occurs". The frame period is the one
        observed (an average, at the application cycle's 4 ms resolution) [I: the drive's own measure is not
        described]."""
        with self.drive.transaction() as model:
            supervised = int.from_bytes(model.object_read(SYNC_SUPERVISION, 0), "little") == 1
            if supervised and model.object_value(0x6041, 0) & 0x6F == 0x27:
                model.faults.raise_fault("F125")
                self.f125 += 1


class EthercatRawFace(Face):
    def __init__(self, ifname: str, drive: SimDrive, injector: Injector, serial: int | None = None,
                 foe_busy: int = 0) -> None:
        super().__init__()
        self.ifname = ifname
        self.serial = serial
        self.drive = drive
        self.esc = Esc(self._sii_image())
        self.worker = SlaveWorker(self.esc, drive, injector, foe_busy)
        # A bare ESC (no drive model behind it, as the frame fuzzer builds it) keeps its AL state to itself.
        self.al = AlStateBinding(self.esc, drive) if drive is not None else None
        self.injector = injector
        self._sizes: tuple[int, int] = (0, 0)  # (RxPDO, TxPDO) bytes, read when the AL registers are touched
        self.esc.process_sizes = lambda: self._sizes
        self.pd = ProcessData(self.esc, drive, self._watchdog_expired) if drive is not None else None
        self._silent_until = 0.0  # the drive restarts after BOOT -> INIT: no frame is answered until then
        self._sock: socket.socket | None = None

    def open(self) -> None:
        # Its own replies are not handed back (one wake-up and one receive per frame less); on a kernel that
        # ignores the request the PACKET_OUTGOING check in _serve drops them.
        self._sock = open_raw_socket(self.ifname, ec.ETHERTYPE_ECAT, f"--ethercat-raw {self.ifname}",
                                     ignore_outgoing=True)
        self.esc.quick = quick_request  # _serve answers uploads after each frame (SlaveWorker.answer_quick)
        warm_up(self.worker.drive)
        self._sock.settimeout(0.2)
        self.spawn(self.worker.serve, "ecat-raw-app", self._stop)
        if self.pd is not None:
            self.spawn(self.pd.serve, "ecat-raw-pd", self._stop)
        self.spawn(self._serve, "ecat-raw-face")

    def _sii_image(self) -> SiiImage:
        """The SII the ESC powers up with: the AKD's, without EoE (:data:`SIM_MAILBOX_PROTOCOLS`), with the
        configured station alias the drive keeps (FBUS.PARAM03, CoE 0x36E7: an alias written to SII word 4
        is kept there, seed 001 5.14) -- so the alias survives a power cycle (``sim serve`` restarted)."""
        # Mailboxes of 512 bytes, the AKD ESI default (a real drive's SII says 1024): the simulated drive's SDO
        # server takes mailboxes up to 512 bytes, and a master sizes its requests from what the SII declares.
        image = sim_sii_image(self.serial, self.drive)  # the one identity record (issue 23.8)
        image = dataclasses.replace(image, mailbox_protocols=SIM_MAILBOX_PROTOCOLS)
        if self.drive is not None:
            with contextlib.suppress(Exception):
                with self.drive.transaction() as model:
                    alias = int.from_bytes(model.object_read(ALIAS_OBJECT, 0), "little") & 0xFFFF
                image = dataclasses.replace(image, station_alias=alias)
        return image

    def power_cycle(self) -> None:
        """The drive restarts: the ESC powers up again from its EEPROM (register 0x0012 takes word 4 now)."""
        eeprom = bytes(self.esc.eeprom)
        self.esc.reset()
        self.esc.eeprom[:] = eeprom
        self.esc.reset()  # load 0x0012 (and the CRC verdict) from the kept EEPROM
        if self.al is not None:
            self.al.known = -1
            _synced(lambda: self.al.push() if self.al is not None else None)

    def _watchdog_expired(self) -> None:
        self.esc.watchdog_expired()
        if self.al is not None:
            _synced(self.al.push)

    def _eeprom_written(self, words: list[int]) -> None:
        """SII word 4 written: the AKD takes it as its configured station alias (FBUS.PARAM03) and saves its
        parameters (seed 001 5.14: "forces the AKD to store the drive parameters automatically using
        DRV.NVSAVE"; the simulator keeps every parameter anyway). Register 0x0012 follows at the next power-on."""
        if 4 not in words or self.drive is None:
            return
        alias = struct.unpack_from("<H", self.esc.eeprom, 8)[0]

        def write() -> None:
            with self.drive.transaction() as model:
                model.object_write(ALIAS_OBJECT, 0, alias.to_bytes(4, "little"))
        _synced(write)

    def handle_frame(self, frame: bytes) -> bytes | None:
        """One received frame -> the frame to send back (None: not EtherCAT, lost by injection, or the drive
        restarting). Any source MAC is served: EtherCAT slaves do not filter on it (SOEM's, IgH's and many
        masters' locally administered addresses included); our own replies are told apart by the socket."""
        if self._silent_until:
            if time.monotonic() < self._silent_until:
                return None
            self._silent_until = 0.0
            self.power_cycle()
        try:
            dst, src, datagrams = ec.decode_frame(frame)
        except CodecError:
            return None
        al = self.al if self.al is not None and self.al.touches(datagrams) else None
        if al is not None:
            if not _synced(al.pull):
                al = None  # the ESC still answers; the AL state is synced when the registers are next touched
            elif any(d.cmd in ec.WRITE_CMDS | ec.READWRITE_CMDS and d.ado <= ec.REG_AL_CONTROL + 1
                     and ec.REG_AL_CONTROL < d.ado + len(d.data) for d in datagrams):
                _synced(self._update_sizes)  # an AL control write: P -> S checks the SM lengths against these
        before = self.esc.al_status & 0x0F
        self.esc.process(datagrams)
        if al is not None:
            _synced(al.push)
        if self.esc.eeprom_writes:
            words, self.esc.eeprom_writes = self.esc.eeprom_writes, []
            self._eeprom_written(words)
        if before == ec.AlState.BOOT and (self.esc.al_status & 0x0F) == ec.AlState.INIT:
            self._silent_until = time.monotonic() + REBOOT_SECONDS  # this frame is answered, then the restart
        if self.esc.lost_frame:
            return None
        # an ESC sets bit 1 of the source MAC's first byte when the frame leaves port 0
        return ec.encode_frame(datagrams, src=bytes([src[0] | 0x02]) + src[1:], dst=dst)

    def _update_sizes(self) -> None:
        if self.drive is not None:
            with self.drive.transaction() as model:
                self._sizes = (image_size(model, "rx"), image_size(model, "tx"))

    def _serve(self) -> None:
        assert self._sock is not None
        while not self._stop.is_set():
            try:
                frame, address = self._sock.recvfrom(2048)
            except socket.timeout:
                continue
            except OSError:
                break
            if len(address) > 2 and address[2] == socket.PACKET_OUTGOING:
                continue  # our own reply, seen on the way out
            try:
                reply = self.handle_frame(frame)
            except Exception as exc:  # noqa: BLE001 - a frame that breaks the ESC is lost, as on a wire
                request_failed("ethercat-raw", exc)
                reply = None
            if reply is not None:
                with contextlib.suppress(OSError):
                    self._sock.send(reply)
            self.worker.answer_quick()

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None
        if self.al is not None:
            self.al.leave_bus()

    def describe(self) -> str:
        inject = self.injector.describe()
        extra = f" inject {inject}" if inject != "none" else ""
        return f"ethercat-raw {self.ifname} slave AKD serial {self.esc.sii.serial}{extra}"


def _synced(step: object) -> bool:
    """Run one AL-state sync step with the drive model; a failing model (its state file locked) costs the sync, not
    the frame."""
    try:
        step()  # type: ignore[operator]
        return True
    except Exception as exc:  # noqa: BLE001
        request_failed("ethercat-raw", exc)
        return False


def from_options(drive: SimDrive, **kwargs: object) -> EthercatRawFace | None:
    ifname = kwargs.get("ethercat_raw")
    if not ifname:
        return None
    injector = Injector.parse(kwargs.get("ecat_raw_inject") or None, "--ecat-raw-inject")  # type: ignore[arg-type]
    serial = kwargs.get("ecat_serial")
    busy = kwargs.get("ecat_foe_busy")
    return EthercatRawFace(str(ifname), drive, injector, int(serial) if serial is not None else None,  # type: ignore[call-overload]
                           int(busy) if busy else 0)  # type: ignore[call-overload]


def sim_sii_image(serial: int | None = None, drive: object = None) -> SiiImage:
    """The raw slave's SII: order code and firmware from the drive's one identity record (issue 23.8), the serial
    the drive reports in 0x1018:4 (``--ecat-serial`` overrides it for a bus of several simulated slaves)."""
    from akdctl.sim import identity

    return akd_sii_image(mailbox_size=SIM_MAILBOX, serial=serial if serial is not None else identity.serial_of(drive),
                         revision=identity.COE_REVISION, order=identity.ORDER_CODE, firmware=identity.FIRMWARE)
