"""Opening and closing a python-can bus, with every failure turned into one akdctl error.

Why here: the ``can://`` transport and the simulator's CAN face both open a bus
from the same description and must shut it down the same way (stop canopen's
notifier first, else its thread reads from a closed bus); one copy here, below
``transport/`` and ``sim/``. python-can is imported only when a bus is opened.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

from akdctl.errors import CommError, UsageError

if TYPE_CHECKING:
    import can
    import canopen


@dataclass(frozen=True)
class BusConfig:
    """What :func:`can.Bus` is called with, derived from a target (pure data, testable)."""

    interface: str | None
    channel: str | None
    kwargs: dict[str, Any] = field(default_factory=dict)
    use_config: bool = False
    context: str | None = None
    node: int = 1
    block: bool = False

    def describe(self) -> str:
        iface = self.interface or "configured interface"
        chan = self.channel if self.channel is not None else "default channel"
        return f"{iface} {chan}"


#: ``sleep_after_open`` for slcan when the target does not give one (seconds). python-can waits 2 s after opening
#: the serial port, for adapters that reset when the port opens (Arduino-based ones); a CANable, CANtact or Lawicel
#: CANUSB answers at once, and 2 s on every command is most of what a technician waits for. An adapter that
#: resets on open needs ``?sleep_after_open=2`` in its target (README, "CAN targets").
SLCAN_SLEEP_AFTER_OPEN = 0.05


def _slcan_class(write_timeout: Callable[[], float]) -> Any:
    """python-can's slcan bus whose every write to the serial port ends within ``write_timeout()`` seconds.

    Why: python-can writes with pyserial's ``write_timeout`` = the ``timeout`` of ``send`` (None, i.e. for ever,
    as canopen sends) and none at all while opening; an adapter that stops reading (its pty or USB buffer full)
    then blocks the command in ``poll()`` for ever (issue 23.12). Bounded, the write fails with python-can's
    ``CanOperationError`` and the command ends with exit 3 within its ``--timeout``.
    """
    from can.interfaces.slcan import slcanBus

    class BoundedSlcanBus(slcanBus):  # type: ignore[misc]
        def _write(self, string: str) -> None:
            self.serialPortOrig.write_timeout = max(write_timeout(), 0.001)
            super()._write(string)

    return BoundedSlcanBus


def open_bus(config: BusConfig, write_timeout: Callable[[], float] | None = None) -> "can.BusABC":
    """Open the python-can bus, translating every failure into one akdctl error.

    python-can's backends fail in their own ways when a vendor library is missing: an
    ``ImportError``, a ``CanInterfaceNotImplementedError``, an ``OSError`` -- or, for kvaser without
    CANlib, a ``NameError`` from a function the backend never defined. Bad options (``TypeError``,
    ``ValueError``) are the user's (exit 2); anything else is one line naming the interface (exit 3).
    """
    import can

    where = config.describe()
    if config.interface is not None and config.interface not in can.VALID_INTERFACES:
        raise UsageError(
            f"unknown python-can interface {config.interface!r}; known: {', '.join(sorted(can.VALID_INTERFACES))}"
        )
    kwargs = dict(config.kwargs)
    try:
        if config.interface == "slcan" and write_timeout is not None:
            kwargs.setdefault("sleep_after_open", SLCAN_SLEEP_AFTER_OPEN)
            if not config.channel:
                raise ValueError("Must specify a serial port.")
            return _slcan_class(write_timeout)(channel=config.channel, **kwargs)  # type: ignore[no-any-return]
        if config.interface == "udp_multicast":  # python-can's, without its own frames looped back
            from akdctl.io.udp_multicast_own import OwnFramesDropped

            return OwnFramesDropped(**kwargs) if config.channel is None else OwnFramesDropped(config.channel, **kwargs)
        if config.use_config:
            return can.Bus(channel=config.channel, config_context=config.context, **kwargs)
        return can.Bus(interface=config.interface, channel=config.channel, ignore_config=True, **kwargs)
    except can.CanInterfaceNotImplementedError as exc:
        raise CommError(f"CAN interface {where} is not available here: {reason(exc)} (is its driver or library installed?)") from None
    except can.CanInitializationError as exc:
        raise CommError(f"cannot open CAN interface {where}: {reason(exc)}") from None
    except ImportError as exc:
        raise CommError(f"CAN interface {where} needs a Python module that is missing: {reason(exc)}") from None
    except OSError as exc:
        raise CommError(f"cannot open CAN interface {where}: {exc.strerror or reason(exc)}") from None
    except can.CanError as exc:
        raise CommError(f"cannot open CAN interface {where}: {reason(exc)}") from None
    except (TypeError, ValueError) as exc:
        raise UsageError(f"CAN interface {where} rejected its options {kwargs or '(none)'}: {reason(exc)}") from None
    except Exception as exc:  # noqa: BLE001 - a backend failing in its own way (kvaser without CANlib: NameError)
        raise CommError(f"CAN interface {where} is not available here: python-can's {config.interface or 'configured'} "
                        f"backend failed while loading its driver library ({type(exc).__name__}: {reason(exc)}); "
                        "is the vendor's library installed?") from None


def reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def close_bus(network: "canopen.Network | None", bus: "can.BusABC | None") -> None:
    """Stop canopen's receive thread (which shuts its bus down) or else shut the bare bus down.

    Safe with either or both ``None`` and after a failed open; teardown errors are
    swallowed, since the caller is already leaving.
    """
    if network is not None:
        try:
            network.disconnect()  # stops the notifier and shuts the bus down
            bus = None
        except Exception:
            pass
    if bus is not None:
        try:
            bus.shutdown()
        except Exception:
            pass


#: Seconds canopen's receive thread (python-can's Notifier) waits in one ``bus.recv`` before it looks whether it
#: must stop. Closing the network joins that thread, so every close waits up to this long: each ``can://`` command
#: as it exits, each stop of a CAN face. No one wake-up reaches the thread on every interface (a queue for
#: ``virtual``, a serial port for slcan, a socket for ``udp_multicast``), so the wait is short instead: 20 empty
#: wake-ups a second cost an idle thread nothing measurable. (0.2 s before: a command's exit waited 0.2 s.)
NOTIFIER_CYCLE_S = 0.05
