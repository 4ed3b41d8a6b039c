"""The user's config file and how the target is resolved.

Resolution order (first wins): ``--target/-T``, ``$AKDCTL_TARGET``, the
``target`` of the selected profile, ``sim``. The profile is ``--profile``, else
``$AKDCTL_PROFILE``, else the file's ``default_profile``. The file is
``--config FILE``, else ``$AKDCTL_CONFIG``, else ``config.toml`` in the user's
config dir (``$XDG_CONFIG_HOME/akdctl`` or ``~/.config/akdctl``)::

    default_profile = "bench"

    [profiles.bench]
    target = "sim"
    timeout = 1.5              # seconds, overridden by --timeout

    [profiles.line3-axis1]
    target = "pn://192.168.0.21"
    drive = "profidrive"       # or "cia402", "cip": which axis profile motion commands use
    [profiles.line3-axis1.limits]
    max_velocity = 600         # rpm
    max_acceleration = 5000    # rpm/s
    max_jog_duration = 10      # s, a timed jog (jog --for) is refused beyond it (the tool's own maximum is 60 s)
    travel = [-100.0, 100.0]   # rev, absolute moves outside are refused
    [profiles.line3-axis1.units]
    name = "mm"
    per_rev = 5.0              # user units per motor revolution
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from akdctl.errors import UsageError
from akdctl.protocol.record import Record
from akdctl.profiles.vocabulary import PROFILE_WORDS


def default_config_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "akdctl" / "config.toml"


class Profile(Record):
    """One named profile of the config file (all keys optional; the tables are the file's, read-only by use).

    A :class:`~akdctl.protocol.record.Record`, not a named tuple: every command loads this module, and building a
    named tuple class costs about 1 M instructions of each start (issue 29)."""

    __slots__ = ("name", "target", "timeout", "drive", "limits", "units", "raw")

    def __init__(self, name: str, target: str | None = None, timeout: float | None = None, drive: str | None = None,
                 limits: dict[str, Any] | None = None, units: dict[str, Any] | None = None,
                 raw: dict[str, Any] | None = None) -> None:
        self.name = name
        self.target = target
        self.timeout = timeout
        self.drive = drive
        self.limits: dict[str, Any] = {} if limits is None else limits
        self.units: dict[str, Any] = {} if units is None else units
        self.raw: dict[str, Any] = {} if raw is None else raw

    __hash__ = None  # type: ignore[assignment]  # its tables are dicts, as the named tuple's made it unhashable


class Config(Record):
    """The parsed file (a Record for the reason :class:`Profile` is one)."""

    __slots__ = ("path", "default_profile", "profiles")

    def __init__(self, path: Path | None, default_profile: str | None, profiles: dict[str, Profile]) -> None:
        self.path = path
        self.default_profile = default_profile
        self.profiles = profiles

    __hash__ = None  # type: ignore[assignment]  # its profiles are a dict


TOP_KEYS = ("default_profile", "profiles")
PROFILE_KEYS = ("target", "timeout", "drive", "limits", "units")
LIMIT_KEYS = ("max_velocity", "max_acceleration", "max_jog_duration", "travel")
UNIT_KEYS = ("name", "per_rev")
DRIVE_PROFILES = PROFILE_WORDS  # the one vocabulary (profiles/vocabulary.py); a target may narrow it


class _Where:
    """Names file, profile and key in every config error (exit 2)."""

    def __init__(self, file: Path) -> None:
        self.file = file

    def error(self, key: str, problem: str) -> UsageError:
        return UsageError(f"config file {self.file}: {key}: {problem}")

    def unknown(self, prefix: str, data: dict[str, Any], allowed: tuple[str, ...]) -> None:
        import difflib

        for key in data:
            if key not in allowed:
                close = difflib.get_close_matches(str(key), allowed, n=1)
                hint = f"did you mean '{close[0]}'?" if close else f"known keys: {', '.join(allowed)}"
                raise self.error(f"{prefix}{key}", f"unknown key; {hint}")

    def number(self, key: str, value: Any, *, positive: bool = False) -> float:
        import math

        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"must be a number, got {type(value).__name__} {value!r}")
        if not math.isfinite(float(value)):
            raise self.error(key, f"must be a finite number, got {value!r}")
        if positive and value <= 0:
            raise self.error(key, f"must be greater than 0, got {value!r}")
        return float(value)


#: The largest config file read (bytes): a hand-written file of profiles is a few KiB; 1 MiB leaves room for
#: thousands of profiles and refuses a wrong path (a log, an image, /dev/zero) before it costs memory.
CONFIG_LIMIT = 1 << 20


def load_config(path: str | os.PathLike[str] | None) -> Config:
    """Load and validate the config file (unknown keys, types, NaN/inf, signs: exit 2 naming file and key).

    An explicit path must exist; the default one may be absent.
    """
    explicit = path is not None or bool(os.environ.get("AKDCTL_CONFIG"))
    file = Path(path) if path is not None else Path(os.environ.get("AKDCTL_CONFIG") or default_config_path())
    from akdctl.io.safe_read import FileRefused, read_bounded

    try:
        # The one bounded reader (issue 23.13): /dev/zero, a FIFO or a huge file is refused, never read for ever.
        text = read_bounded(file, CONFIG_LIMIT).decode("utf-8")
    except FileNotFoundError:
        if explicit:
            raise UsageError(f"config file {file} does not exist") from None
        return Config(None, None, {})
    except FileRefused as refused:
        what = f"is {refused.kind}, not a regular file" if refused.kind else (
            f"grew beyond {CONFIG_LIMIT} bytes while it was read" if refused.grew
            else f"has {refused.size} bytes, more than the {CONFIG_LIMIT} a config file may have")
        raise UsageError(f"config file {file} {what}") from None
    except OSError as exc:
        raise UsageError(f"cannot read config file {file}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise UsageError(f"config file {file} is not UTF-8 text") from None
    import tomllib  # only when there is a file: most runs have none, and the parser costs a cold start ~3 ms

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"config file {file}: {exc}") from None
    where = _Where(file)
    where.unknown("", data, TOP_KEYS)
    profiles_data = data.get("profiles", {})
    if not isinstance(profiles_data, dict):
        raise UsageError(f"config file {file}: [profiles] must be a table of profiles")
    profiles = {}
    for name, body in profiles_data.items():
        if not isinstance(body, dict):
            raise UsageError(f"config file {file}: profile {name!r} must be a table")
        profiles[name] = _profile(where, name, body)
    default = data.get("default_profile")
    if default is not None and not isinstance(default, str):
        raise UsageError(f"config file {file}: default_profile must be a string")
    return Config(file, default, profiles)


def _profile(where: _Where, name: str, body: dict[str, Any]) -> Profile:
    prefix = f"profiles.{name}."
    where.unknown(prefix, body, PROFILE_KEYS)

    def typed(key: str, kind: type | tuple[type, ...], words: str) -> Any:
        value = body.get(key)
        if value is not None and not isinstance(value, kind):
            raise UsageError(f"config file {where.file}: {prefix}{key} has the wrong type: must be {words}, got "
                             f"{type(value).__name__} {value!r}")
        return value

    timeout = body.get("timeout")
    if timeout is not None:
        timeout = where.number(prefix + "timeout", timeout, positive=True)
    drive = typed("drive", str, "text")
    if drive is not None and drive not in DRIVE_PROFILES:
        raise where.error(prefix + "drive", f"must be one of {', '.join(repr(d) for d in DRIVE_PROFILES)}, "
                                            f"got {drive!r}")
    limits = dict(typed("limits", dict, "a table") or {})
    where.unknown(prefix + "limits.", limits, LIMIT_KEYS)
    for key in ("max_velocity", "max_acceleration", "max_jog_duration"):
        if key in limits:
            limits[key] = where.number(f"{prefix}limits.{key}", limits[key], positive=True)
    if "travel" in limits:
        travel = limits["travel"]
        key = f"{prefix}limits.travel"
        if not isinstance(travel, list) or len(travel) != 2:
            raise where.error(key, f"must be [min, max] in revolutions, got {travel!r}")
        lo, hi = (where.number(key, v) for v in travel)
        if lo >= hi:
            raise where.error(key, f"min {lo:g} must be less than max {hi:g}")
        limits["travel"] = [lo, hi]
    units = dict(typed("units", dict, "a table") or {})
    where.unknown(prefix + "units.", units, UNIT_KEYS)
    if "per_rev" in units:
        units["per_rev"] = where.number(f"{prefix}units.per_rev", units["per_rev"], positive=True)
    if "name" in units and not isinstance(units["name"], str):
        raise where.error(f"{prefix}units.name", f"must be text, got {units['name']!r}")
    return Profile(
        name=name,
        target=typed("target", str, "text"),
        timeout=timeout,
        drive=drive,
        limits=limits,
        units=units,
        raw=dict(body),
    )


def select_profile(config: Config, name: str | None) -> Profile | None:
    """The profile asked for (``--profile``/``$AKDCTL_PROFILE``) or the file's default."""
    wanted = name or os.environ.get("AKDCTL_PROFILE") or None
    if wanted is None:
        wanted = config.default_profile
        if wanted is None:
            return None
    profile = config.profiles.get(wanted)
    if profile is None:
        where = f" in {config.path}" if config.path else " (no config file found)"
        known = ", ".join(sorted(config.profiles)) or "none"
        raise UsageError(f"no profile {wanted!r}{where}; profiles: {known}")
    return profile


def resolve_target_text(cli_target: str | None, profile: Profile | None) -> tuple[str, str]:
    """(target string, where it came from)."""
    if cli_target:
        return cli_target, "--target"
    env = os.environ.get("AKDCTL_TARGET")
    if env:
        return env, "AKDCTL_TARGET"
    if profile is not None and profile.target:
        return profile.target, f"profile {profile.name!r}"
    return "sim", "default"
