"""The one process pool of every ``--jobs`` command (vectors, evaluate, sweep).

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

from firmware_model.runtime.errors import UserError
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
                on_result: Callable[[int, Any], None] | None = None) -> list[Any]:
    """``[fn(x) for x in items]``, in ``jobs`` worker processes when ``jobs`` > 1 (``fn`` and the items must
    pickle). Results come back in the order of ``items`` whatever the workers' timing; an error or an interrupt
    ends the workers at once. ``on_result(i, result)`` is called as each result arrives, in order."""
    if not isinstance(jobs, int) or isinstance(jobs, bool) or jobs < 1:
        raise UserError(f"--jobs {jobs!r}: must be a positive integer")
    out: list[Any] = []
    if jobs == 1 or len(items) <= 1:
        for i, item in enumerate(items):
            out.append(fn(item))
            if on_result:
                on_result(i, out[-1])
        return out
    pool = start_pool(min(jobs, len(items)))
    completed = False
    try:
        for i, res in enumerate(pool.imap(fn, items)):
            out.append(res)
            if on_result:
                on_result(i, res)
        completed = True
    finally:
        end_pool(pool, completed)
    return out
