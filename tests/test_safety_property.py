"""Property: without --yes and without a terminal, no command line moves or enables the simulated axis.

Random command lines over every command that can power or move the axis (motion commands, raw
``pnu set`` / ``sdo write`` of any gated or ungated address, recipes with motion or set steps), with
random and hostile numbers (NaN, inf, huge, negative). After each one the simulated drive must be at
standstill, disabled, and must never have received a control word with "enable operation"
(the simulator's ``enabling_words`` counter, both profiles). The property runs twice: through the CLI's entry
point in this process (many examples: the refusal is the code's, and stdin there is no terminal either), and through
the real CLI in subprocesses (fewer examples: each costs a cold start, ~0.3 s CPU, and this half is only the check that
the process as shipped refuses the same way).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from akdctl.sim.drive import SimDrive
from tests.harness import CliResult, run_akdctl, run_akdctl_inproc

pytestmark = pytest.mark.slow  # runs the real CLI in subprocesses

ROOT = Path(__file__).resolve().parent.parent

numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32), st.integers(-70000, 70000),
                    st.sampled_from([0, 1, 15, 0x047F, 0x040F, 0x000F, 8000, 12000, 20000, -1]))
text_numbers = numbers.map(lambda v: repr(v) if isinstance(v, float) else str(v))
targets = st.sampled_from(["sim", "sim?drive=profidrive", "sim?drive=cia402"])
gated_pnus = st.sampled_from([1, 5, 32, 34, 35, 36, 37, 38, 930, 915, 922, 1004, 1005, 1006, 1007])
gated_objects = st.sampled_from(["0x6040:0", "0x60FF:0", "0x607A:0", "0x6071:0", "0x6081:0", "0x6083:0",
                                 "0x6060:0", "0x1C12:0", "0x60C1:1"])


@st.composite
def command_lines(draw: st.DrawFn) -> list[str]:
    kind = draw(st.sampled_from(["enable", "jog", "jog_distance", "home", "move", "pnu", "sdo", "recipe"]))
    if kind == "enable":
        return ["enable"]
    if kind == "jog":
        return ["jog", draw(text_numbers), "--for", draw(st.sampled_from(["1s", "100ms", "2s", "0.5"]))]
    if kind == "jog_distance":
        return ["jog", draw(text_numbers), "--distance", draw(text_numbers)]
    if kind == "home":
        return ["home"] + (["--mode", str(draw(st.integers(-5, 40)))] if draw(st.booleans()) else [])
    if kind == "move":
        line = ["move", draw(text_numbers)]
        if draw(st.booleans()):
            line.append("--relative")
        for option in ("--velocity", "--accel", "--decel"):
            if draw(st.booleans()):
                line += [option, draw(text_numbers)]
        return line
    if kind == "pnu":
        pairs = draw(st.lists(st.tuples(gated_pnus, st.integers(0, 0xFFFF)), min_size=1, max_size=3))
        return ["pnu", "set", *(f"{p}={v}" for p, v in pairs)]
    if kind == "sdo":
        return ["sdo", "write", draw(gated_objects), str(draw(st.integers(-100, 0xFFFF)))]
    steps = draw(st.lists(st.sampled_from([
        '[[step]]\naction = "enable"\n', '[[step]]\naction = "home"\nmode = 0\n',
        '[[step]]\naction = "move"\ntarget = 1\nrelative = true\n',
        '[[step]]\naction = "set"\npnu = "1004"\nvalue = 500\n',
        '[[step]]\naction = "set"\nobject = "0x60FF:0"\nvalue = 1000\n',
    ]), min_size=1, max_size=3))
    return ["commission", "\n".join(steps)]


def _run(line: list[str], target: str, folder: Path, runner: Callable[..., CliResult]) -> int:
    if line[0] == "commission":
        recipe = folder / "prop.toml"
        recipe.write_text(line[1])
        line = ["commission", str(recipe)]
    proc = runner("-T", target, *line)
    assert "internal error" not in proc.stderr and "Traceback" not in proc.stderr, (line, proc.stderr)
    return proc.returncode


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])  # a busy CI box
@given(lines=st.lists(st.tuples(command_lines(), targets), min_size=1, max_size=3))
def test_without_consent_the_drive_never_leaves_standstill_nor_sees_an_enabling_word(
        lines: list[tuple[list[str], str]], tmp_path: Path) -> None:
    _check(lines, tmp_path, run_akdctl_inproc)


# Fewer examples than the in-process half above: every command line here is a subprocess (a cold start each).
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lines=st.lists(st.tuples(command_lines(), targets), min_size=1, max_size=3))
def test_the_shipped_process_refuses_the_same_way(lines: list[tuple[list[str], str]], tmp_path: Path) -> None:
    _check(lines, tmp_path, run_akdctl)


def _check(lines: list[tuple[list[str], str]], folder: Path, runner: Callable[..., CliResult]) -> None:
    for line, target in lines:
        _run(line, target, folder, runner)
        with SimDrive("default").transaction() as model:
            motion = model.component("motion")
            assert motion.enabling_words == 0, line
            assert motion.standstill and motion.axis.activity == "idle", line
            assert motion.state in ("switch_on_disabled", "ready"), line


@pytest.fixture(autouse=True)
def _speedy() -> None:
    """Virtual time runs fast, so anything that did start would show at once."""
    SimDrive("default").set_time_scale(1000.0)
