"""``akdctl info``: identify the drive."""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc


def _flatten(prefix: str, value: Any, doc: Doc) -> None:
    if isinstance(value, dict):
        for key, sub in value.items():
            _flatten(f"{prefix}.{key}" if prefix else key, sub, doc)
    elif isinstance(value, int) and not isinstance(value, bool) and value > 9:
        doc.kv(prefix, f"{value} (0x{value:X})")
    else:
        doc.kv(prefix, value)


@click.command()
def info() -> None:
    """Identify the drive: PNU 964/965/975 and/or 0x1018, 0x1008-0x100A (and I&M0 on PROFINET)."""
    from akdctl.drive.identity import read_identity

    app = get_app()
    identity = read_identity(app.connection)

    def human() -> Doc:
        doc = Doc("drive identity", app.target.display)
        _flatten("", identity, doc)
        return doc

    app.emit({"target": app.target.display, **identity}, human)
