"""A support bundle as a report: sections of key/value rows and tables, in the order a support engineer reads them.

Why one model and two writers: ``support show --html`` and ``support show --format markdown`` must show the same
facts (identity, status, the fault dump with explanations and remedies, parameters with the values that differ
from the catalogue default marked, process-data mapping, the session trace, a scope recording) and the same
escaping rules; the facts are chosen here once, and :mod:`akdctl.drive.bundle_html` / :func:`markdown` only lay
them out. Every value is kept as plain text: the writers escape it, nothing from the bundle is ever markup.

A bundle is a file from outside: every section is read defensively (a missing or odd section becomes a note in
that section, never an exception), so a damaged-but-loadable bundle still gives a page.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

#: PNUs whose value the selected telegram sets (PZD set point / actual value assignment): compared with nothing.
FOLLOW_TELEGRAM = frozenset({915, 916})
#: Trace rows shown at most (a long session's trace would make a page nobody can open).
MAX_TRACE_ROWS = 5000


class Table:
    """Rows under headers; ``marked[i]`` highlights row i (a non-default parameter, an active fault)."""

    __slots__ = ("headers", "marked", "rows", "title")

    def __init__(self, title: str, headers: list[str]) -> None:
        self.title = title
        self.headers = headers
        self.rows: list[list[str]] = []
        self.marked: list[bool] = []

    def add(self, row: list[Any], marked: bool = False) -> None:
        self.rows.append([text(v) for v in row])
        self.marked.append(marked)


class Section:
    """One part of the report: key/value pairs, tables, notes, and optionally an SVG the report drew itself."""

    __slots__ = ("key", "notes", "pairs", "svg", "tables", "title")

    def __init__(self, key: str, title: str) -> None:
        self.key = key
        self.title = title
        self.pairs: list[tuple[str, str]] = []
        self.tables: list[Table] = []
        self.notes: list[str] = []
        self.svg: str | None = None  # built by scope_svg from numbers only: its text parts are escaped there

    def kv(self, key: str, value: Any) -> Section:
        self.pairs.append((text(key), text(value)))
        return self

    def table(self, title: str, headers: list[str]) -> Table:
        table = Table(title, headers)
        self.tables.append(table)
        return table


def text(value: Any) -> str:
    """A value as the text a page shows: None is empty, lists are joined, everything else is ``str``."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (list, tuple)):
        return ", ".join(text(v) for v in value)
    return str(value)


def _flat(prefix: str, value: Any, section: Section, depth: int = 0,
          shown: Callable[[str, Any], Any] | None = None) -> None:
    """Nested values as dotted key/value pairs; ``shown(key, value)`` gives a leaf's text where the caller knows more."""
    if isinstance(value, dict) and depth < 6:
        for key, sub in value.items():
            _flat(f"{prefix}.{key}" if prefix else str(key), sub, section, depth + 1, shown)
    elif isinstance(value, list) and value and all(isinstance(v, dict) and "set" in v for v in value):
        section.kv(prefix, ", ".join(text(v.get("name", v.get("bit"))) for v in value if v.get("set")) or "none set")
    elif isinstance(value, list) and len(value) > 16:
        section.kv(prefix, f"[{len(value)} values] " + text(value[:16]) + ", …")
    elif isinstance(value, list) and any(isinstance(v, dict) for v in value):
        section.kv(prefix, "; ".join(" ".join(text(x) for x in v.values()) if isinstance(v, dict) else text(v)
                                     for v in value))
    else:
        section.kv(prefix, shown(prefix, value) if shown is not None else value)


def _dict(value: Any) -> dict[str, Any]:
    return value if isinstance(value, dict) else {}


def _list(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


# ---------------------------------------------------------------------------- sections
def header(data: dict[str, Any], name: str) -> Section:
    tool, target = _dict(data.get("tool")), _dict(data.get("target"))
    s = Section("bundle", "Support bundle")
    s.kv("file", name).kv("created", data.get("created"))
    s.kv("written by", f"{text(tool.get('name'))} {text(tool.get('version'))} (Python {text(tool.get('python'))}, "
                       f"{text(tool.get('platform'))})")
    s.kv("target", target.get("display")).kv("scheme", target.get("scheme"))
    s.kv("drive profile", target.get("drive_profile") or "auto")
    for section, words in sorted(_dict(data.get("errors")).items()):
        s.notes.append(f"{section}: {text(words)}")
    return s


def identity(data: dict[str, Any]) -> Section:
    """Who the drive is in words first (vendor, model, firmware, serial: ``info``'s summary), then every value read,
    numbers with their words as ``info`` shows them (``256 (0x100, Kollmorgen)``)."""
    from akdctl.drive.identity import summary, value_text

    s = Section("identity", "Identity")
    ident = data.get("identity")
    if isinstance(ident, dict) and "error" in ident:
        s.notes.append(f"not readable: {text(ident['error'])}")
        return s
    ident = _dict(ident)
    try:
        brief = summary(ident)
    except (TypeError, ValueError, AttributeError, KeyError):  # a bundle from elsewhere may hold anything
        brief = {}
    for key, value in brief.items():
        s.kv(key, value)
    _flat("", ident, s, shown=lambda key, value: value_text(key, value)
          if isinstance(value, int) and not isinstance(value, bool) else value)
    return s


def status(data: dict[str, Any]) -> Section:
    s = Section("status", "Status")
    st = data.get("status")
    if isinstance(st, dict) and "error" in st:
        s.notes.append(f"not readable: {text(st['error'])}")
        return s
    st = _dict(st)
    for key in ("state", "state_text", "mode_text", "enabled", "fault", "warning", "homed", "target_reached",
                "standstill", "position_counts", "position_rev", "velocity_rpm", "current_pct", "word_hex"):
        if key in st:  # None: the drive's status does not say (homed outside position mode, for one)
            s.kv(key.replace("_", " "), "not reported" if st[key] is None else st[key])
    for key in ("faults", "warnings"):
        items = _list(st.get(key))
        if items:
            s.kv(key, "; ".join(f"{text(_dict(i).get('code'))} {text(_dict(i).get('text'))}".strip() for i in items))
    bits = _list(st.get("bits"))
    if bits:
        s.kv("bits set", ", ".join(text(_dict(b).get("name")) for b in bits if _dict(b).get("set")) or "none")
    return s


def diagnosis(data: dict[str, Any]) -> Section | None:
    """The bundle's diagnosis (``akdctl diagnose``): each cause with its remedy, blocking ones marked."""
    if "diagnosis" not in data:
        return None  # a bundle written before the diagnosis was collected
    s = Section("diagnosis", "Diagnosis")
    d = data.get("diagnosis")
    if not isinstance(d, dict) or "error" in d:
        s.notes.append(f"not readable: {text(_dict(d).get('error', 'missing'))}")
        return s
    s.kv("verdict", d.get("verdict"))
    t = s.table("causes, most likely first", ["", "cause", "remedy", "evidence"])
    for c in _list(d.get("causes")):
        c = _dict(c)
        t.add(["blocks" if c.get("blocking") else "note", c.get("text"), c.get("remedy"), c.get("evidence")],
              marked=bool(c.get("blocking")))
    for name, why in _dict(d.get("not_read")).items():
        s.kv(f"not read: {name}", why)
    return s


def _fault_items(faults: dict[str, Any]) -> list[tuple[str, dict[str, Any], str]]:
    """(source, item, role) for every fault or warning the dump names: active first, then the history."""
    active, past = [], []
    for source, body in faults.items():
        body = _dict(body)
        for key in ("active", "faults", "warnings"):
            for item in _list(body.get(key)):
                if isinstance(item, dict):
                    active.append((source, item, "active" if key != "warnings" else "warning"))
        for situation in _list(body.get("acknowledged")):
            for item in _list(_dict(situation).get("faults")):
                if isinstance(item, dict):
                    past.append((source, item, f"acknowledged (situation {text(_dict(situation).get('situation'))})"))
        for key in ("fault_history", "error_history"):
            for item in _list(body.get(key)):
                if isinstance(item, dict):
                    past.append((source, item, key.replace("_", " ")))
    return active + past


def faults(data: dict[str, Any]) -> Section:
    """The fault dump, each fault with the catalogue's explanation and remedy (or where to look for one)."""
    from akdctl.catalog import faults as catalog

    s = Section("faults", "Faults")
    dump = data.get("faults")
    if not isinstance(dump, dict) or "error" in dump:
        s.notes.append(f"not readable: {text(_dict(dump).get('error', 'missing'))}")
        return s
    for source, body in dump.items():
        if isinstance(body, dict):
            for key in ("fault_present", "warning_present", "fault_message_counter", "error_register_text"):
                if key in body:
                    s.kv(f"{source} {key.replace('_', ' ')}", body[key])
    items = _fault_items(dump)
    table = s.table("faults and warnings", ["role", "source", "code", "name", "explanation", "remedy"])
    for source, item, role in items:
        code = item.get("code") or item.get("number")
        fault = catalog.by_code(code) if isinstance(code, (str, int)) and not isinstance(code, bool) else None
        if fault is None and isinstance(item.get("emcy"), str):
            try:
                found = catalog.by_emcy(int(item["emcy"], 16))
            except ValueError:
                found = []
            fault = found[0] if found else None
        name = item.get("name") or item.get("text") or (fault.name if fault else "")
        explanation = "not in the AKD fault table"
        if fault is not None:
            explanation = f"{fault.kind} {fault.code or ''}, EMCY 0x{fault.emcy:04X}".replace(" ,", ",")
            if fault.reaction:
                explanation += f"; drive reaction: {fault.reaction}"
        remedy = (fault.remedy or catalog.where_to_look(fault)) if fault else ""
        table.add([role, source, code, name, explanation, remedy], marked=role in ("active", "warning"))
    if not items:
        s.notes.append("no fault or warning active, none in the history")
    return s


def _pnu_default(pnu: Any) -> tuple[list[int] | None, bool]:
    from akdctl.catalog.pnus import pnu_table

    try:
        info = pnu_table().get(int(pnu))
    except (TypeError, ValueError):
        return None, False
    if info is None:
        return None, False
    if info.pnu in FOLLOW_TELEGRAM:
        return None, False  # the PZD lists follow the telegram (PNU 922): their catalogue 0s are no default
    return info.default_values(), "w" in info.access


def _object_default(address: Any) -> tuple[Any, bool]:
    from akdctl.catalog import objects as catalog

    try:
        index_text, _, sub_text = str(address).partition(":")
        entry = catalog.lookup(int(index_text, 16), int(sub_text or "0", 0))
    except ValueError:
        return None, False
    if entry is None:
        return None, False
    return entry.default, "w" in entry.access


def parameters(data: dict[str, Any]) -> Section:
    """PNUs and objects; a writable value that differs from the catalogue's default is marked."""
    s = Section("parameters", "Parameters")
    params = data.get("parameters")
    if not isinstance(params, dict) or "error" in params:
        s.notes.append(f"not readable: {text(_dict(params).get('error', 'missing'))}")
        return s
    marked = 0
    pnus = params.get("pnus")
    if isinstance(pnus, list):
        t = s.table("PNUs", ["PNU", "name", "value", "default", "meaning"])
        for r in pnus:
            r = _dict(r)
            if "error" in r:
                t.add([r.get("pnu"), r.get("name"), _dict(r["error"]).get("text", r["error"]), "", ""])
                continue
            values = _list(r.get("values"))
            default, writable = _pnu_default(r.get("pnu"))
            differs = writable and default is not None and values != default[:len(values)]
            marked += differs
            t.add([r.get("pnu"), r.get("name"), values, default if writable else "", r.get("meanings")], differs)
    elif isinstance(pnus, dict):
        s.notes.append(f"PNUs not readable: {text(pnus.get('error'))}")
    objects = params.get("objects")
    if isinstance(objects, list):
        t = s.table("objects", ["object", "name", "value", "default"])
        for o in objects:
            o = _dict(o)
            if "error" in o:
                t.add([o.get("object"), o.get("name"), o["error"], ""])
                continue
            value = o.get("value", o.get("hex"))
            default, writable = _object_default(o.get("object"))
            differs = writable and default is not None and value != default
            marked += differs
            t.add([o.get("object"), o.get("name"), value, default if writable else ""], differs)
    elif isinstance(objects, dict):
        s.notes.append(f"objects not readable: {text(objects.get('error'))}")
    s.kv("values not at their catalogue default", marked)
    return s


def mapping(data: dict[str, Any]) -> Section:
    s = Section("mapping", "Process-data mapping")
    m = data.get("mapping")
    if not isinstance(m, dict) or "error" in m:
        s.notes.append(f"not readable: {text(_dict(m).get('error', 'missing'))}")
        return s
    pd = m.get("profidrive")
    if isinstance(pd, dict):
        s.kv("telegram", pd.get("telegram"))
        s.kv("set points (PNU 915)", pd.get("setpoints_pnu915")).kv("actual values (PNU 916)", pd.get("actuals_pnu916"))
    co = m.get("canopen")
    if isinstance(co, dict) and "error" in co:
        s.notes.append(f"CANopen mapping not readable: {text(co['error'])}")
    elif isinstance(co, dict):
        t = s.table("PDO entries", ["dir", "PDO", "object", "bits", "name"])
        for direction, d in co.items():
            d = _dict(d)
            s.kv(f"{direction} assignment", f"{text(d.get('assign_object'))} = {text(d.get('assigned')) or 'none'} "
                                            f"({text(d.get('bytes'))} of {text(d.get('max_bytes'))} bytes)")
            for pdo in _list(d.get("pdos")):
                for e in _list(_dict(pdo).get("entries")):
                    e = _dict(e)
                    t.add([direction, _dict(pdo).get("name"), e.get("address"), e.get("bits"), e.get("name")])
    return s


def trace(data: dict[str, Any]) -> Section:
    records = _list(data.get("trace"))
    s = Section("trace", f"Session trace ({len(records)} frames)")
    t = s.table("frames", ["time", "dir", "layer", "bytes", "note"])
    first = None
    for rec in records[:MAX_TRACE_ROWS]:
        rec = _dict(rec)
        stamp = rec.get("time")
        if isinstance(stamp, (int, float)) and not isinstance(stamp, bool):
            first = stamp if first is None else first
            stamp = f"+{stamp - first:.4f}"
        t.add([stamp, "->" if rec.get("direction") == "tx" else "<-", rec.get("layer"), rec.get("hex"), rec.get("note")])
    if len(records) > MAX_TRACE_ROWS:
        s.notes.append(f"{len(records) - MAX_TRACE_ROWS} more frames not shown (the bundle holds them all)")
    return s


def _scope_columns(value: Any) -> list[tuple[str, list[float]]] | None:
    """An ``akdctl-scope`` recording (engineer "scope"'s bundle member: ``channels`` [{name, unit}], ``t``,
    ``values`` one column per channel) as named columns; None for another layout."""
    if not isinstance(value, dict) or value.get("format") != "akdctl-scope":
        return None
    channels, columns = value.get("channels"), value.get("values")
    if not isinstance(channels, list) or not isinstance(columns, list):
        return None
    out = []
    for channel, column in zip(channels, columns):
        if isinstance(column, list) and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in column):
            name = f"{text(_dict(channel).get('name'))} [{text(_dict(channel).get('unit'))}]"
            out.append((name, [float(v) for v in column]))
    return out


def _number_lists(value: Any, path: str = "", depth: int = 0) -> list[tuple[str, list[float]]]:
    """Every list of at least two numbers in the recording, named by its path (the channels to plot)."""
    scope_columns = _scope_columns(value) if depth == 0 else None
    if scope_columns is not None:
        return scope_columns
    found: list[tuple[str, list[float]]] = []
    if depth > 5:
        return found
    if isinstance(value, dict):
        label = value.get("name") if isinstance(value.get("name"), str) else None
        for key, sub in value.items():
            found += _number_lists(sub, label or (f"{path}.{key}" if path else str(key)), depth + 1)
    elif isinstance(value, list):
        if len(value) >= 2 and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            return [(path or "samples", [float(v) for v in value])]
        for i, sub in enumerate(value[:32]):
            found += _number_lists(sub, f"{path}[{i}]", depth + 1)
    return found


COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf")


def scope_svg(recording: Any) -> str | None:
    """The recording's channels as one inline SVG (each scaled to its own range), or None without numbers.

    Why our own drawing: the page must not carry markup from the bundle, so an SVG stored in the file is never
    pasted in; the numbers are plotted here and every name is escaped.
    """
    from html import escape
    from math import isfinite

    channels = [(name, [v for v in values if isfinite(v)]) for name, values in _number_lists(recording)]
    channels = [(n, v) for n, v in channels if len(v) >= 2 and n.split(".")[-1] not in ("time", "t", "time_s")][:6]
    if not channels:
        return None
    width, height, pad = 800, 240, 10
    parts = [(f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width} {height + 20 * len(channels)}" '
              f'width="{width}" role="img" aria-label="scope recording">'),
             f'<rect x="0" y="0" width="{width}" height="{height}" fill="#fff" stroke="#999"/>']
    for i, (name, values) in enumerate(channels):
        low, high = min(values), max(values)
        span = (high - low) or 1.0
        step = (width - 2 * pad) / (len(values) - 1)
        points = " ".join(f"{pad + k * step:.1f},{pad + (height - 2 * pad) * (1 - (v - low) / span):.1f}"
                          for k, v in enumerate(values[:4000]))
        colour = COLOURS[i % len(COLOURS)]
        parts.append(f'<polyline fill="none" stroke="{colour}" stroke-width="1.5" points="{points}"/>')
        parts.append(f'<text x="{pad}" y="{height + 16 + 20 * i}" font-size="13" fill="{colour}">'
                     f'{escape(name)}: {len(values)} samples, {low:g} … {high:g}</text>')
    parts.append("</svg>")
    return "".join(parts)


def _their_svg(recording: Any) -> str | None:
    """The scope's own picture (``drive/scope_svg.render_svg``: panels per unit, axes, trigger; it escapes every
    text it writes) when the member is an ``akdctl-scope`` recording; None otherwise, and ours is drawn."""
    from akdctl.drive.scope_model import Recording
    from akdctl.drive.scope_svg import render_svg

    try:
        svg = render_svg(Recording.from_json(recording))
    except (ValueError, TypeError, KeyError, ZeroDivisionError, OverflowError):
        return None
    svg = str(svg)
    return svg[svg.index("<svg"):] if "<svg" in svg else None  # the element only (no XML prolog inside HTML)


def scope(data: dict[str, Any]) -> Section | None:
    """The scope recording the bundle holds (member ``scope``), drawn; None when the bundle has none."""
    if "scope" not in data:
        return None
    s = Section("scope", "Scope recording")
    recording = data.get("scope")
    if isinstance(recording, dict) and "error" in recording:
        s.notes.append(f"not recorded: {text(recording['error'])}")
        return s
    s.svg = _their_svg(recording) or scope_svg(recording)
    if s.svg is None:
        s.notes.append("the recording holds no samples to draw")
    if isinstance(recording, dict):
        for key, value in recording.items():
            if not isinstance(value, (list, dict)):
                s.kv(key, value)
    return s


def build(data: dict[str, Any], name: str) -> list[Section]:
    """Every section of the report, in reading order."""
    sections = [header(data, name), identity(data), status(data)]
    diagnosed = diagnosis(data)
    if diagnosed is not None:
        sections.append(diagnosed)
    sections += [faults(data), parameters(data), mapping(data)]
    recorded = scope(data)
    if recorded is not None:
        sections.append(recorded)
    sections.append(trace(data))
    return sections


# ---------------------------------------------------------------------------- markdown
def _md(value: str) -> str:
    """Table-cell text that Markdown shows as typed: no HTML, no emphasis, no broken rows."""
    from html import escape

    out = escape(value, quote=False).replace("\\", "\\\\")
    for ch in "|*_`[]#!~":
        out = out.replace(ch, "\\" + ch)
    return " ".join(out.split()) if "\n" in out or "\r" in out else out


def markdown(sections: list[Section]) -> str:
    """The report as Markdown for a ticket (values escaped; marked rows carry a leading ``**!**`` column)."""
    lines: list[str] = []
    for s in sections:
        lines += [f"## {_md(s.title)}", ""]
        for note in s.notes:
            lines.append(f"> {_md(note)}")
        if s.notes:
            lines.append("")
        if s.pairs:
            lines += ["| key | value |", "|---|---|"]
            lines += [f"| {_md(k)} | {_md(v)} |" for k, v in s.pairs]
            lines.append("")
        for t in s.tables:
            if not t.rows:
                continue
            lines += [f"**{_md(t.title)}**", "", "| ! | " + " | ".join(_md(h) for h in t.headers) + " |",
                      "|---|" + "---|" * len(t.headers)]
            lines += ["| " + ("**!**" if mark else "") + " | " + " | ".join(_md(c) for c in row) + " |"
                      for row, mark in zip(t.rows, t.marked)]
            lines.append("")
        if s.svg is not None:
            lines += ["(the scope recording is drawn in the HTML page: support show --html)", ""]
    return "\n".join(lines)
