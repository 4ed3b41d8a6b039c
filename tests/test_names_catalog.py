"""The AKD name catalogue, the name gate and the parameter file (issue 24): rules, not examples only."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from akdctl.catalog import akd_params
from akdctl.catalog import objects as object_catalog
from akdctl.drive import gate, names
from akdctl.drive.param_file import kind_of, parse, render

ROOT = Path(__file__).resolve().parents[1]


def test_the_shipped_table_is_what_the_generator_writes() -> None:
    import importlib.util
    import sys

    sys.path.insert(0, str(ROOT / "tools"))
    try:
        spec = importlib.util.spec_from_file_location("gen_akd_params", ROOT / "tools" / "gen_akd_params.py")
        gen = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        spec.loader.exec_module(gen)  # type: ignore[union-attr]
    finally:
        sys.path.remove(str(ROOT / "tools"))
    expected = gen.render(gen.merge(gen.esi_rows()))
    assert (ROOT / "akdctl" / "catalog" / "data" / "akd_params.tsv").read_text(encoding="utf-8") == expected, \
        "akd_params.tsv is stale: run tools/gen_akd_params.py"


def test_every_esi_name_of_the_object_table_is_catalogued_at_its_address() -> None:
    """Each AKD name the shipped object dictionary carries is a catalogue row, at that address unless the
    reference resolves a duplicate otherwise (akd-parameter-names.md 1.3) or a fact moves it."""
    moved = {"VL.KVFF", "VL.ERR", "DRV.DISTO", "DRV.NVSAVE"}
    for entry in object_catalog.entries().values():
        name = entry.param
        if not name or not name.isupper() or 0x6000 <= entry.index or entry.index < 0x2000:
            continue
        if entry.name.endswith((" low", " high")):
            continue   # one half of a 64-bit parameter: no single address
        row = akd_params.lookup(name)
        assert row is not None, name
        if name not in moved and row.coe == (entry.index, entry.subindex):
            assert row.mark("coe") == "V"


def test_rows_are_consistent() -> None:
    rows = akd_params.all_params()
    assert len(rows) > 450 and len({r.name for r in rows}) == len(rows)
    for row in rows:
        assert row.source, row.name
        assert row.access in ("NV", "RW", "RO", "WO", "CMD"), row.name
        if row.n:
            assert row.modbus == 2 * (row.n - 1)
        if row.coe is not None and 0x5000 <= row.coe[0] <= 0x5FFF and row.kind != "command":
            assert row.n == row.coe[0] - 0x5000 + 1, row.name   # the 0x5000 block is the n table [V data, I rule]
        if row.coe is not None and row.kind not in ("command", "string", "text"):
            assert row.scale in ("1", "1000", "var"), row.name
        if row.mark("scale") == "I" or row.mark("n") == "I":
            assert "[" in " ".join(row.addresses().values())     # an inferred fact is shown with its mark
    # the facts the reference verified are marked so; the ones it infers are not
    assert akd_params.lookup("IL.KP").mark("scale") == "V"                  # type: ignore[union-attr]
    assert akd_params.lookup("VL.KP").mark("scale") == "I"                  # type: ignore[union-attr]
    assert akd_params.lookup("HOME.MODE").pnu == 1001                       # type: ignore[union-attr]


def test_lookup_is_case_insensitive_and_suggests() -> None:
    assert akd_params.lookup("drv.opmode") == akd_params.lookup("DRV.OPMODE") is not None
    assert akd_params.lookup("NOT.THERE") is None and akd_params.lookup("") is None
    assert akd_params.close_matches("DRV.OPMOD")[0] == "DRV.OPMODE"
    assert [r.name for r in akd_params.matching("unit.p*")] == ["UNIT.PIN", "UNIT.PLINEAR", "UNIT.POUT", "UNIT.PROTARY"]


def test_a_name_is_gated_exactly_as_its_object() -> None:
    """By name as by index: for every catalogued name with a CoE object, the object's class decides first."""
    for row in akd_params.all_params():
        if row.coe is None:
            continue
        by_index = gate.classify_object(row.coe[0], row.coe[1], row.name)
        by_name = names.classify(row)
        if by_index is not None:
            assert by_name == by_index, row.name
    assert names.classify(names.resolve("MT.P")).reason == gate.classify_object(0x607A, 0).reason  # type: ignore[union-attr]
    for name in ("DRV.EN", "MT.MOVE", "HOME.MOVE", "VL.CMDU", "IL.CMDU", "COGCOMP.TEACH", "WS.ARM"):
        verdict = names.classify(names.resolve(name))
        assert verdict is not None and not verdict.when_enabled, name
    for name in ("DRV.OPMODE", "DRV.CMDSOURCE", "MT.LOAD", "HOME.SET"):
        assert names.classify(names.resolve(name)).when_enabled, name    # type: ignore[union-attr]
    for row in akd_params.all_params():   # by name exactly as the gate's name classes say
        by_gate = gate.classify_name(row.name)
        if by_gate is not None and row.coe is None:
            assert names.classify(row) == by_gate, row.name
    for name in ("DRV.DIS", "DRV.STOP", "DRV.CLRFAULTS", "DRV.NVSAVE", "VL.KP", "UNIT.PIN"):
        assert names.classify(names.resolve(name)) is None, name


def test_the_passthrough_runs_only_known_safe_reads_freely() -> None:
    for line in ("DRV.INFO", "drv.faults", "VL.KP", "DRV.HELP VL.KP", "MT.LIST"):
        assert names.classify_line(line)[1] is None, line
    for line in ("VL.KP 2", "DRV.EN", "MT.MOVE 1", "SOMETHING.NEW", "DRV.INFO now"):
        assert names.classify_line(line)[1] is not None, line


def test_parameter_file_round_trip_and_leniency() -> None:
    data = render([("VL.KP", "1.500"), ("DRV.NAME", "Achse µ")], ["made by a test"])
    assert data.endswith(b"\r\n") and b"\xb5" in data              # CRLF, Latin-1
    assert parse(data, "f") == [(2, "VL.KP", "1.500"), (3, "DRV.NAME", "Achse µ")]
    lenient = b"' comment\nvl.kp 1.000 [A/(rad/s)]\nHOME.MODE 3 (0)   # was changed\n\n"
    assert parse(lenient, "f") == [(2, "VL.KP", "1.000"), (3, "HOME.MODE", "3")]
    assert kind_of(b"[identity]\nvendor = 1\n") == "toml" and kind_of(b'{"a": 1}') == "json"
    assert kind_of(b"# x\nVL.KP 1\n") == "akd"
    with pytest.raises(Exception, match="line 1"):
        parse(b"VL.KP\n", "f")


@pytest.mark.parametrize(("argv", "code", "words"), [
    (("param", "get", "DRV.OPMOD"), 2, "closest: DRV.OPMODE"),
    (("param", "set", "VL.FB=1"), 2, "read-only"),
    (("param", "set", "VL.KP=0.0001"), 2, "decimals"),
    (("param", "set", "DRV.OPMODE=7"), 2, "range"),
    (("param", "set", "DRV.EN=1"), 2, "is a command"),
    (("param", "get", "DRV.CMDSOURCE"), 2, "not reachable over CoE"),
    (("param", "set", "MT.V=100"), 2, "--raw"),
    (("cmd", "DRV.INFO"), 2, "akd://"),
    (("param", "list", "NOPE.*"), 2, "no AKD parameter"),
    (("param", "set", "VL.KP", "5"), 2, "write it as VL.KP=5"),  # the AKD terminal's spelling, answered with ours
])
def test_bad_input_ends_in_one_line(akd_inproc, argv: tuple[str, ...], code: int, words: str) -> None:
    rc, out, err = akd_inproc(*argv)
    assert rc == code and words in err and err.count("\n") == 1, err


def test_gated_write_by_name_needs_consent(akd_inproc) -> None:
    rc, out, err = akd_inproc("param", "set", "MT.P=1000")            # 0x607A: a set point, always gated
    assert rc == 4 and "consent" in err
    assert len(err.splitlines()) == 1  # the refusal alone: the plan's notes (RAM only ...) come only if it runs
    rc, out, err = akd_inproc("--json", "param", "set", "MT.P=1000", "--dry-run")
    plan = json.loads(out)["plan"]
    assert rc == 0 and plan["needs_consent"] and plan["writes"][0]["address"].startswith("MT.P (CoE 0x607A:0)")
    rc, out, err = akd_inproc("-y", "param", "set", "MT.P=1000")
    assert rc == 0, err


def test_get_json_and_raw(akd_inproc) -> None:
    rc, out, err = akd_inproc("--json", "param", "get", "VL.KP", "IL.KP", "--raw")
    data = json.loads(out)
    assert rc == 0 and data["route"] == "coe"
    kp = data["parameters"][0]
    assert kp["name"] == "VL.KP" and kp["scale"] == "1000" and kp["address"] == "0x3548:0"
    assert kp["value"] * 1000 == kp["raw"] and kp["unit"] == "A/(rad/s)"


def test_params_is_an_alias_and_backup_is_in_param(akd_inproc, tmp_path: Path) -> None:
    backup = tmp_path / "b.toml"
    rc, out, err = akd_inproc("params", "backup", "-o", str(backup))
    assert rc == 0 and backup.exists(), err
    rc, out, err = akd_inproc("param", "diff", str(backup))     # a TOML backup is told apart by content
    assert rc == 0, err
    rc, out, err = akd_inproc("param", "restore", str(backup), "--dry-run")
    assert rc == 0, err


def test_a_plans_notes_are_shown_and_only_for_what_it_writes(akd_inproc, tmp_path: Path) -> None:
    """param set's notes (RAM only until saved, the inferred CoE scale) reach the user on stderr, one line each,
    as every writing command's do (cli/consent.consent_plan). A restore notes the factory MOTOR.INERTIA (0.1 at the
    inferred scale, below the published range) only if it writes it, and says when there is nothing to write."""
    rc, out, err = akd_inproc("-y", "param", "set", "VL.KP=0.5")
    assert rc == 0 and "VL.KP" in out, err
    assert err.splitlines() == [
        "akdctl: note: VL.KP: CoE scale x1000 is inferred [I] (the read-back uses the same scale, so it cannot "
        "confirm it; compare with akd://HOST on a real drive)",
        "akdctl: note: RAM only until 'akdctl param save' (DRV.NVSAVE)"]
    dump = tmp_path / "axis.akd"
    assert akd_inproc("param", "dump", str(dump))[0] == 0
    assert "\nMOTOR.INERTIA 0.100\n" in dump.read_text()
    rc, out, err = akd_inproc("-y", "param", "restore", str(dump))
    assert rc == 0 and "nothing to write" in out and err == "", err
    dump.write_text(dump.read_text().replace("\nVL.KP 0.500\n", "\nVL.KP 0.750\n"), encoding="utf-8")
    rc, out, err = akd_inproc("-y", "param", "restore", str(dump))
    assert rc == 0 and "0.75" in out and "MOTOR.INERTIA" not in err and "RAM only" in err, err


def test_live_discovery_is_cached_per_firmware_and_overrides(akd_inproc, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    rc, out, err = akd_inproc("--json", "param", "list", "--live", "VL.K*")
    first = json.loads(out)
    assert rc == 0 and "cached" not in first["source"] and {"VL.KP", "VL.KI"} <= {p["name"] for p in first["parameters"]}
    assert list((tmp_path / "cache" / "akdctl").glob("akd-names-coe-*.json"))
    rc, out, err = akd_inproc("--json", "param", "list", "--live", "VL.K*")
    assert rc == 0 and "cached" in json.loads(out)["source"]
    from akdctl.drive.name_discovery import live_row

    row = akd_params.lookup("VL.KP")
    moved = live_row(row, "VL.KP", {"VL.KP": {"coe": [0x3549, 0], "type": "u32"}})
    assert moved is not None and moved.coe == (0x3549, 0) and moved.mark("coe") == "live"
    new = live_row(None, "XYZ.NEW", {"XYZ.NEW": {"coe": [0x3999, 0], "type": "i32"}})
    assert new is not None and new.kind == "raw" and new.source == "live"
    assert names.resolve("XYZ.NEW", {"XYZ.NEW": {}}).name == "XYZ.NEW"
    with pytest.raises(Exception, match="unknown AKD parameter"):
        names.resolve("XYZ.NEW")


def test_diff_against_another_drive(akd_inproc) -> None:
    assert akd_inproc("-T", "sim://other", "-y", "param", "set", "VL.KP=3.25")[0] == 0
    rc, out, err = akd_inproc("--json", "param", "diff", "--against", "sim://other")
    doc = json.loads(out)
    assert rc == 5 and [d["name"] for d in doc["differences"]] == ["VL.KP"] and doc["error"]["exit_code"] == 5, err
    assert akd_inproc("-y", "param", "set", "VL.KP=3.25")[0] == 0
    rc, out, err = akd_inproc("param", "diff", "--against", "sim://other")
    assert rc == 0 and "no differences" in out, err
    rc, out, err = akd_inproc("param", "diff", "--against", "sim://other", "--defaults")
    assert rc == 2 and "one of" in err
