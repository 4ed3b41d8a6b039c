"""The simulated drive's store (``akdctl/sim/drive.py``): what reaches the state file, when, and what it survives.

Read-only requests never write the file; a long-lived ``SimDrive`` (``sim serve``) keeps its model and reloads only
when another process saved; parallel writers lose no update; a hostile or unwritable state file is a one-line error.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from akdctl.errors import EXIT_OK
from akdctl.sim.drive import SimDrive
from tests.harness import ROOT, akdctl_env

READ_PNU_930 = bytes.fromhex("01 01 00 01 10 01 03 A2 00 00")


def _set_930(value: int) -> bytes:
    """A BMP change request for PNU 930 (operating mode)."""
    from akdctl.protocol import bmp

    return bmp.encode_request(bmp.ParameterRequest(1, bmp.REQ_CHANGE, 0, (bmp.ParameterAddress(930),),
                                                   (bmp.ParameterValue.of(bmp.Format.WORD, value),)))
UPLOAD_6041 = bytes.fromhex("0a00 0000 0003 0020 4041 6000 0000 0000")


def _file_id(path: Path) -> tuple[int, int]:
    info = path.stat()
    return info.st_ino, info.st_mtime_ns


# ------------------------------------------------------------------ no writes on reads
def test_read_only_cli_commands_leave_the_state_file_untouched(akd, isolated_env: Path) -> None:
    assert akd("pnu", "set", "930=2")[0] == EXIT_OK
    state, lock = isolated_env / "sim-default.json", isolated_env / "sim-default.lock"
    before, token = _file_id(state), lock.read_bytes()
    for argv in (("pnu", "get", "930"), ("sdo", "read", "0x6041"), ("status",)):
        code, _, err = akd(*argv)
        assert code == EXIT_OK, err
        assert _file_id(state) == before, f"{' '.join(argv)} rewrote the state file"
    assert lock.read_bytes() == token


def test_read_requests_save_nothing_and_writes_save_once_each(isolated_env: Path, monkeypatch) -> None:
    drive = SimDrive("default")
    drive.handle_bmp(_set_930(2))  # one save
    saves, loads, load = [], [], SimDrive._load
    monkeypatch.setattr(SimDrive, "_save", lambda self, model, meta: saves.append(model.writes))
    monkeypatch.setattr(SimDrive, "_load", lambda self, token: loads.append(token) or load(self, token))
    for _ in range(200):
        drive.handle_bmp(READ_PNU_930)
        drive.handle_mailbox(UPLOAD_6041)
    assert saves == [] and loads == []  # the held model serves every request
    drive.handle_bmp(_set_930(1))
    assert saves == [2]


def test_a_long_lived_drive_sees_what_another_process_saved(isolated_env: Path) -> None:
    """``sim serve`` holds its model; the token another writer leaves in the lock file makes it reload."""
    served, cli = SimDrive("default"), SimDrive("default")
    assert served.handle_bmp(READ_PNU_930)[-1] == 1
    cli.handle_bmp(_set_930(2))
    assert served.handle_bmp(READ_PNU_930)[-1] == 2
    served.handle_bmp(_set_930(1))
    assert cli.handle_bmp(READ_PNU_930)[-1] == 1


def test_sim_reset_reaches_a_drive_that_holds_its_model(isolated_env: Path) -> None:
    served = SimDrive("default")
    served.handle_bmp(_set_930(2))
    SimDrive("default").reset()
    assert served.handle_bmp(READ_PNU_930)[-1] == 1


def test_a_removed_lock_file_is_reopened(isolated_env: Path) -> None:
    """Someone empties the state directory: the held descriptor would lock a file nobody else locks."""
    served = SimDrive("default")
    served.handle_bmp(_set_930(2))
    for path in isolated_env.iterdir():
        path.unlink()
    assert served.handle_bmp(READ_PNU_930)[-1] == 1  # factory state, as every other process sees it
    assert (isolated_env / "sim-default.lock").exists()


# ------------------------------------------------------------------ concurrency
_BUMP = """
import sys
from akdctl.sim.drive import SimDrive
drive = SimDrive("default")
for _ in range(int(sys.argv[1])):
    with drive.transaction() as model:
        model.set_stored_pnu(1005, [model.stored_pnu(1005)[0] + 1])
"""


@pytest.mark.slow
def test_twenty_parallel_writer_processes_lose_no_update(isolated_env: Path) -> None:
    """20 processes and this one (a long-lived drive, as ``sim serve`` holds it) increment one PNU."""
    rounds, mine = 15, 40
    with SimDrive("default").transaction() as model:
        model.set_stored_pnu(1005, [0])
    env = akdctl_env()
    procs = [subprocess.Popen([sys.executable, "-c", _BUMP, str(rounds)], cwd=ROOT, env=env) for _ in range(20)]
    served = SimDrive("default")
    try:
        for _ in range(mine):
            with served.transaction() as model:
                model.set_stored_pnu(1005, [model.stored_pnu(1005)[0] + 1])
    finally:
        codes = [p.wait(timeout=120) for p in procs]
    assert codes == [0] * 20
    with served.transaction() as model:
        assert model.stored_pnu(1005) == [20 * rounds + mine]
    assert json.loads((isolated_env / "sim-default.json").read_text())["pnus"]["1005"] == [20 * rounds + mine]
    assert not [p.name for p in isolated_env.iterdir() if p.name.endswith(".tmp")]


def test_threads_sharing_one_drive_lose_no_update(isolated_env: Path) -> None:
    """The faces of one ``sim serve`` share one SimDrive (one lock file descriptor)."""
    import threading

    drive = SimDrive("default")
    with drive.transaction() as model:
        model.set_stored_pnu(1005, [0])

    def bump() -> None:
        for _ in range(50):
            with drive.transaction() as model:
                model.set_stored_pnu(1005, [model.stored_pnu(1005)[0] + 1])

    threads = [threading.Thread(target=bump) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    with SimDrive("default").transaction() as model:
        assert model.stored_pnu(1005) == [200]


def test_stale_temporaries_of_a_killed_writer_are_removed(isolated_env: Path) -> None:
    drive = SimDrive("default")
    drive.handle_bmp(READ_PNU_930)
    isolated_env.mkdir(exist_ok=True)
    stale = isolated_env / ".sim-default.k9x_ab12.tmp"
    other = isolated_env / ".sim-default.b.k9x_ab12.tmp"  # drive "default.b": not ours to remove
    stale.write_text("{")
    other.write_text("{")
    SimDrive("default").handle_bmp(READ_PNU_930)
    assert not stale.exists() and other.exists()


# ------------------------------------------------------------------ hostile or unusable state files (17.13, 14)
def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("akdctl: error: "), err
    return lines[0]


@pytest.mark.parametrize("content, words", [
    # A named id: the bytes differ per process, and pytest-xdist workers must collect the same test ids.
    pytest.param(os.urandom(64) + b"\xff\xfe", "not UTF-8", id="random-bytes-not-UTF-8"),
    (b'{"version": 1, "clock": NaN}', "NaN"),
    (b'{"version": 1, "clock": 1e999}', "finite"),
    (b'{"version": 1, "sim": {"wall": "yesterday"}}', "sim"),
    (b"[" * 100000 + b"]" * 100000, "nested too deeply"),
    (b'{"version": 1, "components": {"motion": {"state": "flying"}}}', "flying"),
    (b"[]", "not a JSON object"),
])
def test_a_hostile_state_file_is_a_one_line_error_and_sim_reset_recovers(
        akd_inproc, isolated_env: Path, content: bytes, words: str) -> None:
    isolated_env.mkdir(parents=True, exist_ok=True)
    (isolated_env / "sim-default.json").write_bytes(content)
    for argv in (("pnu", "get", "930"), ("sdo", "read", "0x6041"), ("sim", "show")):
        code, _, err = akd_inproc(*argv)
        line = _one_line(err)
        assert code == 2 and "corrupt" in line and words in line and "akdctl sim reset" in line, err
    assert akd_inproc("sim", "reset")[0] == EXIT_OK
    assert akd_inproc("pnu", "get", "930")[0] == EXIT_OK


def test_a_state_file_that_is_not_a_regular_file_is_refused(akd_inproc, isolated_env: Path) -> None:
    isolated_env.mkdir(parents=True, exist_ok=True)
    os.mkfifo(isolated_env / "sim-default.json")  # reading it would block for ever
    code, _, err = akd_inproc("pnu", "get", "930")
    assert code == 2 and "not a regular file" in _one_line(err)


@pytest.mark.parametrize("errno_, words", [(28, "No space left on device"), (30, "Read-only file system")])
def test_an_unwritable_state_directory_is_a_one_line_error(
        akd_inproc, isolated_env: Path, monkeypatch, errno_: int, words: str) -> None:
    """Issue 23.24: this test once failed both cases in one CI run. The race was its own: ``monkeypatch.undo()``
    undid *every* patch of the test, the autouse ``isolated_env`` one included, so its last ``pnu set`` ran on the
    user's real state directory, shared with every other run on the machine (its drive enabled, or its axis owned
    by a parallel run: exit 4). Only the refusal is undone now, and the test checks it still uses its own directory.
    """
    import akdctl.sim.drive as store

    def refuse(*args: object, **kwargs: object) -> None:
        raise OSError(errno_, os.strerror(errno_))

    with monkeypatch.context() as patch:
        patch.setattr(store, "atomic_open", refuse)
        code, _, err = akd_inproc("pnu", "set", "930=2")
        line = _one_line(err)
        assert code == 2 and "cannot save simulator state" in line and words in line and "AKDCTL_STATE_DIR" in line
        assert akd_inproc("pnu", "get", "930")[0] == EXIT_OK  # reads need no write
    assert os.environ["AKDCTL_STATE_DIR"] == str(isolated_env)
    assert akd_inproc("pnu", "set", "930=2")[0] == EXIT_OK
    assert (isolated_env / "sim-default.json").exists()


def test_a_state_directory_that_cannot_exist_is_a_one_line_error(akd_inproc, tmp_path: Path, monkeypatch) -> None:
    (tmp_path / "a-file").write_text("")
    monkeypatch.setenv("AKDCTL_STATE_DIR", str(tmp_path / "a-file" / "state"))
    code, _, err = akd_inproc("pnu", "get", "930")
    assert code == 2 and "cannot open the simulator's lock file" in _one_line(err)


def test_stale_temporaries_are_cleaned_by_the_next_command(akd_inproc, isolated_env: Path) -> None:
    """A writer killed (kill -9) between writing its temporary file and the rename leaves it behind."""
    assert akd_inproc("pnu", "set", "930=2")[0] == EXIT_OK
    stale = isolated_env / ".sim-default.a1b2c3d4.tmp"
    stale.write_text('{"half": ')
    code, out, _ = akd_inproc("--json", "pnu", "get", "930")
    assert code == EXIT_OK and json.loads(out)["parameters"][0]["values"] == [2]
    assert not stale.exists()


def test_mutated_state_files_either_load_or_are_reported_corrupt(isolated_env: Path) -> None:
    """Seeded mutations of a real state file (wrong types, huge numbers, empty containers at any path): every
    request either works or raises the one-line SimStateError, never anything the CLI would call internal."""
    import random

    from akdctl.sim.drive import SimStateError

    drive = SimDrive("default")
    with drive.transaction() as model:
        model.set_stored_pnu(930, [2])
        model.set_stored_object(0x6081, 0, b"\x01\x00\x00\x00")
    base = json.loads(drive.path.read_text())
    values = [None, True, -1, 0, 2**70, 1.5, -1e300, "x", "", [], {}, [1, "a"], {"a": 1}, "switch_on_disabled"]

    def paths(node: object, at: tuple = ()):  # type: ignore[no-untyped-def]
        yield at
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        for key, child in items:
            yield from paths(child, at + (key,))

    every = [p for p in paths(base) if p]
    rng = random.Random(17)
    for _ in range(300):
        state = json.loads(json.dumps(base))
        for _ in range(rng.randint(1, 3)):
            *parents, last = rng.choice(every)
            node = state
            try:
                for key in parents:
                    node = node[key]
                node[last] = rng.choice(values)
            except (KeyError, IndexError, TypeError):
                continue  # an earlier mutation removed the path
        drive.path.write_text(json.dumps(state))
        fresh = SimDrive("default")
        try:
            fresh.handle_bmp(READ_PNU_930)
            fresh.handle_mailbox(bytes.fromhex("0a00 0000 0003 0020 4064 6000 0000 0000"))  # position actual value
            fresh.snapshot()
        except SimStateError:
            pass
        finally:
            fresh.close()
