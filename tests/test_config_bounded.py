"""Issue 23.13: the config file goes through the one bounded reader (regular files only, a size cap).

Before, ``--config /dev/zero`` grew without end, a FIFO blocked for ever and a 20 MB file was parsed.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest


@pytest.mark.parametrize("via", ["option", "env", "default"])
def test_dev_zero_as_config_is_a_one_line_usage_error(akd, tmp_path: Path, via: str) -> None:
    env: dict[str, str] = {}
    args: list[str] = []
    if via == "option":
        args = ["--config", "/dev/zero"]
    elif via == "env":
        env["AKDCTL_CONFIG"] = "/dev/zero"
    else:
        home = tmp_path / "xdg" / "akdctl"
        home.mkdir(parents=True)
        (home / "config.toml").symlink_to("/dev/zero")
        env["XDG_CONFIG_HOME"] = str(tmp_path / "xdg")
    result = akd(*args, "status", env=env, timeout=20)
    assert result.returncode == 2, result.stderr
    assert "is a character device, not a regular file" in result.stderr
    assert result.stderr.count("\n") == 1


def test_a_fifo_config_is_refused_without_blocking(akd, tmp_path: Path) -> None:
    fifo = tmp_path / "config.fifo"
    os.mkfifo(fifo)
    result = akd("--config", str(fifo), "status", timeout=20)
    assert result.returncode == 2 and "is a FIFO" in result.stderr


def test_a_20_mb_config_is_refused_not_parsed(akd_inproc, tmp_path: Path) -> None:
    big = tmp_path / "big.toml"
    big.write_text("# padding\n" * 2_000_000)
    code, out, err = akd_inproc("--config", str(big), "status")
    assert code == 2
    assert "more than the 1048576 a config file may have" in err and err.count("\n") == 1


def test_a_directory_and_a_normal_config(akd_inproc, tmp_path: Path) -> None:
    code, _, err = akd_inproc("--config", str(tmp_path), "status")
    assert code == 2 and "is a directory" in err
    good = tmp_path / "c.toml"
    good.write_text('default_profile = "b"\n[profiles.b]\ntarget = "sim"\n')
    code, out, err = akd_inproc("--config", str(good), "status")
    assert code == 0, err
