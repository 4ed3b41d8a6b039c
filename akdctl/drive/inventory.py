"""A line of drives: the inventory file, its checks, selection and per-drive substitution.

Why a file: a machine builder commissions 8, 30, 100 AKDs that differ in a name, an alias or a few tuning values.
The inventory names each drive once -- its target string, a stable key (the serial number where the drive
reports one), free tags -- and carries its own values (``vars``) that a recipe takes by substitution. Every
command that runs on many drives (``--inventory FILE --select TAG|NAME``) reads it here, and refuses a bad file
before anything is written to any drive, in one line naming the entry.

The format (TOML)::

    [[drive]]
    name = "axis1"                       # letters, digits, '.', '_', '-'; unique
    target = "pn://192.168.0.21"         # any akdctl target; unique by the drive it reaches
    key = "serial:2575499411"            # optional, unique: how discover recognised the drive
    tags = ["line3", "conveyor"]         # optional: --select matches a tag or a name
    [drive.vars]                         # optional: ${vars.NAME} (or ${NAME}) in a recipe
    alias = 1001
    vl_kp = 0.85

Two entries that reach one drive (the same target spelled twice, ``pn://H`` and ``pn://H:34964``) are refused:
:func:`akdctl.drive.gate.owner_key`, the owner lock's key, is the one rule for "the same axis".
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from difflib import get_close_matches
from pathlib import Path
from typing import Any

from akdctl.errors import UsageError
from akdctl.protocol.record import Record

#: An inventory larger than this is refused, not parsed (it would be ~10 000 drives).
MAX_INVENTORY_BYTES = 4 << 20
NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}"
_NAME = re.compile(NAME_PATTERN)
_ENTRY_KEYS = {"name", "target", "key", "tags", "vars"}
_VAR = re.compile(r"\$(?:\$|\{([A-Za-z_][A-Za-z0-9_.]*)\})")


class LineDrive(Record):
    """One drive of the line as the inventory names it (``entry``: its 1-based position in the file)."""

    __slots__ = ("name", "target", "key", "tags", "vars", "entry")

    def __init__(self, name: str, target: str, key: str | None = None, tags: Sequence[str] = (),
                 vars: dict[str, Any] | None = None, entry: int = 0) -> None:
        self.name = name
        self.target = target
        self.key = key
        self.tags = tuple(tags)
        self.vars = dict(vars or {})
        self.entry = entry

    def to_json(self) -> dict[str, Any]:
        data: dict[str, Any] = {"name": self.name, "target": self.target}
        if self.key:
            data["key"] = self.key
        if self.tags:
            data["tags"] = list(self.tags)
        if self.vars:
            data["vars"] = dict(self.vars)
        return data


class Inventory:
    """The drives of one inventory file, checked; :meth:`select` picks the ones a command runs on."""

    def __init__(self, drives: Sequence[LineDrive], path: str = "") -> None:
        self.drives = list(drives)
        self.path = path

    def select(self, selectors: Iterable[str]) -> list[LineDrive]:
        """The drives matching any selector (a drive name or a tag), in file order; all drives when none.

        An unknown selector is a usage error naming the closest names and tags: a typo must never run a command
        on fewer drives than meant.
        """
        wanted = [s for s in selectors if s]
        if not wanted:
            return list(self.drives)
        names = {d.name for d in self.drives}
        tags = {t for d in self.drives for t in d.tags}
        for selector in wanted:
            if selector not in names and selector not in tags:
                close = get_close_matches(selector, sorted(names | tags), n=3, cutoff=0.5)
                hint = f"; did you mean {', '.join(close)}?" if close else f"; names: {_few(names)}; tags: {_few(tags)}"
                raise UsageError(f"inventory {self.path}: --select {selector!r} is no drive name or tag{hint}")
        return [d for d in self.drives if d.name in wanted or any(t in wanted for t in d.tags)]


def _few(items: Iterable[str]) -> str:
    shown = sorted(items)
    return ", ".join(shown[:8]) + (", ..." if len(shown) > 8 else "") if shown else "(none)"


def load(path: str) -> Inventory:
    """Read and check an inventory file (bounded, regular files only); UsageError naming the entry otherwise."""
    import tomllib

    from akdctl.io.safe_read import FileRefused, read_bounded

    try:
        data = read_bounded(path, MAX_INVENTORY_BYTES)
    except FileRefused as exc:
        why = exc.kind or (f"larger than {MAX_INVENTORY_BYTES} bytes" if exc.size or exc.grew else "refused")
        raise UsageError(f"inventory {path}: not read ({why})") from None
    except OSError as exc:
        raise UsageError(f"inventory {path}: {exc.strerror or exc}") from None
    try:
        document = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise UsageError(f"inventory {path}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"inventory {path}: not valid TOML ({exc})") from None
    return parse(document, path)


def parse(document: dict[str, Any], path: str = "inventory") -> Inventory:
    """Check a parsed inventory document: every problem is one line naming the entry."""
    from akdctl.drive.gate import owner_key
    from akdctl.transport.registry import parse_target

    unknown = set(document) - {"drive", "inventory"}
    if unknown:
        raise UsageError(f"inventory {path}: unknown table {sorted(unknown)[0]!r} (expected [[drive]] entries)")
    entries = document.get("drive")
    if not isinstance(entries, list) or not entries:
        raise UsageError(f"inventory {path}: no [[drive]] entries")
    drives: list[LineDrive] = []
    seen_name: dict[str, int] = {}
    seen_axis: dict[str, LineDrive] = {}
    seen_key: dict[str, LineDrive] = {}
    for number, entry in enumerate(entries, 1):
        where = f"inventory {path}: drive entry {number}"
        if not isinstance(entry, dict):
            raise UsageError(f"{where}: expected a table ([[drive]]), found {type(entry).__name__}")
        extra = set(entry) - _ENTRY_KEYS
        if extra:
            raise UsageError(f"{where}: unknown key {sorted(extra)[0]!r} (known: {', '.join(sorted(_ENTRY_KEYS))})")
        name = entry.get("name")
        if not isinstance(name, str) or not _NAME.fullmatch(name):
            raise UsageError(f"{where}: 'name' must be 1-64 letters, digits, '.', '_' or '-', "
                             f"starting with a letter or digit (found {name!r})")
        where = f"inventory {path}: drive {name!r} (entry {number})"
        if name in seen_name:
            raise UsageError(f"{where}: the name is also entry {seen_name[name]}")
        target_text = entry.get("target")
        if not isinstance(target_text, str) or not target_text.strip():
            raise UsageError(f"{where}: 'target' must be a target string such as pn://HOST or sim://NAME")
        try:
            target = parse_target(target_text, source=f"{where}: target")
        except UsageError as exc:
            raise UsageError(exc.message if exc.message.startswith(where) else f"{where}: {exc.message}") from None
        key = entry.get("key")
        if key is not None and (not isinstance(key, str) or not key):
            raise UsageError(f"{where}: 'key' must be a non-empty string")
        tags = entry.get("tags", [])
        if not isinstance(tags, list) or not all(isinstance(t, str) and _NAME.fullmatch(t) for t in tags):
            raise UsageError(f"{where}: 'tags' must be a list of names (letters, digits, '.', '_', '-')")
        variables = entry.get("vars", {})
        if not isinstance(variables, dict):
            raise UsageError(f"{where}: 'vars' must be a table")
        for var, value in variables.items():
            if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", var):
                raise UsageError(f"{where}: variable name {var!r} must be letters, digits and '_'")
            if isinstance(value, (dict, list)) or value is None:
                raise UsageError(f"{where}: variable {var!r} must be a string, number or boolean")
        drive = LineDrive(name, target_text, key, tags, variables, number)
        axis = owner_key(target)
        if axis in seen_axis:
            other = seen_axis[axis]
            raise UsageError(f"{where}: target {target_text} reaches the same drive as {other.name!r} "
                             f"(entry {other.entry}, {other.target})")
        if key is not None and key in seen_key:
            other = seen_key[key]
            raise UsageError(f"{where}: key {key!r} is also drive {other.name!r} (entry {other.entry}): "
                             "two entries for one drive")
        seen_name[name] = number
        seen_axis[axis] = drive
        if key is not None:
            seen_key[key] = drive
        drives.append(drive)
    return Inventory(drives, path)


def substitute(text: str, drive: LineDrive, *, what: str = "recipe") -> str:
    """``${name}``, ``${target}``, ``${key}``, ``${vars.X}`` (or ``${X}``) replaced by the drive's values;
    ``$$`` is a literal ``$``; comments are left as written. A variable the drive does not define is a usage error naming both.

    Values are inserted as TOML would write them: a string quoted, a number or boolean bare -- so
    ``speed = ${vars.rpm}`` and ``name = ${name}`` both parse. Inside a quoted string write ``"${X}"`` and the
    string's own text is inserted (without a second pair of quotes).
    """
    fixed = {"name": drive.name, "target": drive.target, "key": drive.key or ""}

    def value_of(var: str) -> Any:
        if var in fixed:
            return fixed[var]
        short = var.removeprefix("vars.")
        if short in drive.vars:
            return drive.vars[short]
        known = sorted([*fixed, *(f"vars.{k}" for k in drive.vars)])
        raise UsageError(f"{what}: ${{{var}}} is not defined for drive {drive.name!r} "
                         f"(entry {drive.entry}; defined: {', '.join(known)})")

    out: list[str] = []
    last = 0
    for match in _VAR.finditer(text):
        out.append(text[last:match.start()])
        last = match.end()
        var = match.group(1)
        where = _context(text, match.start())
        if where == "comment":
            out.append(match.group(0))  # a comment keeps its text: documentation of a variable is no use of it
            continue
        if var is None:
            out.append("$")
            continue
        value = value_of(var)
        if where == "string":
            out.append(toml_escape(str(value)))
        else:
            out.append(toml_value(value))
    out.append(text[last:])
    return "".join(out)


def _context(text: str, position: int) -> str:
    """Where ``position`` of a TOML line lies: ``"string"`` inside a basic ("...") string, ``"comment"`` after a
    ``#`` outside one, else ``"value"``."""
    line_start = text.rfind("\n", 0, position) + 1
    inside = False
    escaped = False
    for char in text[line_start:position]:
        if escaped:
            escaped = False
        elif char == "\\" and inside:
            escaped = True
        elif char == '"':
            inside = not inside
        elif char == "#" and not inside:
            return "comment"
    return "string" if inside else "value"


def toml_value(value: Any) -> str:
    """A scalar as TOML writes it: booleans and numbers bare, anything else a basic string."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    return '"' + toml_escape(str(value)) + '"'


def toml_escape(text: str) -> str:
    """The inside of a TOML basic string: quote, backslash and every control character (DEL included) escaped,
    everything else as it is (TOML files are UTF-8; an escaped astral character would need a surrogate pair,
    which TOML forbids)."""
    out = []
    for char in text:
        code = ord(char)
        if char in '"\\':
            out.append("\\" + char)
        elif code < 0x20 or code == 0x7F:
            out.append(f"\\u{code:04X}")
        else:
            out.append(char)
    return "".join(out)


def dump(drives: Sequence[LineDrive], *, comment: str = "") -> str:
    """An inventory file's text for ``discover --write-inventory`` (loadable by :func:`load`)."""
    lines = [f"# {line}" for line in comment.splitlines()] if comment else []
    lines.append("# akdctl inventory: one [[drive]] per drive; add tags and [drive.vars] for recipes.")
    for drive in drives:
        lines += ["", "[[drive]]", f"name = {toml_value(drive.name)}", f"target = {toml_value(drive.target)}"]
        if drive.key:
            lines.append(f"key = {toml_value(drive.key)}")
        lines.append("tags = [" + ", ".join(toml_value(t) for t in drive.tags) + "]")
        if drive.vars:
            lines.append("[drive.vars]")
            lines += [f"{k} = {toml_value(v)}" for k, v in drive.vars.items()]
    return "\n".join(lines) + "\n"


def unique_name(wanted: str, taken: set[str]) -> str:
    """A drive name derived from ``wanted`` that the inventory does not have yet (``axis``, ``axis-2``...)."""
    base = re.sub(r"[^A-Za-z0-9._-]+", "-", wanted).strip("-._")[:56] or "drive"
    if not base[0].isalnum():
        base = "d" + base
    name, number = base, 2
    while name in taken:
        name = f"{base}-{number}"
        number += 1
    taken.add(name)
    return name


def write(path: str, text: str) -> None:
    """Write the inventory atomically with the project's one file-mode rule."""
    from akdctl.io.atomic import write_user_file

    write_user_file(Path(path), text)


__all__ = ["Inventory", "LineDrive", "dump", "load", "parse", "substitute", "toml_value", "unique_name", "write"]
