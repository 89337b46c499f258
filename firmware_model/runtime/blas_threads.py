"""One BLAS thread for the processes fwemu starts: the CLI, its worker processes, the tests and the benchmarks.

numpy's OpenBLAS starts a pool of ``cores - 1`` threads at import, and after a threaded call (``np.linalg.solve``
of the altitude table's normal equations, the gain design's Riccati iteration, a matrix product above
OpenBLAS's size threshold) those threads busy-wait for the next one before they sleep. Every matrix here is small
(3 x 3 to a few hundred nodes), so the pool computes nothing faster, and its spinning takes a core from the other
process on a 2-core machine (``--jobs 2``, the two pytest workers) and is charged to the process's CPU time: it
made ``bench/bench_cpu.py``'s firmware figures flip between two values a factor of two apart
(docs/history/testing-rounds.md, sixth round).

:func:`single_threaded_blas` must run before numpy is first imported (the thread count is read once, when the
library loads); it only sets variables the user has not set, so ``OPENBLAS_NUM_THREADS=4 fwemu ...`` still works.
It does not touch a process that imported numpy already (the library ``firmware_model`` itself never calls it).
"""

from __future__ import annotations

import os
import sys

#: The thread-count variables of the BLAS builds numpy ships with (OpenBLAS) or may be linked against (MKL). Not
#: ``OMP_NUM_THREADS``: the integer model's numba kernels run their own thread pool over streams.
VARIABLES: tuple[str, ...] = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def single_threaded_blas() -> bool:
    """Ask for one BLAS thread (each variable of :data:`VARIABLES` the environment does not set yet); True if it
    can still take effect (numpy not imported yet). Child processes inherit the variables."""
    for name in VARIABLES:
        os.environ.setdefault(name, "1")
    return "numpy" not in sys.modules
