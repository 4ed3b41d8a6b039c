"""Shared test fixtures: every test gets its own simulator state dir and no user config.

``akd`` runs the real CLI in a subprocess (``python -m akdctl``, see :mod:`tests.harness`) and returns
``(exit_code, stdout, stderr)``; ``akd_inproc`` runs the same entry point in this process (faster, for the many
bad-input cases).

Two markers are policed here rather than trusted:

* ``root`` tests skip with a visible reason when not root outside CI; in CI (CI=true) they always run.
* ``slow`` is on every test that starts a subprocess.  Tests using a subprocess fixture get it at collection; an
  audit hook sees every ``subprocess.Popen`` and fails a test that started one without carrying the mark, so the
  marker cannot drift out of date (``-m "not slow"`` really is the in-process suite).

The same hook fails an in-process test whose socket connects, sends or resolves a name beyond loopback, or binds to
every interface: no test sends a packet off the machine.

Bytecode is cached even where the environment says ``PYTHONDONTWRITEBYTECODE`` (see :func:`_bytecode_cache`), in a
directory of this run's that its first process removes at its end (:func:`run_cache`).

The suite runs on two pytest-xdist workers (README's test command), so nothing here is shared between tests: state
and config live in ``tmp_path``, servers bind port 0, namespaces have random names.  What a test leaves behind is
checked once per process at the end of the session (``nothing_left_behind``): a live child process or a namespace
still in ``/run/netns`` fails the run, after being removed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from pathlib import Path

import pytest


#: The environment variable naming this run's cache directory (:func:`run_cache`), inherited by xdist workers and
#: every subprocess.
RUN_CACHE_ENV = "AKDCTL_TESTS_RUN_CACHE"


def run_cache() -> Path:
    """This run's directory for caches its processes share (bytecode, mypy's incremental cache): made by the first
    pytest process of the run (the xdist controller, which loads this file before it starts its workers, or the
    only process) and removed when that process exits, so the suite leaves no cache behind in the user's home
    or the checkout. A worker or subprocess finds it in the environment (:data:`RUN_CACHE_ENV`)."""
    named = os.environ.get(RUN_CACHE_ENV)
    if named:
        return Path(named)
    import atexit
    import shutil
    import tempfile

    made = tempfile.mkdtemp(prefix="akdctl-tests-")
    os.environ[RUN_CACHE_ENV] = made
    atexit.register(shutil.rmtree, made, True)
    return Path(made)


def _bytecode_cache() -> None:
    """Where ``PYTHONDONTWRITEBYTECODE`` is set (kept out of the checkout), compiled bytecode goes to this run's
    cache (``PYTHONPYCACHEPREFIX``, :func:`run_cache`) instead of nowhere.

    Why: the suite starts the CLI in a subprocess about a thousand times, and without cached bytecode every one of
    them compiles each module it imports (~0.12 s of its ~0.25 s CPU), and every xdist worker rewrites the asserts
    of every test module it collects (~14 s CPU) - work an installed package (.pyc files) never does. Set before
    any test module is imported, and in the environment every subprocess inherits; the source tree stays free of
    ``__pycache__``. Python checks each cached file against its source (mtime and size), so an edited module is
    compiled anew. A prefix chosen by the caller is left as it is."""
    if not os.environ.get("PYTHONDONTWRITEBYTECODE") or os.environ.get("PYTHONPYCACHEPREFIX"):
        return
    prefix = run_cache() / "pycache"
    try:
        prefix.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError:
        return  # no cache directory: compile as before
    del os.environ["PYTHONDONTWRITEBYTECODE"]
    os.environ["PYTHONPYCACHEPREFIX"] = str(prefix)
    sys.pycache_prefix = str(prefix)
    sys.dont_write_bytecode = False


_bytecode_cache()


def _hypothesis_profile() -> None:
    """Property tests judge results, never time: no per-example deadline and no "too slow" health check.

    Why: both are wall-clock limits (200 ms an example; data generation), so a loaded host -- the suite runs on two
    workers on two cores, beside whatever else runs there -- failed correct code with DeadlineExceeded or
    FailedHealthCheck; the project asserts no timings in tests. Loaded before any test module is imported, so
    every ``@settings`` without a deadline of its own inherits it; ``max_examples`` stay each test's own."""
    try:
        from hypothesis import HealthCheck, settings
    except ImportError:
        return
    settings.register_profile("akdctl", deadline=None, suppress_health_check=[HealthCheck.too_slow])
    settings.load_profile("akdctl")


_hypothesis_profile()

from tests.harness import ROOT, run_akdctl  # noqa: F401 - re-exported: tests import them from here too
from tests.watch import Watch

# Fixtures whose use means the test starts a subprocess: such tests are marked slow at collection.
SUBPROCESS_FIXTURES = frozenset({"akd"})


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "root: needs root/CAP_NET_RAW/network namespaces")
    Watch.install()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """``slow`` on tests using a subprocess fixture; root-only tests skip visibly when not root and not in CI."""
    for item in items:
        if SUBPROCESS_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
    if os.geteuid() == 0:
        return
    if os.environ.get("CI") == "true":
        return  # in CI they run regardless, and fail loudly if root is missing
    for item in items:
        if "root" in item.keywords:
            item.add_marker(pytest.mark.skip(reason="needs root (CAP_NET_RAW, network namespaces); runs in CI"))


@pytest.fixture(scope="session", autouse=True)
def nothing_left_behind():
    """At the session's end (after every module fixture is torn down): no process this one started still runs and
    no namespace a test made still exists.  Leftovers are removed, then reported as an error of the last test."""
    yield
    from tests.harness import live_descendants
    from tests.netns import delete_namespace, leftover_namespaces

    processes, spaces = live_descendants(), leftover_namespaces()
    for pid in processes:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
    for name in spaces:
        delete_namespace(name)
    if processes or spaces:
        pytest.fail("left behind by the tests: " + "; ".join(
            [f"process {pid} ({cmd})" for pid, cmd in sorted(processes.items())]
            + [f"network namespace {name}" for name in spaces]), pytrace=False)


@pytest.fixture(autouse=True)
def process_and_network_policy(request: pytest.FixtureRequest):
    """Fail a test that started a subprocess (in its body or its fixtures) without ``@pytest.mark.slow``, or whose
    in-process sockets aimed off the machine."""
    Watch.started.clear()
    Watch.off_machine.clear()
    yield
    started, off = list(Watch.started), list(Watch.off_machine)
    if off:
        pytest.fail(f"{request.node.nodeid} sends off the machine: {'; '.join(sorted(set(off)))}", pytrace=False)
    if started and request.node.get_closest_marker("slow") is None:
        pytest.fail(f"{request.node.nodeid} starts subprocesses ({', '.join(sorted(set(started)))}) "
                    "but is not marked @pytest.mark.slow", pytrace=False)


@pytest.fixture(autouse=True)
def isolated_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    state = tmp_path / "akd-state"
    monkeypatch.setenv("AKDCTL_STATE_DIR", str(state))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg-config"))
    for var in ("AKDCTL_TARGET", "AKDCTL_PROFILE", "AKDCTL_CONFIG", "AKDCTL_DEBUG"):
        monkeypatch.delenv(var, raising=False)
    return state


@pytest.fixture
def akd():
    return run_akdctl


@pytest.fixture
def akd_inproc(capsys: pytest.CaptureFixture[str]):
    """Run ``akdctl.cli.main.main(argv)`` in-process; returns (exit_code, stdout, stderr)."""
    from akdctl.cli.main import main

    def run(*args: str) -> tuple[int, str, str]:
        capsys.readouterr()
        try:
            main(list(args))
            code = 0
        except SystemExit as exc:
            code = int(exc.code or 0)
        out, err = capsys.readouterr()
        return code, out, err

    return run
