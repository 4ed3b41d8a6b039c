"""``sim serve`` faces: options declared as data, ready lines naming what was bound, the udp_multicast warning.

No test here sends a packet off the machine: sockets bind to 127.0.0.1 and the CAN face is not started."""

from __future__ import annotations

import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from akdctl.cli import sim as cli_sim
from akdctl.sim import face_can, face_ethercat_udp, face_profinet
from akdctl.sim.drive import SimDrive
from akdctl.sim.face import Face


def test_every_face_declares_options_as_data_and_serve_accepts_exactly_them() -> None:
    serve = cli_sim.sim.commands["serve"]
    declared = {o.flag for module in cli_sim.FACES for o in module.OPTIONS}
    accepted = {opt for p in serve.params if isinstance(p, click.Option) for opt in p.opts} - {"--name", "--duration"}
    assert declared == accepted
    for module in cli_sim.FACES:
        assert not hasattr(module, "click"), f"{module.__name__} builds click options itself"


@pytest.mark.parametrize("module", [face_profinet, face_ethercat_udp])
def test_ready_line_names_the_bound_port(module: object, tmp_path: Path) -> None:
    drive = SimDrive("default", tmp_path)
    face = module.from_options(drive, **{module.OPTIONS[0].dest: "127.0.0.1:0"})  # type: ignore[attr-defined]
    assert isinstance(face, Face)
    face.start()
    try:
        match = re.search(r"udp 127\.0\.0\.1:(\d+)", face.describe())
        assert match is not None and int(match.group(1)) == face.port != 0  # type: ignore[attr-defined]
    finally:
        face.stop()


def test_udp_multicast_face_warns_that_the_bus_reaches_the_lan(tmp_path: Path) -> None:
    drive = SimDrive("default", tmp_path)
    lan = face_can.CanFace(drive, face_can.parse_spec("udp_multicast:239.74.163.2:1"))
    assert any("reachable from the LAN" in w for w in lan.warnings())
    assert face_can.CanFace(drive, face_can.parse_spec("virtual:bench:1")).warnings() == []


def test_serve_help_says_udp_multicast_reaches_the_lan() -> None:
    result = CliRunner().invoke(cli_sim.sim, ["serve", "--help"], terminal_width=200)
    assert result.exit_code == 0
    assert "udp_multicast listens on all interfaces" in " ".join(result.output.split())
