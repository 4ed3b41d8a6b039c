"""Reading recipe files: TOML text → raw steps that remember their file and line.

Why line numbers by hand: ``tomllib`` returns plain data without positions, yet
a technician fixing a broken recipe needs "file:line". The ``[[step]]`` headers
are found in the text in order (the n-th header is the n-th step) and a key's
line is the first ``key =`` inside that step's block.

Recipes are data. The only way one file reaches another is an ``include`` step
(or a ``restore`` step's backup file), and both must stay inside the recipe's
folder unless the caller passes ``allow_outside`` (``--allow-outside-includes``).
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from akdctl.errors import UsageError

MAX_INCLUDE_DEPTH = 8
MAX_RECIPE_BYTES = 1_000_000
_HEADER = re.compile(r"^\s*\[\[\s*step\s*\]\]\s*(#.*)?$")
_ANY_HEADER = re.compile(r"^\s*\[")


@dataclass
class RawStep:
    """One ``[[step]]`` table as written, with where it was written."""

    data: dict[str, Any]
    file: Path
    line: int | None
    key_lines: dict[str, int] = field(default_factory=dict)
    number: int = 0  # 1-based position in the whole (flattened) recipe

    def line_of(self, key: str | None) -> int | None:
        if key is not None and key in self.key_lines:
            return self.key_lines[key]
        return self.line

    def where(self, key: str | None = None, display_root: Path | None = None) -> str:
        line = self.line_of(key)
        name = display_path(self.file, display_root)
        return f"{name}:{line}" if line is not None else name


@dataclass
class RawRecipe:
    path: Path
    name: str
    description: str
    steps: list[RawStep]
    header: dict[str, Any]


class RecipeError(UsageError):
    """The recipe file is not a valid recipe; ``problems`` lists every reason (file:line: step: what)."""

    kind = "recipe"

    def __init__(self, problems: list[str]) -> None:
        first = problems[0]
        more = f" (and {len(problems) - 1} more problem{'s' if len(problems) > 2 else ''})" if len(problems) > 1 else ""
        super().__init__(f"recipe rejected, nothing was written: {first}{more}", details={"problems": problems})
        self.problems = problems


def display_path(path: Path, root: Path | None) -> str:
    """A path as the user gave it (relative to the working directory when possible, never absolute if avoidable)."""
    try:
        return str(path.relative_to(Path.cwd()))
    except ValueError:
        pass
    if root is not None:
        try:
            return str(path.relative_to(root))
        except ValueError:
            pass
    return str(path)


def _step_lines(text: str) -> list[tuple[int, dict[str, int]]]:
    """(header line, {key: line}) of every ``[[step]]`` block, in order."""
    lines = text.splitlines()
    blocks: list[tuple[int, dict[str, int]]] = []
    current: dict[str, int] | None = None
    for number, line in enumerate(lines, start=1):
        if _HEADER.match(line):
            current = {}
            blocks.append((number, current))
            continue
        if _ANY_HEADER.match(line):
            current = None
            continue
        if current is not None:
            match = re.match(r"^\s*\"?([A-Za-z0-9_\-]+)\"?\s*=", line)
            if match and match.group(1) not in current:
                current[match.group(1)] = number
    return blocks


def _top_key_line(text: str, key: str) -> int | None:
    for number, line in enumerate(text.splitlines(), start=1):
        if re.match(rf"^\s*{re.escape(key)}\s*=", line) or re.match(rf"^\s*\[+\s*{re.escape(key)}\s*\]+", line):
            return number
    return None


def read_recipe_file(path: Path, display_root: Path | None = None) -> tuple[dict[str, Any], str]:
    from akdctl.io.safe_read import read_regular_text

    name = display_path(path, display_root)
    if not path.exists() and not path.is_symlink():
        raise RecipeError([f"{name}: no such recipe file"])
    try:
        text = read_regular_text(path, limit=MAX_RECIPE_BYTES, what="a recipe (TOML)", name=name)
    except UsageError as exc:
        raise RecipeError([exc.message]) from None
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise RecipeError([f"{name}: nested too deeply to be a recipe"]) from None
    except tomllib.TOMLDecodeError as exc:
        detail = str(exc)
        match = re.search(r"\(at line (\d+), column (\d+)\)", detail)
        if match:
            detail = detail[: match.start()].strip()
            raise RecipeError([f"{name}:{match.group(1)}: not valid TOML: {detail} (column {match.group(2)})"]) from None
        raise RecipeError([f"{name}: not valid TOML: {detail}"]) from None
    return data, text


def inside(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
        return True
    except ValueError:
        return False


def load(path: str | Path, *, allow_outside: bool = False) -> tuple[RawRecipe, list[str]]:
    """Read a recipe and its includes; returns the recipe and the structural problems found."""
    root_file = Path(path)
    if root_file.suffix.lower() != ".toml":
        raise RecipeError([f"{root_file}: a recipe is a .toml file"])
    folder = root_file.resolve().parent
    problems: list[str] = []
    data, text = read_recipe_file(root_file)
    header = data.get("recipe", {})
    if not isinstance(header, dict):
        problems.append(f"{display_path(root_file, folder)}:{_top_key_line(text, 'recipe') or 1}: "
                        "'recipe' must be a table ([recipe] with name, description)")
        header = {}
    for key in header:
        if key not in ("name", "description", "format"):
            problems.append(f"{display_path(root_file, folder)}:{_top_key_line(text, key) or 1}: [recipe]: unknown key "
                            f"{key!r}; allowed: name, description, format")
    if header.get("format", 1) != 1:
        problems.append(f"{display_path(root_file, folder)}: [recipe] format {header.get('format')!r} is not supported "
                        "(expected 1)")
    steps: list[RawStep] = []
    _collect(root_file, data, text, folder, allow_outside, steps, problems, [root_file.resolve()])
    for number, step in enumerate(steps, start=1):
        step.number = number
    if not steps and not problems:
        problems.append(f"{display_path(root_file, folder)}: the recipe has no steps; add [[step]] tables")
    name = header.get("name") if isinstance(header.get("name"), str) else root_file.stem
    description = header.get("description") if isinstance(header.get("description"), str) else ""
    return RawRecipe(root_file, name, description, steps, header), problems


def _collect(file: Path, data: dict[str, Any], text: str, folder: Path, allow_outside: bool,
             steps: list[RawStep], problems: list[str], chain: list[Path]) -> None:
    shown = display_path(file, folder)
    for key in data:
        if key not in ("recipe", "step"):
            problems.append(f"{shown}:{_top_key_line(text, key) or 1}: unknown top-level key {key!r}; a recipe has "
                            "[recipe] and [[step]] tables")
    raw_steps = data.get("step", [])
    if not isinstance(raw_steps, list) or not all(isinstance(s, dict) for s in raw_steps):
        problems.append(f"{shown}:{_top_key_line(text, 'step') or 1}: 'step' must be an array of tables ([[step]])")
        return
    positions = _step_lines(text)
    for n, table in enumerate(raw_steps):
        line, key_lines = positions[n] if n < len(positions) else (None, {})
        step = RawStep(dict(table), file, line, dict(key_lines))
        if table.get("action") != "include":
            steps.append(step)
            continue
        target = table.get("file")
        where = step.where("file", folder)
        if not isinstance(target, str) or not target:
            problems.append(f"{where}: include step: 'file' must name a recipe file (a string)")
            continue
        included = (file.parent / target)
        if not allow_outside and not inside(included, folder):
            problems.append(f"{where}: include step: {target!r} is outside the recipe's folder; recipes may only "
                            "include files from their own folder (use --allow-outside-includes to permit it)")
            continue
        if included.suffix.lower() != ".toml":
            problems.append(f"{where}: include step: {target!r} is not a .toml recipe")
            continue
        if included.resolve() in chain:
            problems.append(f"{where}: include step: {target!r} includes itself (include loop)")
            continue
        if len(chain) >= MAX_INCLUDE_DEPTH:
            problems.append(f"{where}: include step: includes nested deeper than {MAX_INCLUDE_DEPTH}")
            continue
        extra = set(table) - {"action", "file", "name"}
        if extra:
            problems.append(f"{where}: include step: unknown key(s) {', '.join(sorted(extra))}; allowed: file, name")
        try:
            sub_data, sub_text = read_recipe_file(included, folder)
        except RecipeError as exc:
            problems.append(f"{where}: include step: {exc.problems[0]}")
            continue
        _collect(included, sub_data, sub_text, folder, allow_outside, steps, problems, chain + [included.resolve()])
