"""``akdctl targets``: which transports exist and whether they can run here."""

from __future__ import annotations

import click

from akdctl.cli.context import get_app
from akdctl.cli.output import Doc


@click.command()
def targets() -> None:
    """List the transports, their target syntax and whether their dependencies are present.

    \b
    Examples:
      akdctl targets
      akdctl targets --json
    """
    from akdctl.profiles.vocabulary import Channel
    from akdctl.transport.registry import BUILTIN, module_available

    app = get_app()
    rows = []
    for spec in BUILTIN.values():
        missing = [m for m in spec.requires if not module_available(m)]  # other projects' modules only
        if missing:
            state = f"missing {', '.join(missing)}" + (f" (pip install 'akdctl[{spec.extra}]')" if spec.extra else "")
        else:
            state = "available"
        rows.append({"scheme": spec.scheme, "syntax": spec.syntax,
                     "channels": ", ".join(c.value for c in Channel.ALL if c in spec.channels),
                     "state": state, "available": not missing, "summary": spec.summary})
    app.emit(
        {"transports": rows},
        lambda: Doc("transports").table(
            ["scheme", "target syntax", "channels", "state", "what"],
            [[r["scheme"], r["syntax"], r["channels"], r["state"], r["summary"]] for r in rows],
        ),
    )
