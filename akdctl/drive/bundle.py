"""The support bundle: everything a support engineer needs about one drive, in one file.

Why one file with stable keys: the technician on site runs one command and
attaches one file; the engineer opens it days later without a drive
(``akdctl support show``). Each section is collected on its own: a refusal or
a missing feature becomes ``{"error": "..."}`` in that section instead of
losing the rest; only the bundle's own bookkeeping can fail the command.

Layout (``FORMAT`` / ``FORMAT_VERSION`` identify the file)::

    format, format_version, created (UTC ISO 8601), tool {name, version, python, platform},
    target {display, scheme}, identity, faults (the ``fault dump`` data), status,
    parameters {pnus: [...], objects: [...], round_trips}, mapping, diagnosis (``akdctl diagnose --json``),
    trace [...], errors {section: text}

Written atomically (temporary file in the same directory, fsync, ``os.replace``),
so an interrupted run never leaves half a bundle. ``.zip`` output holds the
same JSON as ``bundle.json`` plus the trace as text (``trace.txt``).
"""

from __future__ import annotations

import datetime as _dt
import io
import json
import os
import platform
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

from akdctl.errors import AkdError, CommError, UsageError
from akdctl.io.atomic import write_user_file

if TYPE_CHECKING:
    from akdctl.channels.base import ObjectChannel
    from akdctl.channels.base import ParameterChannel
    from akdctl.connection import Connection

FORMAT = "akdctl-support-bundle"
FORMAT_VERSION = 1
ZIP_MEMBER = "bundle.json"
ZIP_TRACE = "trace.txt"
REQUIRED_KEYS = ("format", "format_version", "created", "tool", "target")

# Objects worth a support engineer's look on every CoE/CANopen drive (the whole dictionary is opt-in).
CORE_OBJECTS: tuple[tuple[int, int], ...] = (
    (0x1000, 0), (0x1001, 0), (0x1008, 0), (0x1009, 0), (0x100A, 0),
    (0x1018, 1), (0x1018, 2), (0x1018, 3), (0x1018, 4),
    (0x6040, 0), (0x6041, 0), (0x6060, 0), (0x6061, 0), (0x6063, 0), (0x6064, 0), (0x606C, 0),
    (0x607A, 0), (0x6081, 0), (0x6083, 0), (0x6084, 0), (0x605A, 0), (0x60C2, 1), (0x60C2, 2), (0x6502, 0),
)


# ---------------------------------------------------------------------------- sections
#: The ``errors`` key that says the link failed ("SECTION: message"): the bundle is written, the command exits 3.
LINK_ERROR = "link"
#: What a section not read after a link failure says.
SKIPPED = "not read: the drive did not answer earlier"


def _guard(errors: dict[str, str], name: str, func: Any) -> Any:
    """Run one section; a refusal is recorded and the next section runs.

    A communication failure (no answer, timeout, lost link) is recorded too, but it ends the reading:
    every later section would wait its own timeout for the same silent drive (an unreachable gateway
    made ``support bundle`` take 30 s). The sections after it say they were not read, and
    ``errors["link"]`` makes the command exit 3 once the bundle is written.
    """
    if LINK_ERROR in errors:
        text = f"{SKIPPED} (section {errors[LINK_ERROR].split(':', 1)[0]})"
        errors[name] = text
        return {"error": text, "kind": "skipped"}
    try:
        return func()
    except CommError as exc:
        errors[name] = exc.message
        errors[LINK_ERROR] = f"{name}: {exc.message}"
        return {"error": exc.message, "kind": exc.kind}
    except AkdError as exc:
        errors[name] = exc.message
        return {"error": exc.message, "kind": exc.kind}


def _tool() -> dict[str, Any]:
    from akdctl import __version__

    return {"name": "akdctl", "version": __version__, "python": platform.python_version(),
            "platform": f"{platform.system()} {platform.machine()}"}


def pnu_snapshot(channel: "ParameterChannel") -> list[dict[str, Any]]:
    """Every readable catalogue PNU in ONE batched read call (the channel packs the fewest requests)."""
    from akdctl.catalog.pnus import pnu_table
    from akdctl.drive.values import PnuSpec, read_pnus

    specs = [PnuSpec(n, 0, info.length if info.is_array else 1, info)
             for n, info in sorted(pnu_table().items()) if "r" in info.access]
    return [r.to_json() for r in read_pnus(channel, specs)]


def object_snapshot(channel: "ObjectChannel", *, everything: bool = False) -> list[dict[str, Any]]:
    """Upload the core objects (or every readable catalogue object); aborts are recorded per object."""
    from akdctl.catalog import objects as catalog
    from akdctl.drive.values import decode, json_value

    if everything:
        keys = sorted(k for k, e in catalog.entries().items() if e.readable)
    else:
        keys = [k for k in CORE_OBJECTS if catalog.lookup(*k) is not None]
    out = []
    for index, sub in keys:
        entry = catalog.lookup(index, sub)
        item: dict[str, Any] = {"object": f"0x{index:04X}:{sub}", "name": entry.name if entry else None}
        try:
            data = channel.upload(index, sub)
            item["hex"] = bytes(data).hex()
            if entry is not None:
                item["value"] = json_value(entry.short_type, decode(entry.short_type, data))
        except CommError:
            raise
        except AkdError as exc:
            item["error"] = exc.message
        out.append(item)
    return out


def _readings_by_pnu(pnus: list[dict[str, Any]]) -> dict[int, dict[str, Any]]:
    return {int(r["pnu"]): r for r in pnus if isinstance(r, dict) and "pnu" in r}


def status(conn: "Connection") -> dict[str, Any]:
    """The axis status exactly as the ``status`` command reads it (the axis profile the target uses)."""
    return {"source": "axis", **conn.axis().read_status().to_json()}


def mapping(conn: "Connection", sources: list[str], pnus: list[dict[str, Any]] | None) -> dict[str, Any]:
    """Process-data mapping: telegram + PZD lists (from the snapshot) and/or the CoE PDO assignment."""
    out: dict[str, Any] = {}
    if "profidrive" in sources and pnus:
        by_pnu = _readings_by_pnu(pnus)
        out["profidrive"] = {
            "telegram": (by_pnu.get(922, {}).get("values") or [None])[0],
            "setpoints_pnu915": by_pnu.get(915, {}).get("values"),
            "actuals_pnu916": by_pnu.get(916, {}).get("values"),
        }
    if "canopen" in sources:
        from akdctl.drive.pdo import read_mapping

        try:
            out["canopen"] = {d: m.to_json() for d, m in read_mapping(conn.objects()).items()}
        except CommError:
            raise
        except AkdError as exc:
            out["canopen"] = {"error": exc.message}
    return out


def collect(conn: "Connection", *, all_objects: bool = False) -> dict[str, Any]:
    """Read everything from the target into one JSON-able bundle (never raises for a drive problem)."""
    from akdctl.drive import faults, identity

    errors: dict[str, str] = {}
    target = conn.target
    conn.options.tracer.record = True  # the bundle carries the session's trace (the tracer keeps none by default)
    bundle: dict[str, Any] = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "tool": _tool(),
        "target": {"display": target.display, "scheme": target.scheme, "drive_profile": conn.drive_profile},
    }
    transport = _guard(errors, "transport", conn.transport)
    if isinstance(transport, dict):  # could not open: every section says why
        errors.pop(LINK_ERROR, None)  # "transport" says it
        for key in ("identity", "faults", "status", "parameters", "mapping", "diagnosis"):
            bundle[key] = {"error": errors["transport"]}
    else:
        sources = faults._sources(conn)
        bundle["identity"] = _guard(errors, "identity", lambda: identity.read_identity(conn))
        if sources:
            bundle["faults"] = _guard(errors, "faults", lambda: faults.dump(conn))
        elif conn.has_cip:  # eip://: what CIP offers (drive/eip_faults.py)
            from akdctl.drive import eip_faults

            bundle["faults"] = _guard(errors, "faults", lambda: eip_faults.dump(conn))
        else:
            bundle["faults"] = _guard(errors, "faults", lambda: faults.dump(conn))
        params: dict[str, Any] = {"round_trips": {}}
        pnus = None
        if "profidrive" in sources:
            channel = conn.parameters()
            before = channel.requests
            pnus = _guard(errors, "parameters.pnus", lambda: pnu_snapshot(channel))
            params["pnus"] = pnus
            params["round_trips"]["pnus"] = channel.requests - before
            pnus = pnus if isinstance(pnus, list) else None
        if "canopen" in sources:
            objects = conn.objects()
            before = objects.requests
            params["objects"] = _guard(errors, "parameters.objects",
                                       lambda: object_snapshot(objects, everything=all_objects))
            params["round_trips"]["objects"] = objects.requests - before
        bundle["parameters"] = params
        bundle["status"] = _guard(errors, "status", lambda: status(conn))
        bundle["mapping"] = _guard(errors, "mapping", lambda: mapping(conn, sources, pnus))
        from akdctl.drive.diagnose import diagnose

        bundle["diagnosis"] = _guard(errors, "diagnosis", lambda: diagnose(conn))  # why it won't enable, ranked
    bundle["trace"] = [r.to_json() for r in conn.options.tracer.records]
    bundle["errors"] = errors
    return bundle


# ---------------------------------------------------------------------------- files
def _trace_text(bundle: dict[str, Any]) -> str:
    lines = []
    for rec in bundle.get("trace", []):
        arrow = "->" if rec.get("direction") == "tx" else "<-"
        lines.append(f"{rec.get('time')} {arrow} {rec.get('layer', ''):8s} {rec.get('hex', '')}")
    return "\n".join(lines) + ("\n" if lines else "")


def encode(bundle: dict[str, Any], *, as_zip: bool) -> bytes:
    text = json.dumps(bundle, indent=2, default=_json_default) + "\n"
    if not as_zip:
        return text.encode("utf-8")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(ZIP_MEMBER, text)
        zf.writestr(ZIP_TRACE, _trace_text(bundle))
    return buf.getvalue()


def _json_default(value: Any) -> Any:
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).hex()
    if hasattr(value, "to_json"):
        return value.to_json()
    return str(value)


def write(bundle: dict[str, Any], path: str | os.PathLike[str]) -> Path:
    """Write atomically into an existing directory (io/atomic.py's rules): JSON, or a zip when the name ends
    in ``.zip``."""
    target = Path(path)
    write_user_file(target, encode(bundle, as_zip=target.suffix.lower() == ".zip"))
    return target


#: A bundle file at most this large is read (ours are a few MB even with ``--all-objects``).
MAX_BUNDLE_BYTES = 32 * 1024 * 1024
#: Every zip member's *uncompressed* size (as the zip declares it, and as read) at most this, all of them at most
#: :data:`MAX_UNPACKED_BYTES`, and at most :data:`MAX_ZIP_MEMBERS` members: a small zip can unpack to gigabytes.
MAX_MEMBER_BYTES = 64 * 1024 * 1024
MAX_UNPACKED_BYTES = 128 * 1024 * 1024
MAX_ZIP_MEMBERS = 16
_WHAT = "a support bundle"


def _zip_members(raw: bytes, name: str) -> int | None:
    """The member count the zip's end record declares (read before zipfile builds its index); None if no record."""
    end = raw.rfind(b"PK\x05\x06", max(0, len(raw) - 65557))
    if end < 0 or end + 22 > len(raw):
        return None
    return int.from_bytes(raw[end + 10:end + 12], "little")


def _unzip(raw: bytes, name: str) -> bytes:
    """``bundle.json`` from a zip bundle, within the member, total and count caps."""
    count = _zip_members(raw, name)
    if count is not None and count > MAX_ZIP_MEMBERS:
        raise UsageError(f"{name}: a zip of {count} members is not {_WHAT} (at most {MAX_ZIP_MEMBERS})")
    with zipfile.ZipFile(io.BytesIO(raw)) as zf:
        infos = zf.infolist()
        if len(infos) > MAX_ZIP_MEMBERS:
            raise UsageError(f"{name}: a zip of {len(infos)} members is not {_WHAT} (at most {MAX_ZIP_MEMBERS})")
        for info in infos:
            if info.file_size > MAX_MEMBER_BYTES:
                raise UsageError(f"{name}: member {info.filename!r} unpacks to {info.file_size} bytes, more than the "
                                 f"{MAX_MEMBER_BYTES} a bundle member may have")
        total = sum(info.file_size for info in infos)
        if total > MAX_UNPACKED_BYTES:
            raise UsageError(f"{name}: unpacks to {total} bytes, more than the {MAX_UNPACKED_BYTES} {_WHAT} may have")
        if ZIP_MEMBER not in zf.namelist():
            raise UsageError(f"{name} is not an akdctl support bundle (zip without {ZIP_MEMBER})")
        with zf.open(ZIP_MEMBER) as member:
            data = member.read(MAX_MEMBER_BYTES + 1)  # the declared size bounds the read; this bounds a liar
        if len(data) > MAX_MEMBER_BYTES:
            raise UsageError(f"{name}: member {ZIP_MEMBER} unpacks to more than {MAX_MEMBER_BYTES} bytes")
        return data


def load(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a bundle (JSON or zip); a damaged, foreign, oversized or non-regular file is a one-line
    :class:`UsageError` (exit 2), decided before anything large is read or unpacked."""
    from akdctl.io.safe_read import read_regular

    name = str(path)
    raw = read_regular(path, limit=MAX_BUNDLE_BYTES, what=_WHAT)
    if raw[:4] == b"PK\x03\x04" or _zip_members(raw, name) is not None:
        try:
            raw = _unzip(raw, name)
        except (zipfile.BadZipFile, zipfile.LargeZipFile, RuntimeError, ValueError, OSError, EOFError) as exc:
            if isinstance(exc, UsageError):
                raise
            raise UsageError(f"{name} is not a readable support bundle ({type(exc).__name__}: {exc})"
                             .splitlines()[0]) from None
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:  # JSONDecodeError, int digit limit, nesting
        raise UsageError(f"{name} is not an akdctl support bundle (damaged JSON: {type(exc).__name__}: {exc})"
                         .splitlines()[0][:300]) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise UsageError(f"{name} is not an akdctl support bundle (format key missing or foreign)")
    version = data.get("format_version")
    if isinstance(version, int) and not isinstance(version, bool) and version > FORMAT_VERSION:
        raise UsageError(f"{name}: support bundle format version {version} comes from a newer akdctl (this one reads "
                         f"version {FORMAT_VERSION}); update akdctl to open it")
    if version != FORMAT_VERSION:
        raise UsageError(f"{name}: support bundle format version {str(data.get('format_version'))[:20]!r} is not "
                         f"supported (this akdctl reads version {FORMAT_VERSION})")
    missing = [k for k in REQUIRED_KEYS if k not in data]
    if missing:
        raise UsageError(f"{name}: damaged support bundle (missing {', '.join(missing)})")
    if not isinstance(data.get("tool"), dict) or not isinstance(data.get("target"), dict):
        raise UsageError(f"{name}: damaged support bundle (tool/target are not objects)")
    return data
