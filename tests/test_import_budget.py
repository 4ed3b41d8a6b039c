"""Cold start stays lean: what ``akdctl --help``, ``pnu get 930``, ``sdo read 0x6041``, ``status`` and ``param get
DRV.OPMODE`` import (issue 15, deliver 4; issue 29, deliver 4).

A command's cold start is mostly what it imports, so the budget is kept as module sets, read from the real CLI's
``sys.modules`` when it exits (``python -X importtime`` misses what ``importlib.import_module`` loads: the command
modules and the simulator's lazy components): modules a command must not import (a codec it does not speak, a parser
for a file that does not exist, ``logging`` when nothing is logged, a simulator component it does not touch), and a
cap on how many modules it imports beyond a minimal click application run the same way. Counts, not timings: no
test here measures time (the figures are in ``benchmarks/run_all.py --only cold-start``). A cap that fails names the
modules, so a new import is a decision.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.harness import akdctl_env, run_akdctl

MINIMAL_CLICK = '''
import click


@click.group()
@click.option("--json", is_flag=True)
def cli(json):
    """Minimal click application."""


@cli.command()
def hello():
    """Say hello."""
    click.echo("hello")


cli()
'''

#: Never on these paths: no config file exists, nothing is logged, data files are plain files, the fault table is not
#: read, no rich when piped, no bus library, no cycle time is checked (fractions), no owner lock is taken (shlex).
#: Issue 29: the state file is read without the json package (io/json_text.py), nothing is written (tempfile, the
#: atomic writer), no record class is a dataclass, and the simulator builds neither its PDO mapping nor its files.
NEVER = {"tomllib", "logging", "importlib.resources", "zipfile", "csv", "rich", "canopen", "can", "pysoem",
         "akdctl.recipe", "fractions", "decimal", "shlex", "json", "dataclasses", "tempfile", "akdctl.io.atomic",
         "akdctl.sim.pdo", "akdctl.sim.foe", "akdctl.sim.recorder"}
#: The object side (CoE codecs, the SDO client and server) is not a PNU command's business, and the reverse.
OBJECT_SIDE = {"akdctl.protocol.coe", "akdctl.protocol.coe_info", "akdctl.protocol.mailbox", "akdctl.channels.coe_sdo",
               "akdctl.sim.sdo_server"}
PARAMETER_SIDE = {"akdctl.protocol.bmp", "akdctl.channels.bmp", "akdctl.channels.batching", "akdctl.sim.pnu_server"}
#: What ``--help`` may load of akdctl: the root command and the pieces its callback names.
# cli.parsing: the listing's one short-help rule (it imports only re and click).
HELP_MODULES = {"akdctl", "akdctl.__main__", "akdctl.cli", "akdctl.cli.main", "akdctl.cli.context", "akdctl.cli.parsing",
                "akdctl.errors"}

#: A read-only command neither asks for consent nor moves: the write gate, motion progress and stop signals stay out.
NO_MOTION = {"akdctl.cli.consent", "akdctl.cli.progress", "akdctl.cli.signals"}
#: Issue 29, second pass: the simulated axis' parts are built on first use (sim/motion.PARTS); reading the operating
#: mode (PNU 930, DRV.OPMODE) asks the motion component's own field, so neither the axis nor a word machine is built.
AXIS_PARTS = {"akdctl.sim.kinematics", "akdctl.sim.cia402_machine", "akdctl.sim.stw1_machine", "akdctl.sim.task_table"}

# (argv, must not import, cap on modules beyond the minimal click app, cap on akdctl modules).
# Caps leave a few modules of room above what the command imports today (issue 29, counted from sys.modules, beyond
# the minimal app and of akdctl: pnu get 61 and 57, sdo read 65 and 61, status 66 and 62, param get 66 and 62, --help
# 6 and 6; before it 73/61, 76/64, 77/65 and 77/65; after its second pass, the axis parts built on first use: 53/49,
# 60/56, 60/56, 58/54; after its third pass, the CLI process's garbage-collector policy of cli/main.py, one module
# more beyond the minimal app - the built-in gc - and no akdctl module more: 54/49, 61/56, 61/56, 59/54, --help 7/6):
# a new module on these paths is a decision, and a test names it.
BUDGETS = {
    "--help": (("--help",), NEVER, 10, len(HELP_MODULES)),
    "pnu get 930": (("pnu", "get", "930"),
                    NEVER | NO_MOTION | OBJECT_SIDE | AXIS_PARTS | {"akdctl.drive.axis"}, 56, 52),
    "sdo read 0x6041": (("sdo", "read", "0x6041"), NEVER | NO_MOTION | PARAMETER_SIDE | {"akdctl.drive.axis"}, 63, 59),
    # status: profiles.vocabulary (the one list of channel/profile words) and io.state_dir (the owner locks'
    # directory, so a real-drive client need not import the simulator to find it), issue 22.
    "status": (("status",), NEVER | NO_MOTION, 63, 59),
    # issue 24: a parameter by name costs about what 'sdo read' does: the catalogue row is found in the table's
    # text, the CoE side only.
    "param get DRV.OPMODE": (("param", "get", "DRV.OPMODE"),
                             NEVER | NO_MOTION | PARAMETER_SIDE | AXIS_PARTS | {"akdctl.drive.axis", "pymodbus"},
                             61, 57),
}

#: Runs a script or ``-m module`` as python would and reports ``sys.modules`` on exit (after SystemExit too).
_PROBE = """
import atexit, runpy, sys
atexit.register(lambda: sys.stderr.write("\\n".join(["--modules--", *sys.modules]) + "\\n"))
what, sys.argv = sys.argv[1], sys.argv[1:]
if what == "-m":
    sys.argv = [sys.argv[1], *sys.argv[2:]]
    runpy.run_module(sys.argv[0], run_name="__main__", alter_sys=True)
else:
    runpy.run_path(what, run_name="__main__")
"""


def imported(argv: list[str], env: dict[str, str]) -> list[str]:
    """The modules ``python ARGV`` had imported when it exited (fails on a non-zero exit)."""
    proc = subprocess.run([sys.executable, "-c", _PROBE, *argv], capture_output=True, text=True, env=env,
                          timeout=120, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr[-2000:]
    _, found, names = proc.stderr.rpartition("--modules--\n")
    assert found, proc.stderr[-2000:]
    return [name for name in names.splitlines() if name]


@pytest.fixture(scope="module")
def baseline(tmp_path_factory: pytest.TempPathFactory) -> dict[str, set[str]]:
    """What a minimal click application imports for --help and for a subcommand."""
    app = tmp_path_factory.mktemp("minimal") / "minimal_click.py"
    app.write_text(MINIMAL_CLICK)
    env = akdctl_env()
    return {"--help": set(imported([str(app), "--help"], env)), "run": set(imported([str(app), "hello"], env))}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(BUDGETS))
def test_command_stays_within_its_import_budget(name: str, baseline: dict[str, set[str]], tmp_path: Path) -> None:
    argv, forbidden, cap_extra, cap_akdctl = BUDGETS[name]
    env = akdctl_env({"XDG_CONFIG_HOME": str(tmp_path / "no-config")})
    assert run_akdctl("sim", "reset", env=env).code == 0  # the state file exists, as after any first use
    modules = imported(["-m", "akdctl", *argv], env)
    loaded = set(modules)
    bad = sorted(m for m in loaded if m in forbidden or any(m.startswith(f + ".") for f in forbidden))
    assert not bad, f"akdctl {name} imports {bad}"
    ours = sorted(m for m in loaded if m == "akdctl" or m.startswith("akdctl."))
    if name == "--help":
        assert set(ours) <= HELP_MODULES, f"akdctl --help imports {sorted(set(ours) - HELP_MODULES)}"
    assert len(ours) <= cap_akdctl, f"akdctl {name} imports {len(ours)} akdctl modules (cap {cap_akdctl}): {ours}"
    extra = sorted(loaded - baseline["--help" if name == "--help" else "run"])
    assert len(extra) <= cap_extra, (f"akdctl {name} imports {len(extra)} modules beyond a minimal click app "
                                     f"(cap {cap_extra}): {extra}")


@pytest.mark.slow
@pytest.mark.parametrize("name", ["pnu get 930", "sdo read 0x6041"])
def test_a_read_only_command_does_not_load_the_file_writer(name: str, tmp_path: Path) -> None:
    env = akdctl_env({"XDG_CONFIG_HOME": str(tmp_path / "no-config")})
    assert run_akdctl("sim", "reset", env=env).code == 0
    loaded = set(imported(["-m", "akdctl", *BUDGETS[name][0]], env))
    assert "tempfile" not in loaded


def test_a_pnu_command_builds_only_the_objects_it_needs(akd_inproc) -> None:
    """The object table is split by index and built per object: ``pnu get`` over the simulator (whose PDO defaults
    need a few objects) never builds the whole table, ``sdo read`` builds its object."""
    from akdctl.catalog import objects

    objects._all.cache_clear()
    objects._object.cache_clear()
    assert akd_inproc("pnu", "get", "930")[0] == 0
    assert objects._all.cache_info().currsize == 0
    assert objects._object.cache_info().currsize <= 24
    code, out, err = akd_inproc("sdo", "read", "0x6041")
    assert code == 0, err
    assert objects._all.cache_info().currsize == 0
    assert objects.lookup(0x6041, 0) is not None and objects.object_name(0x6041)
