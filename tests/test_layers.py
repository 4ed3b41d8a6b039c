"""Imports point only down (docs/internals.md, "Layers"): parse every module's imports and fail on an upward one.

Lazy imports inside functions count too: a packaging mistake or a cycle hides there just as well. Imports under
``if TYPE_CHECKING:`` do not: they name a type for the reader and the checker and load nothing at run time
(``drive/`` names the :class:`~akdctl.connection.Connection` it is handed that way)."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "akdctl"

_GROUND = {"errors", "protocol", "io", "profiles"}
#: package -> the akdctl packages (first component under akdctl/) its modules may import.
ALLOWED: dict[str, set[str]] = {
    "protocol": set(),  # pure codecs: nothing of akdctl but their own helpers
    "errors": set(),
    "io": {"errors", "protocol"},
    # what a transport offers (record link, mailbox link, native SDO clients): below channels and transports.
    "links": {"errors", "protocol"},
    "profiles": {"errors", "protocol"},
    "catalog": _GROUND,
    "config": _GROUND | {"catalog"},
    "channels": _GROUND | {"catalog", "links"},
    # transport/sim.py is the in-process link to the simulated drive, so transport may use sim (not the reverse).
    "transport": _GROUND | {"catalog", "links", "sim"},
    "sim": _GROUND | {"catalog"},  # never cli, transport, drive or channels
    "drive": _GROUND | {"catalog", "channels", "transport", "config", "links"},
    # the Connection wires transport, channels and the axis profile together: above drive, below recipe/cli.
    "connection": _GROUND | {"catalog", "channels", "transport", "config", "links", "drive"},
    "recipe": _GROUND | {"catalog", "channels", "transport", "config", "links", "drive", "connection"},
    "cli": _GROUND | {"catalog", "channels", "transport", "config", "links", "drive", "connection", "recipe", "sim"},
    "__main__": {"cli"},
    "__init__": set(),
}

#: Known upward imports that must go, each with its reason: (importing module, imported package).
#: Keep this list short; an entry here is a debt, not a permission.
ALLOW_LIST: set[tuple[str, str]] = set()


def _parse(path: Path) -> ast.Module:
    """The module's syntax tree, parsed once per session for each version of the file (path, size and mtime).

    Why: the checks below each parse every module of the package (a second of CPU or more per check)."""
    stat = path.stat()
    return _parsed(str(path), stat.st_mtime_ns, stat.st_size)


@functools.cache
def _parsed(path: str, _mtime_ns: int, _size: int) -> ast.Module:
    return ast.parse(Path(path).read_text(encoding="utf-8"), path)


def _package(path: Path, root: Path = ROOT) -> tuple[str, str]:
    rel = path.relative_to(root.parent).with_suffix("")
    module = ".".join(rel.parts)
    return module.removesuffix(".__init__"), rel.parts[1]


def _imports(path: Path, root: Path = ROOT) -> set[str]:
    """Every ``akdctl.<package>...`` a module imports (``from akdctl import x`` counts when x is a module); worked
    out once per session for each version of the file (two checks ask for every module's)."""
    stat = path.stat()
    return set(_imports_of(str(path), stat.st_mtime_ns, stat.st_size, root))


@functools.cache
def _imports_of(name: str, _mtime_ns: int, _size: int, root: Path) -> frozenset[str]:
    path = Path(name)
    found: set[str] = set()
    tree = _parse(path)
    type_only = {id(n) for block in ast.walk(tree)
                 if isinstance(block, ast.If) and isinstance(block.test, ast.Name) and block.test.id == "TYPE_CHECKING"
                 for stmt in block.body for n in ast.walk(stmt)}
    for node in ast.walk(tree):
        if id(node) in type_only:
            continue
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level:
            raise AssertionError(f"{path}: relative import; akdctl uses absolute imports only")
        elif isinstance(node, ast.ImportFrom) and node.module == "akdctl":
            found.update(f"akdctl.{a.name}" for a in node.names
                         if (root / a.name).is_dir() or (root / f"{a.name}.py").is_file())
        elif isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
    return frozenset(name for name in found if name.startswith("akdctl."))


def upward_imports(root: Path = ROOT) -> list[str]:
    problems = []
    for path in sorted(root.rglob("*.py")):
        module, package = _package(path, root)
        allowed = ALLOWED.get(package)
        assert allowed is not None, f"{path}: package {package!r} has no place in the layer table (tests/test_layers.py)"
        for name in sorted(_imports(path, root)):
            target = name.split(".")[1]
            if target == package or target in allowed or (module, target) in ALLOW_LIST:
                continue
            problems.append(f"{module} imports {name} ({package} may import only {sorted(allowed) or 'nothing'})")
    return problems


def test_imports_point_only_down() -> None:
    assert upward_imports() == []


def test_allow_list_holds_only_live_debts() -> None:
    """An allow-list entry whose import is gone must be removed, so the list never hides a new one."""
    live = set()
    for path in ROOT.rglob("*.py"):
        module, _ = _package(path)
        live.update((module, name.split(".")[1]) for name in _imports(path))
    assert ALLOW_LIST <= live, sorted(ALLOW_LIST - live)


def test_the_check_sees_upward_imports(tmp_path: Path) -> None:
    """The check can fail: a codec importing the catalogue, and the simulator importing a transport lazily."""
    root = tmp_path / "akdctl"
    for package, text in (("protocol", "from akdctl.catalog import texts\n"),
                          ("sim", "def f():\n    from akdctl.transport.canopen_bus import open_bus\n"),
                          ("catalog", "X = 1\n")):
        (root / package).mkdir(parents=True)
        (root / package / "probe.py").write_text(text, encoding="utf-8")
    found = upward_imports(root)
    assert len(found) == 2
    assert found[0].startswith("akdctl.protocol.probe imports akdctl.catalog")
    assert found[1].startswith("akdctl.sim.probe imports akdctl.transport.canopen_bus")


# ---------------------------------------------------------------------------- capabilities are declared, not probed
#: What only some transports, links, channels or drive models can do. Each is declared once with a neutral default
#: (Transport: time_scale, al_state, read_im0; Connection: axis_owner; Axis: issued_target; ObjectChannel:
#: take_emergencies; links: trace_meta; the simulator's servers: raw_reads=/files= at construction), so nobody asks
#: ``getattr(x, "al_state", None)`` (issue 22 item 2).
CAPABILITIES = {"al_state", "time_scale", "read_im0", "read_im0_record", "issued_target", "pnu_read_raw", "foe_read",
                "foe_write", "axis_owner", "take_emergencies", "trace_meta", "object_list", "object_description",
                "entry_description", "read_description", "wait_emergencies", "mailbox_size", "max_record"}
#: Words naming what a probe must not be aimed at (the object expression's source): the wiring's own objects.
_WIRED = ("transport", "conn", "channel", "link", "access", "axis", "objects", "parameters", "session", "app")


def capability_probes(root: Path = ROOT) -> list[str]:
    """``getattr(x, "name", ...)``/``hasattr(x, "name")`` of a capability or on a wired object, and a
    ``__getattr__`` that lets any name fall through a channel, transport, link or the Connection."""
    found = []
    for path in sorted(root.rglob("*.py")):
        module, package = _package(path, root)
        tree = _parse(path)
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("getattr", "hasattr") \
                    and len(node.args) >= 2 and isinstance(node.args[1], ast.Constant) \
                    and isinstance(node.args[1].value, str):
                name, target = node.args[1].value, ast.unparse(node.args[0])
                words = set(target.replace(".", " ").replace("_", " ").replace("(", " ").replace(")", " ").split())
                if name in CAPABILITIES or words & set(_WIRED):
                    found.append(f"{module}:{node.lineno}: {node.func.id}({target}, {name!r})")
            elif isinstance(node, ast.FunctionDef) and node.name == "__getattr__" \
                    and package in ("channels", "transport", "links", "connection"):
                found.append(f"{module}:{node.lineno}: __getattr__ lets any name fall through")
    return found


def test_no_capability_is_probed() -> None:
    assert capability_probes() == []


def test_the_probe_check_can_fail(tmp_path: Path) -> None:
    root = tmp_path / "akdctl"
    (root / "drive").mkdir(parents=True)
    (root / "channels").mkdir(parents=True)
    (root / "drive" / "probe.py").write_text(
        "def f(conn, transport, thing):\n"
        "    a = getattr(conn.transport(), 'read_im0', None)\n"
        "    b = hasattr(transport, 'whatever')\n"
        "    c = getattr(thing, 'al_state', None)\n"
        "    d = getattr(thing, 'name', None)\n", encoding="utf-8")
    (root / "channels" / "lazy.py").write_text(
        "class C:\n    def __getattr__(self, name):\n        return 1\n", encoding="utf-8")
    found = capability_probes(root)
    assert {f.split(": ", 1)[1] for f in found} == {
        "getattr(conn.transport(), 'read_im0')", "hasattr(transport, 'whatever')", "getattr(thing, 'al_state')",
        "__getattr__ lets any name fall through"}


def test_no_module_getattr() -> None:
    """No module hands out names it does not define (issue 22 item 8: protocol/coe.py, profiles/units.py did):
    such names hide from readers, checkers and ``grep``; a user imports the module that defines them."""
    found = [str(path.relative_to(ROOT.parent)) for path in sorted(ROOT.rglob("*.py"))
             if any(isinstance(node, ast.FunctionDef) and node.name == "__getattr__"
                    for node in _parse(path).body)]
    assert found == []


# ---------------------------------------------------------------------------- a plan's consent and dry run, in one place
#: A CLI module other than cli/consent.py that may render a plan's lines itself, and why.
OWN_DRY_RUN = {"akdctl.cli.scope": "a recording plan's dry run carries its source and motion (scope._render_plan)"}


def plans_rendered_outside_consent(root: Path = ROOT) -> list[str]:
    """CLI code that asks a write plan's consent itself (``consent_needed``) or prints its dry run itself
    (``plan.lines()``). Each command once did its own: a plan's notes (RAM only until saved, an inferred scale,
    what --force let past) were shown as warnings by two commands, joined into one line by one and dropped by the
    rest; cli/consent.consent_plan and render_dry_run are now the one way."""
    found = []
    for path in sorted((root / "cli").glob("*.py")):
        module, _ = _package(path, root)
        if path.name == "consent.py":
            continue
        for node in ast.walk(_parse(path)):
            if not isinstance(node, ast.Call):
                continue
            name = node.func.id if isinstance(node.func, ast.Name) else \
                node.func.attr if isinstance(node.func, ast.Attribute) else ""
            if name == "consent_needed" or (name == "lines" and not node.args and module not in OWN_DRY_RUN):
                found.append(f"{module}:{node.lineno}: {ast.unparse(node)}")
    return found


def test_plans_are_asked_and_dry_run_in_cli_consent() -> None:
    assert plans_rendered_outside_consent() == []


def test_the_plan_rendering_check_can_fail(tmp_path: Path) -> None:
    root = tmp_path / "akdctl"
    (root / "cli").mkdir(parents=True)
    (root / "cli" / "probe.py").write_text(
        "from akdctl.drive.operation import consent_needed\n"
        "def f(app, plan):\n"
        "    print('\\n'.join(plan.lines()))\n"
        "    consent_needed(plan, print, given=app.yes)\n", encoding="utf-8")
    (root / "cli" / "consent.py").write_text("def g(plan):\n    return plan.lines()\n", encoding="utf-8")
    found = plans_rendered_outside_consent(root)
    assert sorted(f.split(": ", 1)[1] for f in found) == ["consent_needed(plan, print, given=app.yes)", "plan.lines()"]
