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
