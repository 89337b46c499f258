"""Outputs of every ``fwemu`` command: atomic files, atomic folders, folder locks and clean interruption.

One rule for all commands: **a run either replaces its outputs completely or leaves the previous ones untouched,
and never leaves a temporary name behind** (after a clean run, an error, SIGINT or SIGTERM; only SIGKILL or a
power cut can leave a ``.fwemu-*`` name, which the next run does not trip over).

API
---
``write_file(path, data)``
    Write ``bytes`` or ``str`` (UTF-8) to ``path`` atomically: a temporary name in the same folder, then
    :func:`os.replace`. Parent folders are created. Returns ``path``.

``open_atomic(path, mode="w")`` (context manager)
    The streaming form: yields an open file on the temporary name; on a clean exit the file is closed and moved
    onto ``path``; on any exception (including an interrupt) it is deleted and ``path`` is untouched. Use it for
    large outputs that must not be built in memory.

``staged_folder(target, owned=(), whole=False, guard=None)`` (context manager)
    For a folder of files. Yields an empty *stage* folder (a hidden sibling of ``target`` on the same filesystem,
    or inside ``target`` when the parent folder is not writable). Write every output file into the stage under
    its final relative path (streaming is fine). On a clean exit the stage is committed into ``target`` under the
    folder lock (:func:`folder_lock`) with SIGINT/SIGTERM deferred until the commit is done:

    * files replace files of the same relative path (each by :func:`os.replace`); other files in ``target``
      are kept (``target`` may hold hand-written files, e.g. ``vectors/c/fw.c``);
    * each top-level sub-folder named in ``owned`` replaces the folder of that name as a whole (atomic
      ``renameat2(RENAME_EXCHANGE)`` where the kernel has it), so files that the new run did not write disappear
      (``vectors/cases/``);
    * ``whole=True`` swaps the entire ``target`` folder (only for folders a command owns completely: anything
      else in it is deleted).

    Top-level names in ``last`` are committed after everything else (a manifest).
    ``guard(target)`` runs under the lock just before the commit and may raise :class:`UserError` to refuse it
    (e.g. "this folder holds the committed vector set"). On an exception nothing in ``target`` changes and the
    stage is removed. Two processes staging into the same target both succeed; the later commit wins, each commit
    is complete, and nothing is mixed.

``folder_lock(target, timeout=None)`` (context manager)
    An exclusive ``fcntl.flock`` on the lock file ``<parent>/.fwemu-lock-<name>`` (inside ``target`` when the
    parent is not writable); the file is removed on release, so no lock file outlives a run. A second writer
    waits, says so on stderr after a second, and fails with a clear :class:`OutputError` after ``timeout``
    seconds (default ``$FWEMU_LOCK_TIMEOUT`` or 600 s). Hold it for the short commit, not for the computation.

``interruptible()`` (context manager, used by :func:`firmware_model.cli.main.main`)
    Installs SIGINT/SIGTERM handlers that raise :class:`Interrupted` (a :class:`KeyboardInterrupt`) in the main
    thread, so every ``finally`` and every context manager above cleans up; restores the previous handlers on
    exit. :func:`interrupted_message` words the one line the CLI prints; exit status 128 + signal number
    (130 for SIGINT, 143 for SIGTERM).

``declare_output(*targets)``
    A command names its outputs up front, so that an interrupt during the computation (before anything is
    staged) also reports "previous outputs in DIR left intact".

``signals_deferred()`` (context manager)
    Blocks SIGINT/SIGTERM for a short critical section; a signal that arrives meanwhile is delivered at its end.

``worker_signals_ignored()`` (context manager) and ``worker_init()``
    Start worker processes inside the first (they begin with SIGINT ignored); pass the second as their
    initializer (``--jobs N``): they ignore SIGINT (the parent handles it and terminates
    them) and die on SIGTERM without a traceback.

Errors writing outputs are :class:`OutputError` (a :class:`~firmware_model.runtime.errors.UserError`): one line naming
the path the user gave and the reason, e.g. ``out/budget: cannot write: Read-only file system``.

Temporary names: ``.fwemu-tmp-<name>-XXXX`` (files), ``.fwemu-stage-<name>-XXXX`` (stage folders),
``.fwemu-lock-<name>`` (locks); :data:`TEMP_PREFIX` is their common prefix.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any

from firmware_model.runtime.errors import UserError

try:  # POSIX; elsewhere the lock is a no-op (documented)
    import fcntl
except ImportError:  # pragma: no cover - not on Linux
    fcntl = None  # type: ignore[assignment]  # no fcntl module on this platform: the lock is a no-op

#: Prefix of every temporary and lock name this module creates.
TEMP_PREFIX: str = ".fwemu-"
#: Signals turned into :class:`Interrupted`.
SIGNALS: tuple[int, ...] = (signal.SIGINT, signal.SIGTERM)


class OutputError(UserError):
    """Writing an output failed for a reason the user can fix (read-only, not a folder, disk full, locked)."""


class Interrupted(KeyboardInterrupt):
    """Raised in the main thread by SIGINT or SIGTERM while :func:`interruptible` is active."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        return 128 + self.signum


# --------------------------------------------------------------------------------------------- run state
_state: dict[str, list[str]] = {"active": [], "aborted": [], "committed": [], "planned": []}
#: Signals received during this run. Python runs a signal handler between bytecodes of the main thread, also
#: inside a finalizer (``__del__``) or a callback whose exceptions are ignored: an :class:`Interrupted` raised
#: there is swallowed ("Exception ignored in ...") and the run would go on and commit as if never interrupted.
#: The commit points and the CLI therefore check this record too (:func:`raise_if_interrupted`).
_pending: list[int] = []
#: Depth of :func:`interrupts_deferred` sections: while > 0 the handler records a signal but does not raise.
_deferring: list[int] = [0]


def declare_output(*targets: str | Path) -> None:
    """Name the outputs a command is about to (re)write, so an interrupt before they are staged still says
    "previous outputs in DIR left intact"."""
    _state["planned"].extend(str(t) for t in targets)


def reset_run_state() -> None:
    """Forget the targets of a previous run (called by the CLI at the start of each command)."""
    for value in _state.values():
        value.clear()
    _pending.clear()


def pending_signal() -> int | None:
    """The first SIGINT/SIGTERM received during this run, or None."""
    return _pending[0] if _pending else None


def raise_if_interrupted() -> None:
    """Raise :class:`Interrupted` if a signal arrived during this run, even one whose exception was swallowed."""
    if _pending:
        raise Interrupted(_pending[0])


def interrupted_message(exc: BaseException | None = None) -> str:
    """The one line printed when a run is interrupted: which outputs were left intact or completed."""
    committed_set = set(_state["committed"])
    aborted = list(dict.fromkeys(_state["aborted"] + _state["active"]
                                 + [t for t in _state["planned"] if t not in committed_set]))
    parts = ["fwemu: interrupted"]
    if aborted:
        parts.append(f"previous outputs in {', '.join(aborted)} left intact")
    committed = [t for t in dict.fromkeys(_state["committed"]) if t not in aborted]
    if committed:
        parts.append(f"outputs in {', '.join(committed)} complete")
    if not aborted and not committed:
        parts.append("nothing written")
    return "; ".join(parts)


# --------------------------------------------------------------------------------------------- signals
def _is_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """SIGINT/SIGTERM raise :class:`Interrupted` once (a second signal during the clean-up is ignored).

    An :class:`Interrupted` that Python cannot raise (the handler ran inside a finalizer or a callback, e.g.
    importlib's module-lock weakref callback) goes to ``sys.unraisablehook``, which would print an "Exception
    ignored in ..." traceback before the run's one line; it is recorded in :func:`pending_signal` and ends the run
    at the next :func:`raise_if_interrupted`, so the hook installed here drops it silently (every other
    unraisable exception goes to the previous hook, as before)."""
    if not _is_main_thread():
        yield
        return
    fired = {"n": 0}

    def handler(signum: int, frame: Any) -> None:
        fired["n"] += 1
        _pending.append(signum)
        if fired["n"] == 1 and not _deferring[0]:
            raise Interrupted(signum)

    previous_hook = sys.unraisablehook

    def unraisable(info: Any) -> None:
        if not (isinstance(info.exc_type, type) and issubclass(info.exc_type, Interrupted) and _pending):
            previous_hook(info)

    old = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, handler)
    sys.unraisablehook = unraisable
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Let a library call finish before an interrupt takes effect: inside this block SIGINT/SIGTERM are only
    recorded; at its end (normal or not) a recorded signal raises :class:`Interrupted`. For calls that must not be
    torn apart by an exception raised between two of their bytecodes, e.g. numba compiling a kernel (an interrupt
    there surfaced as numba's "RuntimeError: no compiled object yet", and once as a segmentation fault)."""
    _deferring[0] += 1
    try:
        yield
    finally:
        _deferring[0] -= 1
        if not _deferring[0]:
            raise_if_interrupted()


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Block SIGINT/SIGTERM for a short critical section (main thread only; elsewhere a no-op)."""
    if not _is_main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextlib.contextmanager
def worker_signals_ignored() -> Iterator[None]:
    """Start worker processes inside this block: SIGINT is ignored meanwhile, so the children start with it
    ignored (an ignored disposition survives exec, and Python keeps it) and a Ctrl-C to the process group during
    their start-up does not reach them; the parent's handler is restored at the end (main thread only)."""
    if not _is_main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old if old is not None else signal.SIG_DFL)


def worker_init() -> None:
    """Worker processes ignore SIGINT (the parent terminates them) and end quietly on SIGTERM."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


# --------------------------------------------------------------------------------------------- helpers
def _why(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _fail(path: Path | str, what: str, exc: OSError) -> OutputError:
    return OutputError(f"{path}: {what}: {_why(exc)}")


def _make_parent(path: Path, shown: Path | str) -> None:
    parent = path.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError(f"{shown}: cannot create folder {parent}: a file of that name is in the way") from None
    except NotADirectoryError:
        raise OutputError(f"{shown}: cannot create folder {parent}: a path component is a file") from None
    except OSError as exc:
        raise _fail(shown, f"cannot create folder {parent}", exc) from None
    if not parent.is_dir():
        raise OutputError(f"{shown}: {parent} is not a folder")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _tmp_file(directory: Path, name: str) -> tuple[int, Path]:
    fd, tmp = tempfile.mkstemp(prefix=f"{TEMP_PREFIX}tmp-{name}-", dir=directory)
    os.fchmod(fd, 0o666 & ~_umask())
    return fd, Path(tmp)


def _unlink(path: Path) -> None:
    with contextlib.suppress(OSError):
        os.unlink(path)


# --------------------------------------------------------------------------------------------- files
@contextlib.contextmanager
def open_atomic(path: str | Path, mode: str = "w", encoding: str = "utf-8") -> Iterator[IO[Any]]:
    """Stream into ``path`` atomically (see the module docstring). ``mode``: ``"w"`` (text) or ``"wb"``."""
    if mode not in ("w", "wb"):
        raise ValueError(f"open_atomic: mode {mode!r} (use 'w' or 'wb')")
    shown = path
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{shown}: is a folder, not a file")
    _make_parent(path, shown)
    try:
        fd, tmp = _tmp_file(path.parent, path.name)
    except OSError as exc:
        raise _fail(shown, "cannot write", exc) from None
    key = str(shown)
    _state["active"].append(key)
    done = False
    try:
        text: dict[str, Any] = {} if "b" in mode else {"encoding": encoding, "newline": ""}
        with os.fdopen(fd, mode, **text) as f:
            yield f
        with signals_deferred():
            raise_if_interrupted()
            os.replace(tmp, path)
            done = True
        _state["committed"].append(key)
    except OSError as exc:
        raise _fail(shown, "cannot write", exc) from None
    finally:
        if not done:
            _unlink(tmp)
            _state["aborted"].append(key)
        with contextlib.suppress(ValueError):
            _state["active"].remove(key)


def write_file(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` atomically; returns ``Path(path)``."""
    with open_atomic(path, "wb") as f:
        f.write(data.encode("utf-8") if isinstance(data, str) else data)
    return Path(path)


# --------------------------------------------------------------------------------------------- locks
def _lock_path(target: Path) -> Path:
    parent = target.parent
    if os.access(parent, os.W_OK | os.X_OK) or not target.is_dir():
        return parent / f"{TEMP_PREFIX}lock-{target.name or 'root'}"
    return target / f"{TEMP_PREFIX}lock"


def _lock_timeout() -> float:
    try:
        return float(os.environ.get("FWEMU_LOCK_TIMEOUT", "600"))
    except ValueError:
        return 600.0


@contextlib.contextmanager
def folder_lock(target: str | Path, timeout: float | None = None) -> Iterator[None]:
    """Hold an exclusive lock on ``target`` (see the module docstring)."""
    if fcntl is None:  # pragma: no cover
        yield
        return
    shown = target
    target = Path(os.path.abspath(target))
    lock = _lock_path(target)
    limit = _lock_timeout() if timeout is None else timeout
    start = time.monotonic()
    told = False
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise _fail(shown, f"cannot create lock file {lock}", exc) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "?"
            os.close(fd)
            waited = time.monotonic() - start
            if waited > limit:
                raise OutputError(f"{shown}: another fwemu (pid {holder}) is writing it; gave up after "
                                  f"{limit:g} s (FWEMU_LOCK_TIMEOUT)") from None
            if waited > 1.0 and not told:
                print(f"fwemu: waiting for another fwemu (pid {holder}) writing {shown} ...", file=sys.stderr)
                told = True
            time.sleep(0.02)
            continue
        # the lock file may have been removed (and recreated) by the previous holder between open and flock
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        _unlink(lock)  # while still holding it: a waiter that opened the old file sees it is stale and retries
        os.close(fd)


# --------------------------------------------------------------------------------------------- folders
_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
_renameat2: Any = None


def _exchange(a: Path, b: Path) -> bool:
    """Atomically exchange two paths (Linux renameat2); False when the system cannot."""
    global _renameat2
    if _renameat2 is None:
        try:
            _renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
            _renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
        except (AttributeError, OSError):
            _renameat2 = False
    if _renameat2 is False:
        return False
    rc = _renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def _swap_dir(new: Path, dest: Path, trash: Path) -> None:
    """Put folder ``new`` at ``dest``; the previous ``dest`` (if any) ends up inside ``trash`` (deleted later)."""
    if not dest.exists() and not dest.is_symlink():
        os.rename(new, dest)
        return
    if not dest.is_dir() or dest.is_symlink():
        raise OSError(errno.ENOTDIR, "exists and is not a folder", str(dest))
    if _exchange(new, dest):
        return  # the old contents are now at ``new`` (inside the stage), removed with it
    old = trash / f"{TEMP_PREFIX}old-{dest.name}"
    os.rename(dest, old)
    os.rename(new, dest)


def _merge(stage: Path, dest: Path, owned: Sequence[str], trash: Path, top: bool, last: Sequence[str] = ()) -> None:
    dest.mkdir(exist_ok=True)
    for item in sorted(stage.iterdir(), key=lambda p: (top and p.name in last, p.name)):
        if item.name.startswith(TEMP_PREFIX):
            continue
        there = dest / item.name
        if item.is_dir():
            if top and item.name in owned:
                _swap_dir(item, there, trash)
            else:
                if there.exists() and not there.is_dir():
                    raise OSError(errno.ENOTDIR, "exists and is not a folder", str(there))
                _merge(item, there, owned, trash, False)
        else:
            if there.is_dir():
                raise OSError(errno.EISDIR, "is a folder", str(there))
            os.replace(item, there)


def _stage_base(target: Path) -> Path:
    """Where the stage folder goes: beside ``target`` when the parent is writable, else inside ``target``."""
    parent = target.parent
    if os.access(parent, os.W_OK | os.X_OK):
        return parent
    if target.is_dir() and os.access(target, os.W_OK | os.X_OK):
        return target
    return parent  # let mkdtemp raise the real error


@contextlib.contextmanager
def staged_folder(target: str | Path, owned: Sequence[str] = (), whole: bool = False,
                  guard: Callable[[Path], None] | None = None, last: Sequence[str] = ()) -> Iterator[Path]:
    """Stage a folder of outputs and commit it into ``target`` (see the module docstring)."""
    shown = target
    target = Path(os.path.abspath(target))
    if target.is_symlink() and target.is_dir():
        target = target.resolve()
    if target.exists() and not target.is_dir():
        raise OutputError(f"{shown}: exists and is not a folder")
    _make_parent(target, shown)
    base = _stage_base(target)
    if whole and base != target.parent:
        raise OutputError(f"{shown}: cannot replace it: its parent folder {target.parent} is not writable")
    remove_stale_stages(base, target.name or "root")
    try:
        stage = Path(tempfile.mkdtemp(prefix=f"{TEMP_PREFIX}stage-{target.name or 'root'}-{os.getpid()}-", dir=base))
    except OSError as exc:
        raise _fail(shown, "cannot write", exc) from None
    key = str(shown)
    _state["active"].append(key)
    done = False
    try:
        yield stage
        with folder_lock(target):
            if guard is not None:
                guard(target)
            with signals_deferred():
                raise_if_interrupted()
                if whole:
                    # gather the staged files into one folder inside the stage, then swap it with the target
                    content = stage / f"{TEMP_PREFIX}content"
                    content.mkdir()
                    for item in list(stage.iterdir()):
                        if item != content:
                            os.rename(item, content / item.name)
                    _swap_dir(content, target, stage)
                else:
                    _merge(stage, target, owned, stage, True, last)
                done = True
        _state["committed"].append(key)
    except OSError as exc:
        raise _fail(shown, "cannot write", exc) from None
    finally:
        if not done:
            _state["aborted"].append(key)
        with contextlib.suppress(ValueError):
            _state["active"].remove(key)
        shutil.rmtree(stage, ignore_errors=True)


#: A stage folder without its owner's process id (written before the id was part of the name) is stale after this
#: many seconds.
STALE_STAGE_S: float = 24 * 3600.0


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True      # someone else's process: alive as far as we can tell
    return True


def remove_stale_stages(base: Path, name: str) -> list[Path]:
    """Remove the stage folders of ``name`` in ``base`` that a killed run left (issue 33: a SIGKILLed ``vectors``
    left 12 MB that no later run removed): a stage is named ``.fwemu-stage-NAME-PID-XXXX``; it is stale when
    process PID no longer runs on this machine (a live run staging into the same target keeps its own). A stage
    without a PID (older versions) is stale after :data:`STALE_STAGE_S`. Returns the folders removed."""
    removed: list[Path] = []
    prefix = f"{TEMP_PREFIX}stage-{name}-"
    try:
        entries = [p for p in base.iterdir() if p.name.startswith(prefix) and p.is_dir()]
    except OSError:
        return removed
    for p in entries:
        rest = p.name[len(prefix):]
        if "-" in rest:
            head, tail = rest.split("-", 1)
            if not head.isdigit() or "-" in tail:
                continue                       # another target's stage (its name goes on after NAME-)
            stale = int(head) != os.getpid() and not _pid_alive(int(head))
        else:
            try:
                stale = time.time() - p.stat().st_mtime > STALE_STAGE_S
            except OSError:
                continue
        if stale:
            shutil.rmtree(p, ignore_errors=True)
            removed.append(p)
    return removed


def leftovers(folder: str | Path) -> list[Path]:
    """Temporary or lock names of this module directly inside ``folder`` (e.g. after a SIGKILL)."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.name.startswith(TEMP_PREFIX))


__all__ = ["TEMP_PREFIX", "STALE_STAGE_S", "remove_stale_stages", "Interrupted", "OutputError", "declare_output",
           "folder_lock", "interruptible",
           "interrupts_deferred", "interrupted_message", "leftovers", "open_atomic", "pending_signal",
           "raise_if_interrupted", "reset_run_state", "signals_deferred", "staged_folder", "worker_init",
           "worker_signals_ignored", "write_file"]
