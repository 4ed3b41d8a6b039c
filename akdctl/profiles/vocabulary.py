"""The one vocabulary of channels and axis profiles: which words exist and what each needs.

Why a module of its own on the ground floor: the transport registry (what a scheme offers), the
axis choice (which profile a target speaks), the recipe's step check (which channel a step needs)
and the config file (which ``drive`` a profile may name) all spoke of the same few words, each with
its own copy -- a comma string split in one place, a word table in another, a tuple in a third --
and the copies drifted (a recipe step on an ``eip://`` target looked up a word its table lacked).
Here they are written once, as constants whose values are the words users type (``str`` subclasses, so
comparing with a string still works; plain class attributes rather than ``enum`` members, which cost every
start that imports this module about ten times as much -- docs/internals.md, "Cold start"). A word maps to
its one constant with :func:`channel` / :func:`drive_profile`; each constant exists once, so ``is`` compares.
"""

from __future__ import annotations

from typing import ClassVar


class Channel(str):
    """A channel a target offers: what the Connection can build over the transport's links."""

    __slots__ = ()
    PARAMETERS: ClassVar[Channel]  # PROFIdrive base-mode parameter access (PNUs)
    OBJECTS: ClassVar[Channel]  # CoE/CANopen SDO (index:subindex)
    ATTRIBUTES: ClassVar[Channel]  # CIP explicit messaging (class/instance/attribute)
    COMMANDS: ClassVar[Channel]  # the AKD's ASCII command channel (NAME[ value] lines)
    REGISTERS: ClassVar[Channel]  # Modbus TCP holding registers
    ALL: ClassVar[tuple[Channel, ...]]

    @property
    def value(self) -> str:
        """The word (as an enum member's ``value``)."""
        return str.__str__(self)

    @property
    def words(self) -> str:
        """The channel in a sentence ("this step needs a PROFIdrive parameter channel (PNUs)")."""
        return _CHANNEL_WORDS[self]


Channel.PARAMETERS = Channel("parameters")
Channel.OBJECTS = Channel("objects")
Channel.ATTRIBUTES = Channel("attributes")
Channel.COMMANDS = Channel("commands")
Channel.REGISTERS = Channel("registers")
Channel.ALL = (Channel.PARAMETERS, Channel.OBJECTS, Channel.ATTRIBUTES, Channel.COMMANDS, Channel.REGISTERS)

_CHANNEL_WORDS = {
    Channel.PARAMETERS: "a PROFIdrive parameter channel (PNUs)",
    Channel.OBJECTS: "an object channel (SDO)",
    Channel.ATTRIBUTES: "a CIP attribute channel (EtherNet/IP)",
    Channel.COMMANDS: "the AKD's command channel (akd://)",
    Channel.REGISTERS: "Modbus TCP registers (mb://)",
}


class DriveProfile(str):
    """An axis profile: the language motion speaks to the drive (``?drive=``, a config profile's ``drive``)."""

    __slots__ = ()
    PROFIDRIVE: ClassVar[DriveProfile]  # STW1/ZSW1, telegrams (PROFINET, the simulator)
    CIA402: ClassVar[DriveProfile]  # controlword/statusword over SDO (EtherCAT, CANopen, the simulator)
    CIP: ClassVar[DriveProfile]  # the Position Controller object 0x25 (EtherNet/IP)
    AKD: ClassVar[DriveProfile]  # the AKD's own DRV.* commands over its command channel (akd://)
    ALL: ClassVar[tuple[DriveProfile, ...]]

    @property
    def value(self) -> str:
        """The word (as an enum member's ``value``)."""
        return str.__str__(self)

    @property
    def channel(self) -> Channel:
        """The channel this profile's axis is driven over."""
        return _PROFILE_CHANNEL[self]


DriveProfile.PROFIDRIVE = DriveProfile("profidrive")
DriveProfile.CIA402 = DriveProfile("cia402")
DriveProfile.CIP = DriveProfile("cip")
DriveProfile.AKD = DriveProfile("akd")
DriveProfile.ALL = (DriveProfile.PROFIDRIVE, DriveProfile.CIA402, DriveProfile.CIP, DriveProfile.AKD)

_PROFILE_CHANNEL = {
    DriveProfile.PROFIDRIVE: Channel.PARAMETERS,
    DriveProfile.CIA402: Channel.OBJECTS,
    DriveProfile.CIP: Channel.ATTRIBUTES,
    DriveProfile.AKD: Channel.COMMANDS,
}
_CHANNELS = {c.value: c for c in Channel.ALL}
_PROFILES = {p.value: p for p in DriveProfile.ALL}

#: The profile words in the order messages list them ("use 'profidrive', 'cia402' or 'cip'").
PROFILE_WORDS: tuple[str, ...] = tuple(p.value for p in DriveProfile.ALL)


def channel(word: str) -> Channel | None:
    """The channel a word names (its one constant), or None if it names none."""
    return _CHANNELS.get(word)


def drive_profile(word: str) -> DriveProfile | None:
    """The profile a word names (its one constant), or None if it names none."""
    return _PROFILES.get(word)


def profiles_text(profiles: tuple[DriveProfile, ...] = DriveProfile.ALL) -> str:
    """"'profidrive', 'cia402' or 'cip'": the choices in a message."""
    quoted = [f"'{p.value}'" for p in profiles]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]


def default_profile(offered: frozenset[Channel]) -> DriveProfile:
    """The profile a target speaks when nobody chose one: the CIP Position Controller where CIP is
    offered, the AKD's own commands on its command channel, PROFIdrive where parameters are, else CiA 402.
    Modbus offers no axis: no published AKD register holds the enable state (issue 24)."""
    if Channel.ATTRIBUTES in offered:
        return DriveProfile.CIP
    if Channel.COMMANDS in offered:
        return DriveProfile.AKD
    if offered == frozenset({Channel.REGISTERS}):
        from akdctl.errors import UsageError

        raise UsageError("the axis (status, enable, motion) is not offered over Modbus: no published AKD register "
                         "holds its enable state; read 'akdctl param get DRV.MOTIONSTAT DRV.FAULT1' there, or use "
                         "akd://HOST or a fieldbus target")
    if Channel.PARAMETERS in offered:
        return DriveProfile.PROFIDRIVE
    return DriveProfile.CIA402


def usable_profiles(offered: frozenset[Channel]) -> tuple[DriveProfile, ...]:
    """The profiles whose channel the target offers."""
    return tuple(p for p in DriveProfile.ALL if p.channel in offered)


__all__ = ["Channel", "DriveProfile", "PROFILE_WORDS", "channel", "default_profile", "drive_profile",
           "profiles_text", "usable_profiles"]
