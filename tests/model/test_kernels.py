"""The integer model's kernels (firmware_model.model.kernels): numba-compiled == the same source as plain Python on
exact ints == the earlier numpy model (tests.support.model_numpy), every word of every sample, the first wrap and
its word included.

* The Python-int path is the oracle for the int64 arithmetic of the compiled code: the same source, but every
  value an unbounded Python int, so an int64 overflow, a shift or a division that rounded differently in numba
  would show as a difference. The single steps are compared from states and constants at the int32 extremes
  (where the products and sums are largest), not only on realistic streams.
* The numpy model is an independent second implementation (whole-array np.where per sample, a wrap tracker);
  the emulated 68000 is the ground truth for the words (tests/firmware/test_cpu_vs_model.py), but it reports no
  wrap-around, so first_wrap / wrap_word are cross-checked here, on designs that do wrap.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.flights import strategies as fst
from firmware_model.spec.config import PROGRAMS, BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.fixed import QGain
from firmware_model.runtime.errors import UserError
from firmware_model.spec.fixed import rs as rs_exact
from firmware_model.model.streams import FlightParams, synthetic_flight
from firmware_model.model.run import compiled_kernels, pure_kernels, run_model
from tests.support.model_numpy import run_model_numpy
from firmware_model.model.trace import EVENT_BITS, LATCHED_EVENTS, STATE_WORDS
from tests.support.profiles import examples

KC = compiled_kernels()
KP = pure_kernels()
needs_numba = pytest.mark.skipif(not KC.COMPILED, reason="numba not importable (or FWEMU_NO_NUMBA set)")
ROOT = Path(__file__).resolve().parents[2]

INT32_EDGES = (-(2 ** 31), -(2 ** 31) + 1, -(2 ** 30), -32769, -1, 0, 1, 32768, 2 ** 30, 2 ** 31 - 2, 2 ** 31 - 1)


def _same_trace(a, b, where: str) -> None:
    assert a.names == b.names, where
    assert np.array_equal(a.init_words, b.init_words), where
    if not np.array_equal(a.words, b.words):
        bad = tuple(np.argwhere(a.words != b.words)[0])
        pytest.fail(f"{where}: first difference at {bad} ({a.names[bad[-1]]}): {a.words[bad]} != {b.words[bad]}")
    assert np.array_equal(np.asarray(a.first_wrap), np.asarray(b.first_wrap)), (where, a.first_wrap, b.first_wrap)
    assert np.array_equal(np.asarray(a.wrap_word, dtype=object), np.asarray(b.wrap_word, dtype=object)), \
        (where, a.wrap_word, b.wrap_word)


# ---------------------------------------------------------------------------------------------------- layout
def test_kernel_numbering_matches_the_trace_contract():
    assert set(KC.PROGRAMS) == set(PROGRAMS) == set(STATE_WORDS) and len(KC.PROGRAMS) == len(PROGRAMS)
    for program, cols in KC.OUT_COLS.items():
        assert len(cols) == len(STATE_WORDS[program]) and max(cols) < KC.N_STATE
    for name, bit in EVENT_BITS.items():
        assert getattr(KC, name) == bit
    assert KC.LATCHED == LATCHED_EVENTS
    assert len(KC.WRAP_NAMES) == 22 and len(set(KC.WRAP_NAMES)) == 22 and KC.WRAP_NAMES[0] == ""
    assert KP.COMPILED is False


# ---------------------------------------------------------------------------------------------------- shifts
@needs_numba
def test_numba_right_shift_floors_like_python():
    """numba's >> on a signed int64 is arithmetic (floor), and the kernels' rs equals fixed.rs on Python ints in
    both roundings, for negative and positive values around every power of two up to 2^47 and shifts 0..47."""
    vals = []
    for p in range(48):
        for v in (1 << p, (1 << p) + 1, (1 << p) - 1, 3 << max(p - 1, 0)):
            vals += [v, -v]
    vals += [-(2 ** 47) + 1, 2 ** 47 - 1, -(2 ** 46) * 3 // 2]
    for s in range(48):
        for rnd, mode in ((0, "floor"), (1, "half_up")):
            for x in vals:
                assert KC.rs(np.int64(x), np.int64(s), np.int64(rnd)) == rs_exact(x, s, mode), (x, s, mode)


# -------------------------------------------------------------------------------------------------- one step, extremes
@st.composite
def _extreme_case(draw):
    """(program, constants, state, adc, acc) with values drawn from the int32 / register extremes."""
    edge32 = st.one_of(st.sampled_from(INT32_EDGES), st.integers(-(2 ** 31), 2 ** 31 - 1))
    program = draw(st.sampled_from(PROGRAMS))
    c = [0] * KC.N_CONST
    c[KC.C_K] = draw(st.sampled_from((0, 1, 4, 7, 10)))
    c[KC.C_ROUND] = draw(st.sampled_from((0, 1)))
    c[KC.C_BARO_SIGN] = draw(st.sampled_from((1, -1)))
    c[KC.C_S] = draw(st.integers(1, 8))
    for i in (KC.C_THR, KC.C_V_LIFT, KC.C_V_GATE, KC.C_MACH_VLO, KC.C_MACH_VHI):
        c[i] = draw(edge32)
    c[KC.C_MACH_E] = draw(st.one_of(st.sampled_from((0, 1, 2 ** 31 - 1)), st.integers(0, 2 ** 31 - 1)))
    lo = draw(st.sampled_from((0, 1, 30000, 65535)))
    c[KC.C_BARO_MIN], c[KC.C_BARO_MAX] = lo, draw(st.sampled_from((lo, 65535)))
    for i in range(KC.C_G11_M, KC.C_G31T_S + 1, 2):
        c[i] = draw(st.one_of(st.sampled_from((-32768, -32767, -1, 0, 1, 32767)), st.integers(-32768, 32767)))
        c[i + 1] = draw(st.one_of(st.sampled_from((0, 1, 15, 16, 31, 47)), st.integers(0, 47)))
    # field-ready constants (spec §3) and an altitude table with nodes anywhere in +-2^30 (alt_table's limit)
    c[KC.C_ALT_SHIFT] = draw(st.sampled_from((4, 7, 12, 15)))
    c[KC.C_CAL_P] = draw(st.integers(0, 8))
    c[KC.C_E_GATE] = draw(st.one_of(st.sampled_from((0, 1, 2 ** 31 - 1)), st.integers(0, 2 ** 31 - 1)))
    c[KC.C_GATE_N] = draw(st.integers(1, 32767))
    c[KC.C_APO_N] = draw(st.integers(1, 32767))
    n_nodes = (1 << (16 - c[KC.C_ALT_SHIFT])) + 1
    node = st.one_of(st.sampled_from((-(2 ** 30), 0, 2 ** 30)), st.integers(-(2 ** 30), 2 ** 30))
    some = draw(st.lists(node, min_size=7, max_size=7))
    c += [some[j % 7] for j in range(n_nodes)]     # adjacent nodes differ by anything up to 2^31
    state = [draw(edge32) for _ in range(KC.N_STATE)]
    if program.startswith("kalman"):
        ncal = 1 << c[KC.C_CAL_P]
        state[KC.CAL] = draw(st.sampled_from((0, ncal - 1, ncal, ncal)))
        state[KC.REJ] = draw(st.sampled_from((0, c[KC.C_GATE_N] - 1, c[KC.C_GATE_N])))
        state[KC.NEG] = draw(st.sampled_from((0, c[KC.C_APO_N] - 1)))
        state[KC.SUMA] = draw(st.integers(-(2 ** 23), 2 ** 23))
    if program == "recursive":
        ncal = 1 << c[KC.C_CAL_P]
        state[KC.ACC0_R] = draw(st.integers(-32768, 32767))
        state[KC.EVENTS_R] = draw(st.integers(0, 511))
        state[KC.ZL_R] = draw(st.sampled_from((-65535, 0, 65535)) | st.integers(-65535, 65535))  # a z
        state[KC.SUMA_R] = draw(st.integers(-(2 ** 23), 2 ** 23))
        state[KC.CAL_R] = draw(st.sampled_from((0, ncal - 1, ncal, ncal)))
        state[KC.REJ_R] = draw(st.sampled_from((0, c[KC.C_GATE_N] - 1, c[KC.C_GATE_N])))
        state[KC.NEG_R] = draw(st.sampled_from((0, c[KC.C_APO_N] - 1)))
    else:
        state[KC.ACC0] = draw(st.integers(-32768, 32767))
        state[KC.EVENTS] = draw(st.integers(0, 127))
        state[KC.APFRAC] = draw(st.integers(0, 65535))
    adc = draw(st.one_of(st.sampled_from((0, 1, 65534, 65535)), st.integers(0, 65535)))
    acc = draw(st.one_of(st.sampled_from((-32768, -32767, 0, 32767)), st.integers(-32768, 32767)))
    return program, c, state, adc, acc


_STEPS = {"recursive": "recursive_step", "recursive_seed_literal": "seed_literal_step",
          "kalman_baro": "kalman_baro_step", "kalman_accel": "kalman_accel_step"}


@needs_numba
@settings(max_examples=examples(400, ci=100))
@given(case=_extreme_case())
def test_compiled_step_equals_python_int_step_at_int32_extremes(case):
    """One step from a state anywhere in int32 (e.g. X1 = -2^31, X3 = 2^31 - 1), any 16-bit input and constants
    at their limits (gain mantissas -32768 / 32767, shifts 0 / 47, K = 0 / 10): the compiled int64 step and the
    Python-int step give the same new state and the same wrap id, so no int64 intermediate overflowed."""
    program, c, state, adc, acc = case
    st64 = np.array(state, dtype=np.int64)
    stpy = np.array(state, dtype=object)
    w64 = getattr(KC, _STEPS[program])(st64, np.int64(adc), np.int64(acc), np.array(c, dtype=np.int64))
    wpy = getattr(KP, _STEPS[program])(stpy, adc, acc, np.array(c, dtype=object))
    assert int(w64) == wpy, (program, KC.WRAP_NAMES[int(w64)], KC.WRAP_NAMES[wpy])
    assert st64.tolist() == [int(v) for v in stpy], program
    assert all(-(2 ** 31) <= int(v) < 2 ** 31 for v in stpy)


def test_wrap_ids_are_reached_at_the_extremes():
    """The extremes really wrap (the step test is not vacuous): X1 = 2^31 - 1 with X2 > 0 wraps X1 in the predict;
    a gain 32767 / 2^0 on e1 = -2^31 wraps mulg(e1,G11); EST = -2^31 wraps EST; VEL = 2^31 - 1 wraps VEL."""
    c = np.zeros(KP.N_CONST + 3, dtype=object)          # + a 3-node altitude table (ALT_SHIFT 15), all 0
    c[KP.C_BARO_SIGN], c[KP.C_BARO_MAX], c[KP.C_S], c[KP.C_ALT_SHIFT] = 1, 65535, 5, 15
    c[KP.C_GATE_N], c[KP.C_APO_N], c[KP.C_E_GATE] = 1, 1, 2 ** 31 - 1

    def kst(*head):  # a calibrated Kalman state (CAL = 2^CAL_P = 1)
        v = list(head) + [0] * (KP.N_STATE - len(head))
        v[KP.CAL] = 1
        return np.array(v, dtype=object)

    st = kst(2 ** 31 - 1, 1 << 10)
    assert KP.WRAP_NAMES[KP.kalman_baro_step(st, 0, 0, c)] == "X1"
    c[KP.C_G11_M] = 32767
    st = kst(2 ** 31 - 1)
    assert KP.WRAP_NAMES[KP.kalman_baro_step(st, 0, 0, c)] == "mulg(e1,G11)"
    st = kst(0, 0, 0, 0, 0, 0, 0, 2 ** 31 - 1)
    st[KP.CAL] = 0
    c[KP.C_ALT + 1] = 1000
    assert KP.WRAP_NAMES[KP.kalman_baro_step(st, 1 << 14, 0, c)] == "SUMZ"     # calibration sum
    st = np.array([-(2 ** 31), 0, 0, 0, 0, 0], dtype=object)
    assert KP.WRAP_NAMES[KP.seed_literal_step(st, 65535, 0, c)] == "EST"
    st = np.array([0, 0, 2 ** 31 - 1, -5, 0, 0, 0, 1, 0, 0, 0, 0], dtype=object)   # calibrated: CAL = 2^0
    assert KP.WRAP_NAMES[KP.recursive_step(st, 0, 0, c)] == "VEL"
    c[KP.C_E_GATE] = 1                                   # re-base after GATE_N = 1 held sample: EXT wraps
    st = np.array([0, 2 ** 31 - 100, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0], dtype=object)
    assert KP.WRAP_NAMES[KP.recursive_step(st, 1000, 0, c)] == "EXT"


# ---------------------------------------------------------------------------------------------------- whole runs
def _hot(program: str, seed: int, rounding: str = "floor", k: int = 6):
    """Constants of ``program`` with every gain replaced by a random large one (mantissa up to 2^15, shift 0..18:
    gains up to 2^15): outside any design, so the state runs all over int32 and wraps in many places."""
    consts = build_constants(BuildConfig(program=program, k=k, rounding=rounding, cal_p=2))   # short pad
    rng = np.random.default_rng(seed)
    gains = {name: QGain(int(rng.integers(-32768, 32768)), int(rng.integers(0, 19)), 0.0) for name in consts.gains}
    return dataclasses.replace(consts, gains=gains)


WRAPPING = [  # outside the tuning range: the state runs all over int32 and wraps (first_wrap >= 0)
    ("kalman_baro k10 ratio 1e-7", lambda: build_constants(
        BuildConfig(program="kalman_baro", k=10, ratio=1e-7, noise_model="accel_only", cal_p=0, gate_sigmas=0.0))),
    ("kalman_baro hot floor", lambda: _hot("kalman_baro", 1)),
    ("kalman_baro hot half_up k0", lambda: _hot("kalman_baro", 2, "half_up", 0)),
    ("kalman_accel hot floor", lambda: _hot("kalman_accel", 3)),
    ("kalman_accel hot half_up", lambda: _hot("kalman_accel", 4, "half_up", 10)),
    ("kalman_accel hot floor k0", lambda: _hot("kalman_accel", 5, "floor", 0)),
    ("recursive_seed_literal S1", lambda: build_constants(
        BuildConfig(program="recursive_seed_literal", shift=1, rounding="half_up"))),
]


def _wrapping_streams(n_streams: int, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    adc = np.where(rng.random((n_streams, n)) < 0.5, 0, 65535)
    adc[:, :5] = rng.integers(0, 65536, (n_streams, 1))
    acc = rng.choice(np.array([-32768, 32767, 0]), (n_streams, n))
    return adc, acc


@pytest.mark.parametrize("name,make", WRAPPING, ids=[w[0] for w in WRAPPING])
def test_wrapping_designs_numba_python_numpy_agree(name, make):
    """Full-scale random steps on designs that wrap: the three engines agree on every word, on the first wrap
    sample and on the wrap word, per stream; and the wraps happen (at least 2 of 8 streams wrap, naming a word)."""
    consts = make()
    adc, acc = _wrapping_streams(8, 120, len(name))
    fast = run_model(consts, adc, acc)
    _same_trace(fast, run_model_numpy(consts, adc, acc), f"{name} numba/numpy")
    _same_trace(fast, run_model(consts, adc, acc, engine="python"), f"{name} numba/python")
    assert (fast.first_wrap >= 0).sum() >= 2 and all(w for w in fast.wrap_word[fast.first_wrap >= 0])
    j = int(np.argmax(fast.first_wrap >= 0))
    one = run_model(consts, adc[j], acc[j])
    assert one.first_wrap == fast.first_wrap[j] and one.wrap_word == fast.wrap_word[j]
    assert isinstance(one.first_wrap, int) and isinstance(one.wrap_word, str)
    WRAP_WORDS_SEEN.update(fast.wrap_word[fast.first_wrap >= 0].tolist())
    _WRAPPING_RUN.add(name)


WRAP_WORDS_SEEN: set[str] = set()
_WRAPPING_RUN: set[str] = set()


def test_wrapping_designs_reach_many_wrap_words():
    """Over the designs above, the first wraps name several different quantities, so the order of the wrap checks
    is compared, not only one word. Runs them itself unless all of them ran in this process (under xdist they
    may be spread over the workers: a partial set is not evidence)."""
    if len(_WRAPPING_RUN) < len(WRAPPING):
        for name, make in WRAPPING:
            test_wrapping_designs_numba_python_numpy_agree(name, make)
    assert len(WRAP_WORDS_SEEN) >= 4, WRAP_WORDS_SEEN


@settings(max_examples=examples(25))
@given(cfg=fst.build_configs(k=range(0, 11)), data=st.data())
def test_kernels_equal_numpy_model_many_streams(cfg, data):
    """Random designs (every program, k = 0..10, both roundings, every noise model and tuning ratio), 1..4
    streams of random / edge / flight-shaped inputs in one call: numba == numpy model on everything."""
    n = data.draw(st.integers(1, 150), label="n")
    n_streams = data.draw(st.integers(1, 4), label="streams")
    adc = np.stack([data.draw(st.one_of(fst.adc_streams(min_len=n, max_len=n), fst.edge_streams(length=n)))
                    for _ in range(n_streams)])
    acc = np.stack([data.draw(fst.accel_streams(min_len=n, max_len=n)) for _ in range(n_streams)])
    consts = build_constants(cfg)
    _same_trace(run_model(consts, adc, acc), run_model_numpy(consts, adc, acc), str(cfg))


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
def test_python_path_equals_compiled_on_a_short_flight(program, rounding):
    """The uncompiled path (the kernels' source as Python on exact ints) on 400 samples of a synthetic flight
    plus two random streams: the same words and wrap report as the compiled kernels and the numpy model."""
    consts = build_constants(BuildConfig(program=program, k=6, rounding=rounding))
    s = synthetic_flight(6, seed=3)
    rng = np.random.default_rng(9)
    adc = np.stack([s.adc[:400], rng.integers(0, 65536, 400), rng.integers(30000, 30010, 400)])
    acc = np.stack([s.acc[:400], rng.integers(-32768, 32768, 400), rng.integers(-10, 10, 400)])
    py = run_model(consts, adc, acc, engine="python")
    _same_trace(run_model(consts, adc, acc), py, f"{program} {rounding} auto/python")
    _same_trace(run_model_numpy(consts, adc, acc), py, f"{program} {rounding} numpy/python")


#: A 20 g boost on the synthetic flights' +-16 g accelerometer (2048 counts/g): the int16 register sits at 32767
#: for the whole burn, i.e. after liftoff, where the recursive program's ACC_CLIP logic (spec section 5, step 3) runs.
CLIP_FLIGHT = FlightParams(boost_accel_g=20.0, burn_s=0.8, after_apogee_s=3.0)


@pytest.mark.parametrize("program", PROGRAMS)
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
@pytest.mark.parametrize("k", [4, 6])
def test_kernels_equal_numpy_model_on_a_clipping_accelerometer(program, rounding, k):
    """A flight whose accelerometer clips after liftoff (checked: samples at 32767 inside the burn, after the
    LIFTOFF sample of the programs that read the accelerometer; the recursive program sets ACC_CLIP), with a
    random stream beside it: the compiled kernels == the numpy model (and == the Python-int path at k = 4)."""
    s = synthetic_flight(k, seed=11, params=CLIP_FLIGHT)
    clipped = np.flatnonzero(s.acc == 32767)
    burn = (CLIP_FLIGHT.pad_s * 2 ** k, (CLIP_FLIGHT.pad_s + CLIP_FLIGHT.burn_s) * 2 ** k)
    assert clipped.size >= CLIP_FLIGHT.burn_s * 2 ** k * 0.75, clipped.size   # most of the burn at the rail
    assert burn[0] <= clipped.min() and clipped.max() <= burn[1] + 1, (clipped.min(), clipped.max(), burn)
    rng = np.random.default_rng(12)
    adc = np.stack([s.adc, rng.integers(0, 65536, len(s.adc))])
    acc = np.stack([s.acc, rng.choice(np.array([-32768, 32767, 0, 1]), len(s.acc))])
    consts = build_constants(BuildConfig(program=program, k=k, rounding=rounding))
    fast = run_model(consts, adc, acc)
    if program in ("recursive", "kalman_accel"):  # the accelerometer programs: it clips after their liftoff
        events = fast.column("EVENTS")[0]
        liftoff = int(np.flatnonzero(events & EVENT_BITS["LIFTOFF"])[0])
        assert (clipped > liftoff).sum() >= clipped.size // 2, (liftoff, clipped.min())
        # CLIP_N rail samples set ACC_CLIP; the coast then clears it (recursive: 2^k drag-low samples; kalman_accel:
        # the 2^(k+1)-sample window that re-bases the velocity), before apogee
        seen = np.bitwise_or.reduce(events)
        assert seen & EVENT_BITS["ACC_CLIP"] and seen & EVENT_BITS["CLIP_CLEAR"], seen
        clear = int(np.flatnonzero(events & EVENT_BITS["CLIP_CLEAR"])[0])
        apogee = np.flatnonzero(events & EVENT_BITS["APOGEE"])
        assert apogee.size and clear < apogee[0], (clear, apogee[:1])
        if program == "kalman_accel":
            assert fast.column("E0")[0][clear - 1] != 0 and fast.column("CLP")[0][clear - 1] == 2 ** (k + 1) - 1
    _same_trace(fast, run_model_numpy(consts, adc, acc), f"{program} k={k} {rounding} numba/numpy")
    if k == 4:
        _same_trace(fast, run_model(consts, adc, acc, engine="python"), f"{program} k={k} {rounding} numba/python")


def test_engine_argument_and_env_switch():
    """engine= names its choices; FWEMU_NO_NUMBA=1 makes the kernels plain Python (a fresh process) and
    engine='numba' then refuses with a one-line UserError."""
    consts = build_constants(BuildConfig(program="kalman_accel"))
    with pytest.raises(UserError, match="engine='fast'"):
        run_model(consts, np.array([1, 2]), engine="fast")
    code = ("import numpy as np\n"
            "from firmware_model.model.run import compiled_kernels, run_model\n"
            "from firmware_model.spec.build_constants import build_constants\n"
            "from firmware_model.spec.config import BuildConfig\n"
            "from firmware_model.runtime.errors import UserError\n"
            "c = build_constants(BuildConfig(program='kalman_accel'))\n"
            "print(compiled_kernels().COMPILED, run_model(c, np.full(5, 30000)).words[-1].tolist())\n"
            "try:\n    run_model(c, np.full(5, 30000), engine='numba')\nexcept UserError as e:\n    print(e)\n")
    env = {**os.environ, "FWEMU_NO_NUMBA": "1", "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    lines = out.splitlines()
    want = run_model(consts, np.full(5, 30000)).words[-1].tolist()
    assert lines[0] == f"False {want}"
    assert lines[1] == "run_model: engine='numba' but FWEMU_NO_NUMBA is set"


_FORK_AND_THREADS = """
import sys, threading, multiprocessing
import numpy as np
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.model.run import run_model
c = build_constants(BuildConfig(program="kalman_accel"))
def f(i):  # 4 x 8,000 samples: above PARALLEL_MIN_SAMPLES, so the parallel driver runs
    return int(run_model(c, np.full((4, 8000), 30000 + i)).words.sum())
parent = f(0)
out = [None] * 4
def g(i):
    out[i] = f(i)
threads = [threading.Thread(target=g, args=(i,)) for i in range(4)]
for t in threads: t.start()
for t in threads: t.join()
with multiprocessing.get_context("fork").Pool(2) as pool:
    print(parent, out, pool.map(f, range(4)))
"""


@needs_numba
def test_parallel_kernel_then_fork_and_threads():
    """A process that ran the parallel kernel can still fork workers that run it (a --jobs pool; with GNU
    OpenMP as numba's threading layer they would terminate and the pool hang), and threads may call run_model
    concurrently (serialised by a lock). In a fresh process, with a time limit."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    env["PYTHONPATH"] = str(ROOT)
    res = subprocess.run([sys.executable, "-c", _FORK_AND_THREADS], env=env, capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    want = [int(run_model(build_constants(BuildConfig(program="kalman_accel")), np.full((4, 8000), 30000 + i))
                .words.sum()) for i in range(4)]
    assert res.stdout.strip() == f"{want[0]} {want} {want}"


@needs_numba
def test_one_compiled_specialization_whatever_the_input_layout():
    """Read-only, strided, int32 or uint16 inputs run through the same machine code (numba would otherwise
    compile the driver again, seconds each, for every new array type) and give the same words."""
    consts = build_constants(BuildConfig(program="kalman_accel"))
    rng = np.random.default_rng(4)
    adc = rng.integers(20000, 40000, (3, 80))
    acc = rng.integers(-3000, 3000, (3, 80))
    want = run_model(consts, adc, acc)
    n_sigs = len(KC.run_streams.signatures)
    ro_adc, ro_acc = adc.copy(), acc.copy()
    ro_adc.flags.writeable = ro_acc.flags.writeable = False
    variants = [(ro_adc, ro_acc), (adc.T.copy().T, acc.T.copy().T), (adc.astype(np.int32), acc.astype(np.int32)),
                (adc.astype(np.uint16), acc.astype(np.int16))]
    for a, b in variants:
        _same_trace(run_model(consts, a, b), want, f"{a.dtype} {a.flags.c_contiguous} {a.flags.writeable}")
    strided = np.repeat(adc, 2, axis=1)[:, ::2], np.repeat(acc, 2, axis=1)[:, ::2]
    _same_trace(run_model(consts, *strided), want, "strided")
    assert len(KC.run_streams.signatures) == n_sigs


@needs_numba
@pytest.mark.parametrize("program", PROGRAMS)
def test_parallel_driver_equals_serial_driver_and_one_by_one(program):
    """A call above PARALLEL_MIN_SAMPLES runs the parallel driver; it equals the serial driver on the same
    arrays and run_model one stream at a time (4,000 samples: serial), every word and the wrap report."""
    from firmware_model.model import run as model_mod

    consts = _hot(program, 11) if program.startswith("kalman") else build_constants(
        BuildConfig(program=program, shift=1))
    adc, acc = _wrapping_streams(6, 4_000, 6)
    assert adc.size >= model_mod.PARALLEL_MIN_SAMPLES
    many = run_model(consts, adc, acc)
    init, words, first, word = model_mod._run_kernels(KC, consts, adc, acc)       # the same call, parallel
    assert np.array_equal(words, many.words) and np.array_equal(first, many.first_wrap)
    cols = np.array(KC.OUT_COLS[program], dtype=np.int64)
    out = np.empty_like(words)
    init_s, first_s, word_s = np.empty_like(init), np.empty_like(first), np.empty_like(word)
    KC.run_streams_serial(KC.PROGRAMS.index(program), adc, acc, KC.pack_constants(consts), cols,
                          np.zeros((6, KC.N_STATE), dtype=np.int64), init_s, out, first_s, word_s)
    assert np.array_equal(out, words) and np.array_equal(init_s, init)
    assert np.array_equal(first_s, first) and np.array_equal(word_s, word)
    assert (first >= 0).any() == (program != "recursive")   # recursive VEL needs > 32,767 samples to wrap
    for j in range(6):
        one = run_model(consts, adc[j], acc[j])
        assert np.array_equal(one.words, many.words[j]) and one.first_wrap == many.first_wrap[j]
        assert one.wrap_word == many.wrap_word[j]


# ---------------------------------------------------------------------------------------------------- out=
@pytest.mark.parametrize("engine", ["auto", "python"])
def test_out_buffer_gives_the_same_trace_and_is_the_words(engine):
    """run_model(..., out=buf) writes the words into buf (returned as trace.words, the same object) and gives
    the same words, init words and wrap report as a fresh call, for one stream and many, serial and parallel
    driver sizes, a buffer reused over calls (stale words from the previous call overwritten) and the Python
    path; on a design that wraps, so the wrap report is compared where it says something (without the thrust
    guard of issue 30, which on these streams' full-scale accelerometer keeps the barometer, and so its gain
    products, out of most of the 50 samples)."""
    consts = dataclasses.replace(_hot("kalman_accel", 11), GUARDS=6)
    sizes = [(3, 50)] if engine == "python" else [(3, 50), (6, 4_000)]
    for n_streams, n in sizes:
        adc, acc = _wrapping_streams(n_streams, n, 3)
        want = run_model(consts, adc, acc, engine=engine)
        buf = np.full_like(want.words, -7)
        for _ in range(2):
            got = run_model(consts, adc, acc, engine=engine, out=buf)
            assert got.words is buf
            _same_trace(got, want, f"out= {n_streams}x{n}")
        one_want = run_model(consts, adc[1], acc[1], engine=engine)
        one_buf = np.full_like(one_want.words, 99)
        one = run_model(consts, adc[1], acc[1], engine=engine, out=one_buf)
        assert one.words is one_buf and one.first_wrap == one_want.first_wrap and one.wrap_word == one_want.wrap_word
        _same_trace(one, one_want, "out= one stream")
    assert (want.first_wrap >= 0).any()


def test_out_buffer_is_checked_with_one_line_errors():
    """A wrong out= (type, dtype, shape, layout, read-only, overlapping an input) is a UserError saying which,
    before anything runs; the buffer is left untouched."""
    consts = build_constants(BuildConfig(program="kalman_accel"))
    adc = np.full((2, 30), 30000, dtype=np.int64)
    acc = np.zeros((2, 30), dtype=np.int64)
    n_words = len(STATE_WORDS["kalman_accel"])
    ro = np.zeros((2, 30, n_words), dtype=np.int64)
    ro.flags.writeable = False
    shared = np.zeros((2, 30, n_words), dtype=np.int64)
    cases = [([[0]], "must be a numpy array, not list"),
             (np.zeros((2, 30, n_words), dtype=np.int32), "dtype int32; the words need int64"),
             (np.zeros((2, 31, n_words), dtype=np.int64),
              rf"shape \(2, 31, {n_words}\); these inputs give .* \(2, 30, {n_words}\)"),
             (np.zeros((30, n_words), dtype=np.int64), rf"shape \(30, {n_words}\)"),
             (np.zeros((2, 30, n_words), dtype=np.int64, order="F"), "C-contiguous"),
             (ro, "read-only")]
    for bad, msg in cases:
        before = np.array(bad, copy=True)
        with pytest.raises(UserError, match=msg):
            run_model(consts, adc, acc, out=bad)
        assert np.array_equal(np.asarray(bad), before)
    with pytest.raises(UserError, match="overlaps an input"):
        run_model(consts, shared[:, :, 0].copy(), shared[:, :, 1], out=shared)
    with pytest.raises(UserError,
                       match=rf"shape \(2, 30, {n_words}\); these inputs give words of shape \(30, {n_words}\)"):
        run_model(consts, adc[0], acc[0], out=np.zeros((2, 30, n_words), dtype=np.int64))
