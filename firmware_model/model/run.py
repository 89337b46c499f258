"""Bit-exact integer model of the four firmware programs (docs/firmware-spec.md §5-§7), parallel over streams.

:func:`run_model` validates the inputs and runs the kernels of :mod:`firmware_model.model.kernels`: one Python
source, compiled with numba (``@njit``, streams in parallel with ``prange``) when numba is importable, and the
same source run as plain Python on exact ints where it is not, or with ``FWEMU_NO_NUMBA=1`` (or
``engine="python"``). Every right shift is ``rs(., ., mode)`` with the build's rounding, every gain multiply is
``mulg`` (exact 48-bit product, one rounding shift, wrap to 32 bits), every ``.l`` assignment is ``wrap32`` of the
exact integer. The earlier numpy implementation (vectorised over streams, a Python loop over samples) is kept as
:mod:`firmware_model.model_numpy`, an independent cross-check and the benchmark's baseline.

Units: state words are Q24.8 (value = word / 256) in barometer "units" (``z = BARO_SIGN * adc``), Q24.8 units/s
and Q24.8 units/s^2 for the Kalman X1/X2/X3; the recursive ``VEL`` is in accelerometer counts x samples (Q32.0).

Wrap-around: the model also computes every ``.l`` value exactly (int64 values that provably never overflow, see
:mod:`firmware_model.model.kernels`) and compares it with the int32 range, so a run reports whether, where
(sample index) and in which word a 68000 ``.l`` operation would have overflowed (:class:`ModelTrace`
``first_wrap`` / ``wrap_word``). Inside the documented input range no wrap happens (docs/numerics.md,
"Wrap-around"); outside it, it is detected and reported, never hidden.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from firmware_model.model.streams import as_input_streams
from firmware_model.model.trace import STATE_WORDS, Trace, word_names
from firmware_model.runtime.errors import UserError
from firmware_model.runtime.output import interrupts_deferred
from firmware_model.spec.build_constants import FirmwareConstants

#: The rounding mode of ``ROUND`` = 0 / 1 (docs/firmware-spec.md §3).
ROUND_MODES: tuple[str, str] = ("floor", "half_up")


@dataclass
class ModelTrace(Trace):
    """A :class:`~firmware_model.model.trace.Trace` from the integer model, plus wrap-around bookkeeping.

    * ``first_wrap``: index of the first sample whose ``step`` wrapped some ``.l`` value (exact result outside
      [-2^31, 2^31-1]), or -1; an ``int`` for one stream, an int64 array ``(n_streams,)`` for many. A wrap inside
      ``init`` cannot happen (``z << 8`` fits for 16-bit inputs).
    * ``wrap_word``: the name of the quantity that wrapped first (e.g. ``"X3"``, ``"VEL"``, ``"mulg(e1,G31)"``),
      ``""`` when none; a ``str`` for one stream, an object array for many.
    """

    first_wrap: Any = -1
    wrap_word: Any = ""

    @property
    def any_wrap(self) -> bool:
        """True when at least one stream wrapped somewhere."""
        return bool(np.any(np.asarray(self.first_wrap) >= 0))


def rounding_mode(consts: "FirmwareConstants") -> str:
    """The rounding mode name (``floor`` / ``half_up``) of a build's ``ROUND`` constant (0 / 1)."""
    if consts.ROUND not in (0, 1):
        raise UserError(f"build constants: ROUND={consts.ROUND!r} must be 0 (floor) or 1 (half_up)")
    return ROUND_MODES[consts.ROUND]


#: ``engine="auto"`` runs the first samples of a process (at most this many in all, streams x samples, over all
#: calls) on the plain-Python kernels while the compiled ones are not loaded: importing numba and loading the
#: cached machine code costs about 0.6 CPU-s (with a cold cache, 10-20 s of compiling), while the plain-Python
#: kernels do 70 k (kalman_accel) to 350 k (recursive) samples/s, so this budget costs at most ~0.3 s. A short
#: ``fwemu run`` / ``vectors --input`` / ``compare`` then takes 0.3 CPU-s instead of 0.8 (10+ s on a fresh
#: machine). A call that would pass the budget, a call after it, and every call once the compiled kernels are
#: loaded (or after an explicit ``engine="numba"``) use the compiled kernels. The words are the same either way
#: (the same source, tests/model/test_kernels.py); docs/history/testing-rounds.md "Short model calls".
AUTO_PURE_MAX_SAMPLES = 20_000
_pure_budget_used = 0
_BUDGET_LOCK = threading.Lock()


def kernels_for(engine: str, n_samples: int | None = None) -> ModuleType:
    """The kernels module a call of ``n_samples`` (streams x samples; None: a large call) runs on for ``engine``
    (``auto`` / ``numba`` / ``python``, as :func:`run_model`); an ``auto`` call within the plain-Python budget
    (:data:`AUTO_PURE_MAX_SAMPLES`) is charged to it. Used by :func:`run_model` and by the streaming
    :class:`firmware_model.vectors.stream.ModelStepper`."""
    global _pure_budget_used
    if n_samples is None:
        n_samples = AUTO_PURE_MAX_SAMPLES + 1
    if engine == "auto":
        with _BUDGET_LOCK:
            if ("firmware_model.model.kernels" not in sys.modules
                    and _pure_budget_used + n_samples <= AUTO_PURE_MAX_SAMPLES):
                _pure_budget_used += n_samples
                return pure_kernels()
        return compiled_kernels()
    if engine == "python":
        return pure_kernels()
    if engine == "numba":
        k = compiled_kernels()
        if not k.COMPILED:
            why = "FWEMU_NO_NUMBA is set" if os.environ.get("FWEMU_NO_NUMBA", "").strip() not in ("", "0") \
                else "numba is not importable"
            raise UserError(f"run_model: engine='numba' but {why}")
        return k
    raise UserError(f"run_model: engine={engine!r}: must be auto, numba or python")


def compiled_kernels() -> ModuleType:
    """:mod:`firmware_model.model.kernels` as imported (numba-compiled unless numba is missing or
    ``FWEMU_NO_NUMBA=1``; its ``COMPILED`` says which). A lazy load (docs/architecture.md): importing the kernels
    imports numba, about 1.5 s, which commands that never run the model (``fwemu --help``, ``asm``, ``design``)
    must not pay."""
    from firmware_model.model import kernels as model_kernels  # lazy: numba (heavy, optional)

    return model_kernels


_PURE: ModuleType | None = None
#: Calls with fewer samples in all run on the calling thread (``run_streams_serial``): waking numba's worker
#: threads costs 0.02-0.2 ms per call on this loaded 2-core machine. Above it the parallel driver runs, also for
#: one stream: numba compiles a parallel loop body with its array arguments marked ``noalias``, which makes the
#: same kernel ~2x faster per sample (kalman_accel 54 vs 28 M samples/s per CPU-second, measured).
PARALLEL_MIN_SAMPLES = 20_000
#: numba's fork-safe workqueue threading layer must not be entered by two threads at once.
_KERNEL_LOCK = threading.Lock()


def pure_kernels() -> ModuleType:
    """A plain-Python copy of :mod:`firmware_model.model.kernels` (the same source file executed with
    ``FORCE_PURE``), whatever numba's availability: the debugging path, and the oracle that the compiled int64
    code is exact (it computes with Python ints)."""
    global _PURE
    if _PURE is None:
        path = Path(__file__).with_name("kernels.py")
        spec = importlib.util.spec_from_file_location("firmware_model.model._kernels_pure", path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        mod.FORCE_PURE = True  # type: ignore[attr-defined]  # a module attribute set before the module's code runs
        spec.loader.exec_module(mod)
        _PURE = mod
    return _PURE


def run_model(consts: "FirmwareConstants", adc: np.ndarray, acc: np.ndarray | None = None, *,
              engine: str = "auto", out: np.ndarray | None = None) -> ModelTrace:
    """Run the integer model of ``consts.program`` over one or many input streams, bit-exact per
    docs/firmware-spec.md §5-§7.

    * ``adc``: barometer ADC counts (unsigned 16-bit register, 0..65535; a pascal build, ``consts.PASCAL``: the
      signed 32-bit pascal word), shape ``(n,)`` or ``(streams, n)``.
    * ``acc``: accelerometer counts (signed 16-bit register, -32768..32767), same shape, or ``None`` (all zero;
      only ``recursive`` and ``kalman_accel`` read it).
    * ``engine``: ``auto`` (the numba kernels when numba is importable and ``FWEMU_NO_NUMBA`` is not set, else
      the same source in Python; the first :data:`AUTO_PURE_MAX_SAMPLES` samples of a process that has not
      loaded the compiled kernels run in Python too, where that is faster than loading them), ``numba``
      (refuse to run uncompiled) or ``python`` (the kernels' source as plain Python on exact ints: slow, for
      debugging). All give the same words and wrap report.
    * ``out``: an optional caller-supplied array for the words (as numpy's ``out=``): int64, C-contiguous,
      writeable, of the shape the words have (below), sharing no memory with the inputs; anything else is a
      :class:`UserError` naming what is wrong. The returned trace's ``words`` is then ``out`` itself, overwritten.
      Reusing one buffer over many calls saves the page faults of a fresh output (about 100 bytes per sample:
      at 1,000 x 1,000 samples, faulting in and zeroing 96 MB costs about a third of the call, bench/bench_model.py).

    Sequencing as the harness: sample 0 is seen by ``init`` and by the first ``step``. Returns a
    :class:`ModelTrace` whose ``words`` (int64; ``.l`` words signed int32, ``.w`` words unsigned 16-bit) are in
    the order of :data:`firmware_model.model.trace.STATE_WORDS`, shape ``(n, n_words)`` for 1-D input or ``(streams, n,
    n_words)`` for 2-D input; ``init_words`` likewise without the sample axis. Raises :class:`UserError` for
    inputs that the 16-bit input registers cannot hold or a bad program / rounding constant.
    """
    program = consts.program
    if program not in STATE_WORDS:
        raise UserError(f"build constants: unknown program {program!r}; known: {', '.join(STATE_WORDS)}")
    rounding_mode(consts)
    one_stream = np.ndim(adc) == 1
    adc2, acc2 = as_input_streams(adc, acc, bool(getattr(consts, "PASCAL", 0)))
    if consts.BARO_SIGN not in (1, -1):
        raise UserError(f"build constants: BARO_SIGN={consts.BARO_SIGN!r} must be +1 or -1")
    kern = kernels_for(engine, adc2.shape[0] * adc2.shape[1])
    names = word_names(program)
    out3 = None
    if out is not None:
        shape = (adc2.shape[1], len(names)) if one_stream else (adc2.shape[0], adc2.shape[1], len(names))
        out3 = _check_out(out, shape, (adc, acc))
    init_words, words, first, word_ids = _run_kernels(kern, consts, adc2, acc2, out3)
    wrap_names = np.array(kern.WRAP_NAMES, dtype=object)[word_ids]
    if one_stream:
        return ModelTrace(program, names, words[0] if out is None else out, init_words[0], first_wrap=int(first[0]),
                          wrap_word=str(wrap_names[0]))
    return ModelTrace(program, names, words if out is None else out, init_words, first_wrap=first,
                      wrap_word=wrap_names)


def _check_out(out: Any, shape: tuple[int, ...], inputs: tuple[Any, Any]) -> np.ndarray:
    """``out`` as the kernels' 3-D ``(streams, n, n_words)`` view, after checking it is what run_model writes:
    a C-contiguous, writeable int64 ndarray of ``shape``, not overlapping the inputs (UserError otherwise)."""
    if not isinstance(out, np.ndarray):
        raise UserError(f"run_model: out= must be a numpy array, not {type(out).__name__}")
    if out.dtype != np.int64:
        raise UserError(f"run_model: out= has dtype {out.dtype}; the words need int64")
    if out.shape != shape:
        raise UserError(f"run_model: out= has shape {out.shape}; these inputs give words of shape {shape}")
    if not out.flags.c_contiguous:
        raise UserError("run_model: out= must be C-contiguous (e.g. from numpy.empty)")
    if not out.flags.writeable:
        raise UserError("run_model: out= is read-only")
    if any(isinstance(x, np.ndarray) and np.may_share_memory(out, x) for x in inputs):
        raise UserError("run_model: out= overlaps an input array")
    return out.reshape((1,) + shape) if len(shape) == 2 else out


#: Words arrays of at least this many bytes come from a small pool (:func:`_words_buffer`).
POOL_MIN_BYTES = 16 << 20
#: Buffers the pool keeps (two: a loop ``for b in batches: tr = run_model(...)`` still holds the previous result
#: while the next call runs, so the one before it is the free one).
POOL_SLOTS = 2
_POOL: list[np.ndarray] = []
_POOL_LOCK = threading.Lock()


def _free_counts(pool: list[np.ndarray]) -> list[int]:
    """``sys.getrefcount`` of each pooled array as :func:`_words_buffer` sees it (the list, the loop variable,
    the call's argument): the one place the count is taken, so that the calibration below measures the same."""
    return [sys.getrefcount(buf) for buf in pool]


def _calibrate() -> int | None:
    """The count of an array referenced by nothing but the pool, or None (pooling off) when one more reference
    does not show as exactly one more: interpreters differ in what ``getrefcount`` counts (borrowed references),
    and reuse is only safe where a held array is told apart from a free one."""
    probe = [np.empty(1, dtype=np.int64)]
    free = _free_counts(probe)[0]
    held = probe[0]
    if _free_counts(probe)[0] != free + 1:
        return None
    del held
    return free if _free_counts(probe)[0] == free else None


_FREE_COUNT: int | None = _calibrate()


def _words_buffer(shape: tuple[int, int, int]) -> np.ndarray:
    """An int64 words array of ``shape`` for a compiled call. A large one (>= :data:`POOL_MIN_BYTES`) is taken from
    the pool when a pooled buffer of that shape is referenced by nothing but the pool (every trace, view or
    memoryview of it is gone: ``sys.getrefcount``), so a caller running batch after batch does not pay the page
    faults of a fresh ~100-byte-per-sample array (the OS zeroing 96 MB at 1,000 x 1,000 samples costs about a
    third of the call, bench/bench_model.py). Otherwise a fresh array, kept in the pool (the oldest dropped).
    The kernel writes every word of the array (as it must for ``np.empty``), so old contents never show. The pool
    holds at most :data:`POOL_SLOTS` buffers after their traces are gone; :func:`release_buffers` frees them. Off
    (always a fresh array) where the reference count cannot tell a held array from a free one (:func:`_calibrate`).
    """
    if int(np.prod(shape)) * 8 < POOL_MIN_BYTES or _FREE_COUNT is None:
        return np.empty(shape, dtype=np.int64)
    with _POOL_LOCK:
        for buf, count in zip(_POOL, _free_counts(_POOL)):
            if buf.shape == shape and count == _FREE_COUNT:   # referenced by the pool only: nobody else
                return buf
        fresh = np.empty(shape, dtype=np.int64)
        _POOL.append(fresh)
        del _POOL[:-POOL_SLOTS]
        return fresh


def release_buffers() -> None:
    """Drop the words buffers :func:`run_model` keeps for reuse (their memory goes back once no trace holds it)."""
    with _POOL_LOCK:
        _POOL.clear()


def _run_kernels(kern: ModuleType, consts: "FirmwareConstants", adc: np.ndarray, acc: np.ndarray,
                 out_words: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Allocate and call ``kern.run_streams``: (init_words, words, first_wrap, wrap ids), int64 arrays; the words
    go to ``out_words`` (``(streams, n, n_words)`` int64, checked by the caller) when given.
    Compiled kernels get int64 arrays; plain-Python ones object arrays (exact Python ints), converted back at the
    end (every output word is a wrapped int32 or a 16-bit word, so the conversion is exact)."""
    n_streams, n = adc.shape
    cols = np.array(kern.OUT_COLS[consts.program], dtype=np.int64)
    prog = kern.PROGRAMS.index(consts.program)
    first = np.empty(n_streams, dtype=np.int64)
    word = np.empty(n_streams, dtype=np.int64)
    if kern.COMPILED:
        dt: type = np.int64
        # One machine-code specialization only: C-contiguous, writeable int64 (numba types a read-only or
        # strided array differently and would compile the driver again for it).
        adc_k, acc_k = (x if x.flags.c_contiguous and x.flags.writeable and x.dtype == np.int64
                        else np.array(x, dtype=np.int64, order="C") for x in (adc, acc))
    else:
        dt = object
        adc_k, acc_k = adc.astype(object), acc.astype(object)
    c = kern.pack_constants(consts, dtype=dt)
    state = np.zeros((n_streams, kern.N_STATE), dtype=dt)
    init_out: np.ndarray = np.empty((n_streams, len(cols)), dtype=dt)
    if out_words is not None and kern.COMPILED:
        out = out_words
    elif kern.COMPILED:
        out = _words_buffer((n_streams, n, len(cols)))
    else:
        out = np.empty((n_streams, n, len(cols)), dtype=dt)
    args = (prog, adc_k, acc_k, c, cols, state, init_out, out, first, word)
    if not kern.COMPILED:
        kern.run_streams(*args)
    else:
        # a compiled call may compile first (seconds): an interrupt waits for it rather than tear numba apart
        with interrupts_deferred():
            if n_streams * n < PARALLEL_MIN_SAMPLES:
                kern.run_streams_serial(*args)
            else:
                with _KERNEL_LOCK:
                    kern.run_streams(*args)
    if not kern.COMPILED:
        init_out = init_out.astype(np.int64)
        if out_words is None:
            out = out.astype(np.int64)
        else:
            out_words[...] = out
            out = out_words
    return init_out, out, first, word
