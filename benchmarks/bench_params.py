"""``params backup`` of the whole catalogue: round trips used against the protocol minimum.

PROFIdrive base-mode parameter access carries at most 39 parameters per request
and at most 240 bytes per request and response block (SPEC-NOTES 4). The naive
minimum is ceil(N / 39) requests; the byte limit raises it to
ceil(response bytes / 236) when the values do not fit (the fault buffer PNU 947
alone is 64 words). The backup runs through the real CLI entry point on a fresh
simulated drive in a temporary state directory; the requests are counted by the
parameter channel (``requests``) and reported by the command itself. The object
side (SDO: one upload per object, no batching in the protocol) is shown too.

    python benchmarks/bench_params.py [--objects]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def run_cli(*args: str) -> tuple[int, str]:
    from akdctl.cli.main import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            main(list(args))
            code = 0
        except SystemExit as exc:
            code = int(exc.code or 0)
    return code, out.getvalue()


def response_bytes() -> tuple[int, int]:
    """(number of catalogue PNUs, bytes of their value blocks in a read response)."""
    from akdctl.catalog.pnus import pnu_table

    table = pnu_table()
    data = sum(max(6, 2 + (info.length * (info.bits // 8) + 1) // 2 * 2) for info in table.values())
    return len(table), data


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--objects", action="store_true", help="also back up the configuration objects (SDO)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="akdctl-bench-") as tmp:
        os.environ["AKDCTL_STATE_DIR"] = str(Path(tmp) / "state")
        os.environ["XDG_CONFIG_HOME"] = str(Path(tmp) / "config")
        os.environ.pop("AKDCTL_TARGET", None)
        start = time.perf_counter()
        code, out = run_cli("--json", "params", "backup", "-o", str(Path(tmp) / "all.json"), "--source", "pnu")
        elapsed = time.perf_counter() - start
        if code != 0:
            print(f"params backup failed (exit {code})", file=sys.stderr)
            return 1
        used = json.loads(out)["round_trips"]["pnu requests"]
        count, data = response_bytes()
        by_count = math.ceil(count / 39)
        by_bytes = math.ceil(data / (240 - 4))
        minimum = max(by_count, by_bytes)
        print(f"PNUs in the catalogue          {count}")
        print(f"response value bytes           {data}")
        print(f"minimum ceil(N/39)             {by_count}")
        print(f"minimum within 240 bytes       {minimum}")
        print(f"requests used                  {used}")
        print(f"ratio used / ceil(N/39)        {used / by_count:.2f}")
        print(f"ratio used / byte-aware min    {used / minimum:.2f}  ({'at the minimum' if used == minimum else 'above the minimum'})")
        print(f"wall time                      {elapsed * 1000:.0f} ms (in-process, includes start-up of the sim state)")
        if args.objects:
            start = time.perf_counter()
            code, out = run_cli("--json", "params", "backup", "-o", str(Path(tmp) / "obj.json"), "--source", "objects")
            elapsed = time.perf_counter() - start
            data_obj = json.loads(out)
            print(f"objects backed up              {data_obj['objects']}")
            print(f"SDO transfers used             {data_obj['round_trips'].get('sdo transfers')} "
                  f"(protocol minimum: one per object plus the identity objects)")
            print(f"wall time                      {elapsed * 1000:.0f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
