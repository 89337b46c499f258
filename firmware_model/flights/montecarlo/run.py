"""Run a Monte Carlo: cut the flights into chunks, hand them to the engine, commit each chunk's rows as it comes,
merge, summarise (docs/montecarlo.md).

Output folder ``OUT``:

* ``chunks/``: ``run.json`` (the run's fingerprint) and ``chunk-NNNNNN.parquet|csv``, one per chunk of
  ``chunk_flights`` flights, each committed atomically the moment its worker returns it (``--resume`` skips them);
* ``rows.parquet`` (or ``rows.csv``): every chunk in index order, one row per (flight, method, tuning);
* ``summary.md`` / ``summary.json``: per method and tuning the error distribution and the event probabilities
  with Wilson intervals; ``error_cdf.png``, ``error_vs_dispersion.png``.

Chunks are cut by flight id (chunk i = flights i*c .. i*c+c-1), independent of the backend and the number of
workers, so the merged rows are byte-identical for any of them.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Sequence as SequenceABC
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from firmware_model.flights.montecarlo import pipeline
from firmware_model.flights.montecarlo.results import (
    chunk_rows,
    encode,
    have_pyarrow,
    merge,
    read_rows,
    summarize,
    write_figures,
    write_summary,
)
from firmware_model.flights.montecarlo.spec import distributions, fingerprint, is_dispersed, slot_names
from firmware_model.runtime.engine import Backend, ChunkStore, run_chunks
from firmware_model.runtime.errors import UserError

#: The Monte Carlo's sources, relative to this folder: its own modules and the point-mass integration its flights
#: share with sim1dof (what ``code_version`` hashes).
_SOURCES = ("pipeline.py", "sim.py", "spec.py", "results.py", "../simulate/pointmass.py")


def code_version() -> str:
    """Hash of the Monte Carlo sources (a resume across a code change is refused)."""
    h = hashlib.sha256()
    here = Path(__file__).resolve().parent
    for name in _SOURCES:
        h.update((here / name).read_bytes())
    return h.hexdigest()[:16]


@dataclass
class RunResult:
    folder: Path
    rows_path: Path
    summary: list[dict[str, Any]]
    flights: int
    chunks: int
    resumed_chunks: int
    wall_s: float
    seconds: dict[str, float] = field(default_factory=dict)   # summed over chunks computed in this run
    backend: str = ""


#: The most flights one run takes (``-n``): at the ~100 flights/s of a fast machine, 10^9 flights are four months
#: of computing; the chunk index (chunk-NNNNNN) and the merged rows stay in range below it.
MAX_FLIGHTS: int = 1_000_000_000


class Tasks(SequenceABC):
    """The run's chunk tasks, made one at a time when asked for (issue 33: ``-n 1000000000`` built every task
    up front: 2.6 GB in 10 s, then MemoryError). Task ``i`` is flights ``i*c .. min(i*c+c, n)-1``."""

    def __init__(self, spec: dict[str, Any], seed: int, n: int, threads: int | None = None) -> None:
        self.spec, self.seed, self.n, self.threads = spec, seed, n, threads
        self.c = int(spec["chunk_flights"])

    def __len__(self) -> int:
        return -(-self.n // self.c)

    def __getitem__(self, i: int) -> dict[str, Any]:   # type: ignore[override]  # a lazy Sequence of task dicts: Sequence.__getitem__ also takes slices
        if not 0 <= i < len(self):
            raise IndexError(i)
        a = i * self.c
        return {"spec": self.spec, "seed": self.seed, "flights": list(range(a, min(a + self.c, self.n))),
                "threads": self.threads}

    def size(self, i: int) -> int:
        """The number of flights of task ``i``."""
        return min(self.c, self.n - i * self.c)


def make_tasks(spec: dict[str, Any], seed: int, n: int, threads: int | None = None) -> Tasks:
    return Tasks(spec, seed, n, threads)


def run_montecarlo(spec: dict[str, Any], seed: int, n: int, out: Path, backend: Backend = Backend(),
                   fmt: str | None = None, resume: bool = False,
                   progress: Callable[[int, int, float], None] | None = None,
                   figures: bool = True, note: Callable[[str], None] | None = None) -> RunResult:
    """Run ``n`` flights of ``spec`` with master seed ``seed`` into ``out``. ``progress(flights_done, n,
    seconds)`` after every chunk (resumed chunks count as done at the start); ``note(text)`` is told of chunk files
    a resume found not whole (they are computed again)."""
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= MAX_FLIGHTS:
        raise UserError(f"-n {n!r}: allowed: an integer 1..{MAX_FLIGHTS:,} (the cap on flights per run)")
    fmt = fmt or ("parquet" if have_pyarrow() else "csv")
    if fmt == "parquet" and not have_pyarrow():
        raise UserError("--format parquet needs pyarrow: pip install 'fwemu[montecarlo]' (or --format csv)")
    out = Path(out)
    multi = backend.kind == "dask" or backend.workers > 1
    tasks = make_tasks(spec, seed, n, threads=1 if multi else None)
    fp = {"spec": fingerprint(spec), "seed": seed, "flights": n, "chunk_flights": spec["chunk_flights"],
          "format": fmt, "code": code_version()}
    rows_per_flight = len(spec["methods"]) * len(spec["tunings"])

    def whole(path: Path) -> bool:      # a chunk file that reads back with every row of its flights
        i = int(path.name[len("chunk-"):].split(".")[0])
        return i < len(tasks) and chunk_rows(path, fmt) == tasks.size(i) * rows_per_flight

    store = ChunkStore(out / "chunks", fp, fmt, resume=resume, valid=whole)
    done = store.done()
    if store.redone and note:
        note(f"--resume: {len(store.redone)} chunk file(s) not whole (truncated or corrupt), computed again: "
             + ", ".join(p.name for p in store.redone[:5]) + (" ..." if len(store.redone) > 5 else ""))
    start = time.perf_counter()
    n_done = sum(tasks.size(i) for i in done if i < len(tasks))
    if progress:
        progress(n_done, n, 0.0)
    seconds: dict[str, float] = {}
    pipeline.plan_for(spec)          # refuse a bad spec here, before any worker starts
    for i, res in run_chunks(pipeline.run_task, tasks, backend, skip=done):
        store.commit(i, encode(res["rows"], fmt))
        for k, v in res["seconds"].items():
            seconds[k] = seconds.get(k, 0.0) + v
        n_done += tasks.size(i)
        if progress:
            progress(n_done, n, time.perf_counter() - start)
    wall = time.perf_counter() - start
    rows_path = out / f"rows.{fmt}"
    merge((store.path(i) for i in range(len(tasks))), rows_path, fmt)
    dists = distributions(spec)
    dispersed = [p for p in slot_names(spec) if is_dispersed(dists[p])]
    cols = read_rows(rows_path, ["method", "tuning", "status", "fired", "error_s", *pipeline.ROW_COLUMNS[12:]]
                     + [f"p_{p}" for p in dispersed])
    summary = summarize(cols, dispersed)
    title = f"{spec['name']}, {n} flights, seed {seed}"
    meta = {"spec": spec, "seed": seed, "flights": n, "backend": backend.describe(), "format": fmt,
            "code": code_version()}
    write_summary(out, summary, meta, title)
    if figures:
        write_figures(out, cols, summary, title)
    return RunResult(out, rows_path, summary, n, len(tasks), len(done), wall, seconds, backend.describe())


__all__ = ["MAX_FLIGHTS", "RunResult", "Tasks", "code_version", "make_tasks", "run_montecarlo"]
