"""Rows measured over loopback: simulator CPU, gateway and PROFINET round trips, client CPU, batches, state writes.

Every ratio here is against a bare UDP round trip measured in the same run, interleaved block by block
(:func:`benchlib.interleave`); the client's CPU is ``time.thread_time`` of this process, the server's comes from
``/proc``. The simulator runs in ``akdctl sim serve`` (its own process) unless a row says "in-process".
"""

from __future__ import annotations

from benchlib import Result, Settings, fmt_ratio, fmt_us, interleave, run_block
from clients import batch_pnus, connection, pnu_read, requests_of, sdo_download, sdo_upload, state_dir
from servers import EchoClient, canned, canned_stats, sim_server, udp_echo

ECAT_UPLOAD_BYTES = 18   # ETG.8200 header 2 + mailbox header 6 + CoE/SDO 10
PNIO_RECORD_BYTES = 170  # DCE/RPC header 80 + NDR 20 + record block 64 + a short PROFIdrive request
BIG_STATE_BYTES = 256 * 1024
#: Issue 29's goals for the served simulator's CPU per request: an SDO upload, a PNU read (two RPCs).
SDO_GOAL_US = 30.0
PNU_GOAL_US = 40.0


def _faces(name: str) -> tuple[str, ...]:
    return ("--name", name, "--ethercat-udp", "127.0.0.1:0", "--profinet", "127.0.0.1:0")


def _ecat(server: object) -> str:
    host, port = server.address_of("ethercat-udp")  # type: ignore[attr-defined]
    return f"ecat-udp://{host}:{port}/1001"


def _pn(server: object) -> str:
    host, port = server.address_of("profinet")  # type: ignore[attr-defined]
    return f"pn://{host}:{port}"


def sim_cpu(s: Settings) -> Result:
    """Simulator CPU per request in ``sim serve``: a factory-fresh drive against one holding a 256 KB string."""
    state = s.tmp / "sim-cpu"
    env = {"AKDCTL_STATE_DIR": str(state)}
    with state_dir(str(state)), connection("sim://big") as conn:
        sdo_download(conn, 0x2032, 0, b"x" * BIG_STATE_BYTES)  # DRV.CUSTOMIDENTIFIER: the sim stores any length
    with sim_server(*_faces("small"), faces=2, env=env) as small, sim_server(*_faces("big"), faces=2, env=env) as big, \
            connection(_ecat(small)) as es, connection(_ecat(big)) as eb, \
            connection(_pn(small)) as ps, connection(_pn(big)) as pb, udp_echo() as echo:
        up_s, up_b, rd_s, rd_b = sdo_upload(es), sdo_upload(eb), pnu_read(ps, [930]), pnu_read(pb, [930])
        bare = EchoClient(echo.port, PNIO_RECORD_BYTES)

        def two_round_trips() -> None:  # a PNU read's datagrams, echoed: the floor of any server in Python
            bare()
            bare()

        n = s.block
        split = _Split()
        run = interleave(lambda: run_block(up_s, n, small.cpu), lambda: run_block(up_b, n, big.cpu),
                         lambda: split.block(rd_s, n // 2, small.cpu), lambda: split.block(rd_b, n // 2, big.cpu),
                         lambda: run_block(two_round_trips, n // 2, echo.cpu), rounds=s.rounds)
        bare.close()
    key = lambda x: x.server_us  # noqa: E731
    sdo_small, sdo_big, pnu_small, pnu_big = (run.median(k, key) for k in range(4))
    figures = {"sdo_small_us": sdo_small, "sdo_big_us": sdo_big, "pnu_small_us": pnu_small, "pnu_big_us": pnu_big}
    ok = all(v is not None and v <= SDO_GOAL_US for v in (sdo_small, sdo_big)) and \
        all(v is not None and v <= PNU_GOAL_US for v in (pnu_small, pnu_big))
    return Result(
        f"SDO {fmt_us(sdo_small)} / {fmt_us(sdo_big)}, PNU {fmt_us(pnu_small)} / {fmt_us(pnu_big)}", ok,
        [f"server CPU per request, factory state / with a {BIG_STATE_BYTES // 1024} KB string stored "
         f"(ratio SDO {fmt_ratio(run.ratio(1, 0, key))}, PNU {fmt_ratio(run.ratio(3, 2, key))})",
         "a PNU read over PROFINET is one request of two RPCs (write record, read record): both counted; "
         f"of the server's CPU in them, {split.text()}; a bare Python UDP echo server (recvfrom + sendto) spends "
         f"{fmt_us(run.median(4, key))} on the same two round trips, measured beside them",
         f"CPU from /proc ({small.cpu.source}); medians of {s.rounds} interleaved rounds"], figures)


class _Split:
    """The server's user and kernel CPU summed over blocks (clock ticks from /proc: a note on where the CPU goes --
    the kernel's share is the floor of a served request -- never the judged figure)."""

    def __init__(self) -> None:
        self.user = self.system = 0.0
        self.n = 0

    def block(self, op, n, cpu):  # noqa: ANN001, ANN201
        before = cpu.user_system()
        sample = run_block(op, n, cpu)
        after = cpu.user_system()
        if before is not None and after is not None:
            self.user += after[0] - before[0]
            self.system += after[1] - before[1]
            self.n += n
        return sample

    def text(self) -> str:
        if not self.n or self.user + self.system <= 0:
            return "the user/kernel split is unknown (/proc/PID/stat unreadable)"
        user, system = self.user / self.n * 1e6, self.system / self.n * 1e6
        return (f"user {fmt_us(user)}, kernel {fmt_us(system)} per read ({system / (user + system):.0%} kernel: "
                "2 recvfrom + 2 sendto, the wake-ups)")


def ecat_udp(s: Settings) -> Result:
    """ETG.8200 SDO upload end to end (client + ``sim serve``) against a bare UDP round trip."""
    env = {"AKDCTL_STATE_DIR": str(s.tmp / "ecat-udp")}
    with udp_echo() as echo, sim_server("--ethercat-udp", "127.0.0.1:0", env=env) as server, \
            connection(_ecat(server)) as conn:
        bare, upload = EchoClient(echo.port, ECAT_UPLOAD_BYTES), sdo_upload(conn)
        run = interleave(lambda: run_block(bare, s.block, echo.cpu), lambda: run_block(upload, s.block, server.cpu),
                         rounds=s.rounds)
        bare.close()
    ratio = run.ratio(0, 1)
    return Result(fmt_ratio(ratio), ratio >= 0.30, [
        f"per upload {fmt_us(run.median(1))} wall, client CPU {fmt_us(run.median(1, lambda x: x.cpu_us))}, "
        f"server CPU {fmt_us(run.median(1, lambda x: x.server_us))}; bare round trip {fmt_us(run.median(0))} "
        f"(client {fmt_us(run.median(0, lambda x: x.cpu_us))}, echo {fmt_us(run.median(0, lambda x: x.server_us))})"],
        {"ratio": ratio, "upload_us": run.median(1), "bare_us": run.median(0)})


def client_cpu(s: Settings) -> Result:
    """Client CPU per gateway SDO upload, answered by the canned-reply yardstick (the simulator out of the way)."""
    env = {"AKDCTL_STATE_DIR": str(s.tmp / "client-cpu")}
    with udp_echo() as echo, sim_server("--ethercat-udp", "127.0.0.1:0", env=env) as server:
        host, port = server.address_of("ethercat-udp")
        with canned("ecat", host, port) as yard, connection(f"ecat-udp://127.0.0.1:{yard.port}/1001") as conn:
            bare, upload = EchoClient(echo.port, ECAT_UPLOAD_BYTES), sdo_upload(conn)
            run = interleave(lambda: run_block(bare, s.block, echo.cpu), lambda: run_block(upload, s.block, yard.cpu),
                             rounds=s.rounds)
            bare.close()
            answered, forwarded = canned_stats(yard)
    cpu = run.median(1, lambda x: x.cpu_us)
    assert cpu is not None
    return Result(fmt_us(cpu), cpu <= 30.0, [
        f"yardstick: canned replies {answered}, forwarded to the simulator {forwarded}; client-side ratio to a bare "
        f"round trip {fmt_ratio(run.ratio(0, 1))} (wall {fmt_us(run.median(1))} vs {fmt_us(run.median(0))}); "
        f"a bare round trip's client CPU {fmt_us(run.median(0, lambda x: x.cpu_us))}"],
        {"client_cpu_us": cpu, "bare_cpu_us": run.median(0, lambda x: x.cpu_us)})


def profinet(s: Settings) -> Result:
    """A single PNU read over PROFINET (two RPCs) against a bare UDP round trip; the canned yardstick beside it."""
    env = {"AKDCTL_STATE_DIR": str(s.tmp / "pn")}
    n = max(1, s.block // 2)
    with udp_echo() as echo, sim_server("--profinet", "127.0.0.1:0", env=env) as server:
        host, port = server.address_of("profinet")
        with canned("pnio", host, port) as yard, connection(_pn(server)) as real, \
                connection(f"pn://127.0.0.1:{yard.port}") as fake:
            bare, read, read_canned = EchoClient(echo.port, PNIO_RECORD_BYTES), pnu_read(real, [930]), pnu_read(fake, [930])
            run = interleave(lambda: run_block(bare, n, echo.cpu), lambda: run_block(read, n, server.cpu),
                             lambda: run_block(read_canned, n, yard.cpu), rounds=s.rounds)
            bare.close()
            answered, forwarded = canned_stats(yard)
    ratio = run.ratio(0, 1)
    return Result(fmt_ratio(ratio), ratio >= 0.15, [
        f"per read {fmt_us(run.median(1))} wall, client CPU {fmt_us(run.median(1, lambda x: x.cpu_us))}, "
        f"server CPU {fmt_us(run.median(1, lambda x: x.server_us))}; bare round trip {fmt_us(run.median(0))}",
        f"yardstick (canned {answered}, forwarded {forwarded}): ratio {fmt_ratio(run.ratio(0, 2))}, client CPU "
        f"{fmt_us(run.median(2, lambda x: x.cpu_us))} per read"],
        {"ratio": ratio, "canned_ratio": run.ratio(0, 2), "client_cpu_us": run.median(1, lambda x: x.cpu_us)})


def batch(s: Settings) -> Result:
    """Cost of each extra PNU in a 39-PNU read: in-process ``sim`` and ``pn://`` to ``sim serve``."""
    state = s.tmp / "batch"
    env = {"AKDCTL_STATE_DIR": str(state)}
    one, many = [930], batch_pnus(39)
    n = max(1, s.block // 4)
    with state_dir(str(state)), sim_server("--profinet", "127.0.0.1:0", env=env) as server, \
            connection("sim") as sim, connection(_pn(server)) as pn:
        work = [_counting(conn, pnus, n, cpu) for conn, cpu in ((sim, None), (pn, server.cpu)) for pnus in (one, many)]
        run = interleave(*work, rounds=s.rounds)
    figures: dict[str, float | None] = {}
    notes = []
    worst = 0.0
    for label, k in (("sim (in-process)", 0), ("pn:// (sim serve)", 2)):
        extra = run.diff(k + 1, k) / (len(many) - 1)
        extra_cpu = run.diff(k + 1, k, lambda x: x.cpu_us + (x.server_us or 0.0)) / (len(many) - 1)
        worst = max(worst, extra)
        req = run.runs[k + 1][-1].extra.get("requests", float("nan"))
        notes.append(f"{label}: 1 PNU {fmt_us(run.median(k))}/request; 39 PNUs {fmt_us(run.median(k + 1))}/request "
                     f"({fmt_us(run.median(k + 1) / len(many))}/PNU, {req:g} request(s) each); each extra PNU "
                     f"{fmt_us(extra)} wall, {fmt_us(extra_cpu)} CPU client+server")
        figures[f"{label.split()[0]}_extra_us"] = extra
    return Result(fmt_us(worst), worst <= 8.0, notes, figures)


def _counting(conn: object, pnus: list[int], n: int, cpu: object):  # noqa: ANN202
    """A block of ``n`` reads of ``pnus`` that also notes how many PROFIdrive requests each read took."""
    op = pnu_read(conn, pnus)

    def block():  # noqa: ANN202
        before = requests_of(conn)
        sample = run_block(op, n, cpu)  # type: ignore[arg-type]
        after = requests_of(conn)
        if before is not None and after is not None:
            sample.extra["requests"] = (after - before) / n
        return sample

    return block
