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
    drive = "profidrive"       # or "cia402": which axis profile motion commands use
    [profiles.line3-axis1.limits]
    max_velocity = 600         # rpm
    max_acceleration = 5000    # rpm/s
    travel = [-100.0, 100.0]   # rev, absolute moves outside are refused
    [profiles.line3-axis1.units]
    name = "mm"
    per_rev = 5.0              # user units per motor revolution
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from akdctl.errors import UsageError


def default_config_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "akdctl" / "config.toml"


@dataclass
class Profile:
    """One named profile of the config file (all keys optional)."""

    name: str
    target: str | None = None
    timeout: float | None = None
    drive: str | None = None
    limits: dict[str, Any] = field(default_factory=dict)
    units: dict[str, Any] = field(default_factory=dict)
    raw: dict[str, Any] = field(default_factory=dict)


@dataclass
class Config:
    path: Path | None
    default_profile: str | None
    profiles: dict[str, Profile]


def load_config(path: str | os.PathLike[str] | None) -> Config:
    """Load the config file. An explicit path must exist; the default one may be absent."""
    explicit = path is not None or bool(os.environ.get("AKDCTL_CONFIG"))
    file = Path(path) if path is not None else Path(os.environ.get("AKDCTL_CONFIG") or default_config_path())
    try:
        data = tomllib.loads(file.read_text())
    except FileNotFoundError:
        if explicit:
            raise UsageError(f"config file {file} does not exist") from None
        return Config(None, None, {})
    except OSError as exc:
        raise UsageError(f"cannot read config file {file}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise UsageError(f"config file {file} is not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"config file {file}: {exc}") from None
    profiles_data = data.get("profiles", {})
    if not isinstance(profiles_data, dict):
        raise UsageError(f"config file {file}: [profiles] must be a table of profiles")
    profiles = {}
    for name, body in profiles_data.items():
        if not isinstance(body, dict):
            raise UsageError(f"config file {file}: profile {name!r} must be a table")
        profiles[name] = _profile(file, name, body)
    default = data.get("default_profile")
    if default is not None and not isinstance(default, str):
        raise UsageError(f"config file {file}: default_profile must be a string")
    return Config(file, default, profiles)


def _profile(file: Path, name: str, body: dict[str, Any]) -> Profile:
    def typed(key: str, kind: type | tuple[type, ...]) -> Any:
        value = body.get(key)
        if value is not None and not isinstance(value, kind):
            raise UsageError(f"config file {file}: profiles.{name}.{key} has the wrong type")
        return value

    timeout = typed("timeout", (int, float))
    if timeout is not None and timeout <= 0:
        raise UsageError(f"config file {file}: profiles.{name}.timeout must be positive")
    drive = typed("drive", str)
    if drive is not None and drive not in ("profidrive", "cia402"):
        raise UsageError(f"config file {file}: profiles.{name}.drive must be 'profidrive' or 'cia402'")
    return Profile(
        name=name,
        target=typed("target", str),
        timeout=float(timeout) if timeout is not None else None,
        drive=drive,
        limits=dict(typed("limits", dict) or {}),
        units=dict(typed("units", dict) or {}),
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
