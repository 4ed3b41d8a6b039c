"""``can://INTERFACE/CHANNEL/NODE``: CANopen over any python-can interface.

python-can opens the adapter (socketcan, slcan through pyserial, pcan, kvaser,
ixxat, vector, virtual, udp_multicast, socketcand, ...) and the ``canopen``
library speaks CiA 301 on it (SDO client, NMT master, heartbeat consumer, EMCY
consumer). akdctl adds only what those libraries do not know: target syntax,
error translation into akdctl's exit codes, and frame tracing. The node's SDO
client is offered as ``sdo_client``; the Connection puts
:class:`~akdctl.channels.canopen_sdo.CanopenObjectChannel` on it.

Target syntax
-------------
``can://INTERFACE/CHANNEL/NODE[?bitrate=500000&KEY=VALUE...]``

* ``INTERFACE`` is a python-can interface name.  ``config`` (alias
  ``default``) takes interface, channel and bus options from python-can's own
  configuration (``CAN_INTERFACE``/``CAN_CHANNEL``/``CAN_BITRATE``/``CAN_CONFIG``
  environment variables, ``~/can.conf``, ``/etc/can.conf``, ``~/.canrc``);
  ``?context=NAME`` selects a section.  With any other interface the target is
  the whole configuration and python-can's files are ignored, so a stray
  ``~/.canrc`` cannot change which adapter a command talks to.
* ``CHANNEL`` is everything between the first and the last ``/`` of the path,
  percent-decoded: ``can0``, ``239.74.163.2``, ``PCAN_USBBUS1``.  A device path
  keeps its leading slash, so it follows a double slash:
  ``can://slcan//dev/ttyACM0/1``.  ``-`` means "the configured/default channel".
* ``NODE`` is the CANopen node id (1..127).
* Query parameters other than akdctl's own (``block``, ``context``) are passed to
  the python-can bus as keyword arguments, typed the way python-can types its
  config files (``500000`` -> int, ``0.5`` -> float, ``true`` -> bool, others
  stay strings): ``?bitrate=250000``, ``?port=43114``, ``?sleep_after_open=2``.
* slcan: akdctl waits 0.05 s after opening the serial port (python-can's own default is 2 s, for adapters that
  reset on open: give those ``?sleep_after_open=2``), and every write to the port ends within the command's
  ``--timeout``, so an adapter that stops reading cannot hang a command; ``-v`` shows how long the open took.
* ``?block=1`` uses SDO block transfer for uploads and downloads.

Errors
------
* unknown interface name, bad bus option (python-can's ``ValueError``/
  ``TypeError``) -> :class:`~akdctl.errors.UsageError` (exit 2);
* adapter missing, driver or vendor library missing
  (``CanInterfaceNotImplementedError``, ``CanInitializationError``, ``OSError``,
  ``ImportError``) -> :class:`~akdctl.errors.CommError` (exit 3): the link is
  down as far as the user can tell, whether the cable or the driver is missing;
* SDO abort -> :class:`~akdctl.errors.SdoAborted` (exit 1), SDO timeout ->
  :class:`~akdctl.errors.NoAnswer` (exit 3) (see
  :mod:`akdctl.channels.canopen_sdo`).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote

from akdctl.errors import AkdError, CommError, NoAnswer, UsageError
from akdctl.io.canbus import NOTIFIER_CYCLE_S, SLCAN_SLEEP_AFTER_OPEN, BusConfig, close_bus, open_bus, reason
from akdctl.links import CanopenSdoClient
from akdctl.protocol.nmt import state_name as _state_name
from akdctl.transport.base import LinkOptions, Transport

if TYPE_CHECKING:
    from collections.abc import Callable

    import can
    import canopen

    from akdctl.io.can_reader import BusReader
    from akdctl.transport.target import Target
    from akdctl.transport.trace import Tracer

# canopen/python-can log transfer aborts and retries at ERROR/WARNING; without a handler Python's
# last-resort handler would print them under akdctl's own one-line messages. -v/--debug may add handlers.
for _name in ("canopen", "can"):
    logging.getLogger(_name).addHandler(logging.NullHandler())

#: How many distinct frames a session's network keeps built for sending again (SDO requests of a poll, NMT).
FRAME_CACHE = 256
#: Query parameters akdctl reads itself; the rest go to the python-can bus.
OWN_QUERY = frozenset({"block", "context"})
#: INTERFACE names that mean "python-can's configuration decides".
CONFIG_INTERFACES = frozenset({"config", "default"})

#: NMT command names accepted by :meth:`CanopenTransport.nmt` -> CiA 301 command specifier.
NMT_COMMANDS: dict[str, int] = {
    "start": 0x01,
    "stop": 0x02,
    "preop": 0x80,
    "reset": 0x81,
    "reset-comm": 0x82,
}


def _cast(text: str) -> Any:
    """Type a query value the way python-can types configuration file values."""
    from can.util import cast_from_string

    return cast_from_string(text)


def _flag(target: "Target", name: str) -> bool:
    text = target.query.get(name)
    if text is None:
        return False
    lowered = text.strip().lower()
    if lowered in ("", "1", "true", "yes", "on"):
        return True
    if lowered in ("0", "false", "no", "off"):
        return False
    raise UsageError(f"target {target.raw!r}: {name}={text!r}; use {name}=1 or {name}=0")


def bus_config(target: "Target") -> BusConfig:
    """Split a ``can://`` target into python-can bus arguments.

    Pure (imports python-can only to type values), so the syntax is testable
    without an adapter.
    """
    path = target.path
    if not path.startswith("/") or path.count("/") < 2 and target.host not in CONFIG_INTERFACES:
        raise UsageError(f"malformed target {target.raw!r}: expected can://INTERFACE/CHANNEL/NODE, e.g. can://socketcan/can0/1")
    body, _, node_text = path[1:].rpartition("/")
    try:
        node = int(node_text, 0)
    except ValueError:
        raise UsageError(f"malformed target {target.raw!r}: NODE {node_text!r} is not a number") from None
    if not 1 <= node <= 127:
        raise UsageError(f"malformed target {target.raw!r}: CANopen node id {node} is outside 1..127")
    channel: str | None = unquote(body) if body not in ("", "-") else None
    interface: str | None = target.host.lower()
    use_config = interface in CONFIG_INTERFACES
    if use_config:
        interface = None
    elif channel is None and interface not in ("virtual", "udp_multicast"):
        raise UsageError(f"malformed target {target.raw!r}: interface {interface} needs a CHANNEL, e.g. can://{interface}/can0/{node}")
    kwargs = {key: _cast(value) for key, value in target.query.items() if key not in OWN_QUERY}
    context = target.query.get("context") or None
    if context is not None and not use_config:
        raise UsageError(f"target {target.raw!r}: context= selects a python-can configuration section; use it with can://config/...")
    return BusConfig(interface, channel, kwargs, use_config, context, node, _flag(target, "block"))


def frame_meta(can_id: int, extended: bool = False, remote: bool = False) -> dict[str, object]:
    """Trace metadata for one CAN frame (a pcap sink writes LINKTYPE_CAN_SOCKETCAN from it)."""
    return {"proto": "can", "can_id": can_id, "extended": extended, "remote": remote}


def frame_note(can_id: int) -> str:
    """Name the CANopen service of a COB-ID for the ``--trace`` dump."""
    function, node = can_id & 0x780, can_id & 0x7F
    names = {0x000: "NMT", 0x080: "EMCY" if node else "SYNC", 0x100: "TIME", 0x580: "SDO tx", 0x600: "SDO rx",
             0x700: "heartbeat", 0x180: "TPDO1", 0x200: "RPDO1", 0x280: "TPDO2", 0x300: "RPDO2",
             0x380: "TPDO3", 0x400: "RPDO3", 0x480: "TPDO4", 0x500: "RPDO4"}
    name = names.get(function, "")
    if can_id == 0:
        return "id 0x000 NMT"
    return f"id 0x{can_id:03X} {name} node {node}".rstrip() if name else f"id 0x{can_id:03X}"


def _make_network(bus: "can.BusABC", tracer: "Tracer") -> "tuple[canopen.Network, BusReader]":
    """A canopen Network that reports every frame it sends or receives to the tracer, connected: the
    :class:`~akdctl.io.can_reader.BusReader` that reads its bus (and lets a caller waiting for an answer read for it)
    is running and returned with it.

    With tracing off (``tracer.active`` false) a frame costs one attribute test each way: no note, no meta dict,
    no copy of the data (tests/test_trace_off.py counts them).
    """
    import can
    import canopen

    from akdctl.io.can_reader import BusReader

    frames: dict[tuple[int, bytes, bool], can.Message] = {}

    class TracingNetwork(canopen.Network):
        def send_message(self, can_id: int, data: bytes, remote: bool = False) -> None:
            """canopen's ``Network.send_message`` with the frame built once per distinct request: a poll sends the
            same few frames again and again, and python-can's buses read a message when they send it (its own
            periodic tasks send one message object again and again too)."""
            data = bytes(data)
            if tracer.active:
                tracer.frame("tx", "can", data, note=frame_note(can_id), meta=frame_meta(can_id, can_id > 0x7FF, remote))
            if not self.bus:
                raise RuntimeError("Not connected to CAN bus")
            key = (can_id, data, remote)
            message = frames.get(key)
            if message is None:
                message = can.Message(is_extended_id=can_id > 0x7FF, arbitration_id=can_id, data=data,
                                      is_remote_frame=remote)
                if len(frames) < FRAME_CACHE:
                    frames[key] = message
            with self.send_lock:
                self.bus.send(message)
            self.check()

    class TraceListener(can.Listener):
        def on_message_received(self, msg: "can.Message") -> None:
            if not tracer.active or msg.is_error_frame:
                return
            tracer.frame("rx", "can", bytes(msg.data), note=frame_note(msg.arbitration_id),
                         meta=frame_meta(msg.arbitration_id, msg.is_extended_id, msg.is_remote_frame))

        def stop(self) -> None:
            pass

    network = TracingNetwork(bus)
    network.NOTIFIER_CYCLE = NOTIFIER_CYCLE_S  # how long a close waits for the receive thread
    network.listeners.append(TraceListener())
    # canopen's ``connect`` for a bus given to the constructor only starts python-can's Notifier on it; a BusReader is
    # that Notifier, and a caller waiting for an answer may read for it
    network.notifier = reader = BusReader(bus, network.listeners, NOTIFIER_CYCLE_S)
    return network, reader


@dataclass
class NodeInfo:
    """One node that answered a scan."""

    node: int
    state: str | None = None
    device_type: int | None = None
    vendor_id: int | None = None
    product_code: int | None = None
    revision: int | None = None
    serial: int | None = None
    device_name: str | None = None

    def to_json(self) -> dict[str, object]:
        return {
            "node": self.node,
            "nmt_state": self.state,
            "device_type": self.device_type,
            "vendor_id": self.vendor_id,
            "product_code": self.product_code,
            "revision": self.revision,
            "serial": self.serial,
            "device_name": self.device_name,
        }


class CanopenTransport(Transport):
    """One CANopen node on one CAN bus, reached through python-can + canopen.

    ``sdo_client`` is the node's default SDO channel (0x600/0x580 + node), for the
    Connection's :class:`~akdctl.channels.canopen_sdo.CanopenObjectChannel`.  The NMT
    master and a node scan work on the whole bus.
    """

    scheme = "can"

    def __init__(self, target: "Target", options: LinkOptions) -> None:
        super().__init__(target, options)
        self.config = bus_config(target)
        self.node_id = self.config.node
        self.bus: "can.BusABC | None" = None
        self.network: "canopen.Network | None" = None
        self.node: "canopen.RemoteNode | None" = None
        self._watches: dict[int, _StateWatch] = {}
        self._nmt_sent_at: float | None = None
        self._reader: "BusReader | None" = None

    # -- life cycle -------------------------------------------------------------------------------------------
    def open(self) -> None:
        import canopen

        started = time.monotonic()
        self.bus = open_bus(self.config, write_timeout=self.options.budget.left)
        if self.options.verbose:  # where the time of a slow start went (issue 23.21)
            import sys

            extra = (f", sleep_after_open {self.config.kwargs.get('sleep_after_open', SLCAN_SLEEP_AFTER_OPEN):g} s"
                     if self.config.interface == "slcan" else "")
            sys.stderr.write(f"akdctl: opened CAN interface {self.config.describe()} in "
                             f"{(time.monotonic() - started) * 1000:.0f} ms{extra}\n")
        try:
            self.network, self._reader = _make_network(self.bus, self.options.tracer)
            self.node = self._remote_node(self.node_id)
            self.sdo_client = CanopenSdoClient(self.node, self.where(self.node_id), block=self.config.block,
                                               reader=self._reader)
        except AkdError:
            self.close()
            raise
        except Exception as exc:  # canopen/python-can failures while starting the receive thread
            self.close()
            raise CommError(f"cannot start CANopen on {self.config.describe()}: {reason(exc)}") from None
        _ = canopen  # imported for its side effect of failing early when missing

    def close(self) -> None:
        """Stop the receive thread and shut the bus down; safe twice and after a failed open."""
        network, bus = self.network, self.bus
        self.network = None
        self.bus = None
        self.sdo_client = None
        self._reader = None
        close_bus(network, bus)

    @property
    def display_name(self) -> str:
        return f"{self.target.display} ({self.where(self.node_id)})"

    def where(self, node_id: int) -> str:
        """"CANopen node N on INTERFACE CHANNEL", as messages name a node."""
        return f"CANopen node {node_id} on {self.config.describe()}"

    # -- helpers ----------------------------------------------------------------------------------------------
    def _need_network(self) -> "canopen.Network":
        if self.network is None:
            raise CommError("the CAN bus is not open")
        return self.network

    def _remote_node(self, node_id: int) -> "canopen.RemoteNode":
        import canopen

        network = self._need_network()
        if node_id in network.nodes:
            return network.nodes[node_id]  # type: ignore[return-value]
        node = canopen.RemoteNode(node_id, canopen.ObjectDictionary())
        node.sdo.RESPONSE_TIMEOUT = self.options.timeout
        node.sdo.MAX_RETRIES = max(1, self.options.retries + 1)
        network.add_node(node)
        return node

    def _hand_back(self) -> None:
        """Before a wait for frames that only the receive thread hands on (heartbeats, scan answers): it reads now,
        not after an SDO caller's hand-back time."""
        if self._reader is not None:
            self._reader.hand_back()

    def _send(self, can_id: int, data: bytes, remote: bool = False) -> None:
        import can

        try:
            self._need_network().send_message(can_id, data, remote)
        except can.CanError as exc:
            raise CommError(f"cannot send on {self.config.describe()}: {reason(exc)}") from None

    # -- NMT --------------------------------------------------------------------------------------------------
    def nmt(self, command: str, node: int | None = None) -> None:
        """Send an NMT command to ``node`` (default: the target's node; 0 = all nodes)."""
        code = NMT_COMMANDS.get(command)
        if code is None:
            raise UsageError(f"unknown NMT command {command!r}; use one of {', '.join(NMT_COMMANDS)}")
        node_id = self.node_id if node is None else node
        if not 0 <= node_id <= 127:
            raise UsageError(f"NMT node id {node_id} is outside 0..127 (0 = all nodes)")
        if node_id:
            self._watch(node_id)  # listen before sending: a boot-up can come back at once
        self._nmt_sent_at = time.monotonic()
        self._send(0x000, bytes([code, node_id]))

    def _watch(self, node_id: int) -> "_StateWatch":
        watch = self._watches.get(node_id)
        if watch is None:
            watch = self._watches[node_id] = _StateWatch()
            self._remote_node(node_id).nmt.add_heartbeat_callback(watch.seen)
        return watch

    def nmt_state(self, node: int | None = None, timeout: float | None = None, fresh: bool = False,
                  expect: str | None = None) -> str:
        """The node's NMT state from its heartbeat, or by node guarding if it sends none.

        A heartbeat seen in the last ``timeout`` seconds answers at once unless
        ``fresh``: then only what came after the last NMT command counts. Halfway through
        the wait a node-guarding remote frame asks nodes without heartbeat. With ``expect``
        (a state name), states that came but are not it are waited past until the wait ends
        (a heartbeat sent before the command took effect), and then the last one is the answer.
        Raises :class:`NoAnswer` if neither came in time.
        """
        node_id = self.node_id if node is None else node
        watch = self._watch(node_id)
        self._hand_back()
        wait = self.options.timeout if timeout is None else timeout
        now = time.monotonic()
        since = (self._nmt_sent_at if self._nmt_sent_at is not None else now) if fresh else now - wait
        wanted = None if expect is None else (lambda code: _state_name(code) == expect)
        state = watch.wait_after(since, wait / 2, wanted)
        if state is None:
            self._send(0x700 + node_id, b"", remote=True)
            state = watch.wait_after(since, wait / 2, wanted)
        elif wanted is not None and not wanted(state):
            state = watch.wait_after(since, wait / 2, wanted)
        if state is None:
            raise NoAnswer(f"no heartbeat or node-guarding reply from CANopen node {node_id} on {self.config.describe()} within {wait:g} s")
        return _state_name(state)

    # -- scan -------------------------------------------------------------------------------------------------
    def scan(self, nodes: range | list[int] = range(1, 128), wait: float | None = None) -> list[NodeInfo]:
        """Nodes that show themselves: SDO answer to 0x1000 (sent to each id), heartbeat, EMCY or TPDO.

        Each found node is then asked for its identity (0x1018, 0x1000, 0x1008);
        what it does not answer stays ``None``.
        """
        network = self._need_network()
        listen = self.options.timeout if wait is None else wait
        self._hand_back()
        network.scanner.reset()
        for node_id in nodes:
            self._send(0x600 + node_id, b"\x40\x00\x10\x00\x00\x00\x00\x00")
        time.sleep(listen)  # collecting answers from an unknown number of nodes: wait the whole window
        found = sorted(n for n in network.scanner.nodes if n in set(nodes))
        return [self.identify(n) for n in found]

    def identify(self, node_id: int) -> NodeInfo:
        """Identity (0x1018:1..4), device type (0x1000), name (0x1008) and NMT state of one node.

        One try per object and whatever goes wrong leaves that field ``None``: a scan
        reports what nodes answer, it does not fail on one that answers partly.
        """
        import can
        from canopen.sdo.exceptions import SdoAbortedError, SdoCommunicationError

        sdo = self._remote_node(node_id).sdo
        self._hand_back()  # canopen's own uploads: its receive thread reads for them
        tries, sdo.MAX_RETRIES = sdo.MAX_RETRIES, 1
        info = NodeInfo(node_id)

        def upload(index: int, sub: int) -> bytes | None:
            try:
                return bytes(sdo.upload(index, sub))
            except (SdoAbortedError, SdoCommunicationError, can.CanError, RuntimeError):
                return None

        def u32(index: int, sub: int) -> int | None:
            data = upload(index, sub)
            return None if data is None else int.from_bytes(data[:4].ljust(4, b"\0"), "little")

        try:
            info.device_type = u32(0x1000, 0)
            info.vendor_id = u32(0x1018, 1)
            info.product_code = u32(0x1018, 2)
            info.revision = u32(0x1018, 3)
            info.serial = u32(0x1018, 4)
            name = upload(0x1008, 0)
            info.device_name = name.rstrip(b"\0").decode("latin-1") or None if name is not None else None
        finally:
            sdo.MAX_RETRIES = tries
        try:
            info.state = self.nmt_state(node_id, timeout=min(self.options.timeout, 1.5))
        except AkdError:
            info.state = None
        return info


class _StateWatch:
    """Last heartbeat/guarding state of one node, with a condition to wait for a newer one."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._state: int | None = None
        self._at = float("-inf")

    def seen(self, state: int) -> None:
        with self._cond:
            self._state, self._at = state, time.monotonic()
            self._cond.notify_all()

    def wait_after(self, since: float, timeout: float, wanted: Callable[[int], bool] | None = None) -> int | None:
        """The state once one came at or after ``since`` -- with ``wanted``, once one came that it accepts --
        waiting at most ``timeout``; when the wait ends, the last state that came after ``since`` (None: none).

        Why ``wanted``: a heartbeat the node sent just before an NMT command took effect can arrive after the
        command was sent, so the first state after it may still be the old one."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._at < since or (wanted is not None and self._state is not None and not wanted(self._state)):
                left = deadline - time.monotonic()
                if left <= 0:
                    return self._state if self._at >= since else None
                self._cond.wait(left)
            return self._state
