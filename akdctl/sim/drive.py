"""A named, persisted simulated drive shared safely between processes.

A real drive keeps its state while the tool comes and goes; so does this one.
Each access runs as a *transaction*: take an exclusive lock on the drive's lock
file, bring the model up to date, advance the virtual clock by the wall time
that passed (times the drive's time scale), handle the request, save the state
if the request changed it, release the lock. Two processes (``akdctl move`` and
``akdctl sim fault F501``, or a network face and the CLI) therefore see one
consistent drive, and a crash never leaves a half-written state file.

Why it is cheap (a network face answers thousands of requests a second):

* The lock file stays open for the life of the ``SimDrive``; each transaction
  only takes and drops the ``flock``.
* The lock file also carries a *token*, rewritten by every save. A process
  keeps the model of its last transaction in memory and reloads the state file
  only when the token is not the one it saw: another process saved meanwhile.
* Whether to save is decided by a *mark*: the model's revision (one integer
  every change of persisted state bumps - stored values, accepted writes, each
  component's state; the rule is ``sim/component.Tracked``) and the time
  scale. Nothing is serialised to decide, so a request costs the same whatever
  the state holds; the virtual clock is not part of the mark, because a
  process that loads an older file advances it by the same wall time.
  Read-only requests on a drive at rest therefore never write the file, and a
  save costs what the state costs, once per change.
* A drive that answers network faces (``sim serve``, :meth:`SimDrive.serve_faces`)
  *keeps* the lock between its requests instead of taking and dropping it per
  request: while it holds the lock nobody else can have saved, so a request costs
  no lock or token system call at all. It hands the lock over on demand: a
  process that finds the drive locked takes the *turn* file (one asker at a time)
  and writes a byte into the *ask* FIFO; the holder's watcher thread wakes, drops
  the lock once the request in progress has ended, and waits until the asker
  holds the lock (it lets go of the turn then) before its faces may take it
  again. The next face request takes the lock the ordinary way, reads the token
  and reloads what the asker saved before it answers. While others want the
  drive (it was asked, or had to wait for the lock) it takes the lock per
  request for a while, as every other process does, so a crowd of writers is
  not queued behind one hand-over each. The watcher also drops the lock after a
  moment without requests (a locker that does not ask still gets it) and when
  the lock file was removed.
* While a command runs a motion, its changes are not saved as a new state file (temporary file, fsync, rename:
  1-6 ms of disk latency each, on every poll) but written into the lock file behind the token as the *pending
  state*: the same JSON a save writes, in one ``pwrite`` with its length and CRC-32, in the page cache only. A
  process that loads takes the pending state when there is one, else the state file, so it sees exactly what a
  save would have shown it (tests/test_sim_pending.py). Which PROFIdrive requests go there: every read that changed
  the state (a poll of a moving axis: the clock moved it, the read fed the watchdog), every write that leaves the
  axis moving (the start of a homing or move) and a write that directly follows such a read of the same process
  while its pending state is still the lock file's (the write that ends the motion it polled: no save between the
  drive's end of a motion and the command's return; the write after that saves). Everything else saves the state
  file at once and empties the pending state: a write at rest from any other process (the next command's first
  write), SDO requests, changes outside a PROFIdrive request, and the PENDING_MAX-th pending write in a row (a
  machine crash loses at most the pending state: one cut short or damaged is passed over, the drive is then as it
  was at the last save).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import math
import os
import stat
import struct
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from akdctl.errors import CommError, UsageError
from akdctl.io.state_dir import state_dir  # re-exported: sim users name it here
from akdctl.sim.errors import DamagedState
from akdctl.sim.model import DriveModel

T = TypeVar("T")

LOCK_TIMEOUT = 5.0
#: How long a network face waits for the state lock before it answers "busy" in its protocol's words: less than
#: one attempt of a client with the default --timeout (2 s over 3 attempts), so the client hears the answer instead
#: of giving up first (issue 23.15). A transaction holds the lock for milliseconds; 0.5 s means something is stuck.
FACE_LOCK_TIMEOUT = 0.5
DEFAULT_TIME_SCALE = 1.0
MAX_STATE_BYTES = 64 << 20  # far above any real state; a bigger file is not ours
TOKEN_BYTES = 32
MAX_TIME_SCALE = 1e7  # the most `akdctl sim speed` accepts
#: How often the watcher of a drive that keeps its lock looks at it (idle, lock file removed); also how long a
#: locker that does not ask waits at most beyond HOLD_IDLE_S.
HOLD_TICK_S = 0.05
#: A kept lock is dropped after this long without a request.
HOLD_IDLE_S = 0.1
#: Poll interval of a process that holds the turn (it asked the holder and waits for the lock).
TURN_POLL_S = 0.001
#: After handing the lock over, a served drive takes it per request (as every other process does) for this long
#: before it keeps it again: while others want the drive, keeping it would make each of them wait for a hand-over.
HOLD_BACKOFF_S = 0.25
#: At most this many changes in a row go to the lock file's pending state before the state file is written again
#: (the module doc): a long motion on a real-time drive (20 polls a second) still saves every few seconds.
PENDING_MAX = 64
_PENDING = struct.Struct("<II")  # the lock file after the token: bytes of pending state that follow, their CRC-32
_HEAD_BYTES = TOKEN_BYTES + _PENDING.size


class SimStateError(UsageError):
    """The state file or its directory cannot be used; the message says how to recover."""

    kind = "sim-state"


def _mark(model: DriveModel, meta: dict[str, Any]) -> tuple[int, Any]:
    """What must reach the file when it changes, in O(1) (see the module doc)."""
    return model.revision, meta.get("time_scale")


class _Held:
    """The model of the last transaction, valid while the lock file's token is ``token``."""

    __slots__ = ("model", "meta", "token", "mark", "pending", "after_read")

    def __init__(self, model: DriveModel, meta: dict[str, Any], token: bytes, mark: tuple[int, Any]) -> None:
        self.model = model
        self.meta = meta
        self.token = token
        self.mark = mark  # the mark of what the state file (or the pending state) holds
        self.pending = 0  # changes in a row this object wrote as the lock file's pending state (the module doc)
        self.after_read = False  # the last of them was a read's


class SimDrive:
    """One simulated AKD identified by ``name`` (``sim`` → "default", ``sim://bench2`` → "bench2")."""

    def __init__(self, name: str = "default", directory: Path | None = None) -> None:
        self.name = name
        self.directory = Path(directory) if directory is not None else state_dir()
        self.path = self.directory / f"sim-{name}.json"
        self.lock_path = self.directory / f"sim-{name}.lock"
        self.turn_path = self.directory / f"sim-{name}.turn"  # one asker at a time (see the module doc)
        self.ask_path = self.directory / f"sim-{name}.ask"  # the FIFO an asker writes a byte into
        self.meta: dict[str, Any] = {}
        self._sdo_server: Any = None
        self._pnu_server: Any = None
        self._pnu_answer: Callable[[bytes], bytes] | None = None  # the PnuServer's handle, once it exists
        self._sdo_answer: Callable[[bytes], list[bytes]] | None = None  # the SdoServer's handle, once it exists
        self._lock_fd = -1
        self.lock_timeout = LOCK_TIMEOUT  # sim serve lowers it to FACE_LOCK_TIMEOUT for its faces
        # flock excludes other open files, not threads sharing this one (the faces of one `sim serve`)
        self._mutex = threading.Lock()
        self._held: _Held | None = None
        self._keep = False  # serve_faces(): keep the lock between requests
        self._holding = False  # the lock is kept now (flock held outside a transaction)
        self._trusted = False  # the held model is current: the lock was kept since the last transaction
        self._turn_fd = -1
        self._watcher: threading.Thread | None = None
        self._keep_from = 0.0  # monotonic time from which a lock taken is kept again (HOLD_BACKOFF_S)
        self._tmp_prefix = f".sim-{name}."  # atomic_open's temporaries: PREFIX + 8 of [a-z0-9_] + ".tmp"
        self._pending_bytes = 0  # the pending state's size in the lock file, as last read or written under the lock

    def serve_faces(self) -> None:
        """This object answers network faces from now on (``sim serve``): a face waits FACE_LOCK_TIMEOUT for the
        lock, and the lock is kept between requests and handed over to whoever asks (the module doc)."""
        self.lock_timeout = FACE_LOCK_TIMEOUT
        self._keep = True

    @property
    def keeps_lock(self) -> bool:
        """Whether :meth:`serve_faces` made this drive keep its lock between requests."""
        return self._keep

    def close(self) -> None:
        """Close the lock file and forget the model (the state file stays)."""
        with self._mutex:
            self._held = None
            self._holding = self._trusted = False
            if self._lock_fd >= 0:
                os.close(self._lock_fd)
                self._lock_fd = -1
            if self._turn_fd >= 0:
                os.close(self._turn_fd)
                self._turn_fd = -1

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            for fd in (self._lock_fd, self._turn_fd):
                if fd >= 0:
                    os.close(fd)

    # ------------------------------------------------------------------ locking
    def _locked_text(self) -> str:
        return f"simulated drive {self.name!r} is locked by another process for more than {self.lock_timeout:g} s"

    def _open_lock(self) -> int:
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            return os.open(self.lock_path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise self._os_error("cannot open the simulator's lock file", self.lock_path, exc) from None

    def _acquire(self) -> int:
        """Hold this drive exclusively: the thread mutex, then the ``flock`` on the kept-open lock file (kept
        already when :attr:`_holding`); returns the lock file's descriptor. :meth:`_release` lets go of both
        (of the flock only when it is not kept)."""
        if not self._mutex.acquire(timeout=self.lock_timeout):
            raise CommError(self._locked_text())
        if self._holding:
            return self._lock_fd
        try:
            return self._take_lock()
        except BaseException:
            self._mutex.release()
            raise

    def _take_lock(self) -> int:
        """Under the mutex: ``flock`` the lock file. Found locked, ask the holder for it (the turn, then a byte in
        the ask FIFO) and poll until it is ours or ``lock_timeout`` passed."""
        deadline = None
        turn = False
        self._trusted = False
        try:
            while True:
                if self._lock_fd < 0:
                    self._lock_fd = self._open_lock()
                try:
                    fcntl.flock(self._lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except OSError as exc:
                    now = time.monotonic()
                    deadline = deadline or now + self.lock_timeout
                    if exc.errno not in (errno.EAGAIN, errno.EACCES) or now > deadline:
                        raise CommError(self._locked_text()) from None
                    turn = turn or self._try_turn()
                    if turn:
                        self._ask_holder()
                    time.sleep(TURN_POLL_S if turn else 0.005)
                    continue
                if os.fstat(self._lock_fd).st_nlink:
                    if self._keep and (deadline is None and time.monotonic() >= self._keep_from):
                        self._start_holding()
                    return self._lock_fd
                # The lock file was removed (a user cleaning the state directory): others lock the new one.
                os.close(self._lock_fd)
                self._lock_fd = -1
                self._held = None
        finally:
            if turn:
                fcntl.flock(self._turn_fd, fcntl.LOCK_UN)

    def _release(self, lock_fd: int) -> None:
        try:
            if not self._holding:
                fcntl.flock(lock_fd, fcntl.LOCK_UN)
        finally:
            self._mutex.release()

    # ------------------------------------------------------------------ hand-over of a kept lock
    def _try_turn(self) -> bool:
        """Take the turn file without waiting: one asker at a time, so a holder can tell when its asker got in."""
        try:
            if self._turn_fd < 0:
                self._turn_fd = os.open(self.turn_path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o644)
            fcntl.flock(self._turn_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except OSError:
            return False  # taken by another asker (or unusable): poll the lock as before

    def _ask_holder(self) -> None:
        """One byte into the ask FIFO: wakes the watcher of a drive that keeps the lock (none listening: ENXIO)."""
        try:
            fd = os.open(self.ask_path, os.O_WRONLY | os.O_NONBLOCK | os.O_CLOEXEC | os.O_NOFOLLOW)
        except OSError:
            return
        try:
            if stat.S_ISFIFO(os.fstat(fd).st_mode):  # never write into a file someone put in its place
                os.write(fd, b"?")
        except OSError:
            pass  # full: the holder has not read the earlier bytes yet, it will
        finally:
            os.close(fd)

    def _open_ask(self) -> int:
        """The ask FIFO opened for the watcher (read and write, so it never reads end-of-file); -1 if there
        cannot be one (then the lock is not kept: each request takes it, as before)."""
        with contextlib.suppress(FileExistsError, OSError):
            os.mkfifo(self.ask_path, 0o644)
        try:
            fd = os.open(self.ask_path, os.O_RDWR | os.O_NONBLOCK | os.O_CLOEXEC | os.O_NOFOLLOW)
        except OSError:
            return -1
        if not stat.S_ISFIFO(os.fstat(fd).st_mode):
            os.close(fd)
            return -1
        return fd

    def _start_holding(self) -> None:
        """Under the mutex, the lock just taken: keep it from now on, the watcher running."""
        if self._watcher is None:
            ask_fd = self._open_ask()
            if ask_fd < 0:
                return
            self._watcher = threading.Thread(target=self._watch, args=(ask_fd,), name=f"sim-{self.name}-lock",
                                             daemon=True)
            self._watcher.start()
        self._holding = True

    def _watch(self, ask_fd: int) -> None:
        """The watcher: gives the kept lock up when asked, after HOLD_IDLE_S without a request, or when the lock
        file was removed; then it ends (a drive nobody uses keeps no thread), the next kept lock starts another."""
        import select  # only sim serve keeps a lock: the CLI's read paths never load it

        try:
            while True:
                ready = select.select([ask_fd], [], [], HOLD_TICK_S)[0]
                if ready:
                    with contextlib.suppress(OSError):
                        while os.read(ask_fd, 512):
                            pass
                if not self._mutex.acquire(timeout=HOLD_TICK_S):
                    continue  # a long request; asked, it is asked again
                try:
                    if not self._holding:  # closed
                        self._watcher = None
                        return
                    if ready or time.time() - self.meta.get("wall", 0.0) > HOLD_IDLE_S \
                            or not os.fstat(self._lock_fd).st_nlink:
                        self._give_up(wait_for_asker=bool(ready))
                        self._watcher = None
                        return
                finally:
                    self._mutex.release()
        finally:
            os.close(ask_fd)

    def _give_up(self, wait_for_asker: bool) -> None:
        """Under the mutex: drop the kept lock; asked, wait (up to lock_timeout) until the asker has it -- it lets
        go of the turn once it holds the lock -- so this drive's next request cannot take it back first."""
        self._holding = self._trusted = False
        fcntl.flock(self._lock_fd, fcntl.LOCK_UN)
        if wait_for_asker:
            self._keep_from = time.monotonic() + HOLD_BACKOFF_S
        if not os.fstat(self._lock_fd).st_nlink:
            os.close(self._lock_fd)
            self._lock_fd = -1
            self._held = None
            return
        deadline = time.monotonic() + self.lock_timeout
        while wait_for_asker and time.monotonic() < deadline:
            if self._try_turn():
                fcntl.flock(self._turn_fd, fcntl.LOCK_UN)
                return
            time.sleep(TURN_POLL_S)

    @contextlib.contextmanager
    def _locked(self) -> Iterator[int]:
        lock_fd = self._acquire()
        try:
            yield lock_fd
        finally:
            self._release(lock_fd)

    # ------------------------------------------------------------------ storage
    def _os_error(self, what: str, path: Path, exc: OSError) -> SimStateError:
        return SimStateError(f"{what} {path}: {exc.strerror or exc}; check that {self.directory} is a writable "
                             "directory with free space (set AKDCTL_STATE_DIR to use another)")

    def _corrupt(self, why: str) -> SimStateError:
        return SimStateError(f"simulator state file {self.path} is corrupt ({why}); "
                             "run 'akdctl sim reset' to restore factory state")

    def _directory_error(self) -> SimStateError:
        """The state file's path is a directory: 'sim reset' replaces an empty one; one with files in it is
        the user's to move, never deleted by us (issue 23.22: the advice must work when followed)."""
        try:
            empty = not any(os.scandir(self.path))
        except OSError:
            empty = False
        if empty:
            return self._corrupt("an empty directory, not a regular file")
        return SimStateError(f"simulator state file {self.path} is a directory with files in it, not a state file; "
                             "move it away (akdctl never deletes it), then the drive starts in factory state")

    def _clear_directory(self) -> None:
        """For :meth:`reset`: an empty directory where the state file belongs is removed; any other is refused."""
        try:
            os.rmdir(self.path)
        except FileNotFoundError:
            pass
        except NotADirectoryError:
            pass
        except OSError:
            if self.path.is_dir():
                raise self._directory_error() from None

    def _clean_temporaries(self) -> None:
        """Remove temporary state files a killed writer left (any one present while we hold the lock is stale)."""
        with contextlib.suppress(OSError), os.scandir(self.directory) as entries:
            for entry in entries:
                if self._is_temporary(entry.name):
                    with contextlib.suppress(OSError):
                        os.unlink(entry.path)

    def _is_temporary(self, name: str) -> bool:
        """A temporary state file of this drive (``.sim-NAME.`` + 8 of [a-z0-9_] + ``.tmp``), told without a
        regular expression (compiling one costs every process start)."""
        prefix = self._tmp_prefix
        if len(name) != len(prefix) + 12 or not name.startswith(prefix) or not name.endswith(".tmp"):
            return False
        return all(c in _TMP_CHARS for c in name[len(prefix):-4])

    def _read_text(self) -> str | None:
        """The state file's text, None when there is none; anything but a small regular UTF-8 file is refused
        (the one bounded reader, io/safe_read.py)."""
        from akdctl.io.safe_read import FileRefused, read_bounded

        try:
            data = read_bounded(self.path, MAX_STATE_BYTES)
        except FileNotFoundError:
            return None
        except OSError as exc:
            raise self._os_error("cannot read simulator state", self.path, exc) from None
        except FileRefused as refused:
            if refused.kind == "a directory":
                raise self._directory_error() from None
            if refused.kind is not None:
                raise self._corrupt(f"{refused.kind}, not a regular file") from None
            raise self._corrupt(f"{refused.size or 'grew beyond ' + str(MAX_STATE_BYTES)} bytes, "
                                "more than a state ever holds") from None
        try:
            return data.decode("utf-8")
        except UnicodeDecodeError:
            raise self._corrupt("not UTF-8 text") from None

    def _load(self, token: bytes) -> _Held:
        """The model and meta data the lock file's pending state holds, else the state file (factory state when
        there is none)."""
        self._clean_temporaries()
        text = self._pending_text() if self._pending_bytes else None
        if text is None:
            text = self._read_text()
        if text is None:
            model, meta = factory_model(self.name), {"wall": time.time(), "time_scale": DEFAULT_TIME_SCALE}
            return _Held(model, meta, token, _mark(model, meta))
        from akdctl.io.json_text import loads  # json.loads without importing json (issue 29)

        try:
            state = loads(text, parse_constant=_refuse_constant, parse_float=_finite_float)
            if not isinstance(state, dict):
                raise ValueError("not a JSON object")
            meta = state.pop("sim", {})
            if not isinstance(meta, dict):
                raise ValueError("'sim' is not an object")
            meta["wall"] = _finite_float(meta.get("wall", time.time()))
            meta["time_scale"] = _finite_float(meta.get("time_scale", DEFAULT_TIME_SCALE))
            if not 0 < meta["time_scale"] <= MAX_TIME_SCALE:
                raise ValueError(f"sim.time_scale {meta['time_scale']} is outside (0, {MAX_TIME_SCALE:g}]")
            model = DriveModel.from_state(state)
            model.to_state()  # renders every derived value once: a field of the wrong type fails here, as corrupt
            return _Held(model, meta, token, _mark(model, meta))
        except RecursionError:
            raise self._corrupt("nested too deeply") from None
        except Exception as exc:  # noqa: BLE001 - hostile content may fail anywhere in from_state; all mean corrupt
            raise self._corrupt(str(exc) or type(exc).__name__) from None

    def _save(self, model: DriveModel, meta: dict[str, Any]) -> None:
        text = _state_text(model, meta)
        try:
            with atomic_open(self.path, prefix=f".sim-{self.name}.") as fh:
                fh.write(text)
        except OSError as exc:
            raise self._os_error("cannot save simulator state", self.path, exc) from None

    def _new_token(self, lock_fd: int, pending: bytes = b"", *, keep: bool = False) -> bytes:
        """Tell other processes to reload; written *before* the state file is replaced (a crash between costs
        only a reload), with the pending state that stands for the state file (none: the file holds the state).
        ``keep``: the token only, the pending state left as it is (:meth:`_commit` drops it once the file holds
        the newer state, so a crash in between leaves the pending state, not an older file, to load)."""
        import zlib

        token = os.urandom(TOKEN_BYTES // 2).hex().encode()
        data = token if keep else token + _PENDING.pack(len(pending), zlib.crc32(pending)) + pending
        try:
            os.pwrite(lock_fd, data, 0)
        except OSError as exc:
            raise self._os_error("cannot write the simulator's lock file", self.lock_path, exc) from None
        if not keep:
            self._pending_bytes = len(pending)
        return token

    def _drop_pending(self, lock_fd: int) -> None:
        """The state file now holds the newest state: the lock file announces no pending state any more."""
        import zlib

        try:
            os.pwrite(lock_fd, _PENDING.pack(0, zlib.crc32(b"")), TOKEN_BYTES)
        except OSError as exc:
            raise self._os_error("cannot write the simulator's lock file", self.lock_path, exc) from None
        self._pending_bytes = 0

    def _pend(self, held: _Held, lock_fd: int, request: bytes) -> bool:
        """Under the lock, for a PROFIdrive request that changed the state: write the state as the lock file's
        pending state instead of saving it (the module doc); False when it must be saved. Which requests pend
        decides only when the state file is written, never what a process that loads sees: the same JSON either
        way."""
        if held.pending >= PENDING_MAX:
            return False
        from akdctl.protocol.bmp import REQ_READ, BmpError, decode_header

        try:
            read = decode_header(request)[1] == REQ_READ
        except BmpError:
            return False
        if not read and not held.after_read and held.model.motion.still():
            return False  # a write at rest that does not end our own polling: the state file holds it at once
        pending = _state_text(held.model, held.meta).encode("utf-8")
        if len(pending) > MAX_STATE_BYTES:
            return False
        held.token = self._new_token(lock_fd, pending)
        held.pending += 1
        held.after_read = read
        return True

    def _pending_text(self) -> str | None:
        """Under the lock: the lock file's pending state (``_pending_bytes`` announced by its head), checked; None
        when it is cut short or damaged -- what a machine crash leaves of a pending state the page cache had not
        written yet (no fsync: the module doc) -- and the state file, the last save, is then the drive, as the
        module doc promises for a crash."""
        import zlib

        size = self._pending_bytes
        if size > MAX_STATE_BYTES:
            return None
        try:
            head = os.pread(self._lock_fd, _HEAD_BYTES + size, 0)
        except OSError as exc:
            raise self._os_error("cannot read the simulator's lock file", self.lock_path, exc) from None
        data = head[_HEAD_BYTES:]
        if len(data) != size or zlib.crc32(data) != _PENDING.unpack_from(head, TOKEN_BYTES)[1]:
            return None
        try:
            return data.decode("utf-8")
        except UnicodeDecodeError:
            return None

    def _begin(self, lock_fd: int, advance: bool) -> _Held:
        """Under the lock: the model up to date (reloaded when another process saved) and its clock advanced."""
        held, self._held = self._held, None  # dropped unless _commit puts it back (a failed body reloads)
        # A kept lock: nobody else can have saved since our last transaction, the token need not be read.
        if held is not None and self._trusted:
            token = held.token
        else:
            head = os.pread(lock_fd, _HEAD_BYTES, 0)
            token = head[:TOKEN_BYTES]
            self._pending_bytes = _PENDING.unpack_from(head, TOKEN_BYTES)[0] if len(head) == _HEAD_BYTES else 0
        fresh = held is None or held.token != token  # an empty token: nobody saved since the lock file began
        if fresh:
            held = self._load(token)
        assert held is not None
        model, meta = held.model, held.meta
        now = time.time()
        model.time_scale = meta["time_scale"]  # wall-time watchdogs need it
        if advance:
            try:
                model.advance(max(0.0, now - meta["wall"]) * model.time_scale)
            except Exception as exc:  # noqa: BLE001 - a loaded state the model cannot run is a corrupt one
                if not fresh:
                    raise
                raise self._corrupt(f"the drive model cannot run it: {exc}") from None
        meta["wall"] = now
        self.meta = meta
        return held

    def _commit(self, held: _Held, lock_fd: int, bmp_request: bytes | None = None) -> None:
        """Under the lock, after a body that did not raise: save if the mark moved, keep the model.

        ``bmp_request``: the body answered this PROFIdrive request, which may go to the lock file's pending state
        instead (the module doc; not when the time scale changed)."""
        if held.model.damage is not None:  # a lazy component's state was damaged (a server may have refused only)
            raise self._corrupt(f"damaged simulator state: {held.model.damage}")
        mark = _mark(held.model, held.meta)
        if mark != held.mark:
            if bmp_request is None or mark[1] != held.mark[1] or not self._pend(held, lock_fd, bmp_request):
                pending = self._pending_bytes
                held.token = self._new_token(lock_fd, keep=bool(pending))
                self._save(held.model, held.meta)
                if pending:
                    self._drop_pending(lock_fd)
                held.pending, held.after_read = 0, False
            held.mark = mark
        self._held = held
        self._trusted = self._holding

    @contextlib.contextmanager
    def transaction(self, advance: bool = True) -> Iterator[DriveModel]:
        """Lock, bring the model up to date, advance the virtual clock, yield the model, save if changed, unlock.

        If the body raises, nothing is saved and the held model is dropped (a
        refused access changes nothing; the next transaction reloads the file).
        """
        lock_fd = self._acquire()
        try:
            held = self._begin(lock_fd, advance)
            try:
                yield held.model
            except DamagedState as exc:
                raise self._corrupt(str(exc)) from None
            self._commit(held, lock_fd)
        finally:
            self._release(lock_fd)

    def reset(self) -> None:
        """Restore factory state (works on a corrupt state file too)."""
        with self._locked() as lock_fd:
            self._held = None
            self._clean_temporaries()
            if self.path.is_dir() and not self.path.is_symlink():
                self._clear_directory()
            self._new_token(lock_fd)
            self._save(factory_model(self.name), {"wall": time.time(), "time_scale": DEFAULT_TIME_SCALE})

    def set_time_scale(self, scale: float) -> None:
        with self.transaction():  # the scale is saved with the model, under its lock
            self.meta["time_scale"] = float(scale)

    def snapshot(self) -> dict[str, Any]:
        """The whole persisted state (for ``akdctl sim show``)."""
        with self.transaction() as model:
            state = model.to_state()
            state["sim"] = dict(self.meta)
        return state

    # ------------------------------------------------------------------ wire faces
    # The faces' hot paths: one transaction each, spelled out rather than through the transaction() generator
    # (same steps, same rules; a request costs the microseconds the simulator is measured by).

    def handle_bmp(self, request: bytes) -> bytes:
        """Answer one PROFIdrive base-mode request as the drive's parameter manager."""
        answer = self._pnu_answer
        if answer is None:
            from akdctl.sim.pnu_server import PnuServer

            self._pnu_server = PnuServer(_OUTSIDE, raw_reads=True)
            answer = self._pnu_answer = self._pnu_server.handle  # bound once, not a method object per request
        return self._serve(self._pnu_server, answer, request)

    def handle_mailbox(self, mailbox: bytes) -> list[bytes]:
        """Answer one EtherCAT mailbox (CoE) with the mailboxes the drive sends back.

        The SDO server keeps segmented-transfer state between mailboxes, so it
        lives as long as this object; it reaches the model of the running
        transaction only (outside one, its access object refuses every call).
        Its access object is the model (``drive_model=True``): its queued emergencies go ahead of each answer.
        """
        answer = self._sdo_answer
        if answer is None:
            from akdctl.sim.sdo_server import SdoServer

            self._sdo_server = SdoServer(_OUTSIDE, files=True, drive_model=True)
            answer = self._sdo_answer = self._sdo_server.handle  # bound once, not a method object per request
        return self._serve(self._sdo_server, answer, mailbox)

    def _serve(self, server: Any, answer: Callable[[bytes], T], request: bytes) -> T:
        """One face request as one transaction: ``server`` reaches the model only while ``answer`` runs.

        With the lock kept since the last transaction (:attr:`_trusted`; it is only ever true while the lock is
        kept, :attr:`_holding`), the held model is current: the steps of :meth:`_begin` and :meth:`_commit` that
        matter then -- the clock advanced, a save when the mark moved -- are done here as one straight line without
        their token read and calls (the same rules); every other case takes :meth:`_serve_general`."""
        mutex = self._mutex
        # _acquire's steps, inline: a free mutex is taken without converting a timeout (the usual case), else waited
        # for up to lock_timeout (positional: no keyword parsing)
        if not mutex.acquire(False) and not mutex.acquire(True, self.lock_timeout):
            raise CommError(self._locked_text())
        held = self._held
        if held is None or not self._trusted:
            return self._serve_general(server, answer, request)  # it releases the mutex
        try:
            self._held = None  # dropped unless the request succeeds (a failed one reloads)
            model, meta = held.model, held.meta
            now = time.time()
            model.time_scale = scale = meta["time_scale"]
            wall = meta["wall"]
            if now > wall:
                model.advance((now - wall) * scale)
            meta["wall"] = now
            server.access = model
            try:
                result = answer(request)
            except DamagedState as exc:
                raise self._corrupt(str(exc)) from None
            finally:
                server.access = _OUTSIDE
            mark = held.mark  # the mutex is held: meta's time scale is still ``scale``
            if model.revision != mark[0] or scale != mark[1] or model.damage is not None:
                self._commit(held, self._lock_fd)
            else:
                self._held = held
            return result
        finally:
            mutex.release()  # what _release does while the lock is kept

    def _serve_general(self, server: Any, answer: Callable[[bytes], T], request: bytes) -> T:
        """:meth:`_serve` with the mutex taken, when the held model is not known current: the lock taken if it is
        not kept, the model brought up to date by :meth:`_begin`, the request answered and committed."""
        mutex = self._mutex
        if self._holding:
            lock_fd = self._lock_fd
        else:
            try:
                lock_fd = self._take_lock()
            except BaseException:
                mutex.release()
                raise
        try:
            held = self._begin(lock_fd, True)
            server.access = held.model
            try:
                result = answer(request)
            except DamagedState as exc:
                raise self._corrupt(str(exc)) from None
            finally:
                server.access = _OUTSIDE
            self._commit(held, lock_fd, request if server is self._pnu_server else None)
            return result
        finally:
            if self._holding:
                mutex.release()  # what _release does while the lock is kept
            else:
                self._release(lock_fd)

    def object_read(self, index: int, subindex: int) -> bytes:
        with self.transaction() as model:
            return model.object_read(index, subindex)

    def object_write(self, index: int, subindex: int, data: bytes) -> None:
        with self.transaction() as model:
            model.object_write(index, subindex, data)

    def serial(self) -> int:
        """This drive's serial number (0x1018:4): every face reports this one (sim/identity.py, issue 23.8)."""
        return int.from_bytes(self.object_read(0x1018, 4)[:4], "little")

    def take_emergencies(self) -> list[Any]:
        """Emergencies the drive raised since the last call (for the CANopen face)."""
        with self.transaction() as model:
            return _take_emergencies(model)


def serial_for(name: str) -> int:
    """The serial number of the simulated drive ``name``: ``default`` keeps the real AKD's (its SII dump), every
    other name its own, stable across resets and machines -- a line of simulated drives is a line of distinct
    drives (``discover`` keys an inventory on the serial)."""
    import zlib

    from akdctl.sim import identity

    if name == "default":
        return identity.SERIAL
    return 0x80000000 | (zlib.crc32(name.encode("utf-8")) & 0x7FFFFFFF)


def _state_text(model: DriveModel, meta: dict[str, Any]) -> str:
    """The state file's text: the model's state with the store's meta data under "sim"."""
    import json

    state = model.to_state()
    state["sim"] = meta
    # encoded whole, then written at once: json.dump to the text file writes each of its hundreds of pieces
    # through the file object, ~5x the CPU of dumps for the same bytes
    return json.dumps(state, separators=(",", ":"), allow_nan=False)


def factory_model(name: str) -> DriveModel:
    """A drive model in factory state, with the identity of the drive ``name``."""
    model = DriveModel()
    model.object_values[(0x1018, 4)] = serial_for(name).to_bytes(4, "little")
    return model


_TMP_CHARS = frozenset("abcdefghijklmnopqrstuvwxyz0123456789_")


def atomic_open(path: Path, mode: str = "w", *, prefix: str | None = None) -> Any:
    """The one crash-safe writer (``akdctl/io/atomic.py``), imported by the first save: most commands never save."""
    from akdctl.io.atomic import atomic_open as open_atomic

    return open_atomic(path, mode, prefix=prefix)


def _refuse_constant(name: str) -> float:
    raise ValueError(f"{name} is not a value a drive stores")


def _finite_float(text: Any) -> float:
    """A JSON number (or its text) as a finite float; anything else is a damaged state."""
    if isinstance(text, bool):
        raise ValueError(f"{text} is not a number")
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is not a finite number")
    return value


def _take_emergencies(model: DriveModel) -> list[Any]:
    return list(model.faults.take_emergencies())


class _Outside:
    """The servers' access object between transactions: any use is a bug (the model may be stale)."""

    def __getattr__(self, name: str) -> Any:
        raise RuntimeError("simulated drive accessed outside a transaction")


_OUTSIDE = _Outside()

