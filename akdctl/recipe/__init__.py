"""Commissioning recipes: TOML files of ordered steps, validated whole before anything is written.

``loader`` reads the file(s) and remembers lines, ``schema`` checks every step
and resolves it into a :class:`~akdctl.recipe.schema.PlannedStep`, ``ops`` runs
each action through the drive layer's one implementation, ``runner`` runs the
steps and makes the axis safe on failure, ``report`` writes JSON and JUnit XML.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from akdctl.connection import Connection


def load_and_validate(path: str | Path, *, allow_outside: bool = False, conn: "Connection | None" = None) -> tuple[Any, list[Any]]:
    """(RawRecipe, [PlannedStep]); raises RecipeError listing every problem.

    ``conn`` (the connection; nothing is read from the drive) gives the config profile's limits and units and
    the target's axis profile and channels, so motion steps and channels are checked as the commands check them.
    """
    from akdctl.recipe import loader, schema

    recipe, structural = loader.load(path, allow_outside=allow_outside)
    ctx = schema.Context(Path(path).resolve().parent, allow_outside, conn)
    return recipe, schema.validate(recipe, ctx, structural)
