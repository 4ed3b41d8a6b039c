"""`akdctl sim serve --ethercat-raw IFNAME`: a simulated AKD as an EtherCAT
slave on a raw interface (AF_PACKET, EtherType 0x88A4).

Frames from a master are processed by the simulated ESC (:mod:`akdctl.sim.esc`)
and sent back out of the same interface, as the last slave of a line closes
the ring. A worker thread plays the drive's application: it takes each mailbox
the master wrote to SM0, lets the drive's SDO server answer it and queues the
replies for SM1, so frames never wait for an SDO. Any EtherCAT master (pysoem,
TwinCAT, our own ``ecat://``) can run against it; on a veth pair this is how CI
tests interoperability.
"""

from __future__ import annotations

import contextlib
import socket
import threading
from typing import Any

from akdctl.io.raw_socket import open_raw_socket
from akdctl.protocol import ethercat as ec
from akdctl.protocol.errors import CodecError
from akdctl.protocol.sii import akd_sii_image
from akdctl.sim.drive import SimDrive
from akdctl.sim.ecat_inject import Injector, failure_reply, mailbox_error_reply, sdo_abort_reply, warm_up
from akdctl.sim.esc import Esc
from akdctl.sim.face import Face, FaceOption, request_failed
from akdctl.sim.pdo import AL_STATE_CODES


SIM_MAILBOX = 512


OPTIONS = (
    FaceOption("--ethercat-raw", "ethercat_raw", metavar="IFNAME",
               help="Be an EtherCAT slave (simulated AKD ESC) on this raw interface (needs CAP_NET_RAW)."),
    FaceOption("--ecat-raw-inject", "ecat_raw_inject", metavar="drop=N,mbxerr=N,abort=N",
               help="Raw slave fault injection: lose the frame carrying every N-th reply, "
                    "answer with a mailbox error or an SDO abort."),
    FaceOption("--ecat-serial", "ecat_serial", type=int, metavar="N",
               help="Serial number the raw slave's SII reports."),
)


class SlaveWorker:
    """The drive application behind the ESC's mailbox: SDO server + fault injection."""

    def __init__(self, esc: Esc, drive: SimDrive, injector: Injector) -> None:
        from akdctl.sim.mailbox_repeat import MailboxRepeats

        self.esc, self.drive, self.injector = esc, drive, injector
        self.repeats = MailboxRepeats()  # the ESC's one mailbox: a repeated counter is not executed twice
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="ecat-raw-app", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            request = self.esc.take_request(0.2)
            if request is None:
                continue
            try:
                self.esc.post_replies(*self.answer(request))
            except Exception as exc:  # noqa: BLE001 - the application must outlive any one mailbox
                request_failed("ethercat-raw", exc)

    def answer(self, request: bytes) -> tuple[list[bytes], bool]:
        """The replies to one mailbox and whether injection loses them; never raises."""
        fault = self.injector.decide()
        try:
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

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)


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


class EthercatRawFace(Face):
    def __init__(self, ifname: str, drive: SimDrive, injector: Injector, serial: int | None = None) -> None:
        self.ifname = ifname
        # Mailboxes of 512 bytes, the AKD ESI default (a real drive's SII says 1024): the simulated drive's SDO
        # server takes mailboxes up to 512 bytes, and a master sizes its requests from what the SII declares.
        image = sim_sii_image(serial, drive)
        self.esc = Esc(image)
        self.worker = SlaveWorker(self.esc, drive, injector)
        # A bare ESC (no drive model behind it, as the frame fuzzer builds it) keeps its AL state to itself.
        self.al = AlStateBinding(self.esc, drive) if drive is not None else None
        self.injector = injector
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def start(self) -> None:
        self._sock = open_raw_socket(self.ifname, ec.ETHERTYPE_ECAT, f"--ethercat-raw {self.ifname}")
        warm_up(self.worker.drive)
        self._sock.settimeout(0.2)
        self.worker.start()
        self._thread = threading.Thread(target=self._serve, name="ecat-raw-face", daemon=True)
        self._thread.start()

    def handle_frame(self, frame: bytes) -> bytes | None:
        """One received frame -> the frame to send back (None: not EtherCAT, or lost by injection)."""
        try:
            dst, src, datagrams = ec.decode_frame(frame)
        except CodecError:
            return None
        if src[0] & 0x02:
            return None  # already passed a slave's port 0 (our own echo on a shared segment)
        al = self.al if self.al is not None and self.al.touches(datagrams) else None
        if al is not None and not _synced(al.pull):
            al = None  # the ESC still answers the frame; the AL state is synced when the registers are next touched
        self.esc.process(datagrams)
        if al is not None:
            _synced(al.push)
        if self.esc.lost_frame:
            return None
        # an ESC sets bit 1 of the source MAC's first byte when the frame leaves port 0
        return ec.encode_frame(datagrams, src=bytes([src[0] | 0x02]) + src[1:], dst=dst)

    def _serve(self) -> None:
        assert self._sock is not None
        while not self._stop.is_set():
            try:
                frame = self._sock.recv(2048)
            except socket.timeout:
                continue
            except OSError:
                break
            try:
                reply = self.handle_frame(frame)
            except Exception as exc:  # noqa: BLE001 - a frame that breaks the ESC is lost, as on a wire
                request_failed("ethercat-raw", exc)
                reply = None
            if reply is not None:
                with contextlib.suppress(OSError):
                    self._sock.send(reply)

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        self.worker.stop()
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
    return EthercatRawFace(str(ifname), drive, injector, int(serial) if serial is not None else None)  # type: ignore[arg-type]


def sim_sii_image(serial: int | None = None, drive: object = None) -> Any:
    """The raw slave's SII: order code and firmware from the drive's one identity record (issue 23.8), the serial
    the drive reports in 0x1018:4 (``--ecat-serial`` overrides it for a bus of several simulated slaves)."""
    from akdctl.sim import identity

    return akd_sii_image(mailbox_size=SIM_MAILBOX, serial=serial if serial is not None else identity.serial_of(drive),
                         revision=identity.COE_REVISION, order=identity.ORDER_CODE, firmware=identity.FIRMWARE)
