"""run_model's words-buffer pool (firmware_model/model/run.py ``_words_buffer``): a large words array whose traces are
all gone is reused by the next call of that shape, and never while anything still refers to it (the trace, a view
of its words, a memoryview); reused or not, the words are those of a call into a fresh caller-supplied array."""

from __future__ import annotations

import numpy as np
import pytest

from firmware_model.model import run as model
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.model.run import POOL_MIN_BYTES, compiled_kernels, release_buffers, run_model

pytestmark = pytest.mark.skipif(not compiled_kernels().COMPILED, reason="the pool serves the compiled kernels only")

CONSTS = build_constants(BuildConfig(program="kalman_baro", k=6))
N_WORDS = len(model.word_names("kalman_baro"))
STREAMS, N = 8, POOL_MIN_BYTES // (8 * 8 * N_WORDS) + 1        # just over the pool's size floor


def _inputs(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    i = np.arange(N)
    adc = 40000 - (30000 * np.minimum(i, N - i)) // N + rng.integers(-30, 31, (STREAMS, N))
    return adc, np.zeros_like(adc)


def _expected(seed: int) -> np.ndarray:
    buf = np.empty((STREAMS, N, N_WORDS), dtype=np.int64)
    run_model(CONSTS, *_inputs(seed), out=buf)
    return buf


def _addr(a: np.ndarray) -> int:
    return a.__array_interface__["data"][0]


def test_a_dropped_result_is_reused_with_the_right_words() -> None:
    release_buffers()
    first = run_model(CONSTS, *_inputs(1))
    where = _addr(first.words)
    del first
    second = run_model(CONSTS, *_inputs(2))
    assert _addr(second.words) == where                       # the pooled buffer came back...
    assert np.array_equal(second.words, _expected(2))         # ...holding this call's words only
    release_buffers()


@pytest.mark.parametrize("keep", ["trace", "view", "memoryview", "words"])
def test_anything_still_referring_to_a_result_keeps_it_out_of_reuse(keep: str) -> None:
    release_buffers()
    first = run_model(CONSTS, *_inputs(1))
    held = {"trace": first, "view": first.words[3, 10:20], "memoryview": memoryview(first.words),
            "words": first.words}[keep]
    before = np.array(first.words)
    where = _addr(first.words)
    del first
    others = [run_model(CONSTS, *_inputs(s)) for s in (2, 3)]   # the loop pattern: the previous result kept too
    assert all(_addr(t.words) != where for t in others)
    view = np.asarray(held.words if keep == "trace" else held)
    assert np.array_equal(view, before[3, 10:20] if keep == "view" else before)   # not overwritten
    for s, t in zip((2, 3), others):
        assert np.array_equal(t.words, _expected(s))
    release_buffers()


def test_a_batch_loop_alternates_between_two_buffers() -> None:
    """``for ...: tr = run_model(...)`` holds the previous result while the next call runs: two buffers serve."""
    release_buffers()
    seen = set()
    tr = None
    for s in range(5):
        tr = run_model(CONSTS, *_inputs(s))
        seen.add(_addr(tr.words))
        assert np.array_equal(tr.words, _expected(s))
    assert len(seen) == 2
    release_buffers()


def test_small_results_are_not_pooled() -> None:
    release_buffers()
    adc = np.full((2, 100), 30000)
    run_model(CONSTS, adc)
    assert model._POOL == []


def test_the_calibration_tells_a_held_array_from_a_free_one(monkeypatch: pytest.MonkeyPatch) -> None:
    """The free count is measured where it is used; where it could not be (pooling off), no array is reused."""
    probe = [np.empty(1, dtype=np.int64)]
    free = model._free_counts(probe)[0]
    held = probe[0]
    assert model._free_counts(probe)[0] == free + 1 and free == model._FREE_COUNT
    del held
    monkeypatch.setattr(model, "_FREE_COUNT", None)
    release_buffers()
    kept = run_model(CONSTS, *_inputs(1))
    before = np.array(kept.words)
    second = run_model(CONSTS, *_inputs(2))
    assert model._POOL == []             # nothing pooled, so nothing can be handed out again
    assert np.array_equal(kept.words, before) and np.array_equal(second.words, _expected(2))
