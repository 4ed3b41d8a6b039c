"""``akdctl sim serve --can INTERFACE:CHANNEL[:NODE]``: the simulated AKD as a CANopen node.

The node is a ``canopen.LocalNode`` on a python-can bus whose object reads and
writes go straight to :class:`~akdctl.sim.drive.SimDrive` (so the CLI's
``sim://`` target and the bus see one drive). On top of canopen it adds what a
drive does and canopen's LocalNode leaves to the application:

* NMT slave: boot-up message on start and after reset node / reset
  communication, start/stop/pre-operational; SDO is silent in STOPPED, PDOs run
  only in OPERATIONAL (CiA 301 7.3.2);
* heartbeat producer with the period of 0x1017 (re-read when it is written),
  node guarding replies (remote frame on 0x700 + node, state with toggle bit);
* EMCY (0x80 + node) for every emergency the drive model raises;
* TPDO/RPDO exchange per 0x1400/0x1600/0x1800/0x1A00 (:mod:`akdctl.sim.can_pdo`),
  synchronous (SYNC 0x080) and event-driven (change or event timer);
* SDO block transfer (:mod:`akdctl.sim.can_sdo`).

Spec syntax (``--can``)
-----------------------
``INTERFACE:CHANNEL[:NODE][?KEY=VALUE&...]`` -- a python-can interface, its
channel, the node id (default 1) and bus keyword arguments typed as in
``can://`` targets.  Examples: ``udp_multicast:239.74.163.2:1?port=43114``,
``socketcan:vcan0:5``, ``virtual:bench:1``.  An IPv6 channel goes in brackets:
``udp_multicast:[ff15:7079:7468:6f6e:6465:6d6f:6d63:6173]:1``.
``slcan-pty:LINK[:NODE]`` plays an slcan USB adapter on a new pseudo-terminal
(:mod:`akdctl.sim.slcan_device`); LINK is a symlink to create to it, or ``-``.
The ready line names the tty, e.g. ``listening: can slcan-pty /dev/pts/7 node 1``;
connect with ``can://slcan//dev/pts/7/1?sleep_after_open=0``.
"""

from __future__ import annotations

import struct
import threading
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qsl

from akdctl.errors import UsageError
from akdctl.io.canbus import NOTIFIER_CYCLE_S, BusConfig, close_bus, open_bus
from akdctl.sim.face import Face, FaceOption, request_failed

if TYPE_CHECKING:
    import can
    import canopen

    from akdctl.sim.drive import SimDrive

POLL = 0.05  # worker period: emergencies, event-driven TPDOs, event timers
SLCAN_PTY = "slcan-pty"


@dataclass(frozen=True)
class CanSpec:
    """A parsed ``--can`` value."""

    interface: str
    channel: str | None
    node: int = 1
    kwargs: dict[str, Any] = field(default_factory=dict)


def parse_spec(text: str) -> CanSpec:
    """Parse ``INTERFACE:CHANNEL[:NODE][?k=v&...]``; raises UsageError with the syntax."""
    syntax = "expected --can INTERFACE:CHANNEL[:NODE][?KEY=VALUE...], e.g. udp_multicast:239.74.163.2:1"
    body, _, query = text.strip().partition("?")
    interface, sep, rest = body.partition(":")
    if not interface or not sep or not rest:
        raise UsageError(f"--can {text!r}: {syntax}")
    node_text = ""
    if rest.startswith("["):
        channel, close, tail = rest[1:].partition("]")
        if not close or (tail and not tail.startswith(":")):
            raise UsageError(f"--can {text!r}: unclosed [ in the channel; {syntax}")
        node_text = tail[1:]
    else:
        channel, _, node_text = rest.rpartition(":") if rest.count(":") == 1 else (rest, "", "")
        if ":" in rest and rest.count(":") > 1:
            raise UsageError(f"--can {text!r}: put an IPv6 channel in brackets, e.g. udp_multicast:[ff15::1]:1")
    node = 1
    if node_text:
        try:
            node = int(node_text, 0)
        except ValueError:
            raise UsageError(f"--can {text!r}: node {node_text!r} is not a number") from None
    if not 1 <= node <= 127:
        raise UsageError(f"--can {text!r}: CANopen node id {node} is outside 1..127")
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError:
        raise UsageError(f"--can {text!r}: bad option string {query!r}") from None
    from can.util import cast_from_string

    kwargs = {key: cast_from_string(value) for key, value in pairs}
    return CanSpec(interface.lower(), None if channel in ("", "-") else channel, node, kwargs)


OPTIONS = (
    FaceOption("--can", "can_spec", metavar="INTERFACE:CHANNEL[:NODE]",
               help="Put the drive on a CAN bus as a CANopen node (python-can interface; "
                    "slcan-pty:LINK plays an slcan adapter on a pseudo-terminal). udp_multicast listens on all "
                    "interfaces and sends through the default route: the node is reachable from the LAN "
                    "(use virtual, slcan-pty or a vcan interface to stay on this machine)."),
    FaceOption("--can-heartbeat", "can_heartbeat", type=int, range=(0, 65535), metavar="MS",
               help="Set the node's heartbeat producer time (0x1017) before going on the bus."),
)


def from_options(drive: "SimDrive", **kwargs: Any) -> "CanFace | None":
    spec = kwargs.get("can_spec") or kwargs.get("can")
    if not spec:
        return None
    return CanFace(drive, parse_spec(str(spec)), heartbeat_ms=kwargs.get("can_heartbeat"))


def _open_face_bus(spec: CanSpec) -> "can.BusABC":
    if spec.interface == SLCAN_PTY:
        from akdctl.sim.slcan_device import SlcanDeviceBus

        return SlcanDeviceBus(link=spec.channel)

    return open_bus(BusConfig(spec.interface, spec.channel, dict(spec.kwargs)))


class CanFace(Face):
    """The CANopen face: one node on one bus, started and stopped by ``sim serve``."""

    def __init__(self, drive: "SimDrive", spec: CanSpec, heartbeat_ms: int | None = None) -> None:
        super().__init__()
        self.drive = drive
        self.spec = spec
        self.heartbeat_ms = heartbeat_ms
        self.bus: "can.BusABC | None" = None
        self.network: "canopen.Network | None" = None
        self.node: Any = None
        self._pdo_dirty = True
        self._tpdos: list[Any] = []
        self._rpdos: dict[int, Any] = {}
        self._guard_toggle = 0
        self._lock = threading.RLock()

    # -- life cycle (Face: start, stop) --------------------------------------------------------------------------
    def open(self) -> None:
        import canopen

        if self.heartbeat_ms is not None:
            self.drive.object_write(0x1017, 0, struct.pack("<H", self.heartbeat_ms))
        self.bus = _open_face_bus(self.spec)
        self.network = canopen.Network(self.bus)
        self.network.NOTIFIER_CYCLE = NOTIFIER_CYCLE_S
        self.network.listeners.append(_RemoteFrameListener(self))
        self.network.connect()
        self.node = _make_node(self)
        self.network[self.node.id] = self.node
        self.network.subscribe(0x080, self._on_sync)
        self.node.nmt.boot()
        self.spawn(self._work, "akdctl-can-face")

    def close(self) -> None:
        if self.node is not None:
            try:
                self.node.nmt.stop_heartbeat()
            except Exception:
                pass
        network, bus = self.network, self.bus
        self.network = self.bus = None
        close_bus(network, bus)

    def warnings(self) -> list[str]:
        """What the chosen bus means beyond this process: the LAN for udp_multicast, nothing for virtual."""
        if self.spec.interface == "virtual":
            return [f"--can {self.spec.interface}: python-can's virtual bus exists only inside this process, so no "
                    "other process (akdctl -T can://virtual/..., candump) can reach this node; use slcan-pty or a vcan "
                    "interface (socketcan) to reach it from other processes"]
        if self.spec.interface != "udp_multicast":
            return []
        return [f"--can {self.spec.interface}: python-can's udp_multicast listens on all interfaces and sends "
                "through the default route, so this CAN bus is reachable from the LAN; use virtual, slcan-pty "
                "or a vcan interface to keep it on this machine"]

    def describe(self) -> str:
        spec = self.spec
        if spec.interface == SLCAN_PTY and self.bus is not None:
            where = getattr(self.bus, "tty_path", "?")
        else:
            where = spec.channel or "default channel"
        opts = "".join(f" {k}={v}" for k, v in spec.kwargs.items())
        return f"can {spec.interface} {where} node {spec.node}{opts}"

    # -- NMT hooks --------------------------------------------------------------------------------------------
    @property
    def state(self) -> int:
        return self.node.nmt._state if self.node is not None else 0

    def heartbeat_time(self) -> int:
        try:
            return int.from_bytes(self.drive.object_read(0x1017, 0), "little")
        except Exception as exc:  # noqa: BLE001 - no heartbeat rather than no node
            request_failed("can", exc)
            return 0

    def on_state(self, state: int) -> None:
        if state == 5:
            self._pdo_dirty = True

    def on_written(self, index: int, subindex: int, data: bytes) -> None:
        if index == 0x1017:
            self.node.nmt.start_heartbeat(int.from_bytes(bytes(data[:2]).ljust(2, b"\0"), "little"))
        if 0x1400 <= index <= 0x1BFF:
            self._pdo_dirty = True

    def on_guard_request(self) -> None:
        """Node guarding: answer a remote frame on 0x700 + node with the state and a toggle bit."""
        if self.network is None:
            return
        byte = (self.state & 0x7F) | self._guard_toggle
        self._guard_toggle ^= 0x80
        self.network.send_message(0x700 + self.spec.node, bytes([byte]))

    # -- PDOs, emergencies ------------------------------------------------------------------------------------
    def _reload_pdos(self, model: Any) -> None:
        from akdctl.sim import can_pdo

        node = self.spec.node
        self._tpdos = can_pdo.read_configs(model, node, transmit=True)
        rpdos = {c.cob_id: c for c in can_pdo.read_configs(model, node, transmit=False)}
        network = self.network
        if network is not None:
            for cob in set(self._rpdos) - set(rpdos):
                network.unsubscribe(cob, self._on_rpdo)
            for cob in set(rpdos) - set(self._rpdos):
                network.subscribe(cob, self._on_rpdo)
        self._rpdos = rpdos
        self._pdo_dirty = False

    def _on_rpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        from akdctl.sim import can_pdo

        config = self._rpdos.get(can_id)
        if config is None or self.state != 5:
            return
        try:
            with self._lock, self.drive.transaction() as model:
                ok = can_pdo.unpack(model, config, bytes(data))
        except Exception as exc:  # noqa: BLE001 - a PDO the drive could not take is lost, as on a busy node
            request_failed("can", exc)
            return
        if not ok and self.node is not None:
            self.node.emcy.send(0x8210, 0x10)  # PDO not processed due to length error

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self.state != 5:
            return
        try:
            out = self._sync_pdos()
        except Exception as exc:  # noqa: BLE001 - no TPDOs this SYNC; the next one tries again
            request_failed("can", exc)
            return
        for config, payload in out:
            self._send_pdo(config, payload)

    def _sync_pdos(self) -> list[tuple[Any, bytes]]:
        """The synchronous TPDOs due at this SYNC, with their payloads."""
        with self._lock, self.drive.transaction() as model:
            if self._pdo_dirty:
                self._reload_pdos(model)
            from akdctl.sim import can_pdo

            out = []
            for config in self._tpdos:
                if 1 <= config.transmission <= 240:
                    config.sync_count += 1
                    if config.sync_count >= config.transmission:
                        config.sync_count = 0
                        out.append((config, can_pdo.pack(model, config)))
                elif config.transmission == 0:
                    payload = can_pdo.pack(model, config)
                    if payload != config.last:
                        out.append((config, payload))
        return out

    def _send_pdo(self, config: Any, payload: bytes) -> None:
        config.last = payload
        if self.network is not None:
            self.network.send_message(config.cob_id, payload)

    def _work(self) -> None:
        """Poll the drive: emergencies always, event-driven TPDOs in OPERATIONAL."""
        from akdctl.sim import can_pdo

        while not self._stop.wait(POLL):
            try:
                if self.node is not None:
                    self.node.sdo.expire()
                self._send_emergencies()
                if self.state != 5:
                    continue
                now = time.monotonic()
                out = []
                with self._lock, self.drive.transaction() as model:
                    if self._pdo_dirty:
                        self._reload_pdos(model)
                    for config in self._tpdos:
                        if config.transmission < 254:
                            continue
                        payload = can_pdo.pack(model, config)
                        timer = config.event_ms > 0 and now >= config.next_event
                        if payload != config.last or timer:
                            if config.event_ms:
                                config.next_event = now + config.event_ms / 1000.0
                            out.append((config, payload))
                for config, payload in out:
                    self._send_pdo(config, payload)
            except Exception as exc:  # noqa: BLE001 - a busy state file or a bus hiccup must not end the node
                request_failed("can", exc)
                continue

    def _send_emergencies(self) -> None:
        if self.node is None or self.state in (0, 4):
            return
        for emcy in self.drive.take_emergencies():
            code = int(getattr(emcy, "error_code", 0))
            register = int(getattr(emcy, "error_register", 0))
            data = bytes(getattr(emcy, "data", b""))[:5]
            self.node.emcy.send(code, register, data)


def _make_node(face: CanFace) -> Any:
    """A canopen LocalNode whose objects live in the SimDrive (built lazily: canopen is imported late)."""
    import canopen
    from canopen.nmt import NmtSlave
    from canopen.sdo import SdoAbortedError

    from akdctl.sim.can_sdo import BlockSdoServer
    from akdctl.protocol.coe import ABORT_GENERAL
    from akdctl.sim.errors import SdoAccessError

    class SimNmt(NmtSlave):
        """NMT slave with a drive's reset behaviour: reset -> boot-up -> PRE-OPERATIONAL."""

        def boot(self) -> None:
            """Power-on and NMT reset: no SDO transfer survives, boot-up message, PRE-OPERATIONAL."""
            face.node.sdo.reset()
            self._state = 0
            self.network.send_message(0x700 + self.id, bytes([0]))
            self._state = 127
            self.start_heartbeat(face.heartbeat_time())
            face.on_state(127)

        def on_command(self, can_id: int, data: bytearray, timestamp: float) -> None:
            if len(data) < 2:
                return
            cmd, node_id = data[0], data[1]
            if node_id not in (self.id, 0):
                return
            if cmd in (0x81, 0x82):
                self.stop_heartbeat()
                self.boot()
                return
            new = {0x01: 5, 0x02: 4, 0x80: 127}.get(cmd)
            if new is None:
                return
            self._state = new
            self.update_heartbeat()
            face.on_state(new)

    class SimSdo(BlockSdoServer):
        def on_request(self, can_id: int, data: bytearray, timestamp: float) -> None:
            if face.state == 4:  # STOPPED: no SDO (CiA 301)
                return
            super().on_request(can_id, data, timestamp)

    class SimNode(canopen.LocalNode):
        def __init__(self) -> None:
            super().__init__(face.spec.node, canopen.ObjectDictionary())
            self._write_callbacks = []
            self.sdo = SimSdo(0x600 + self.id, 0x580 + self.id, self)
            self.nmt = SimNmt(self.id, self)

        def get_data(self, index: int, subindex: int, check_readable: bool = False) -> bytes:
            from akdctl.sim.can_pdo import predefined_cob_id

            try:
                return predefined_cob_id(index, subindex, face.drive.object_read(index, subindex), self.id)
            except SdoAccessError as exc:
                raise SdoAbortedError(exc.code) from None
            except Exception as exc:  # noqa: BLE001 - the drive failed: general error abort, the node goes on
                request_failed("can", exc)
                raise SdoAbortedError(ABORT_GENERAL) from None

        def set_data(self, index: int, subindex: int, data: bytes, check_writable: bool = False) -> None:
            try:
                face.drive.object_write(index, subindex, bytes(data))
            except SdoAccessError as exc:
                raise SdoAbortedError(exc.code) from None
            except Exception as exc:  # noqa: BLE001 - the drive failed: general error abort, the node goes on
                request_failed("can", exc)
                raise SdoAbortedError(ABORT_GENERAL) from None
            face.on_written(index, subindex, bytes(data))

    return SimNode()


class _RemoteFrameListener:
    """canopen's listener drops remote frames; node guarding needs them."""

    def __init__(self, face: CanFace) -> None:
        self.face = face

    def on_message_received(self, msg: "can.Message") -> None:
        if msg.is_remote_frame and msg.arbitration_id == 0x700 + self.face.spec.node:
            try:
                self.face.on_guard_request()
            except Exception:
                pass

    def on_error(self, exc: Exception) -> None:
        pass

    def stop(self) -> None:
        pass

    def __call__(self, msg: "can.Message") -> None:
        self.on_message_received(msg)
