"""pytest configuration: load the hypothesis profile named by ``HYPOTHESIS_PROFILE`` (default ``ci``), and keep
hypothesis's per-test overhead constant (docs/history/testing-rounds.md).

Two overheads of hypothesis 6.1xx grow with the suite, not with what a test checks:

* For every parametrized invocation its pytest plugin wraps the test function's settings in a new
  ``settings(parent=<the previous wrapper>, suppress_health_check=...)``, so the wrappers chain up (one level per
  invocation: 675 levels by the end of ``test_bus_errors_name_the_faulting_access``), and ``settings.database``
  walks the whole chain twice per test. :func:`pytest_runtest_call` below puts the function's own settings back
  after each test, so every invocation gets the same one-level wrapper that the first one got: the same
  effective settings, the same derandomized examples.
* With ``derandomize`` the seed is a digest of the test's cleaned source, and hypothesis re-tokenizes the source
  for every test (about 3 ms); the cleaning is a pure function of the source text, memoized here, and so is the
  ``inspect.getsource`` read before it (:func:`_memo_inspect`; every digest logged identical with and without).

It also prints the closing lines tests record (the Cortex-M runs', :func:`pytest_terminal_summary`), loads
the compiled model kernels in every test process (below), compiles the model's two numba drivers once before the
xdist workers start when their cache is cold (:func:`pytest_configure`), and runs the longest files first and the
thousands of millisecond oracle tests last (:func:`pytest_collection_modifyitems`): docs/history/testing-rounds.md,
third round.
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import inspect
import os
import subprocess
import sys
import types
from pathlib import Path

import hypothesis
import pytest
from hypothesis import settings


def _end_worker_now() -> None:
    """An xdist worker's last exit handler: flush and leave with ``os._exit(0)``, skipping the interpreter's final
    teardown. By then the worker has reported every test and pytest has unconfigured (its unraisable-exception
    check included); what is left is freeing a heap of hundreds of MB (compiled blocks, numba, 16 MiB CPU maps),
    measured at 2.5-3 s after a full run, while the controller waits for both workers
    (docs/history/testing-rounds.md, sixth round). Registered first thing in this module, before numba and the tests are
    imported, so every exit handler registered later (llvmlite's and numba's shutdown flags, ``weakref.finalize``'s,
    which removes temporary directories still alive, multiprocessing's) runs before it; in a worker nothing registers
    one earlier (checked by logging ``atexit.register`` in a worker: those three, then this). Not in the controller or
    without xdist."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


if os.environ.get("PYTEST_XDIST_WORKER"):
    atexit.register(_end_worker_now)


from tests.support.profiles import PROFILE  # noqa: E402 - after the xdist worker exit hook is registered

from firmware_model.runtime.blas_threads import single_threaded_blas  # noqa: E402 - after the xdist worker exit hook is registered

# One BLAS thread in this process, the xdist workers and the CLI subprocesses the tests start (they inherit it):
# an idle OpenBLAS thread busy-waits after each threaded call and takes the other worker's core
# (firmware_model/runtime/blas_threads.py). Here, before numpy's first import (the next import of firmware_model).
single_threaded_blas()

settings.load_profile(PROFILE)

# Load the model's compiled kernels in every test process, whatever files are selected: run_model's "auto" engine
# runs a process's first 20,000 samples in plain Python while they are not loaded (firmware_model/model/run.py
# AUTO_PURE_MAX_SAMPLES), and the in-process model tests are meant to exercise what a long run uses. (The two
# engines are compared in tests/model/test_kernels.py; tests/model/test_engine_auto.py checks the rule itself in
# fresh interpreters.)
from firmware_model.model import kernels as _model_kernels  # noqa: E402 - after single_threaded_blas(): numpy must not load first


def _memo_inspect() -> types.ModuleType:
    """``inspect`` as hypothesis's reflection module sees it, with ``getsource`` memoized per object.
    ``function_digest`` (the derandomized seed, twice per test) reads the test function's source with
    ``inspect.getsource``, which re-tokenizes the whole function each time (~1 ms; 4,150 single-example ISA tests).
    The source files do not change during a run, so the memo returns the very string ``getsource`` would: same
    digests, same seeds, same examples. Errors are not memoized (raised again as before)."""
    memo: dict[object, str] = {}

    def getsource(obj: object) -> str:
        try:
            return memo[obj]
        except (KeyError, TypeError):
            pass
        src = inspect.getsource(obj)  # type: ignore[arg-type]  # obj is a function or class here
        try:
            memo[obj] = src
        except TypeError:  # unhashable: not memoized
            pass
        return src

    proxy = types.ModuleType("inspect")
    proxy.__dict__.update(inspect.__dict__)
    proxy.getsource = getsource  # type: ignore[attr-defined]  # patching inspect's getsource on the proxy
    return proxy


try:  # a private helper of hypothesis: memoize it only where it is what we expect (a pure str -> bytes function)
    from hypothesis.internal import reflection as _reflection

    if callable(getattr(_reflection, "_clean_source", None)) and callable(getattr(_reflection, "function_digest",
                                                                                  None)):
        _reflection._clean_source = functools.lru_cache(maxsize=4096)(_reflection._clean_source)
        if getattr(_reflection, "inspect", None) is inspect:
            _reflection.inspect = _memo_inspect()
except ImportError:  # pragma: no cover - another hypothesis layout: nothing to memoize
    pass


#: The model's two numba drivers (firmware_model/model/run.py ``_run_kernels``: ``run_streams_serial`` below
#: PARALLEL_MIN_SAMPLES samples, ``run_streams`` above). With a cold numba cache (a fresh clone, as on CI) every
#: process compiles them at its first call (~15 CPU-s for the pair, most of it their common stream kernel):
#: each xdist worker, and CLI subprocesses that start before a worker has written the cache.
_DRIVERS = ("run_streams_serial", "run_streams")
_WARM_SCRIPT = """
import numpy as np
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.model.run import PARALLEL_MIN_SAMPLES, run_model
consts = build_constants(BuildConfig(program="kalman_baro"))
for n in (1, PARALLEL_MIN_SAMPLES):  # run_streams_serial, then run_streams
    run_model(consts, np.full(n, 30000, dtype=np.int64), engine="numba")
"""


def _cold_drivers() -> list[str]:
    """The drivers whose numba cache (``NUMBA_CACHE_DIR`` or ``firmware_model/__pycache__``, what the workers and
    their subprocesses read) holds no machine code for the current source."""
    if not getattr(_model_kernels, "COMPILED", False):
        return []
    cold = []
    for name in _DRIVERS:
        try:
            if getattr(_model_kernels, name)._cache._cache_file._load_index():  # numba's own staleness check
                continue
        except Exception:  # noqa: BLE001 - numba internals moved: compile it anyway (loading is cheap)
            pass
        cold.append(name)
    return cold


_WARMUP: list[subprocess.Popen[bytes]] = []


def pytest_configure(config: pytest.Config) -> None:
    """In the xdist controller, when the drivers' cache is cold: compile them once, in a subprocess started before
    the workers, instead of once in each worker (and in the CLI subprocesses that start before a worker has
    written the cache). Nobody waits for it: it runs while the workers start and collect (~10 CPU-s each), and a
    process that needs a driver before the cache is written compiles it as it always did. Nothing happens with a warm
    cache, without ``-n``, or in a worker; a warm-up that fails changes nothing (the tests then compile, and fail, as
    they would have)."""
    config.addinivalue_line("markers", "seed_per_case: under a derandomized profile (ci), seed each parametrized "
                            "case of this hypothesis test from its own name (case_seed)")
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None) or not _cold_drivers():
        return
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(root), os.environ.get("PYTHONPATH")])))
    _WARMUP.append(subprocess.Popen([sys.executable, "-c", _WARM_SCRIPT], cwd=root, env=env,
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))


def pytest_unconfigure(config: pytest.Config) -> None:
    for proc in _WARMUP:  # a session shorter than the compile: do not leave it running
        proc.kill()
        proc.wait()
    _WARMUP.clear()


#: Scheduling only (which test starts when; the tests and their parameters are the same): the files whose tests
#: take seconds to tens of seconds start first, so that the run does not end with one worker alone on a long
#: test, and the ~4,000 single-example oracle tests (a few ms each) come last, where they fill both workers
#: evenly. Every other file keeps pytest's order between them. Within a file the order is kept. Meant for
#: ``--dist worksteal`` (``make test``): xdist's default ``load`` hands each worker a fixed first slice of an
#: eighth of the tests, which would give one worker all of these files.
_FIRST = ("vectors/test_c_port_mcu.py", "isa/test_blocks.py", "vectors/test_generate.py",
          "vectors/test_vectors_stream.py", "cli/test_output.py", "cli/test_interrupts.py", "model/test_kalman.py",
          "model/test_pascal_input.py", "isa/test_lazy_flags.py", "vectors/test_c_port.py",
          "firmware/test_cpu_vs_model.py", "cli/test_fuzz.py")
_LAST = ("isa/test_vs_m68000py.py", "isa/test_vs_musashi.py")
_TESTS = Path(__file__).resolve().parent


def schedule_problems(tests_dir: Path = _TESTS) -> list[str]:
    """The names of :data:`_FIRST` / :data:`_LAST` that match no file under ``tests_dir`` (a renamed or moved file
    would otherwise turn the scheduling off silently: issue 29 found 11 of 14 stale)."""
    return [name for name in _FIRST + _LAST if not (tests_dir / name).is_file()]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    stale = schedule_problems()
    if stale:
        raise pytest.UsageError(f"tests/conftest.py: scheduled test file(s) not found: {', '.join(stale)}")

    def rank(item: pytest.Item) -> int:
        try:
            name = item.path.resolve().relative_to(_TESTS).as_posix()
        except ValueError:
            return len(_FIRST)
        if name in _FIRST:
            return _FIRST.index(name)
        return len(_FIRST) + 1 + _LAST.index(name) if name in _LAST else len(_FIRST)

    items[:] = sorted(items, key=rank)  # stable


def case_seed(item: pytest.Item) -> int | None:
    """The seed of a ``seed_per_case`` test under a derandomized profile (``ci``): a digest of the file name and
    the test's name with its parameters, so every parametrized case draws its own random states, the same in every
    run and on every machine (the file's folder is left out: moving it keeps the seeds). None otherwise.

    Why: with ``derandomize`` hypothesis seeds a test from the digest of its function's source, one seed for all
    parametrizations, so cases whose draws have the same shape (one row's sizes and modes) drew the same CCR and
    register values (40 consecutive single-example ISA cases drew 4 distinct CCR values)."""
    if item.get_closest_marker("seed_per_case") is None or not settings.default.derandomize:
        return None
    return int.from_bytes(hashlib.sha256(f"{item.path.name}::{item.name}".encode()).digest()[:8], "big")


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_call(item: pytest.Item):
    fn = getattr(getattr(item, "obj", None), "__func__", getattr(item, "obj", None))
    own = getattr(fn, "_hypothesis_internal_use_settings", None)
    own_seed = getattr(fn, "_hypothesis_internal_use_seed", None)
    per_case = case_seed(item) if own is not None else None
    if per_case is not None:
        hypothesis.seed(per_case)(fn)  # public API: overrides derandomize's one-seed-per-function for this call
    try:
        yield
    finally:
        if own is not None:
            fn._hypothesis_internal_use_settings = own
        if per_case is not None:
            fn._hypothesis_internal_use_seed = own_seed


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """Print the closing lines that tests recorded (``record_property("closing_line", ...)``: the Cortex-M runs'
    ``cortex-m0-Os: 673 passed, 0 failed``), in test order, passed or failed; xdist carries them to this process."""
    lines = []
    for key in ("passed", "failed"):
        for rep in terminalreporter.stats.get(key, []):
            if getattr(rep, "when", "call") == "call":
                lines += [(rep.nodeid, v) for k, v in getattr(rep, "user_properties", ()) if k == "closing_line"]
    if lines:
        terminalreporter.section("closing lines")
        for _, line in sorted(lines, key=lambda nl: nl[0]):   # stable: a test's own order kept
            terminalreporter.write_line(line)
