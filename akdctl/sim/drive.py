"""A named, persisted simulated drive shared safely between processes.

A real drive keeps its state while the tool comes and goes; so does this one.
Each access runs as a *transaction*: take an exclusive lock on the drive's lock
file, load the state file, advance the virtual clock by the wall time that
passed (times the drive's time scale), handle the request, write the state to
a temporary file and rename it over the old one, release the lock. Two
processes (``akdctl move`` and ``akdctl sim fault F501``, or a network face and
the CLI) therefore see one consistent drive, and a crash never leaves a
half-written state file.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from akdctl.errors import CommError, UsageError
from akdctl.io.atomic import atomic_open
from akdctl.sim.model import DriveModel

LOCK_TIMEOUT = 5.0
DEFAULT_TIME_SCALE = 1.0


class SimStateError(UsageError):
    """The state file exists but cannot be used; ``akdctl sim reset`` recovers."""

    kind = "sim-state"


def state_dir() -> Path:
    """Where simulated drives keep their state: ``$AKDCTL_STATE_DIR``, else the XDG state dir."""
    env = os.environ.get("AKDCTL_STATE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_STATE_HOME") or os.path.join(os.path.expanduser("~"), ".local", "state")
    return Path(base) / "akdctl"


class SimDrive:
    """One simulated AKD identified by ``name`` (``sim`` → "default", ``sim://bench2`` → "bench2")."""

    def __init__(self, name: str = "default", directory: Path | None = None) -> None:
        self.name = name
        self.directory = Path(directory) if directory is not None else state_dir()
        self.path = self.directory / f"sim-{name}.json"
        self.lock_path = self.directory / f"sim-{name}.lock"
        self._pnu_server: Any = None
        self._sdo_server: Any = None
        self._sdo_model_ref: list[DriveModel | None] = [None]
        self._cache: tuple[Any, DriveModel, dict[str, Any], str] | None = None
        self._saved_scale: object = None

    # ------------------------------------------------------------------ storage
    @contextlib.contextmanager
    def _locked(self) -> Iterator[int]:
        self.directory.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            deadline = time.monotonic() + LOCK_TIMEOUT
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except OSError as exc:
                    if exc.errno not in (errno.EAGAIN, errno.EACCES) or time.monotonic() > deadline:
                        raise CommError(
                            f"simulated drive {self.name!r} is locked by another process for more than {LOCK_TIMEOUT:g} s"
                        ) from None
                    time.sleep(0.005)
            yield fd
        finally:
            os.close(fd)  # closing releases the flock

    def _load(self) -> tuple[DriveModel, dict[str, Any]]:
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            return DriveModel(), {"wall": time.time(), "time_scale": DEFAULT_TIME_SCALE}
        except OSError as exc:
            raise SimStateError(f"cannot read simulator state {self.path.name}: {exc.strerror}") from None
        try:
            state = json.loads(text)
            meta = dict(state.pop("sim", {}))
            model = DriveModel.from_state(state)
        except (ValueError, TypeError, AttributeError) as exc:
            raise SimStateError(
                f"simulator state file {self.path} is corrupt ({exc}); run 'akdctl sim reset' to restore factory state"
            ) from None
        meta.setdefault("wall", time.time())
        meta.setdefault("time_scale", DEFAULT_TIME_SCALE)
        return model, meta

    def _save(self, model: DriveModel, meta: dict[str, Any]) -> None:
        state = model.to_state()
        state["sim"] = meta
        with atomic_open(self.path, prefix=f".sim-{self.name}.") as fh:
            json.dump(state, fh, separators=(",", ":"))

    @staticmethod
    def _token(lock_fd: int) -> bytes:
        """The save generation written into the lock file by the last writer (b"" before any)."""
        return os.pread(lock_fd, 32, 0)

    @staticmethod
    def _new_token(lock_fd: int) -> bytes:
        # Written *before* the state file is replaced: a crash in between only costs a reload.
        token = os.urandom(16).hex().encode()
        os.pwrite(lock_fd, token, 0)
        return token

    @staticmethod
    def _body(model: DriveModel) -> str:
        """The state without the virtual clock: what must reach the file when it changes."""
        state = model.to_state()
        state.pop("clock", None)
        return json.dumps(state, sort_keys=True, separators=(",", ":"))

    @contextlib.contextmanager
    def transaction(self, advance: bool = True) -> Iterator[DriveModel]:
        """Lock, load, advance the virtual clock, yield the model, save, unlock.

        A network face answers thousands of requests a second, so two costs are
        avoided when they buy nothing: the file is not parsed again while it is
        the one this object wrote last (the save token in the lock file is unchanged), and it is not
        rewritten when nothing but the clock moved — another process that loads
        the older file advances its clock by the same wall time. If the body
        raises, nothing is saved and the cached model is dropped (a refused
        access changes nothing).
        """
        with self._locked() as lock_fd:
            key = self._token(lock_fd)
            if key and self._cache is not None and self._cache[0] == key and self.path.exists():
                _, model, meta, saved_body = self._cache
            else:
                model, meta = self._load()
                saved_body = None
            self._cache = None
            now = time.time()
            model.time_scale = float(meta.get("time_scale", DEFAULT_TIME_SCALE))  # wall-time watchdogs need it
            if advance:
                elapsed = max(0.0, now - float(meta.get("wall", now)))
                model.advance(elapsed * float(meta.get("time_scale", DEFAULT_TIME_SCALE)))
            meta["wall"] = now
            self.meta = meta
            yield model
            body = self._body(model)
            if body != saved_body or meta.get("time_scale") != self._saved_scale:
                key = self._new_token(lock_fd)
                self._save(model, meta)
                self._saved_scale = meta.get("time_scale")
            self._cache = (key, model, meta, body)

    def reset(self) -> None:
        """Restore factory state (works on a corrupt state file too)."""
        with self._locked():
            self._save(DriveModel(), {"wall": time.time(), "time_scale": DEFAULT_TIME_SCALE})

    def set_time_scale(self, scale: float) -> None:
        with self.transaction() as _model:
            self.meta["time_scale"] = float(scale)

    def snapshot(self) -> dict[str, Any]:
        """The whole persisted state (for ``akdctl sim show``)."""
        with self.transaction() as model:
            state = model.to_state()
            state["sim"] = dict(self.meta)
        return state

    # ------------------------------------------------------------------ wire faces
    def handle_bmp(self, request: bytes) -> bytes:
        """Answer one PROFIdrive base-mode request as the drive's parameter manager."""
        from akdctl.sim.pnu_server import PnuServer

        with self.transaction() as model:
            return PnuServer(model).handle(request)

    def handle_mailbox(self, mailbox: bytes) -> list[bytes]:
        """Answer one EtherCAT mailbox (CoE) with the mailboxes the drive sends back.

        The SDO server keeps segmented-transfer state between mailboxes, so it
        lives as long as this object; it reaches the current model through a
        proxy that points at the model of the running transaction.
        """
        from akdctl.sim.sdo_server import SdoServer

        with self.transaction() as model:
            if self._sdo_server is None:
                self._sdo_server = SdoServer(_ModelProxy(self._sdo_model_ref))
            self._sdo_model_ref[0] = model
            try:
                for emcy in _take_emergencies(model):
                    self._sdo_server.queue_emergency(emcy)
                return self._sdo_server.handle(mailbox)
            finally:
                self._sdo_model_ref[0] = None

    def object_read(self, index: int, subindex: int) -> bytes:
        with self.transaction() as model:
            return model.object_read(index, subindex)

    def object_write(self, index: int, subindex: int, data: bytes) -> None:
        with self.transaction() as model:
            model.object_write(index, subindex, data)

    def take_emergencies(self) -> list[Any]:
        """Emergencies the drive raised since the last call (for the CANopen face)."""
        with self.transaction() as model:
            return _take_emergencies(model)


def _take_emergencies(model: DriveModel) -> list[Any]:
    take = getattr(model.component("faults"), "take_emergencies", None)
    return list(take()) if take else []


class _ModelProxy:
    """Forwards attribute access to the model of the current transaction."""

    def __init__(self, ref: list[DriveModel | None]) -> None:
        self._ref = ref

    def __getattr__(self, name: str) -> Any:
        model = self._ref[0]
        if model is None:
            raise RuntimeError("simulated drive accessed outside a transaction")
        return getattr(model, name)
