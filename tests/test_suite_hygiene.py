"""The session's leftover check (conftest ``nothing_left_behind``) can see what it is meant to catch: a process a
test started and did not stop, and a namespace a test made and did not remove."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.harness import live_descendants
from tests.netns import LoopbackNetns, leftover_namespaces


@pytest.mark.slow
def test_a_running_child_is_seen_until_it_is_reaped() -> None:
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        assert proc.pid in live_descendants(), "a running child was not seen"
        assert "time.sleep(60)" in live_descendants()[proc.pid]
    finally:
        proc.kill()
        proc.wait(timeout=10)
    assert proc.pid not in live_descendants()


@pytest.mark.slow
def test_grandchildren_count_too() -> None:
    code = "import subprocess, sys; p = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)']); " \
           "print(p.pid, flush=True); p.wait()"
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    grandchild = 0
    try:
        assert proc.stdout is not None
        grandchild = int(proc.stdout.readline())
        assert grandchild in live_descendants()
    finally:
        if grandchild:
            os.kill(grandchild, 9)
        else:
            proc.kill()
        proc.wait(timeout=10)
        proc.stdout.close()
    assert grandchild not in live_descendants() and proc.pid not in live_descendants()


@pytest.mark.root
@pytest.mark.slow
def test_a_namespace_is_a_leftover_until_it_is_deleted() -> None:
    ns = LoopbackNetns()
    with ns:
        assert ns.name in leftover_namespaces()
    assert ns.name not in leftover_namespaces()
