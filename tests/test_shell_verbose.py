"""Issue 14, ``-v`` on every command: the link when the drive is first reached, the requests per layer and the time
waited on the link at the end, one line per exchange with ``-vv`` (cli/verbose.py, from the session's tracer)."""

from __future__ import annotations

from types import SimpleNamespace

from akdctl.cli.verbose import exchanges, summary_lines
from akdctl.errors import EXIT_OK


def _rec(t: float, direction: str, layer: str, size: int) -> SimpleNamespace:
    return SimpleNamespace(time=t, direction=direction, layer=layer, data=bytes(size))


def test_exchanges_pair_requests_with_their_replies() -> None:
    records = [_rec(0.0, "tx", "bmp", 10), _rec(0.004, "rx", "bmp", 20), _rec(0.010, "tx", "mailbox", 16),
               _rec(0.011, "rx", "mailbox", 8), _rec(0.012, "rx", "mailbox", 8), _rec(0.020, "tx", "bmp", 10)]
    done = exchanges(records)
    assert [(e.layer, e.sent, e.received) for e in done] == [("bmp", 10, 20), ("mailbox", 16, 16), ("bmp", 10, 0)]
    assert abs(done[0].rtt_s - 0.004) < 1e-9 and done[2].rtt_s is None
    lines = summary_lines(records, 0.5, 2, contacted=True)
    assert "akdctl: bmp      -> 10 B  <- no reply" in lines
    assert any("bmp 2 -> 1, mailbox 1 -> 1" in line for line in lines) and lines[-1] == "akdctl: done in 500 ms"
    assert summary_lines([], 0.01, 1, contacted=False)[0] == "akdctl: no drive contacted"


def test_verbose_names_the_link_and_counts_the_requests(akd_inproc) -> None:
    code, out, err = akd_inproc("-v", "pnu", "get", "930", "964")
    assert code == EXIT_OK
    lines = err.splitlines()
    assert lines[0].startswith("akdctl: target sim (from default) via built-in simulated AKD") and "timeout 2 s" in lines[0]
    assert "requests (sent -> answered): bmp 1 -> 1" in err and lines[-1].startswith("akdctl: done in")
    code, _, err = akd_inproc("sdo", "read", "0x6041", "-vv", "--timeout", "3")
    assert code == EXIT_OK and "timeout 3 s" in err and "akdctl: mailbox  -> " in err
    code, out, err = akd_inproc("fault", "explain", "F501", "-v")
    assert code == EXIT_OK and "no drive contacted" in err
    assert akd_inproc("pnu", "get", "930")[2] == ""  # without -v: nothing on stderr
