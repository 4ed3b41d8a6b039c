"""Rendering results: rich on a terminal, plain aligned text when piped, JSON for machines.

Commands build a small *document* (title, key/value pairs, tables, lines) and
hand it to :func:`render`; they never print directly. Rich is imported only
when a document is rendered to a terminal, so ``--help`` and piped output stay
fast. Data goes to stdout; messages go to stderr through :func:`message`.

**Everything is shown inert** (issue 14, 17.11). Text that reaches a terminal may
come from a user (a recipe named ``Line 3 [/axis1]``), a drive (a visible string
object holding ``ESC ]0;title BEL``) or a file (a support bundle). One rule,
here: :func:`inert` makes every control character visible (``\x1b``, ``\n``, C1
controls, bidirectional overrides), and the rich renderer never parses markup in
what it prints (cells are :class:`rich.text.Text`, not markup strings), so
neither an escape sequence nor ``[link=...]`` can act on the terminal. Every
printer in akdctl goes through this module (documents, messages, errors, live
views); JSON output escapes control characters by itself.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from typing import Any, TextIO

from akdctl.protocol.record import Record


class Table(Record):
    """A table of a document: column names, rows of cells, an optional title."""

    __slots__ = ("columns", "rows", "title")
    __hash__ = None  # type: ignore[assignment]

    def __init__(self, columns: list[str], rows: list[list[Any]], title: str = "") -> None:
        self.columns = columns
        self.rows = rows
        self.title = title


class Doc(Record):
    """A human-readable result. ``source`` names the target it came from."""

    __slots__ = ("title", "source", "pairs", "tables", "lines")
    __hash__ = None  # type: ignore[assignment]

    def __init__(self, title: str = "", source: str = "", pairs: list[tuple[str, Any]] | None = None,
                 tables: list[Table] | None = None, lines: list[str] | None = None) -> None:
        self.title = title
        self.source = source
        self.pairs: list[tuple[str, Any]] = [] if pairs is None else pairs
        self.tables: list[Table] = [] if tables is None else tables
        self.lines: list[str] = [] if lines is None else lines

    def kv(self, key: str, value: Any) -> "Doc":
        self.pairs.append((key, value))
        return self

    def table(self, columns: list[str], rows: list[list[Any]], title: str = "") -> "Doc":
        self.tables.append(Table(columns, rows, title))
        return self

    def line(self, text: str) -> "Doc":
        self.lines.append(text)
        return self


# C0 controls, DEL, C1 controls, and the Unicode bidirectional overrides/isolates (text that reorders itself).
# (Patterns, compiled by re on first use and cached there: a command prints with one of them, if at all.)
_CONTROL = "[\x00-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]"
_CONTROL_KEEP_LINES = "[\x00-\x08\x0b-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]"
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _visible(match: re.Match[str]) -> str:
    char = match.group()
    if char in _NAMED:
        return _NAMED[char]
    code = ord(char)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def inert(value: Any, *, lines: bool = False) -> str:
    """``value`` as text that cannot act on a terminal: every control character shown as an escape.

    ``ESC`` becomes ``\\x1b``, a newline ``\\n``, C1 controls ``\\x9b``, bidirectional overrides
    ``\\u202e``; printable text (any script) is unchanged. ``lines=True`` keeps newlines and tabs
    (a message of several lines we wrote ourselves). Rich markup is not this function's concern:
    the renderer never parses markup in what it prints.
    """
    shown = value if isinstance(value, str) else str(value)
    if shown.isprintable():  # no control or format character at all (the usual cell): nothing to escape
        return shown
    return re.sub(_CONTROL_KEEP_LINES if lines else _CONTROL, _visible, shown)


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:g}"
    return inert(value)


def render_plain(doc: Doc, out: TextIO) -> None:
    """Aligned plain text: stable, grep-friendly, no colour."""
    header = inert(doc.title)
    if doc.source:
        header = f"{header} ({inert(doc.source)})" if header else f"target: {inert(doc.source)}"
    if header:
        out.write(header + "\n")
    if doc.pairs:
        keys = [inert(k) for k, _ in doc.pairs]
        width = max(len(k) for k in keys)
        for key, (_, value) in zip(keys, doc.pairs):
            out.write(f"  {key.ljust(width)}  {_cell(value)}\n")
    for table in doc.tables:
        if table.title:
            out.write(f"{inert(table.title)}\n")
        columns = [inert(c) for c in table.columns]
        cells = [[_cell(c) for c in row] for row in table.rows]
        widths = [len(c) for c in columns]
        for row in cells:
            for i, c in enumerate(row):
                widths[i] = max(widths[i], len(c))
        out.write("  ".join(c.ljust(w) for c, w in zip(columns, widths)).rstrip() + "\n")
        for row in cells:
            out.write("  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() + "\n")
    for line in doc.lines:
        out.write(inert(line) + "\n")


def text(value: Any, style: str = "") -> Any:
    """A :class:`rich.text.Text` of ``value`` made :func:`inert`: rich shows it literally, never as markup."""
    from rich.text import Text

    return Text(_cell(value), style=style)


def rich_doc(doc: Doc) -> Any:
    """The rich renderable of a document (also what ``status --watch`` redraws in place)."""
    from rich.console import Group
    from rich.table import Table as RichTable

    parts: list[Any] = []
    header = text(doc.title or "result", "bold")
    if doc.source:
        header.append_text(text(f" ({doc.source})", "dim"))
    parts.append(header)
    if doc.pairs:
        grid = RichTable.grid(padding=(0, 2))
        grid.add_column(style="cyan")
        grid.add_column()
        for key, value in doc.pairs:
            grid.add_row(text(key), text(value))
        parts.append(grid)
    for table in doc.tables:
        rt = RichTable(title=text(table.title) if table.title else None, title_justify="left")
        for col in table.columns:
            rt.add_column(text(col), overflow="fold")  # data is wrapped, never cut off
        for row in table.rows:
            rt.add_row(*(text(c) for c in row))
        parts.append(rt)
    parts.extend(text(line) for line in doc.lines)
    return Group(*parts)


def console(stderr: bool = False) -> Any:
    """The one rich Console (markup and highlighting off: nothing we print is parsed)."""
    from rich.console import Console

    return Console(stderr=stderr, markup=False, highlight=False, emoji=False)


def render_rich(doc: Doc) -> None:
    console().print(rich_doc(doc))


def render(doc: Doc | str, out: TextIO | None = None) -> None:
    out = out or sys.stdout
    if isinstance(doc, str):
        shown = inert(doc.rstrip("\n"), lines=True)
        out.write(shown + "\n")
        return
    if out is sys.stdout and sys.stdout.isatty():
        render_rich(doc)
    else:
        render_plain(doc, out)


def emit_json(data: Any, out: TextIO | None = None) -> None:
    out = out or sys.stdout
    import json  # here: only --json output needs it

    json.dump(data, out, indent=2, sort_keys=False, default=_json_default)
    out.write("\n")


def emit_json_line(data: Any, out: TextIO | None = None) -> None:
    """One JSON document on one line, flushed (a stream of documents: ``status --watch --json``)."""
    out = out or sys.stdout
    import json

    out.write(json.dumps(data, separators=(",", ":"), default=_json_default) + "\n")
    out.flush()


class LiveView:
    """Successive states of one view (``status --watch``): redrawn in place on a terminal (rich Live), one JSON
    document per line with ``--json``, plain documents one after another (a blank line between) when piped."""

    def __init__(self, json_lines: bool) -> None:
        self.json_lines = json_lines
        self.terminal = not json_lines and sys.stdout.isatty()
        self._live: Any = None
        self._shown = 0

    def __enter__(self) -> "LiveView":
        if self.terminal:
            from rich.live import Live

            self._live = Live(console=console(), auto_refresh=False, transient=False)
            self._live.start()
        return self

    def show(self, data: Any, human: Callable[[], Doc]) -> None:
        if self.json_lines:
            emit_json_line(data)
        elif self._live is not None:
            self._live.update(rich_doc(human()), refresh=True)
        else:
            if self._shown:
                sys.stdout.write("\n")
            render_plain(human(), sys.stdout)
            sys.stdout.flush()
        self._shown += 1

    def __exit__(self, *exc: object) -> None:
        if self._live is not None:
            self._live.stop()


def _json_default(value: Any) -> Any:
    if isinstance(value, (bytes, bytearray)):
        return value.hex()
    if hasattr(value, "to_json"):
        return value.to_json()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def message(words: str) -> None:
    """A message for the user (stderr), never mixed with data; shown :func:`inert` (its own newlines kept)."""
    sys.stderr.write(inert(words, lines=True) + "\n")
    sys.stderr.flush()
