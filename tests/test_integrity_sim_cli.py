"""Issue 23 items 9 and 22 (simulator CLI): what the simulator's own commands promise, through the real CLI."""

from __future__ import annotations

import json


def test_nine_faults_at_once_are_refused_not_silently_cut_to_eight(akd_inproc) -> None:
    """Issue 23.9: a fault situation holds 8 fault numbers (PNU 947, manual 5.14); the ninth must not vanish."""
    codes = ["F501", "F502", "F503", "F504", "F505", "F523", "F524", "F531", "F535"]
    code, out, err = akd_inproc("sim", "fault", *codes)
    assert code == 2, (out, err)
    assert "9 faults do not fit one fault situation" in err
    assert err.count("\n") == 1
    code, out, _ = akd_inproc("--json", "fault", "dump")
    assert code == 0
    assert "501" not in out  # nothing injected: the refusal came before any change
    code, out, err = akd_inproc("sim", "fault", *codes[:8])
    assert code == 0, err
    code, out, err = akd_inproc("sim", "fault", "F535")
    assert code == 2 and "inject at most 0 more" in err
    code, out, err = akd_inproc("sim", "fault", "n503")  # a warning never enters PNU 947
    assert code == 0, err


def test_sim_serve_serves_the_target_drive_not_default(akd) -> None:
    """Issue 23.9: ``-T sim://axis2 sim serve`` served 'default'."""
    code, out, err = akd("-T", "sim://axis2", "sim", "serve", "--ethernetip", "127.0.0.1:0", "--eip-io-port", "0",
                         "--duration", "0.2")
    assert code == 0, err
    assert "serving simulated drive 'axis2'" in err
    code, out, err = akd("-T", "sim://axis2", "sim", "serve", "--name", "other", "--ethernetip", "127.0.0.1:0",
                         "--eip-io-port", "0", "--duration", "0.2")
    assert code == 0 and "serving simulated drive 'other'" in err


def test_a_face_option_without_its_face_is_refused(akd_inproc) -> None:
    """Issue 23.12: ``sim serve --dcp IF`` without ``--profinet`` was silently ignored."""
    code, out, err = akd_inproc("sim", "serve", "--ethernetip", "127.0.0.1:0", "--dcp", "lo", "--duration", "0")
    assert code == 2
    assert "--dcp needs --profinet" in err and err.count("\n") == 1
    code, out, err = akd_inproc("sim", "serve", "--ethernetip", "127.0.0.1:0", "--pn-ars", "3", "--ecat-serial", "7",
                                "--duration", "0")
    assert code == 2 and "--pn-ars needs --profinet" in err and "--ecat-serial needs --ethercat-raw" in err


def test_a_state_file_that_is_a_directory_gets_advice_that_works(akd_inproc, isolated_env) -> None:
    """Issue 23.22: 'run sim reset' was the advice, and 'sim reset' then failed on the directory."""
    isolated_env.mkdir(parents=True, exist_ok=True)
    (isolated_env / "sim-default.json").mkdir()
    code, _, err = akd_inproc("pnu", "get", "930")
    assert code == 2 and "run 'akdctl sim reset'" in err and err.count("\n") == 1
    code, _, err = akd_inproc("sim", "reset")
    assert code == 0, err
    assert akd_inproc("pnu", "get", "930")[0] == 0
    # A directory with files in it is the user's: the advice is to move it, and reset does not delete it.
    (isolated_env / "sim-default.json").unlink()
    (isolated_env / "sim-default.json").mkdir()
    (isolated_env / "sim-default.json" / "keep.txt").write_text("mine")
    code, _, err = akd_inproc("pnu", "get", "930")
    assert code == 2 and "move it away" in err and "sim reset" not in err
    code, _, err = akd_inproc("sim", "reset")
    assert code == 2 and "move it away" in err
    assert (isolated_env / "sim-default.json" / "keep.txt").read_text() == "mine"


def test_a_full_state_disk_while_taking_the_owner_lock_is_exit_2_naming_the_way_out(akd_inproc, monkeypatch) -> None:
    """Issue 23.22: ``jog`` on a full state disk was exit 4 'cannot take the axis's owner lock'; README promises
    exit 2 naming the way out for a full or read-only state directory."""
    import errno
    import os

    from akdctl.io import owner_lock

    def full(self: object, command: str) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(owner_lock.OwnerLock, "acquire", full)
    code, _, err = akd_inproc("-y", "jog", "100", "--for", "0.2s")
    assert code == 2, err
    assert "No space left on device" in err and "AKDCTL_STATE_DIR" in err and "nothing was written" in err
    assert err.count("\n") == 1


def test_a_change_whose_reply_came_late_is_an_unknown_outcome(akd) -> None:
    """Issue 23.22: the write landed but its answer came after --timeout: "no answer" was wrong; say
    "unknown outcome" and what to check. The face delays its 3rd datagram (the Read record of the change)."""
    from tests.harness import SimServer

    with SimServer("--profinet", "127.0.0.1:0", "--pn-inject", "delay=3:0.8") as server:
        target = f"pn://{server.host}:{server.port}"
        result = akd("-T", target, "--timeout", "0.5", "--retries", "0", "-y", "pnu", "set", "930=2", timeout=30)
        assert result.returncode == 3, result.stderr
        assert "unknown outcome" in result.stderr and "check with 'akdctl pnu get 930'" in result.stderr
        assert result.stderr.count("\n") == 1
        result = akd("-T", target, "--json", "pnu", "get", "930", timeout=30)
        assert json.loads(result.stdout)["parameters"][0]["values"] == [2]  # it had landed


def test_every_scan_takes_the_target_or_iface(akd, akd_inproc) -> None:
    """Issue 23.22: the four scan commands chose what to scan four ways. One rule now: the target (-T), or
    --iface IFNAME to broadcast on a link (never by default). ``eip scan`` asks the target's host; ``ecat scan``
    takes --iface as it takes -T ecat://IFNAME; ``pn scan`` (DCP is link-level) and ``can scan`` (the target's bus)
    already followed it."""
    from tests.harness import SimServer

    with SimServer("--ethernetip", "127.0.0.1:0", "--eip-io-port", "0") as server:
        address = next(line.split()[1] for line in server.ready if line.startswith("ethernetip"))
        by_target = akd("-T", f"eip://{address}", "--json", "eip", "scan", timeout=60)
        assert by_target.returncode == 0, by_target.stderr
        assert [d["product_name"] for d in json.loads(by_target.stdout)["devices"]] == ["AKD-P00606-NBCC-E000"]
    code, _, err = akd_inproc("eip", "scan")
    assert code == 2 and "-T eip://HOST" in err and "--iface" in err
    via_iface = akd_inproc("ecat", "scan", "--iface", "nosuchif0")
    via_target = akd_inproc("-T", "ecat://nosuchif0", "ecat", "scan")
    assert via_iface[0] == via_target[0] == 2 and via_iface[2] == via_target[2]


def test_a_cip_set_whose_reply_came_late_is_an_unknown_outcome(akd) -> None:
    """Issue 23.22 over eip://: the face answers the set (its 2nd request) 0.8 s late, after --timeout 0.5; the
    set landed. Not "no answer": an unknown outcome naming the read to check."""
    from tests.harness import SimServer

    with SimServer("--ethernetip", "127.0.0.1:0", "--eip-io-port", "0", "--eip-inject", "delay=2:0.8") as server:
        target = "eip://" + next(line.split()[1] for line in server.ready if line.startswith("ethernetip"))
        result = akd("-T", target, "--timeout", "0.5", "--retries", "0", "-y", "cip", "set", "0x0F/796/1", "u32",
                     "70000", timeout=60)
        assert result.returncode == 3, result.stderr
        assert "unknown outcome" in result.stderr and "check with 'akdctl cip get 0x0F/796/1'" in result.stderr
        back = akd("-T", target, "--json", "cip", "get", "0x0F/796/1", "u32", timeout=60)
        assert json.loads(back.stdout)["value"] == 70000  # it had landed
