"""Rendering results: rich on a terminal, plain aligned text when piped, JSON for machines.

Commands build a small *document* (title, key/value pairs, tables, lines) and
hand it to :func:`render`; they never print directly. Rich is imported only
when a document is rendered to a terminal, so ``--help`` and piped output stay
fast. Data goes to stdout; messages go to stderr through :func:`message`.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from typing import Any, TextIO


@dataclass
class Table:
    columns: list[str]
    rows: list[list[Any]]
    title: str = ""


@dataclass
class Doc:
    """A human-readable result. ``source`` names the target it came from."""

    title: str = ""
    source: str = ""
    pairs: list[tuple[str, Any]] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)
    lines: list[str] = field(default_factory=list)

    def kv(self, key: str, value: Any) -> "Doc":
        self.pairs.append((key, value))
        return self

    def table(self, columns: list[str], rows: list[list[Any]], title: str = "") -> "Doc":
        self.tables.append(Table(columns, rows, title))
        return self

    def line(self, text: str) -> "Doc":
        self.lines.append(text)
        return self


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def render_plain(doc: Doc, out: TextIO) -> None:
    """Aligned plain text: stable, grep-friendly, no colour."""
    header = doc.title
    if doc.source:
        header = f"{header} ({doc.source})" if header else f"target: {doc.source}"
    if header:
        out.write(header + "\n")
    if doc.pairs:
        width = max(len(k) for k, _ in doc.pairs)
        for key, value in doc.pairs:
            out.write(f"  {key.ljust(width)}  {_cell(value)}\n")
    for table in doc.tables:
        if table.title:
            out.write(f"{table.title}\n")
        cells = [[_cell(c) for c in row] for row in table.rows]
        widths = [len(c) for c in table.columns]
        for row in cells:
            for i, c in enumerate(row):
                widths[i] = max(widths[i], len(c))
        out.write("  ".join(c.ljust(w) for c, w in zip(table.columns, widths)).rstrip() + "\n")
        for row in cells:
            out.write("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() + "\n")
    for line in doc.lines:
        out.write(line + "\n")


def render_rich(doc: Doc) -> None:
    from rich.console import Console
    from rich.table import Table as RichTable

    console = Console()
    header = doc.title or "result"
    if doc.source:
        header += f" [dim]({doc.source})[/dim]"
    console.print(f"[bold]{header}[/bold]")
    if doc.pairs:
        grid = RichTable.grid(padding=(0, 2))
        grid.add_column(style="cyan")
        grid.add_column()
        for key, value in doc.pairs:
            grid.add_row(key, _cell(value))
        console.print(grid)
    for table in doc.tables:
        rt = RichTable(title=table.title or None, title_justify="left")
        for col in table.columns:
            rt.add_column(col)
        for row in table.rows:
            rt.add_row(*(_cell(c) for c in row))
        console.print(rt)
    for line in doc.lines:
        console.print(line, highlight=False, markup=False)


def render(doc: Doc | str, out: TextIO | None = None) -> None:
    out = out or sys.stdout
    if isinstance(doc, str):
        out.write(doc if doc.endswith("\n") else doc + "\n")
        return
    if out is sys.stdout and sys.stdout.isatty():
        render_rich(doc)
    else:
        render_plain(doc, out)


def emit_json(data: Any, out: TextIO | None = None) -> None:
    out = out or sys.stdout
    json.dump(data, out, indent=2, sort_keys=False, default=_json_default)
    out.write("\n")


def _json_default(value: Any) -> Any:
    if isinstance(value, (bytes, bytearray)):
        return value.hex()
    if hasattr(value, "to_json"):
        return value.to_json()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def message(text: str) -> None:
    """A message for the user (stderr), never mixed with data."""
    sys.stderr.write(text + "\n")
    sys.stderr.flush()
