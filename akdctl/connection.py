"""The Connection: the one place where a command's pieces are wired together.

Why one place: every command, recipe step and support bundle needs the same
sequence -- open the target's transport, put channels on the links it offers,
trace every frame once, pick the axis profile, close everything on the way out.
Written once here, ``drive/`` and ``recipe/`` take a :class:`Connection` (never the
CLI's context) and tests hand one a transport of their own (the way httpx hands a
client its transport).

What is built from what:

* a record link (:class:`~akdctl.links.RecordLink`) -> the PROFIdrive parameter
  channel :class:`~akdctl.channels.bmp.BmpParameterChannel`;
* a mailbox link (:class:`~akdctl.links.MailboxLink`) -> the CoE SDO channel
  :class:`~akdctl.channels.coe_sdo.CoeObjectChannel`, built on first use so
  PNU-only commands never import the CoE codecs;
* a message link (:class:`~akdctl.links.MessageLink`, EtherNet/IP) -> the CIP
  attribute channel :class:`~akdctl.channels.cip.CipAttributes`;
* a native SDO client -> its adapter: canopen's node ->
  :class:`~akdctl.channels.canopen_sdo.CanopenObjectChannel`, a pysoem slave ->
  :class:`~akdctl.channels.soem_sdo.SoemObjectChannel`.

Every record and mailbox link is wrapped in the session's tracer
(:mod:`akdctl.transport.trace`) before a channel sees it; the transport reports
its own wire frames to the same tracer (``options.tracer``). So ``--trace``,
``--pcap`` and the bundle's session trace are one record of one session.

Importing this module is cheap (``akdctl --help`` must not load a transport):
everything below the Connection is imported when it is first used.
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING, TypeVar

from akdctl.errors import AkdError, UsageError

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel, ParameterChannel
    from akdctl.channels.cip import CipAttributes
    from akdctl.config import Profile
    from akdctl.drive.axis.base import Axis
    from akdctl.io.owner_lock import OwnerLock
    from akdctl.links import CommandLink, MailboxLink, NativeSdoClient, RecordLink, RegisterLink
    from akdctl.profiles.vocabulary import Channel, DriveProfile
    from akdctl.transport.base import LinkOptions, Transport
    from akdctl.transport.eip_io import IoConnection
    from akdctl.transport.ethercat_raw import ProcessDataCycle
    from akdctl.transport.target import Target
    from akdctl.transport.trace import Tracer

T = TypeVar("T")


def open_tracer(*, enabled: bool = False, pcap: str | None = None, record: bool = False) -> "Tracer":
    """The session's one tracer: ``--trace`` prints, ``--pcap FILE`` captures; it keeps records only when
    asked (``record``: ``-v`` counts the requests; ``tracer.record = True``: the support bundle), so a command
    without any of them traces nothing.

    Close it (``tracer.close()``) after the transport so the capture file is complete.
    """
    from akdctl.transport.trace import Tracer

    tracer = Tracer(enabled=enabled, record=record)
    if pcap:
        from akdctl.transport.pcap import PcapWriter

        try:
            writer = PcapWriter(pcap)
        except OSError as exc:
            raise UsageError(f"cannot write capture file {pcap}: {exc.strerror}") from None
        tracer.add_sink(writer.write, close=writer.close)
    return tracer


class Connection:
    """One target, opened on first use: its transport, its channels, its axis.

    ``profile`` is the config file's profile (limits, units, the default axis
    profile) or ``None``. ``transport`` injects a transport instance (not yet
    opened) instead of the one the registry names for ``target`` -- tests and
    tools that prepare a transport themselves.
    """

    def __init__(self, target: "Target", options: "LinkOptions", profile: "Profile | None" = None, *,
                 transport: "Transport | None" = None) -> None:
        self.target = target
        self.options = options
        self.profile = profile
        self._given = transport
        self._transport: "Transport | None" = None
        self._parameters: "ParameterChannel | None" = None
        self._record_link: "RecordLink | None" = None  # the traced link, until parameters() builds its channel
        self._objects: "ObjectChannel | None" = None
        self._cip: "CipAttributes | None" = None
        #: The axis's owner lock while this command owns the axis (:meth:`own_axis`), else None.
        self.axis_owner: "OwnerLock | None" = None
        self._closed = False
        self._commands: "CommandLink | None" = None   # issue 24: the AKD's ASCII channel (akd://)
        self._registers: "RegisterLink | None" = None  # issue 24: Modbus registers (mb://)

    @classmethod
    def over(cls, transport: "Transport", profile: "Profile | None" = None) -> "Connection":
        """A Connection around a transport made elsewhere (its own target and options)."""
        return cls(transport.target, transport.options, profile, transport=transport)

    # ---------------------------------------------------------------- choices
    @property
    def drive_profile(self) -> str | None:
        """The axis profile someone chose: the target's ``?drive=``, else the config profile's ``drive``;
        None when nobody chose (then :attr:`axis_profile` follows the channels)."""
        chosen = self.target.query.get("drive")
        if chosen is None and self.profile is not None:
            chosen = self.profile.drive
        return chosen

    @property
    def axis_profile(self) -> "DriveProfile":
        """The axis profile motion uses: the chosen one (:attr:`drive_profile`), else the one the offered
        channels make the default (:func:`akdctl.profiles.vocabulary.default_profile`)."""
        from akdctl.profiles.vocabulary import default_profile, drive_profile, profiles_text

        chosen = self.drive_profile
        if chosen is None:
            return default_profile(self.channels)
        profile = drive_profile(chosen)
        if profile is None:
            raise UsageError(f"unknown drive profile {chosen!r}: use {profiles_text()}")
        return profile

    # ---------------------------------------------------------------- declared capabilities
    # Everything a command may ask of a target is declared here, each with a neutral answer where the
    # target has none; nothing above asks a transport or channel with getattr (tests/test_layers.py).

    @property
    def declared_channels(self) -> "frozenset[Channel] | None":
        """The channels the registry declares for this target's scheme (known without connecting), or None
        for a scheme only its opened transport can tell (a third-party entry point)."""
        from akdctl.transport.registry import BUILTIN

        spec = BUILTIN.get(self.target.scheme)
        return spec.channels if spec is not None else None

    @property
    def channels(self) -> "frozenset[Channel]":
        """The channels this target offers: :attr:`declared_channels`, else what the opened transport's links
        make (opens it)."""
        declared = self.declared_channels
        if declared is not None:
            return declared
        from akdctl.profiles.vocabulary import Channel

        self.transport()
        offered = ((Channel.PARAMETERS, self._parameters is not None or self._record_link is not None),
                   (Channel.OBJECTS, self._objects is not None), (Channel.ATTRIBUTES, self._cip is not None))
        return frozenset(channel for channel, present in offered if present)

    @property
    def time_scale(self) -> float:
        """Seconds of the drive's time per wall second (1 for a real drive; the simulator under ``sim speed``
        runs faster); asked again at every use, as ``sim speed`` may change it between transactions. Once the
        connection is closed the answer is 1 (a late wait must not open the target again)."""
        if self._transport is None and self._closed:
            return 1.0
        return float(self.transport().time_scale)

    def al_state(self) -> str | None:
        """The EtherCAT AL state in one spelling ('INIT', 'PREOP', 'SAFEOP', 'OP', 'BOOT', '+ERR' appended
        when the slave flags an error), or None where the target has none or cannot tell."""
        state = self.transport().al_state()
        if state is None:
            return None
        from akdctl.protocol.ethercat import normal_al_state

        return normal_al_state(state)

    def read_im0(self) -> dict[str, object] | None:
        """The device's I&M0 (PROFINET), or None where the network defines none."""
        return self.transport().read_im0()

    def own_axis(self, command: str) -> None:
        """Own this target's axis until :meth:`close` (the kernel frees it if the process dies).

        Two locks: one named by the normalised address (:func:`~akdctl.drive.gate.owner_key`) and, where the drive
        reports a serial number (one read, :func:`~akdctl.drive.identity.serial_number`), one named by it, so two
        spellings of one host (a name and its address) still meet (issue 23.15).
        Raises :class:`~akdctl.io.owner_lock.OwnerBusy` naming the owner when another command holds it,
        OSError when the lock's directory is unusable; a second call is a no-op."""
        if self.axis_owner is not None:
            return
        from akdctl.drive.gate import owner_key
        from akdctl.io.owner_lock import OwnerLock
        from akdctl.io.state_dir import state_dir

        owners = state_dir() / "owners"
        lock = OwnerLock(owners / f"{owner_key(self.target)}.lock")
        lock.acquire(command)
        self.axis_owner = lock
        if self.target.scheme != "sim":  # a simulated drive's address is already its only name
            from akdctl.drive.gate import serial_owner_key
            from akdctl.drive.identity import serial_number

            try:
                serial = serial_number(self)
                if serial is not None:
                    lock.also(OwnerLock(owners / f"{serial_owner_key(serial)}.lock"), command)
            except BaseException:
                self.axis_owner = None
                lock.release()
                raise

    def release_axis(self) -> None:
        """Let go of the axis (:meth:`own_axis`) and keep the link: the end of one command in the shell."""
        owner, self.axis_owner = self.axis_owner, None
        if owner is not None:
            owner.release()

    # ---------------------------------------------------------------- transport and channels
    def new_transport(self) -> "Transport":
        """A transport for this target, not opened: the registry's class for the target's scheme.

        Bus-level commands (``ecat scan``/``state``/``sii``) open it their own way and close it
        themselves; everything else uses :meth:`transport`.
        """
        from akdctl.transport.registry import transport_class

        return transport_class(self.target)(self.target, self.options)

    def transport(self) -> "Transport":
        """The open transport (opened on first use, with its channels built; closed by :meth:`close`)."""
        if self._transport is None:
            transport = self._given if self._given is not None else self.new_transport()
            try:
                transport.open()
                self._build_channels(transport)
            except AkdError as exc:
                with contextlib.suppress(Exception):
                    transport.close()
                raise exc.with_target(self.target.display)
            except BaseException:
                with contextlib.suppress(Exception):
                    transport.close()
                raise
            self._transport = transport
            self._closed = False
        return self._transport

    def _build_channels(self, transport: "Transport") -> None:
        from akdctl.transport.trace import TracedRecordLink, traced_mailbox_link

        tracer = self.options.tracer
        if transport.record_link is not None:  # its channel is built on first use: sdo commands never import it
            self._record_link = TracedRecordLink(transport.record_link, tracer)
        if transport.mailbox_link is not None:
            from akdctl.channels.base import LazyObjectChannel

            link = traced_mailbox_link(transport.mailbox_link, tracer)
            self._objects = LazyObjectChannel(lambda: self._coe_channel(link))
        elif transport.sdo_client is not None:
            self._objects = self._native_channel(transport.sdo_client)
        if transport.message_link is not None:
            from akdctl.channels.cip import CipAttributes

            self._cip = CipAttributes(transport.message_link, self.target.display)

        self._commands = transport.command_link    # declared by every Transport (transport/base.py): None
        self._registers = transport.register_link  # where the target has no such link

    def _coe_channel(self, link: "MailboxLink") -> "ObjectChannel":
        from akdctl.channels.coe_sdo import CoeObjectChannel

        return CoeObjectChannel(link, budget=self.options.budget)

    def _native_channel(self, client: "NativeSdoClient") -> "ObjectChannel":
        from akdctl.links import CanopenSdoClient, SoemSdoClient

        if isinstance(client, CanopenSdoClient):
            from akdctl.channels.canopen_sdo import CanopenObjectChannel

            return CanopenObjectChannel(client.node, budget=self.options.budget, block=client.block,
                                        where=client.where, reader=client.reader)
        if isinstance(client, SoemSdoClient):
            from akdctl.channels.soem_sdo import SoemObjectChannel

            return SoemObjectChannel(client.slave, client.where)
        raise TypeError(f"no object channel for an SDO client of type {type(client).__name__}")

    @property
    def has_parameters(self) -> bool:
        """Whether the target offers PROFIdrive parameters (opens the transport)."""
        self.transport()
        return self._parameters is not None or self._record_link is not None

    @property
    def has_objects(self) -> bool:
        """Whether the target offers SDO object access (opens the transport)."""
        self.transport()
        return self._objects is not None

    @property
    def has_cip(self) -> bool:
        """Whether the target offers CIP explicit messaging (opens the transport)."""
        self.transport()
        return self._cip is not None

    @property
    def has_process_data(self) -> bool:
        """Whether this host can run cyclic process data with the target's slave as the bus master (``ecat://``);
        known without opening the target (its transport class declares it)."""
        if self._given is not None:
            return bool(self._given.cyclic_master)
        from akdctl.transport.registry import transport_class

        return bool(transport_class(self.target).cyclic_master)

    def process_data(self, rx_bytes: int, tx_bytes: int) -> "ProcessDataCycle":
        """The cyclic exchange with the slave (not yet configured: drive/ecat_pdo_watch.enter does that);
        UsageError where this host is not the master of one."""
        cycle = self.transport().process_data(rx_bytes, tx_bytes)
        if cycle is None:
            raise UsageError(f"target {self.target.display} has no cyclic process data with this host as the "
                             "EtherCAT master; use an ecat://IFNAME[/POSITION] target")
        return cycle

    @property
    def has_commands(self) -> bool:
        """Whether the target speaks the AKD's ASCII command channel (akd://; opens the transport)."""
        self.transport()
        return self._commands is not None

    def commands(self) -> "CommandLink":
        """The AKD's ASCII command channel; UsageError naming the alternative if the target has none."""
        self.transport()
        return self._offered(self._commands, "no AKD command channel (ASCII service port); use an akd://HOST target")

    @property
    def has_registers(self) -> bool:
        """Whether the target offers Modbus holding registers (mb://; opens the transport)."""
        self.transport()
        return self._registers is not None

    def registers(self) -> "RegisterLink":
        """The Modbus register link; UsageError naming the alternative if the target has none."""
        self.transport()
        return self._offered(self._registers, "no Modbus registers; use an mb://HOST target")

    def cip(self) -> "CipAttributes":
        """The CIP attribute channel; UsageError naming the alternative if the target has none."""
        self.transport()
        return self._offered(self._cip, "no CIP attribute channel (EtherNet/IP); use an eip://HOST target")

    def io_connection(self, *, rpi_ms: float, port: int, local_port: int,
                      timeout_multiplier: int) -> "IoConnection":
        """A class-1 EtherNet/IP I/O connection (not opened: a context manager) over this target's explicit
        session, traced like the session: the one place that builds it, so ``drive/eip_io`` never sees a
        transport."""
        from akdctl.transport.eip_io import IoConnection

        channel = self.cip()
        return IoConnection(channel.link, self.target.host, rpi_ms=rpi_ms, port=port, local_port=local_port,
                            timeout=self.options.timeout, tracer=self.options.tracer,
                            timeout_multiplier=timeout_multiplier)

    def parameters(self) -> "ParameterChannel":
        """The PROFIdrive parameter channel; UsageError naming the alternatives if the target has none."""
        self.transport()
        if self._parameters is None and self._record_link is not None:
            from akdctl.channels.bmp import BmpParameterChannel

            self._parameters = BmpParameterChannel(self._record_link)
        return self._offered(self._parameters, "no PROFIdrive parameter channel (PNUs); use 'sdo' commands "
                                               "or a sim/pn:// target")

    def objects(self) -> "ObjectChannel":
        """The SDO object channel; UsageError naming the alternatives if the target has none."""
        self.transport()
        return self._offered(self._objects, "no object channel (SDO); use 'pnu' commands or a sim/ecat/can target")

    def _offered(self, channel: "T | None", missing: str) -> "T":
        if channel is None:
            # Name only what this target has (issue 23 item 20): a hint to 'sdo' on a target without SDO misleads.
            missing, _, where = missing.partition("; use ")
            has = [words for present, words in ((self._parameters is not None or self._record_link is not None,
                                                 "'pnu' commands"), (self._objects is not None, "'sdo' commands"),
                                                (self._cip is not None, "'cip' and 'eip' commands"))
                   if present]
            where = where.split(" or ")[-1] if " or " in where else where
            hint = (f"; this target offers {' and '.join(has)}" if has else "") + (f"; or use {where}" if where else "")
            raise UsageError(f"target {self.target.display} offers {missing}{hint}")
        return channel

    def axis(self) -> "Axis":
        """The axis of this target, in the profile :func:`akdctl.drive.axis.choice.open_axis` chooses."""
        from akdctl.drive.axis.choice import open_axis

        return open_axis(self)

    # ---------------------------------------------------------------- end
    def close(self) -> None:
        """Close the channels and the transport; safe to call twice and after a failed open."""
        transport, self._transport = self._transport, None
        self._closed = True
        channels = [c for c in (self._objects, self._parameters) if c is not None]
        self._parameters = self._objects = self._cip = None
        self._commands = self._registers = None
        self._record_link = None
        for channel in channels:
            with contextlib.suppress(Exception):
                channel.close()
        owner, self.axis_owner = self.axis_owner, None
        try:
            if transport is not None:
                transport.close()
        finally:
            if owner is not None:  # the last: another command may move the axis only after we let go of it
                owner.release()


__all__ = ["Connection", "open_tracer"]
