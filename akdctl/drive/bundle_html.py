"""A support bundle as one self-contained HTML page (``akdctl support show --html FILE``).

Why so strict: the page is opened by a support engineer's browser, and everything on it came from a drive or a
technician's machine. So: every value passes :func:`html.escape` (text and attributes), the only markup is what
this module writes, there is no script at all, and a Content-Security-Policy forbids loading anything (no network
access is needed or possible: the style is inline, the scope plot an inline SVG drawn from numbers by
:func:`akdctl.drive.bundle_report.scope_svg`).
"""

from __future__ import annotations

from html import escape

from akdctl.drive.bundle_report import Section

CSP = "default-src 'none'; style-src 'unsafe-inline'; img-src data:"

STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",sans-serif;margin:1.5em;color:#222;background:#fafafa}
h1{font-size:1.4em;margin:0 0 .3em}h2{font-size:1.15em;border-bottom:2px solid #2a5d9f;padding-bottom:.15em;margin-top:1.6em}
nav a{margin-right:1em;color:#2a5d9f}
table{border-collapse:collapse;margin:.4em 0 1em;font-size:.9em;background:#fff}
th,td{border:1px solid #ccc;padding:.2em .5em;text-align:left;vertical-align:top}
th{background:#e8eef7}
td{white-space:pre-wrap;word-break:break-word;max-width:48em}
table.kv td:first-child{font-weight:600;white-space:nowrap}
td:first-child{white-space:nowrap}
tr.mark td{background:#fff3c4}tr.mark td:first-child{border-left:4px solid #d18b00}
.note{color:#8a2b2b;margin:.2em 0}.legend{font-size:.85em;color:#555}
.mono td:nth-child(4){font-family:ui-monospace,monospace;font-size:.85em}
"""


def _table_html(headers: list[str], rows: list[list[str]], marked: list[bool], css: str = "") -> list[str]:
    out = [f'<table class="{escape(css)}">' if css else "<table>"]
    if headers:
        out.append("<tr>" + "".join(f"<th>{escape(h)}</th>" for h in headers) + "</tr>")
    for row, mark in zip(rows, marked):
        out.append(("<tr class=\"mark\">" if mark else "<tr>") + "".join(f"<td>{escape(c)}</td>" for c in row) + "</tr>")
    out.append("</table>")
    return out


def render(sections: list[Section], title: str) -> str:
    """The whole page as text (UTF-8 when written)."""
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f'<meta http-equiv="Content-Security-Policy" content="{escape(CSP)}">',
           '<meta name="viewport" content="width=device-width, initial-scale=1">',
           f"<title>{escape(title)}</title><style>{STYLE}</style></head><body>",
           f"<h1>{escape(title)}</h1>",
           "<nav>" + "".join(f'<a href="#{escape(s.key)}">{escape(s.title)}</a>' for s in sections) + "</nav>",
           ('<p class="legend">Highlighted rows: active faults and warnings; parameters whose value differs from '
            "the catalogue default.</p>")]
    for s in sections:
        out.append(f'<section id="{escape(s.key)}"><h2>{escape(s.title)}</h2>')
        out += [f'<p class="note">{escape(n)}</p>' for n in s.notes]
        if s.pairs:
            out += _table_html([], [[k, v] for k, v in s.pairs], [False] * len(s.pairs), "kv")
        if s.svg is not None:
            out.append(f'<div class="scope">{s.svg}</div>')
        for t in s.tables:
            if t.rows:
                out.append(f"<h3>{escape(t.title)}</h3>")
                out += _table_html(t.headers, t.rows, t.marked, "mono" if s.key == "trace" else "")
        out.append("</section>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"
