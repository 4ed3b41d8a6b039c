"""The one vocabulary of channels and axis profiles: which words exist and what each needs.

Why a module of its own on the ground floor: the transport registry (what a scheme offers), the
axis choice (which profile a target speaks), the recipe's step check (which channel a step needs)
and the config file (which ``drive`` a profile may name) all spoke of the same few words, each with
its own copy -- a comma string split in one place, a word table in another, a tuple in a third --
and the copies drifted (a recipe step on an ``eip://`` target looked up a word its table lacked).
Here they are written once, as enums whose values are the words users type, so comparing with a
string still works and a misspelt member fails at import, not at run time.
"""

from __future__ import annotations

from enum import Enum


class Channel(str, Enum):
    """A channel a target offers: what the Connection can build over the transport's links."""

    PARAMETERS = "parameters"  # PROFIdrive base-mode parameter access (PNUs)
    OBJECTS = "objects"  # CoE/CANopen SDO (index:subindex)
    ATTRIBUTES = "attributes"  # CIP explicit messaging (class/instance/attribute)

    @property
    def words(self) -> str:
        """The channel in a sentence ("this step needs a PROFIdrive parameter channel (PNUs)")."""
        return _CHANNEL_WORDS[self]

    def __str__(self) -> str:
        return self.value


_CHANNEL_WORDS = {
    Channel.PARAMETERS: "a PROFIdrive parameter channel (PNUs)",
    Channel.OBJECTS: "an object channel (SDO)",
    Channel.ATTRIBUTES: "a CIP attribute channel (EtherNet/IP)",
}


class DriveProfile(str, Enum):
    """An axis profile: the language motion speaks to the drive (``?drive=``, a config profile's ``drive``)."""

    PROFIDRIVE = "profidrive"  # STW1/ZSW1, telegrams (PROFINET, the simulator)
    CIA402 = "cia402"  # controlword/statusword over SDO (EtherCAT, CANopen, the simulator)
    CIP = "cip"  # the Position Controller object 0x25 (EtherNet/IP)

    @property
    def channel(self) -> Channel:
        """The channel this profile's axis is driven over."""
        return _PROFILE_CHANNEL[self]

    def __str__(self) -> str:
        return self.value


_PROFILE_CHANNEL = {
    DriveProfile.PROFIDRIVE: Channel.PARAMETERS,
    DriveProfile.CIA402: Channel.OBJECTS,
    DriveProfile.CIP: Channel.ATTRIBUTES,
}

#: The profile words in the order messages list them ("use 'profidrive', 'cia402' or 'cip'").
PROFILE_WORDS: tuple[str, ...] = tuple(p.value for p in DriveProfile)


def profiles_text(profiles: "tuple[DriveProfile, ...] | list[DriveProfile]" = tuple(DriveProfile)) -> str:
    """"'profidrive', 'cia402' or 'cip'": the choices in a message."""
    quoted = [f"'{p.value}'" for p in profiles]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]


def drive_profile(word: str) -> DriveProfile | None:
    """The profile a word names, or None if it names none."""
    try:
        return DriveProfile(word)
    except ValueError:
        return None


def default_profile(offered: frozenset[Channel]) -> DriveProfile:
    """The profile a target speaks when nobody chose one: the CIP Position Controller where CIP is
    offered, PROFIdrive where parameters are, else CiA 402."""
    if Channel.ATTRIBUTES in offered:
        return DriveProfile.CIP
    if Channel.PARAMETERS in offered:
        return DriveProfile.PROFIDRIVE
    return DriveProfile.CIA402


def usable_profiles(offered: frozenset[Channel]) -> tuple[DriveProfile, ...]:
    """The profiles whose channel the target offers."""
    return tuple(p for p in DriveProfile if p.channel in offered)


__all__ = ["Channel", "DriveProfile", "PROFILE_WORDS", "default_profile", "drive_profile", "profiles_text",
           "usable_profiles"]
