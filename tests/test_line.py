"""A line of drives: the inventory's checks, substitution, discover, and --inventory runs of the real CLI.

The end-to-end test is the issue's "done when": drives on four transports of the simulator (named sim drives,
an ETG.8200 gateway with three stations, a PROFINET face, an EtherNet/IP face) are discovered, written to an
inventory, commissioned in parallel with per-drive values, and ``param diff --inventory`` then shows exactly the
per-drive values; a drive whose server is killed mid-run fails that drive only.
"""

from __future__ import annotations

import json
import os
import re
import time
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akdctl.drive import inventory
from akdctl.errors import UsageError
from tests.harness import SimServer, finish, run_akdctl, run_akdctl_inproc, start_akdctl


def _write(tmp_path: Path, text: str, name: str = "line.toml") -> str:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


# ----------------------------------------------------------------------------- the inventory's checks
BAD_INVENTORIES = [
    ("[[drive]\nname = 'a'", "not valid TOML"),
    ("title = 'x'", "unknown table 'title'"),
    ("[[drive]]\ntarget = 'sim://a'", "drive entry 1: 'name' must be"),
    ("[[drive]]\nname = 'a b'\ntarget = 'sim://a'", "drive entry 1: 'name' must be"),
    ("[[drive]]\nname = 'a'\ntarget = 'sim://a'\n[[drive]]\nname = 'a'\ntarget = 'sim://b'",
     "drive 'a' (entry 2): the name is also entry 1"),
    ("[[drive]]\nname = 'a'\ntarget = 'sim://x'\n[[drive]]\nname = 'b'\ntarget = 'sim://x'",
     "drive 'b' (entry 2): target sim://x reaches the same drive as 'a' (entry 1"),
    ("[[drive]]\nname = 'a'\ntarget = 'sim://a'\nkey='serial:1'\n[[drive]]\nname = 'b'\ntarget = 'sim://b'\nkey='serial:1'",
     "key 'serial:1' is also drive 'a' (entry 1): two entries for one drive"),
    ("[[drive]]\nname = 'a'\ntarget = 'nope://a'", "drive 'a' (entry 1)"),
    ("[[drive]]\nname = 'a'\ntarget = 'sim://a'\ncolour = 'red'", "unknown key 'colour'"),
    ("[[drive]]\nname = 'a'\ntarget = 'sim://a'\ntags = 'x'", "'tags' must be a list of names"),
    ("[[drive]]\nname = 'a'\ntarget = 'sim://a'\n[drive.vars]\n'a-b' = 1", "variable name 'a-b'"),
    ("[[drive]]\nname = 'a'\ntarget = 'sim://a'\n[drive.vars]\nx = [1]", "variable 'x' must be a string"),
    ("", "no [[drive]] entries"),
]


@pytest.mark.parametrize(("text", "expected"), BAD_INVENTORIES)
def test_a_bad_inventory_is_refused_naming_the_entry(tmp_path: Path, text: str, expected: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(UsageError) as caught:
        inventory.load(path)
    assert expected in caught.value.message
    assert path in caught.value.message


def test_an_inventory_that_is_no_regular_file_is_refused_unread(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for path in (str(fifo), "/dev/zero", str(tmp_path)):
        with pytest.raises(UsageError, match="not read"):
            inventory.load(path)


def test_select_by_name_and_tag_keeps_file_order_and_refuses_an_unknown_selector(tmp_path: Path) -> None:
    inv = inventory.load(_write(tmp_path, "[[drive]]\nname='a'\ntarget='sim://a'\ntags=['l1']\n"
                                          "[[drive]]\nname='b'\ntarget='sim://b'\ntags=['l2']\n"
                                          "[[drive]]\nname='c'\ntarget='sim://c'\ntags=['l1']\n"))
    assert [d.name for d in inv.select(["l1"])] == ["a", "c"]
    assert [d.name for d in inv.select(["b", "c"])] == ["b", "c"]
    assert [d.name for d in inv.select([])] == ["a", "b", "c"]
    with pytest.raises(UsageError, match=r"--select .l3. is no drive name or tag; did you mean l2, l1\?"):
        inv.select(["l3"])


def test_substitution_inserts_toml_values_and_leaves_comments_alone() -> None:
    drive = inventory.LineDrive("ax1", "sim://ax1", vars={"rpm": 250, "label": 'say "hi"', "on": True})
    text = 'a = ${vars.rpm}\nb = "${label} on ${name}"\nc = ${on}\nd = ${name}  # ${undefined}\ne = "$$5"\n'
    out = inventory.substitute(text, drive)
    assert tomllib.loads(out) == {"a": 250, "b": 'say "hi" on ax1', "c": True, "d": "ax1", "e": "$5"}
    assert "# ${undefined}" in out
    with pytest.raises(UsageError, match=r"\$\{vars.speed\} is not defined for drive 'ax1'"):
        inventory.substitute("x = ${vars.speed}", drive)


@given(st.dictionaries(st.from_regex(r"[a-z_][a-z0-9_]{0,8}", fullmatch=True),
                       st.one_of(st.integers(-10**12, 10**12), st.booleans(), st.text(max_size=20),
                                 st.floats(allow_nan=False, allow_infinity=False)), max_size=6))
def test_substituted_values_always_parse_back_to_themselves(values: dict) -> None:
    drive = inventory.LineDrive("d", "sim://d", vars=values)
    text = "".join(f"v_{k} = ${{vars.{k}}}\ns_{k} = \"${{{k}}}\"\n" for k in values)
    parsed = tomllib.loads(inventory.substitute(text, drive))
    for key, value in values.items():
        assert parsed[f"v_{key}"] == value
        assert parsed[f"s_{key}"] == (value if isinstance(value, str) else str(value))


def test_an_inventory_written_by_dump_loads_back(tmp_path: Path) -> None:
    drives = [inventory.LineDrive("a", "pn://127.0.0.1:34964", "serial:1", ["l3"], {"alias": 1001, "kp": 0.5}),
              inventory.LineDrive("b", "ecat-udp://127.0.0.1:34980/1002", None, ["l3", "x"])]
    path = _write(tmp_path, inventory.dump(drives, comment="a line\nwith two drives"))
    assert inventory.load(path).drives == [inventory.LineDrive(d.name, d.target, d.key, d.tags, d.vars, n)
                                           for n, d in enumerate(drives, 1)]


# ----------------------------------------------------------------------------- the CLI's refusals
def _inv(tmp_path: Path, *names: str) -> str:
    return _write(tmp_path, "".join(f"[[drive]]\nname='{n}'\ntarget='sim://{n}'\ntags=['line']\n"
                                    f"[drive.vars]\nmode = {i % 2 + 1}\n" for i, n in enumerate(names)), "inv.toml")


@pytest.mark.slow
@pytest.mark.parametrize(("argv", "words"), [
    (["jog", "100", "--for", "1"], "'jog' does not run on a line of drives"),
    (["-T", "sim://x", "status"], "--inventory chooses the targets"),
    (["--select", "nope", "status"], "--select 'nope' is no drive name or tag"),
    (["--parallel", "0", "status"], "--parallel '0'"),
    ([], "--inventory needs a command"),
])
def test_line_refusals_are_one_line_and_exit_2_before_any_drive_is_touched(tmp_path: Path, argv: list[str],
                                                                           words: str, isolated_env: Path) -> None:
    result = run_akdctl("--inventory", _inv(tmp_path, "a", "b"), *argv)
    assert result.code == 2, result
    assert words in result.stderr
    assert result.stderr.count("\n") <= 3 and "Traceback" not in result.stderr
    assert not isolated_env.exists() or not list(isolated_env.glob("sim-*.json"))


@pytest.mark.slow
def test_line_options_without_an_inventory_are_a_usage_error() -> None:
    result = run_akdctl("--select", "x", "status")
    assert result.code == 2 and "--select works only with --inventory" in result.stderr


# ----------------------------------------------------------------------------- runs on the simulator
@pytest.mark.slow
def test_status_on_a_line_gives_one_json_document_and_the_worst_exit_code(tmp_path: Path) -> None:
    inv = _write(tmp_path, "[[drive]]\nname='a'\ntarget='sim://a'\n[[drive]]\nname='b'\ntarget='sim://b'\n"
                           "[[drive]]\nname='gone'\ntarget='pn://127.0.0.1:9'\n", "inv.toml")
    result = run_akdctl("--inventory", inv, "--timeout", "0.3", "--retries", "0", "status", "--json")
    assert result.code == 3, result  # the unreachable drive's exit code is the worst
    document = json.loads(result.stdout)
    states = {d["name"]: d["state"] for d in document["drives"]}
    assert states == {"a": "passed", "b": "passed", "gone": "unreachable"}
    assert document["drives"][0]["result"]["target"] == "sim://a"
    assert document["summary"] == {"drives": 3, "passed": 2, "failed": 0, "unreachable": 1, "skipped": 0}
    assert "2 passed, 0 failed, 1 unreachable" in result.stderr


@pytest.mark.slow
def test_a_line_commission_without_consent_writes_nothing_to_any_drive(tmp_path: Path) -> None:
    inv = _inv(tmp_path, "a", "b")
    recipe = _write(tmp_path, "[recipe]\nname='r'\n[[step]]\naction='set'\npnu=930\nvalue=${vars.mode}\n"
                              "[[step]]\naction='enable'\n", "r.toml")
    before = run_akdctl("--inventory", inv, "pnu", "get", "930", "--json")
    result = run_akdctl("--inventory", inv, "commission", recipe)
    assert result.code == 4, result
    assert "refusing to run recipe r.toml on 2 drive(s), which powers or moves the axis of 2: a (sim://a)" \
        in result.stderr
    after = run_akdctl("--inventory", inv, "pnu", "get", "930", "--json")
    assert json.loads(before.stdout)["drives"][0]["result"] == json.loads(after.stdout)["drives"][0]["result"]
    assert not list(tmp_path.glob(".akdctl-line-*")), "the substituted recipes are removed"


@pytest.mark.slow
def test_an_undefined_variable_refuses_the_whole_line_before_anything_runs(tmp_path: Path) -> None:
    inv = _write(tmp_path, "[[drive]]\nname='a'\ntarget='sim://a'\n[drive.vars]\nmode=2\n"
                           "[[drive]]\nname='b'\ntarget='sim://b'\n", "inv.toml")
    recipe = _write(tmp_path, "[recipe]\nname='r'\n[[step]]\naction='set'\npnu=930\nvalue=${vars.mode}\n", "r.toml")
    result = run_akdctl("--yes", "--inventory", inv, "commission", recipe)
    assert result.code == 2, result
    assert "${vars.mode} is not defined for drive 'b' (entry 2" in result.stderr
    assert json.loads(run_akdctl("-T", "sim://a", "pnu", "get", "930", "--json").stdout)["parameters"][0]["values"] == [1]


# ----------------------------------------------------------------------------- the end-to-end run
RECIPE = """
[recipe]
name = "line ${name}"

[[step]]
action = "set"
name = "operating mode of ${name}"
objects = { "0x6060:0" = ${vars.mode} }

[[step]]
action = "expect"
name = "mode stuck"
object = "0x6060:0"
value = ${vars.mode}
"""


@pytest.mark.slow
def test_discover_inventory_commission_and_diff_a_line_of_eight_drives(tmp_path: Path, isolated_env: Path) -> None:
    env = {"AKDCTL_STATE_DIR": str(isolated_env)}
    for name in ("s1", "s2", "s3"):  # three simulated drives to discover (made in this process: preparation)
        assert run_akdctl_inproc("-T", f"sim://{name}", "sdo", "read", "0x1018:1").code == 0
    gateway = SimServer("--ethercat-udp", "127.0.0.1:0", "--ecat-stations", "1001=e1,1002=e2,1003=e3", env=env)
    profinet = SimServer("--profinet", "127.0.0.1:0", "--name", "p1", env=env)
    eip = SimServer("--ethernetip", "127.0.0.1:0", "--eip-io-port", "0", "--name", "i1", env=env)
    try:
        for server in (gateway, profinet, eip):
            server.start()
        gw_host, gw_port = gateway.address_of("ethercat")
        pn_host, pn_port = profinet.address_of("profinet")
        eip_host, eip_port = re.match(r"ethernetip ([\d.]+):(\d+) ", eip.ready[0]).groups()  # type: ignore[union-attr]
        inv_path = tmp_path / "line.toml"
        found = run_akdctl("discover", "--sim", "--ecat-udp", f"{gw_host}:{gw_port}", "--stations", "1001-1004",
                           "--pn", f"{pn_host}:{pn_port}", "--eip", f"{eip_host}:{eip_port}",
                           "--write-inventory", str(inv_path), "--tag", "line3", "--timeout", "1", "--json")
        assert found.code == 0, found
        document = json.loads(found.stdout)
        transports = {d["transport"] for d in document["drives"]}
        assert {"sim", "ecat-udp", "pn", "eip"} <= transports
        assert [d["target"] for d in document["silent"]] == [f"ecat-udp://{gw_host}:{gw_port}/1004"]
        inv = inventory.load(str(inv_path))
        assert len(inv.drives) >= 8
        assert len({d.key for d in inv.drives}) == len(inv.drives), "one key per drive"
        # per-drive values, as a user would add them: the CoE drives get a mode of their own and a tag
        coe = [d for d in inv.drives if d.target.startswith(("sim", "ecat-udp"))]
        odd = {d.name for n, d in enumerate(coe) if n % 3 == 0}
        edited = [inventory.LineDrive(d.name, d.target, d.key, [*d.tags, "coe"], {"mode": 3 if d.name in odd else 1})
                  if d in coe else d for d in inv.drives]
        inv_path.write_text(inventory.dump(edited), encoding="utf-8")
        recipe = _write(tmp_path, RECIPE, "recipe.toml")
        junit = tmp_path / "line.xml"
        run = run_akdctl("--yes", "--inventory", str(inv_path), "--select", "coe", "--parallel", "4",
                         "commission", recipe, "--report", str(junit), "--report", str(tmp_path / "line.json"))
        assert run.code == 0, run
        assert f"commission on {len(coe)} drive(s): {len(coe)} passed" in run.stderr
        suites = ET.parse(junit).getroot()
        assert suites.get("tests") == str(2 * len(coe)) and suites.get("errors") == "0"
        assert {s.get("name") for s in suites.iter("testsuite")} == {f"{d.name} ({d.target})" for d in coe}
        diff = run_akdctl("--inventory", str(inv_path), "--select", "coe", "params", "diff", "--source", "objects", "--json")
        assert diff.code == 5, diff
        differences = json.loads(diff.stdout)["differences"]
        # one mode, two addresses: DRV.OPMODE 35B4h (2, position) and 0x6060 (1, profile position) both differ
        assert [d["key"] for d in differences] == ["0x35B4:0", "0x6060:0"], differences
        assert all(set(d["differ"]) == odd for d in differences)  # the minority differs from the majority
        assert [d["expected"] for d in differences] == ["2", "1"]
        # killing one server mid-run fails its drives only; the others finish and the report says so
        slow = _write(tmp_path, "[recipe]\nname='slow'\n[[step]]\naction='check_faults'\n"
                                "[[step]]\naction='wait'\nseconds=2\n[[step]]\naction='check_faults'\n", "slow.toml")
        line_run = start_akdctl("--yes", "--inventory", str(inv_path), "--select", "coe", "--parallel", "8",
                                "--timeout", "0.5", "--retries", "0", "commission", slow,
                                "--report", str(tmp_path / "slow.json"))
        time.sleep(1.0)
        gateway.stop()
        finished = finish(line_run, timeout=60)
        assert finished.code == 3, finished
        report = json.loads((tmp_path / "slow.json").read_text())
        states = {d["name"]: d["state"] for d in report["drives"]}
        at_gateway = {d.name for d in coe if d.target.startswith("ecat-udp")}
        assert at_gateway and {n for n, s in states.items() if s != "passed"} == at_gateway, states
        assert report["summary"]["passed"] == len(coe) - len(at_gateway)
    finally:
        for server in (gateway, profinet, eip):
            server.stop()



@pytest.mark.slow
def test_forked_and_spawned_drives_give_the_same_document(tmp_path: Path) -> None:
    inv = _inv(tmp_path, "a", "b", "c")
    forked = run_akdctl("--inventory", inv, "sdo", "read", "0x1018:4", "--json")
    spawned = run_akdctl("--inventory", inv, "sdo", "read", "0x1018:4", "--json", env={"AKDCTL_LINE_SPAWN": "1"})
    assert forked.code == spawned.code == 0, (forked, spawned)

    def results(text: str) -> list:
        return [(d["name"], d["state"], d["result"]) for d in json.loads(text)["drives"]]

    assert results(forked.stdout) == results(spawned.stdout)
    serials = [d[2]["value"] for d in results(forked.stdout)]
    assert len(set(serials)) == 3, "each simulated drive has a serial number of its own"


@pytest.mark.slow
@pytest.mark.parametrize("spawn", ["0", "1"])
def test_ctrl_c_during_a_line_commission_stops_every_axis(tmp_path: Path, spawn: str) -> None:
    inv = _inv(tmp_path, "m1", "m2")
    recipe = _write(tmp_path, "[recipe]\nname='long move'\n[[step]]\naction='enable'\n[[step]]\naction='home'\n"
                              "[[step]]\naction='move'\ntarget=200\nunit='rev'\nvelocity=120\n", "long.toml")
    proc = start_akdctl("--yes", "--inventory", inv, "commission", recipe, env={"AKDCTL_LINE_SPAWN": spawn})
    deadline = time.monotonic() + 30
    moving: set[str] = set()
    while time.monotonic() < deadline and len(moving) < 2:
        for name in ("m1", "m2"):
            status = run_akdctl("-T", f"sim://{name}", "status", "--json")
            if status.code == 0 and abs(json.loads(status.stdout)["status"]["velocity_rpm"] or 0) > 1:
                moving.add(name)
        time.sleep(0.2)
    assert moving == {"m1", "m2"}, "both axes should be moving before the interrupt"
    proc.send_signal(2)
    result = finish(proc, timeout=40)
    assert result.code == 130, result
    for name in ("m1", "m2"):
        status = json.loads(run_akdctl("-T", f"sim://{name}", "status", "--json").stdout)["status"]
        assert abs(status["velocity_rpm"]) < 1 and status["standstill"] is True, status


@pytest.mark.slow
def test_the_documented_ci_matrix_command_runs_against_simulated_drives(tmp_path: Path) -> None:
    """docs/line.md's CI-matrix job, its akdctl command line verbatim with the matrix value filled in."""
    import shlex
    import subprocess
    import sys

    from tests.harness import ROOT, akdctl_env

    doc = (ROOT / "docs" / "line.md").read_text(encoding="utf-8")
    line = next(text for text in doc.splitlines() if "akdctl --yes --inventory inventories/" in text)
    argv = shlex.split(line.split("- run: ", 1)[1].replace("${{ matrix.line }}", "line2"))
    assert argv[0] == ".venv/bin/akdctl"
    (tmp_path / "inventories").mkdir()
    (tmp_path / "recipes").mkdir()
    (tmp_path / "inventories" / "line2.toml").write_text(
        "".join(f"[[drive]]\nname='l2a{k}'\ntarget='sim://l2a{k}'\n[drive.vars]\nmode={k % 2 * 2 + 1}\n" for k in range(3)))
    (tmp_path / "recipes" / "line.toml").write_text(
        "[recipe]\nname='line ${name}'\n[[step]]\naction='set'\nobjects={ '0x6060:0' = ${vars.mode} }\n"
        "[[step]]\naction='check_faults'\n")
    proc = subprocess.run([sys.executable, "-m", "akdctl", *argv[1:]], cwd=tmp_path, env=akdctl_env(),
                          capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert proc.returncode == 0, proc.stderr
    suites = ET.parse(tmp_path / "junit-line2.xml").getroot()
    assert [s.get("name") for s in suites.iter("testsuite")] == [f"l2a{k} (sim://l2a{k})" for k in range(3)]
    report = json.loads((tmp_path / "report-line2.json").read_text())
    assert report["summary"]["passed"] == 3


@pytest.mark.slow
def test_discover_lists_the_nodes_of_a_can_bus_and_writes_them_to_an_inventory(tmp_path: Path) -> None:
    link = tmp_path / "slcan-tty"
    with SimServer("--can", f"slcan-pty:{link}:5", "--name", "c5"):
        bus = f"slcan/{link.as_posix().replace('/', '%2F')}?sleep_after_open=0"
        found = run_akdctl("discover", "--can", bus, "--nodes", "1-8", "--timeout", "1",
                           "--write-inventory", str(tmp_path / "can.toml"), "--json")
        assert found.code == 0, found
        drives = json.loads(found.stdout)["drives"]
        assert [(d["transport"], d["alias"], d["vendor"]) for d in drives] == [("can", "5", "Kollmorgen")]
        inv = inventory.load(str(tmp_path / "can.toml"))
        assert inv.drives[0].target == f"can://{bus.split('?')[0]}/5?sleep_after_open=0"
        status = run_akdctl("--inventory", str(tmp_path / "can.toml"), "sdo", "read", "0x1018:1", "--json")
        assert status.code == 0, status
        assert json.loads(status.stdout)["drives"][0]["result"]["value"] == 0x6A


@pytest.mark.slow
@pytest.mark.root
@pytest.mark.skipif(os.geteuid() != 0 and os.environ.get("CI") != "true",
                    reason="needs root for network namespaces and raw sockets")
def test_discover_lists_the_slaves_of_a_raw_ethercat_interface_with_their_sii_identity() -> None:
    from tests.netns import VethPair

    with VethPair() as pair, SimServer("--ethercat-raw", pair.if_b, netns=pair.b):
        found = run_akdctl("discover", "--ecat", pair.if_a, "--timeout", "1", "--json", netns=pair.a)
        assert found.code == 0, found
        drives = json.loads(found.stdout)["drives"]
        assert [(d["transport"], d["target"], d["vendor"]) for d in drives] == \
            [("ecat", f"ecat://{pair.if_a}/0", "Kollmorgen")]
        assert drives[0]["serial"] and drives[0]["key"] == f"serial:{drives[0]['serial']}"
