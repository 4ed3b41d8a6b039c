"""``Face`` owns the thread life cycle once (issue 22, item 5): every face only opens, interrupts and closes."""

from __future__ import annotations

import threading

import pytest

from akdctl.sim.face import Face
from akdctl.sim.face_can import CanFace
from akdctl.sim.face_ethercat_raw import EthercatRawFace
from akdctl.sim.face_ethercat_udp import EthercatUdpFace
from akdctl.sim.face_ethernetip import EthernetIpFace
from akdctl.sim.face_profinet import ProfinetFace


class _Loop(Face):
    def __init__(self, fail_open: bool = False, crash: bool = False) -> None:
        super().__init__()
        self.fail_open, self.crash = fail_open, crash
        self.events: list[str] = []
        self.looping = threading.Event()

    def open(self) -> None:
        self.events.append("open")
        self.spawn(self._loop, "test-loop")
        if self.fail_open:
            raise OSError("cannot bind")

    def _loop(self) -> None:
        self.looping.set()
        if self.crash:
            raise RuntimeError("boom")
        while not self._stop.is_set():
            self._stop.wait(0.01)

    def interrupt(self) -> None:
        self.events.append("interrupt")

    def close(self) -> None:
        self.events.append("close")

    def describe(self) -> str:
        return "test"


def test_start_serves_until_stop_joins_every_thread() -> None:
    face = _Loop()
    face.start()
    assert face.ready and face.looping.wait(5)
    face.stop()
    assert not face.ready and face.events == ["open", "interrupt", "close"]
    assert not any(t.is_alive() for t in face._threads)
    face.stop()  # twice is fine
    assert face.error is None


def test_a_failed_open_stops_what_it_started_and_raises() -> None:
    face = _Loop(fail_open=True)
    with pytest.raises(OSError):
        face.start()
    assert not face.ready and face.events == ["open", "interrupt", "close"]
    assert not any(t.is_alive() for t in face._threads)


def test_a_thread_that_dies_is_reported_not_lost(capsys: pytest.CaptureFixture[str]) -> None:
    face = _Loop(crash=True)
    face.start()
    face.join(5)
    assert isinstance(face.error, RuntimeError)
    assert "test-loop stopped: RuntimeError: boom" in capsys.readouterr().err
    face.stop()


@pytest.mark.parametrize("cls", [CanFace, EthercatRawFace, EthercatUdpFace, EthernetIpFace, ProfinetFace])
def test_no_face_keeps_its_own_copy_of_the_life_cycle(cls: type[Face]) -> None:
    for name in ("start", "stop", "join", "spawn"):
        assert getattr(cls, name) is getattr(Face, name), f"{cls.__name__}.{name}"
