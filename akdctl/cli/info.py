"""``akdctl info``: identify the drive — who made it and what it is first, then every identity value read."""

from __future__ import annotations

from typing import Any

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc


def _flatten(prefix: str, value: Any, doc: Doc) -> None:
    from akdctl.drive.identity import value_text

    if isinstance(value, dict):
        for key, sub in value.items():
            _flatten(f"{prefix}.{key}" if prefix else key, sub, doc)
    elif isinstance(value, int) and not isinstance(value, bool):
        doc.kv(prefix, value_text(prefix, value))
    else:
        doc.kv(prefix, value)


@click.command()
def info() -> None:
    """Identify the drive: vendor, model, firmware, serial, profile; then PNU 964/965/975, 0x1018 and
    0x1008-0x100A, I&M0 on PROFINET, the CIP identity on EtherNet/IP.

    \b
    Examples:
      akdctl info
      akdctl -T pn://192.168.0.10 info --json
    """
    from akdctl.drive.identity import read_identity, summary

    app = get_app()
    identity = read_identity(app.connection)
    brief = summary(identity)

    def human() -> Doc:
        doc = Doc("drive identity", app.target.display)
        for key, value in brief.items():
            doc.kv(key, value)
        _flatten("", identity, doc)
        return doc

    app.emit({"target": app.target.display, "summary": brief, **identity}, human)
