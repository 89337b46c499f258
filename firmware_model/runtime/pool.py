"""The process pools of the ``--jobs`` commands: :func:`ordered_map` (evaluate, sweep: every backend of the task
engine, local processes or Dask) and :func:`start_pool` / :func:`end_pool` (vectors, whose workers start before
the case matrix is built, so their start-up overlaps it).

Workers are *spawned*, not forked: the numba model runs its kernels on a thread pool, and a child forked from a
parent whose thread pool has run deadlocks in its first parallel kernel (seen: workers asleep on a futex). They
start with SIGINT ignored (:func:`~firmware_model.runtime.output.worker_init`), so a Ctrl-C to the process group
ends the run through the parent only. A pool ends with ``close()`` + ``join()`` once every result is in (the
workers leave on their own; ``terminate()`` after ``close()`` once hung in CI), and with ``terminate()`` only on
an error or an interrupt.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from typing import Any

from firmware_model.runtime.engine import parse_scheduler, run_chunks
from firmware_model.runtime.output import worker_init, worker_signals_ignored


def start_pool(n: int, initializer: Callable[[], None] = worker_init) -> Any:
    """``n`` spawned worker processes, started with SIGINT ignored (also while they import)."""
    with worker_signals_ignored():
        return multiprocessing.get_context("spawn").Pool(n, initializer=initializer)


def end_pool(pool: Any, completed: bool) -> None:
    """Finish ``pool``: ``completed`` (every result is in) lets the workers leave; otherwise end them at once."""
    if completed:
        pool.close()
    else:
        pool.terminate()
    pool.join()


def ordered_map(fn: Callable[[Any], Any], items: Sequence[Any], jobs: int = 1,
                on_result: Callable[[int, Any], None] | None = None, scheduler: str | None = None) -> list[Any]:
    """``[fn(x) for x in items]`` through the task engine (:func:`firmware_model.runtime.engine.run_chunks`), one
    item a task: in this process (``jobs`` = 1), in ``jobs`` local worker processes, or on a Dask cluster when
    ``scheduler`` names one (``ADDRESS`` or ``local:N``, :func:`~firmware_model.runtime.engine.parse_scheduler`).
    ``fn`` and the items must pickle. Results come back in the order of ``items`` whatever the workers' timing, so
    the output is the same for every backend; ``on_result(i, result)`` is called in that order as soon as the
    results up to ``i`` are in. An error or an interrupt ends the workers at once."""
    backend = parse_scheduler(scheduler, jobs)
    items = list(items)
    out: list[Any] = [None] * len(items)
    have = [False] * len(items)
    nxt = 0
    for i, res in run_chunks(fn, items, backend):
        out[i], have[i] = res, True
        while nxt < len(items) and have[nxt]:
            if on_result:
                on_result(nxt, out[nxt])
            nxt += 1
    return out
