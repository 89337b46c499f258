"""The task engine: run a picklable task function over plain-data chunks, on local processes or on a Dask cluster.

Runtime layer: it imports nothing of the project but :mod:`firmware_model.runtime.errors` and
:mod:`firmware_model.runtime.output`, and knows nothing of flights or firmware. A caller hands it ``fn`` (a
module-level function, so that it pickles by reference) and a list of chunks (plain data: numbers, strings, tuples,
dicts, numpy arrays) and gets ``(index, fn(chunk))`` back as chunks finish. What a
result means, and how it is written, is the caller's business; :class:`ChunkStore` is the usual place.

Backends (:func:`parse_scheduler`):

* ``local`` (default): ``workers`` processes (spawned, not forked: numba's thread pool does not survive a fork),
  each its own single-process :class:`concurrent.futures.ProcessPoolExecutor`, one chunk at a time. A worker that
  dies (killed, out of memory, a segfault) breaks only its own executor: its one chunk is resubmitted to a fresh
  process, the other workers' chunks are not touched. ``workers=1`` runs in this process (no pool).
* ``dask``: ``--scheduler ADDRESS`` connects a :class:`distributed.Client` to a running scheduler;
  ``--scheduler local:N`` starts a :class:`distributed.LocalCluster` of N single-threaded process workers for
  the run. A lost worker's tasks are rescheduled by Dask itself (its ``allowed-failures``, default 3, bounds how
  often one chunk may take a worker down before the run stops with an error).

Determinism: a chunk's result depends on the chunk alone, so the results are the same for any backend and worker
count; only their arrival order differs, which :class:`ChunkStore` (one file per chunk index, merged in index
order) removes.

Interrupts: SIGINT/SIGTERM in the parent (``firmware_model.runtime.output.interruptible``) end the local workers at once
(they ignore SIGINT themselves) or close the Dask client and the cluster it started; chunks already committed
stay on disk for ``--resume``.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import hashlib
import json
import multiprocessing
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import TEMP_PREFIX, leftovers, raise_if_interrupted, worker_init, write_file

#: How often one chunk may be lost with its local worker before the run gives up (a chunk that kills every
#: process it runs in is a bug to report, not something to retry for ever).
LOCAL_RETRIES: int = 3


@dataclass(frozen=True)
class Backend:
    """Where chunks run: ``kind`` "local" (``workers`` processes; 1 = in this process) or "dask" (``address`` of
    a scheduler, or None with ``workers`` = N for a LocalCluster started for the run)."""

    kind: str = "local"
    workers: int = 1
    address: str | None = None

    def describe(self) -> str:
        if self.kind == "local":
            return "this process" if self.workers == 1 else f"{self.workers} local processes"
        return f"Dask scheduler {self.address}" if self.address else f"Dask LocalCluster of {self.workers} workers"


def parse_scheduler(text: str | None, jobs: int = 1) -> Backend:
    """``--scheduler`` text -> :class:`Backend`: None -> local processes (``jobs`` of them); ``local:N`` -> a Dask
    LocalCluster of N workers; anything else (``tcp://host:8786``, ``host:8786``) -> that Dask scheduler."""
    if not isinstance(jobs, int) or isinstance(jobs, bool) or jobs < 1:
        raise UserError(f"--jobs {jobs!r}: must be a positive integer")
    if text is None:
        return Backend("local", jobs)
    text = text.strip()
    if text.startswith("local:"):
        n = text[len("local:"):]
        if not n.isdigit() or int(n) < 1:
            raise UserError(f"--scheduler {text!r}: local:N needs a positive worker count N")
        return Backend("dask", int(n), None)
    if not text:
        raise UserError("--scheduler '': give an address (tcp://host:8786) or local:N")
    return Backend("dask", 1, text if "://" in text else f"tcp://{text}")


def dask_available() -> bool:
    """True when ``distributed`` is importable (the optional ``montecarlo`` extra)."""
    try:
        import distributed  # noqa: F401 - only whether it imports: an optional heavy dependency
    except ImportError:
        return False
    return True


# --------------------------------------------------------------------------------------------- running
def run_chunks(fn: Callable[[Any], Any], chunks: Sequence[Any], backend: Backend = Backend(),
               skip: Sequence[int] | set[int] = (), on_start: Callable[[str], None] | None = None
               ) -> Iterator[tuple[int, Any]]:
    """Yield ``(i, fn(chunks[i]))`` for every chunk index not in ``skip``, as chunks finish (any order). ``fn``
    and the chunks must pickle (except with one local worker). ``on_start(text)`` is told once the workers are
    up (e.g. the Dask dashboard address)."""
    skip = set(skip)
    n_todo = len(chunks) - sum(1 for i in skip if 0 <= i < len(chunks))
    if n_todo <= 0:
        return
    # the indices are streamed, never listed: a run of 10^9 flights has millions of chunks (issue 33)
    todo = (i for i in range(len(chunks)) if i not in skip)
    if backend.kind == "local":
        if backend.workers == 1 or n_todo == 1:
            if on_start:
                on_start("this process")
            for i in todo:
                raise_if_interrupted()
                yield i, fn(chunks[i])
            return
        yield from _run_local(fn, chunks, todo, min(backend.workers, n_todo), on_start)
    elif backend.kind == "dask":
        yield from _run_dask(fn, chunks, list(todo), backend, on_start)
    else:
        raise UserError(f"engine: unknown backend {backend.kind!r}")


def _new_executor() -> cf.ProcessPoolExecutor:
    return cf.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), initializer=worker_init)


def _kill(ex: cf.ProcessPoolExecutor) -> None:
    """End an executor's process now (an interrupt or an error: its chunk is abandoned)."""
    procs = list(getattr(ex, "_processes", {}).values())   # the stdlib keeps them here; no public handle
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    ex.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(5)


def _run_local(fn: Callable[[Any], Any], chunks: Sequence[Any], todo: Iterator[int], workers: int,
               on_start: Callable[[str], None] | None) -> Iterator[tuple[int, Any]]:
    pending = _Pending(todo)                 # pop() takes the lowest index first (lost chunks before new ones)
    lost: dict[int, int] = {}
    slots: list[cf.ProcessPoolExecutor | None] = [None] * workers
    running: dict[cf.Future, tuple[int, int]] = {}    # future -> (slot, chunk index)
    try:
        if on_start:
            on_start(f"{workers} local processes")
        while pending or running:
            for s in range(workers):
                if pending and not any(v[0] == s for v in running.values()):
                    pool = slots[s] = slots[s] or _new_executor()
                    i = pending.pop()
                    try:
                        running[pool.submit(fn, chunks[i])] = (s, i)
                    except cf.process.BrokenProcessPool:
                        pool = slots[s] = _new_executor()
                        running[pool.submit(fn, chunks[i])] = (s, i)
            done, _ = cf.wait(list(running), timeout=0.5, return_when=cf.FIRST_COMPLETED)
            raise_if_interrupted()
            for fut in done:
                s, i = running.pop(fut)
                try:
                    res = fut.result()
                except cf.process.BrokenProcessPool:
                    # the worker process died: only its chunk is lost; run it again in a new process
                    lost[i] = lost.get(i, 0) + 1
                    if lost[i] > LOCAL_RETRIES:
                        raise UserError(f"engine: chunk {i} lost its worker process {lost[i]} times; giving up "
                                        "(a chunk that kills its worker each time)") from None
                    if (dead := slots[s]) is not None:
                        _kill(dead)
                    slots[s] = None
                    pending.append(i)
                    continue
                yield i, res
        for ex in slots:
            if ex is not None:
                ex.shutdown(wait=True)
        slots = [None] * workers
    finally:
        for ex in slots:
            if ex is not None:
                _kill(ex)


class _Pending:
    """The chunk indices still to run: chunks handed back (a lost worker's) first, then the stream ``todo``;
    truthy while any remain (pulls one index ahead)."""

    def __init__(self, todo: Iterator[int]) -> None:
        self._todo = iter(todo)
        self._back: list[int] = []
        self._next: int | None = next(self._todo, None)

    def __bool__(self) -> bool:
        return bool(self._back) or self._next is not None

    def pop(self) -> int:
        if self._back:
            return self._back.pop()
        i = self._next
        assert i is not None
        self._next = next(self._todo, None)
        return i

    def append(self, i: int) -> None:
        self._back.append(i)


def _run_dask(fn: Callable[[Any], Any], chunks: Sequence[Any], todo: list[int], backend: Backend,
              on_start: Callable[[str], None] | None) -> Iterator[tuple[int, Any]]:
    try:
        import distributed  # lazy: the optional 'montecarlo' extra
    except ImportError:
        raise UserError("--scheduler needs Dask's distributed scheduler: pip install 'fwemu[montecarlo]'") from None
    cluster = None
    client = None
    try:
        if backend.address is None:
            cluster = distributed.LocalCluster(n_workers=backend.workers, threads_per_worker=1, processes=True,
                                               dashboard_address=None, silence_logs=40)
            client = distributed.Client(cluster, set_as_default=False)
        else:
            try:
                client = distributed.Client(backend.address, timeout="20s", set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise UserError(f"--scheduler {backend.address}: cannot connect: {exc}") from None
        if on_start:
            on_start(backend.describe())
        token = hashlib.sha256(os.urandom(16)).hexdigest()[:12]
        futs = {client.submit(fn, chunks[i], key=f"fwemu-chunk-{i}-{token}", pure=False): i for i in todo}
        # everything through this run's own client and its event loop: the process may hold other clients (a
        # caller's, the default one), and a future awaited on another client's loop fails
        for fut in distributed.as_completed(list(futs), loop=client.loop):
            raise_if_interrupted()
            i = futs[fut]
            try:
                res = client.gather(fut)
            except distributed.KilledWorker as exc:
                raise UserError(f"engine: chunk {i} took down its Dask worker too often ({exc})") from None
            fut.release()
            yield i, res
    finally:
        if client is not None:
            with contextlib.suppress(Exception):
                client.close()
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close()


# --------------------------------------------------------------------------------------------- chunk files
class ChunkStore:
    """A folder of committed chunk results: ``chunk-000012.<ext>`` per chunk index, each written atomically
    (:func:`firmware_model.runtime.output.write_file`: a temporary name, then a rename), and ``run.json`` holding the
    run's ``fingerprint`` (a hash of everything that determines the rows). A chunk file either exists complete or
    not at all, so a run interrupted anywhere (even by SIGKILL) resumes from the chunks on disk; a fingerprint
    mismatch (a different spec, seed or code) refuses the resume instead of mixing two runs."""

    def __init__(self, folder: str | Path, fingerprint: dict[str, Any], ext: str, resume: bool = False,
                 valid: Callable[[Path], bool] | None = None) -> None:
        self.folder = Path(folder)
        self.ext = ext
        self.fingerprint = fingerprint
        #: a check of a chunk file's contents (``--resume`` redoes a chunk that fails it: truncated, corrupt)
        self.valid = valid
        #: chunk files found invalid and removed by :meth:`done`
        self.redone: list[Path] = []
        run = self.folder / "run.json"
        want = json.dumps(fingerprint, sort_keys=True, indent=1) + "\n"
        if self.folder.exists() and any(self.folder.iterdir()):
            if not resume:
                raise UserError(f"{self.folder}: holds chunks of an earlier run; use --resume to continue it, or "
                                "another --out")
            if not run.exists() or run.read_text() != want:
                raise UserError(f"{self.folder}: --resume: the chunks on disk are from a different run (spec, "
                                "seed, flights, chunk size or program version differ); use another --out")
            for p in leftovers(self.folder):   # a temporary name a SIGKILL left mid-write: never a chunk
                with contextlib.suppress(OSError):
                    p.unlink()
        write_file(run, want)

    def path(self, i: int) -> Path:
        return self.folder / f"chunk-{i:06d}.{self.ext}"

    def done(self) -> set[int]:
        """Indices of the chunks committed so far."""
        out = set()
        for p in self.folder.glob(f"chunk-*.{self.ext}"):
            if not p.name.startswith(TEMP_PREFIX):
                with contextlib.suppress(ValueError):
                    i = int(p.name[len("chunk-"):-len(self.ext) - 1])
                    if self.valid is not None and not self.valid(p):
                        # a chunk file that is not whole (truncated or overwritten after its commit): redo it
                        with contextlib.suppress(OSError):
                            p.unlink()
                        self.redone.append(p)
                        self.redone.sort()
                        continue
                    out.add(i)
        return out

    def commit(self, i: int, data: bytes) -> None:
        write_file(self.path(i), data)


__all__ = ["Backend", "ChunkStore", "LOCAL_RETRIES", "dask_available", "parse_scheduler", "run_chunks"]
