"""Row: state file writes by read-only commands (goal 0).

A write is seen as a change of the state file's identity (inode, mtime, size): the simulator saves by writing a
temporary file and renaming it over the old one, so every save gives a new inode. Measured for the real CLI
(``pnu get 930``, ``sdo read 0x6041``, ``status``: in-process simulator, one process each) and for read requests
served by ``sim serve`` over both network faces. The drive is reset first (that write is not counted).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from benchlib import Result, Settings, akdctl_env
from clients import connection, pnu_read, sdo_upload
from servers import sim_server

READ_ONLY = (("pnu", "get", "930"), ("sdo", "read", "0x6041"), ("status",))


def _identity(path: Path) -> tuple[int, int, int] | None:
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    return st.st_ino, st.st_mtime_ns, st.st_size


def _cli(env: dict[str, str], *args: str) -> None:
    proc = subprocess.run([sys.executable, "-m", "akdctl", *args], env=env, capture_output=True, text=True,
                          timeout=120)
    if proc.returncode != 0:
        raise RuntimeError(f"akdctl {' '.join(args)} failed ({proc.returncode}): {proc.stderr.strip()}")


def state_writes(s: Settings) -> Result:
    state = s.tmp / "state-writes"
    state.mkdir(parents=True, exist_ok=True)
    env = akdctl_env(AKDCTL_STATE_DIR=str(state), XDG_CONFIG_HOME=str(s.tmp / "config"))
    path = state / "sim-default.json"
    _cli(env, "sim", "reset")
    cli_writes, runs, which = 0, 0, []
    for _ in range(1 if s.quick else 2):
        for args in READ_ONLY:
            before = _identity(path)
            _cli(env, *args)
            runs += 1
            if _identity(path) != before:
                cli_writes += 1
                which.append(" ".join(args))
    served_writes = served = 0
    with sim_server("--ethercat-udp", "127.0.0.1:0", "--profinet", "127.0.0.1:0", faces=2,
                    env={"AKDCTL_STATE_DIR": str(state)}) as server:
        host, port = server.address_of("ethercat-udp")
        pn_host, pn_port = server.address_of("profinet")
        with connection(f"ecat-udp://{host}:{port}/1001") as ecat, connection(f"pn://{pn_host}:{pn_port}") as pn:
            upload, read = sdo_upload(ecat), pnu_read(pn, [930])
            upload(), read()  # a server may write once when it starts serving; not a read-only request's write
            for _ in range(20):
                before = _identity(path)
                for _ in range(10):
                    upload()
                    read()
                served += 20
                served_writes += _identity(path) != before
    ok = cli_writes == 0 and served_writes == 0
    notes = [f"CLI: {cli_writes} of {runs} read-only commands rewrote the state file"
             + (f" ({', '.join(sorted(set(which)))})" if which else ""),
             f"sim serve: {served_writes} of 20 blocks of 20 read requests (SDO upload + PNU read) rewrote it"]
    return Result(f"{cli_writes}/{runs} CLI, {served_writes}/20 served blocks", ok, notes,
                  {"cli_writes": cli_writes, "served_block_writes": served_writes})


__all__ = ["state_writes"]
