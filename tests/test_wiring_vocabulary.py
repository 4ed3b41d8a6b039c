"""One vocabulary of channels and profiles, and the Connection's declared capabilities (issue 22, items 2 and 3).

The words live once (akdctl/profiles/vocabulary.py); the registry declares each scheme's channels with them, the
axis choice, the recipe's channel check and the config file read them from there. The Connection answers what a
target can tell (AL state, time scale, I&M0, owner lock) with a neutral default where it cannot, so nobody probes.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from akdctl.connection import Connection
from akdctl.errors import UsageError
from akdctl.profiles.vocabulary import Channel, DriveProfile, default_profile, usable_profiles
from akdctl.transport.base import LinkOptions, Transport
from akdctl.transport.registry import BUILTIN, parse_target, transport_class
from akdctl.transport.target import split_target
from tests.harness import run_akdctl


def _conn(text: str) -> Connection:
    return Connection(parse_target(text), LinkOptions(timeout=0.2, retries=0))


def test_every_scheme_declares_its_channels_as_a_set_of_the_one_vocabulary() -> None:
    for spec in BUILTIN.values():
        assert isinstance(spec.channels, frozenset) and spec.channels, spec.scheme
        assert all(isinstance(c, Channel) for c in spec.channels), spec.scheme
    assert BUILTIN["sim"].channels == {Channel.PARAMETERS, Channel.OBJECTS}
    assert BUILTIN["eip"].channels == {Channel.ATTRIBUTES}


def test_every_builtin_transport_imports_plainly() -> None:
    """No find_spec probe hides a missing transport module: each one named imports and is a Transport."""
    for spec in BUILTIN.values():
        if spec.requires:
            continue  # needs a third-party library that may be absent (akdctl targets says so)
        cls = transport_class(split_target(f"{spec.scheme}://x", "test"))
        assert issubclass(cls, Transport) and cls.__name__ == spec.cls


@pytest.mark.parametrize(("target", "profile"), [("sim", DriveProfile.PROFIDRIVE), ("pn://10.0.0.5", DriveProfile.PROFIDRIVE),
                                                 ("ecat-udp://10.0.0.5/1001", DriveProfile.CIA402),
                                                 ("eip://10.0.0.5", DriveProfile.CIP),
                                                 ("sim?drive=cia402", DriveProfile.CIA402)])
def test_the_axis_profile_follows_the_declared_channels_without_connecting(target: str, profile: DriveProfile) -> None:
    conn = _conn(target)
    assert conn.axis_profile is profile
    assert conn.axis_profile.channel in conn.channels
    assert conn._transport is None  # nothing was opened


def test_a_profile_the_scheme_cannot_speak_is_refused_when_the_target_is_parsed() -> None:
    for text in ("pn://10.0.0.5?drive=cia402", "eip://10.0.0.5?drive=profidrive", "sim?drive=cip", "sim?drive=bogus"):
        with pytest.raises(UsageError) as info:
            parse_target(text)
        assert "drive=" in info.value.message and "speaks" in info.value.message
    assert usable_profiles(frozenset({Channel.OBJECTS})) == (DriveProfile.CIA402,)
    assert default_profile(frozenset()) is DriveProfile.CIA402


def test_neutral_defaults_where_a_target_cannot_tell() -> None:
    class Bare(Transport):
        scheme = "bare"

        def open(self) -> None:
            pass

        def close(self) -> None:
            pass

    conn = Connection.over(Bare(parse_target("pn://10.0.0.5"), LinkOptions()))
    assert conn.al_state() is None and conn.read_im0() is None and conn.time_scale == 1.0
    assert conn.axis_owner is None
    conn.close()


def test_the_connection_spells_the_al_state_once() -> None:
    class Ecat(Transport):
        scheme = "ecat"
        said = "Pre-Op"

        def open(self) -> None:
            pass

        def close(self) -> None:
            pass

        def al_state(self) -> str | None:
            return self.said

    conn = Connection.over(Ecat(parse_target("ecat://lo"), LinkOptions()))
    assert conn.al_state() == "PREOP"
    conn.close()


def test_the_owner_lock_is_the_connections_and_goes_with_it(tmp_path: Path) -> None:
    first, second = _conn("sim://owned"), _conn("sim://owned")
    first.own_axis("akdctl first")
    assert first.axis_owner is not None and first.axis_owner.held
    from akdctl.io.owner_lock import OwnerBusy

    with pytest.raises(OwnerBusy):
        second.own_axis("akdctl second")
    first.close()
    assert first.axis_owner is None
    second.own_axis("akdctl second")
    second.close()


def _recipe(tmp_path: Path, body: str) -> str:
    path = tmp_path / "r.toml"
    path.write_text(body, encoding="utf-8")
    return str(path)


@pytest.mark.slow
def test_eip_recipe_with_set_step_is_a_clear_refusal_not_an_internal_error(tmp_path: Path) -> None:
    """Regression (issue 22 item 3): this ended in `internal error: KeyError: 'attributes'`, exit 70."""
    path = _recipe(tmp_path, '[[step]]\naction = "set"\npnu = "Operating mode"\nvalue = 2\n')
    code, out, err = run_akdctl("-T", "eip://127.0.0.1", "commission", path, "--dry-run", timeout=60)
    assert code == 2, err
    assert "internal error" not in err and "KeyError" not in err
    assert "needs a PROFIdrive parameter channel (PNUs)" in err and "CIP attribute channel" in err


@pytest.mark.slow
def test_eip_recipe_with_enable_step_plans_on_the_cip_axis(tmp_path: Path) -> None:
    path = _recipe(tmp_path, '[[step]]\naction = "enable"\n')
    code, out, err = run_akdctl("-T", "eip://127.0.0.1", "commission", path, "--dry-run", timeout=60)
    assert code == 0, err
    assert "internal error" not in err and "enable" in out


def test_each_word_is_one_constant() -> None:
    from akdctl.profiles.vocabulary import PROFILE_WORDS, channel, drive_profile

    assert PROFILE_WORDS == ("profidrive", "cia402", "cip", "akd")
    assert all(drive_profile(word) is p for word, p in zip(PROFILE_WORDS, DriveProfile.ALL))
    assert channel("objects") is Channel.OBJECTS and channel("pnu") is None and drive_profile("ds402") is None
    assert DriveProfile.CIA402 == "cia402" and DriveProfile.CIA402.channel is Channel.OBJECTS
