"""``akdctl can monitor``: what every node on the bus says, live, until Ctrl-C or ``--for``.

Why a bare bus and not the ``can://`` transport's canopen network: a monitor only listens; it must see every
node's emergencies and heartbeats, not the one node the target names, and must not answer or own anything. The
meaning of each frame is :mod:`akdctl.drive.can_events` (pure); this module only opens the bus, feeds it frames
with the monotonic clock, and renders each event as a line (or a JSON line with ``--json``).
"""

from __future__ import annotations

import contextlib
import time

import click

from akdctl.cli.context import get_app
from akdctl.cli.parsing import Duration
from akdctl.errors import CommError, Interrupted, UsageError

#: How long one receive waits, so heartbeat timeouts, --for and Ctrl-C are noticed within this.
RECV_SLICE_S = 0.1


@click.command("monitor")
@click.option("--for", "duration", type=Duration(low=0.001, high=86400), metavar="DURATION",
              help="Stop after this long, e.g. 10s, 500ms, 2min (default: until Ctrl-C).")
@click.option("--nodes", "nodes_text", default=None, metavar="RANGE",
              help="Only these node ids, e.g. 1-10 or 2,5 (default: every node).")
@click.option("--heartbeat-timeout", type=Duration(low=0.01, high=3600), metavar="DURATION",
              help="A node silent this long is reported lost (default: 3 of its measured heartbeat periods).")
@click.option("--heartbeats", "every_heartbeat", is_flag=True,
              help="Show every heartbeat too (default: only state changes, boot-ups and timeouts).")
def monitor(duration: float | None, nodes_text: str | None, heartbeat_timeout: float | None,
            every_heartbeat: bool) -> None:
    """Show emergencies (as AKD faults), heartbeats and their timeouts, NMT state changes and boot-ups of every node.

    Listens only: nothing is sent. Emergencies are decoded to the AKD fault number and
    text (one CiA 301 code may stand for several AKD faults: all are named). With --json
    every event is one JSON line (keys: time, kind, node and the kind's fields).

    \b
    Examples:
      akdctl -T can://socketcan/can0/1 can monitor
      akdctl -T can://socketcan/can0/1 can monitor --for 10s --json
      akdctl -T can://socketcan/can0/1 can monitor --nodes 1-4 --heartbeat-timeout 500ms
      akdctl -T can://socketcan/can0/1 can monitor --heartbeats --for 5
    """
    from akdctl.cli.can import parse_nodes
    from akdctl.cli.output import emit_json_line, inert
    from akdctl.cli.signals import stop_signals
    from akdctl.drive.can_events import BusWatch, describe
    from akdctl.io.canbus import close_bus, open_bus, reason
    from akdctl.transport.canopen_bus import bus_config

    app = get_app()
    target = app.target
    if target.scheme != "can":
        raise UsageError(f"'akdctl can monitor' needs a can://INTERFACE/CHANNEL/NODE target; the target is {target.display}")
    nodes = set(parse_nodes(nodes_text)) if nodes_text is not None else None
    config = bus_config(target)
    watch = BusWatch(heartbeat_timeout, nodes, every_heartbeat)
    bus = open_bus(config)
    started = time.monotonic()
    ends = started + duration if duration is not None else None
    count = 0

    def show(event: dict[str, object]) -> None:
        nonlocal count
        count += 1
        event = {**event, "time": round(float(event["time"]) - started, 3)}  # type: ignore[arg-type]
        if app.json:
            emit_json_line(event)
        else:
            click.echo(inert(f"{event['time']:9.3f}  {describe(event)}"))

    if not app.json:
        from akdctl.cli.output import message

        message(f"akdctl: listening on {config.describe()} ("
                + (f"for {duration:g} s" if duration is not None else "Ctrl-C ends") + ")")
    try:
        with contextlib.suppress(Interrupted), stop_signals() as stop:
            while not stop():
                now = time.monotonic()
                if ends is not None and now >= ends:
                    break
                wait = RECV_SLICE_S if ends is None else max(0.0, min(RECV_SLICE_S, ends - now))
                try:
                    msg = bus.recv(timeout=wait)
                except Exception as exc:  # noqa: BLE001 - python-can backends raise their own kinds
                    raise CommError(f"CAN bus {config.describe()} failed while monitoring: {reason(exc)}") from None
                now = time.monotonic()
                if msg is not None and not msg.is_error_frame and not msg.is_remote_frame \
                        and not msg.is_extended_id:
                    for event in watch.frame(now, msg.arbitration_id, bytes(msg.data)):
                        show(event)
                for event in watch.tick(now):
                    show(event)
    finally:
        close_bus(None, bus)
    if not app.json:
        from akdctl.cli.output import message

        message(f"akdctl: {count} event(s) from {len(watch.known)} node(s) with heartbeats")
