"""Integer model of the Kalman programs (docs/firmware-spec.md §6) against the float mirror and the ideal filter.

The integer-vs-mirror bound is derived in :func:`firmware_model.model.float_reference.kalman_switched_bound` and
docs/numerics.md ("Switched bound") from the LSB (rounding of each shift and of the altitude table's
interpolation), the gains actually applied at each sample (barometer used or gated, transonic gains), the pad
calibration's rounding and the gain quantization; it holds while both runs take the same decisions, and where they
differ the mirror's innovation must lie within the derived margin of the gate.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.flights import strategies as fst
from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.spec.fixed import QGain
from firmware_model.spec.fixed import mulg
from firmware_model.model.run import run_model
from firmware_model.model.float_reference import ideal_kalman, kalman_switched_bound, mirror, riccati_iteration
from firmware_model.model.trace import EVENT_BITS
from tests.support.profiles import examples

DECISION_BITS = EVENT_BITS["MACH_LOCKOUT"] | EVENT_BITS["BARO_INVALID"] | EVENT_BITS["BARO_REJECT"]


def _check_bound(consts, adc, acc, int_consts=None, fm=None) -> np.ndarray:
    """Integer model vs float mirror within :func:`kalman_switched_bound` on every sample up to the first
    decision (gate, transonic) on which the two runs differ; such a difference is allowed only where the mirror's
    innovation is within the derived margin of the gate (the integer run may legitimately fall on the other
    side). Returns max observed/bound per state. ``fm``: the mirror of (consts, adc, acc) when the caller has it
    already (the mirror is deterministic: the same run)."""
    tr = run_model(consts if int_consts is None else int_consts, adc, acc)
    fm = mirror(consts, adc, acc) if fm is None else fm
    assert tr.first_wrap == -1, (tr.first_wrap, tr.wrap_word)
    sb = kalman_switched_bound(consts, fm, adc, acc)
    di = tr.column("EVENTS") & DECISION_BITS
    df = fm.column("EVENTS").astype(np.int64) & DECISION_BITS
    rej_i, rej_f = tr.column("REJ"), fm.column("REJ").astype(np.int64)
    lock_i = tr.column("LOCK") if "LOCK" in tr.names else np.zeros_like(rej_i)
    lock_f = fm.column("LOCK").astype(np.int64) if "LOCK" in fm.names else np.zeros_like(rej_i)
    clip = EVENT_BITS["ACC_CLIP"]
    ev_i, ev_f = tr.column("EVENTS"), fm.column("EVENTS").astype(np.int64)
    clip_diff = ((ev_i ^ ev_f) & clip) != 0
    both = ((ev_i & ev_f) & clip) != 0       # the clip window's counter (the rail counter before it moves no state)
    clp_i = tr.column("CLP") if "CLP" in tr.names else np.zeros_like(rej_i)
    clp_f = fm.column("CLP").astype(np.int64) if "CLP" in fm.names else np.zeros_like(rej_i)
    diff = np.flatnonzero((di != df) | (tr.column("CAL") != fm.column("CAL")) | (rej_i != rej_f) | (lock_i != lock_f)
                          | clip_diff | (both & (clp_i != clp_f)))
    n = int(diff[0]) if diff.size else len(adc)
    if diff.size and clip_diff[n]:
        # ACC_CLIP a sample apart: the rail count starts at LIFTOFF, whose decision X2 > V_LIFT may differ by a
        # sample where the mirror's X2 is within the bound of V_LIFT; the comparison ends there
        lift_i, lift_f = tr.first_event("LIFTOFF"), fm.first_event("LIFTOFF")
        j = min(lift_i, lift_f)
        assert lift_i != lift_f and abs(fm.words[j][1] - consts.V_LIFT) <= sb.bound[j][1] + 2, (n, lift_i, lift_f)
        diff = diff[:0]
    elif diff.size and clp_i[n] != clp_f[n]:
        # the clip window's drag test (a >= -A_DRAG, or the coast phase it needs) may differ only where the mirror's
        # value is within the integer run's error of the threshold; the comparison ends there
        assert _drag_or_coast_ambiguous(consts, tr, fm, adc, acc, n), n
        diff = diff[:0]
    if diff.size:
        i = n
        gate = bool((di[i] ^ df[i]) & EVENT_BITS["BARO_REJECT"]) or rej_i[i] != rej_f[i]
        if (di[i] ^ df[i]) & EVENT_BITS["MACH_LOCKOUT"] or lock_i[i] != lock_f[i]:
            if not _thrust_ambiguous(consts, tr, fm, acc, i):
                assert _transonic_ambiguous(consts, tr, fm, sb, i), i
                assert "LOCK" not in tr.names or _lock_consistent(consts, tr, adc, i), i
        if gate:   # one run inside the gate, the other outside: only where the mirror's e1 is within the margin
            e1 = _mirror_e1(consts, fm, adc, i)
            assert abs(abs(e1) - consts.E_GATE) <= sb.e1_margin[i] + 1e-6, (i, e1, consts.E_GATE, sb.e1_margin[i])
        assert (di[i] ^ df[i]) & ~(EVENT_BITS["BARO_REJECT"] | EVENT_BITS["MACH_LOCKOUT"]) == 0, i
    d = np.abs(tr.words[:n, :3] - fm.words[:n, :3])
    assert np.all(d <= sb.bound[:n] * (1 + 1e-9) + 1e-6), (np.argwhere(d > sb.bound[:n] + 1e-6)[:3], d.max(0))
    return (d / np.maximum(sb.bound[:n], 1e-300)).max(axis=0) if n else np.zeros(3)


def _drag_or_coast_ambiguous(consts, tr, fm, adc, acc, i) -> bool:
    """At sample i the two runs' clip windows differ (§6 step 4): the mirror's drag reading is within 2 counts'
    worth of A_DRAG, or the two runs' phases differ there (a coast decision X3 < -A_COAST taken a sample apart)."""
    names = fm.names
    prev_i = tr.words[i - 1] if i else tr.init_words
    prev_f = fm.words[i - 1] if i else fm.init_words
    if int(prev_i[names.index("PHASE")]) != int(round(prev_f[names.index("PHASE")])):
        return True
    acc0 = prev_f[names.index("ACC0")]
    a = (float(acc[i]) - acc0) * consts.float_gains["ACC_G"]
    return abs(a + consts.A_DRAG) <= 2 * abs(consts.float_gains["ACC_G"]) + 2


def _thrust_ambiguous(consts, tr, fm, acc, i) -> bool:
    """The thrust guard on the pad (§6 step 4, issue 30: the raw accelerometer more than A_COAST above 1 g keeps the
    barometer out) may decide differently where the mirror's reading a = (acc - ACC0) ACC_G is within the integer
    run's error of A_COAST: one LSB of mulg's rounding and ACC_G's quantization (|rel_error| <= 2^-15 of a)."""
    if "ACC0" not in fm.names or not (consts.GUARDS & 1):
        return False
    names = fm.names
    prev_i = tr.words[i - 1] if i else tr.init_words
    prev_f = fm.words[i - 1] if i else fm.init_words
    if int(prev_i[names.index("PHASE")]) != 0 or int(round(prev_f[names.index("PHASE")])) != 0:
        return False
    a = (float(acc[i]) - prev_f[names.index("ACC0")]) * consts.float_gains["ACC_G"]
    return abs(a - consts.A_COAST) <= 1.0 + abs(a) * 2.0 ** -15 + 1e-9


def _mirror_e1(consts, fm, adc, i) -> float:
    from firmware_model.model.float_reference import _alt_mirror_e1

    prev = fm.words[i - 1] if i else fm.init_words
    dt = 2.0 ** -consts.K
    return _alt_mirror_e1(consts, float(adc[i]), prev[0] + prev[1] * dt + prev[2] * dt * dt / 2)


def _transonic_ambiguous(consts, tr, fm, sb, i) -> bool:
    """The Mach lockout decision X2 > MACH_VLO may differ when the mirror's predicted X2 is within the bound."""
    prev = fm.words[i - 1]
    x2p = prev[1] + prev[2] * 2.0 ** -consts.K
    return abs(x2p - consts.MACH_VLO) <= sb.bound[i - 1][1] + sb.bound[i - 1][2] + 2


def _lock_consistent(consts, tr, adc, i) -> bool:
    """The integer run's Mach lockout at sample i is what spec §6 step 4 gives from its own previous words (exact
    ints, the correct constants): so where the two runs' lockouts differ, the integer one still followed the spec."""
    from firmware_model.spec.fixed import rs

    prev = tr.words[i - 1] if i else tr.init_words
    names = tr.names
    x2p = int(prev[names.index("X2")]) + int(rs(int(prev[names.index("X3")]), consts.K, tr_mode(consts)))
    lifted = bool(int(prev[names.index("EVENTS")]) & EVENT_BITS["LIFTOFF"])
    lock = int(prev[names.index("LOCK")])
    ok = consts.BARO_MIN <= int(adc[i]) <= consts.BARO_MAX
    if lifted and x2p > consts.MACH_VLO:
        want, locked = consts.MACH_N, True
    elif lock > 1:
        want, locked = lock - 1, True
    elif lock == 1:
        want, locked = (0, False) if ok else (1, True)
    else:
        want, locked = 0, False
    ev = int(tr.words[i][names.index("EVENTS")])
    return int(tr.words[i][names.index("LOCK")]) == want and bool(ev & EVENT_BITS["MACH_LOCKOUT"]) == locked


def tr_mode(consts) -> str:
    return "half_up" if consts.ROUND else "floor"


@st.composite
def _case(draw):
    cfg = draw(fst.build_configs(programs=("kalman_baro", "kalman_accel")))
    kind = draw(st.sampled_from(("random", "edge", "flight")))
    if kind == "flight":
        adc, acc = draw(fst.flight_like_streams(cfg, max_len=400))
    else:
        adc = draw(fst.adc_streams(max_len=300) if kind == "random" else fst.edge_streams(length=300))
        acc = draw(fst.accel_streams(min_len=len(adc), max_len=len(adc)))
    return cfg, adc, acc


@settings(max_examples=examples(30, ci=10), deadline=None)
@given(case=_case())
def test_kalman_within_derived_bound_of_float_mirror(case):
    cfg, adc, acc = case
    _check_bound(build_constants(cfg), adc, acc)


def _noisy_walk(k, n=1500, spikes=True, walk=0.5):
    """A slow random walk (``walk`` counts rms per sample) plus 2 counts of noise around count 30,000, the
    accelerometer at 1 g plus noise; optionally two single-sample spikes of 600 counts (~170 m)."""
    rng = np.random.default_rng(k)
    adc = np.clip(np.round(30000 + np.cumsum(rng.normal(0, walk, n)) + rng.normal(0, 2, n)), 0, 65535).astype(np.int64)
    if spikes:
        adc[n // 2] += 600       # single-sample spikes, far outside the gate: rejected by both runs
        adc[2 * n // 3] -= 600
    acc = np.round(2048 + rng.normal(0, 20, n)).astype(np.int64)
    return adc, acc


@pytest.mark.parametrize("program", ["kalman_baro", "kalman_accel"])
@pytest.mark.parametrize("k", [4, 5, 6, 7, 8])
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
def test_kalman_bound_on_long_noisy_streams_with_spikes(program, k, rounding):
    """1500 samples of a slow random walk plus noise with two single-sample spikes (rejected by the gate in both
    runs), the case where floor biases build up; the bound follows the gate's decisions."""
    # the accelerometer says "no acceleration": a barometer walk it cannot see would (rightly) be gated
    adc, acc = _noisy_walk(k, walk=0.5 if program == "kalman_baro" else 0.02)
    cfg = BuildConfig(program=program, k=k, rounding=rounding, ratio=50000.0 if program == "kalman_baro" else 100.0)
    consts = build_constants(cfg)
    fm = mirror(consts, adc, acc)
    rej = np.flatnonzero(fm.column("EVENTS").astype(np.int64) & EVENT_BITS["BARO_REJECT"])
    assert len(adc) // 2 in rej and 2 * len(adc) // 3 in rej
    ratio = _check_bound(consts, adc, acc, fm=fm)
    assert ratio.max() > 0.005  # the bound is not vacuous: the observed error is a visible fraction of it


def test_bound_has_teeth_a_wrong_gain_breaks_it():
    """The same check fails when the integer model runs with a G21 that is 2 % off (a porting bug), on a fast
    random walk (large innovations; no gate, so that every sample is compared)."""
    cfg = BuildConfig(program="kalman_baro", k=6, gate_sigmas=0.0)
    consts = build_constants(cfg)
    g = consts.gains["G21"]
    bad = dataclasses.replace(consts, gains={**consts.gains, "G21": QGain(int(g.m * 1.02), g.s, g.target)})
    adc, acc = _noisy_walk(6, spikes=False, walk=50.0)
    _check_pair(consts, consts, adc, acc)
    with pytest.raises(AssertionError):
        _check_pair(bad, consts, adc, acc)


def _check_pair(int_consts, mirror_consts, adc, acc):
    """_check_bound with the integer model built from ``int_consts`` (a deliberate defect) and the mirror and
    bound from the correct ``mirror_consts``."""
    _check_bound(mirror_consts, adc, acc, int_consts=int_consts)


def test_bound_has_teeth_a_wrong_table_node_breaks_it():
    """One altitude-table node 1/8 m off (a table copied wrongly) in the segment the stream uses breaks it."""
    consts = build_constants(BuildConfig(program="kalman_baro", k=6))
    adc, acc = _noisy_walk(6, spikes=False)
    j = int(np.median(adc)) >> consts.ALT_SHIFT
    table = list(consts.ALT_TABLE)
    table[j] += 32
    bad = dataclasses.replace(consts, ALT_TABLE=tuple(table))
    _check_pair(consts, consts, adc, acc)          # the correct model passes the same check
    with pytest.raises(AssertionError):
        _check_pair(bad, consts, adc, acc)


def test_bound_has_teeth_a_wrong_gate_breaks_it():
    """An integer model whose gate is off (E_GATE = max, a dropped comparison) or 4x too wide fails the check
    on a stream with a spike of 2.5 gates: the decisions differ where the mirror's innovation is far from its
    gate (the correct model passes the same check)."""
    consts = build_constants(BuildConfig(program="kalman_accel", k=6, ratio=100.0))
    adc, acc = _noisy_walk(6, walk=0.02)
    _check_pair(consts, consts, adc, acc)
    for e_gate in (2**31 - 1, consts.E_GATE * 4):
        adc2 = adc.copy()
        adc2[300] += int(2.5 * consts.E_GATE / 256 * 3.9)   # ~3.9 counts/m at count 30,000: 2.5 gates
        _check_pair(consts, consts, adc2, acc)
        with pytest.raises(AssertionError):
            _check_pair(dataclasses.replace(consts, E_GATE=e_gate), consts, adc2, acc)


@pytest.mark.parametrize("program, ratio", [("kalman_baro", 50000.0), ("kalman_accel", 100.0)])
@pytest.mark.parametrize("noise_model", ["accel_only", "jerk", "dwna"])
@pytest.mark.parametrize("k", [4, 6, 8])
def test_design_gains_match_plain_riccati_iteration(program, ratio, noise_model, k):
    """The design's doubling solution equals an independent plain Riccati iteration
    (float_reference.riccati_iteration)."""
    cfg = BuildConfig(program=program, k=k, noise_model=noise_model, ratio=ratio)
    K, _ = riccati_iteration(cfg)
    consts = build_constants(cfg)
    names = [("G11", "G21", "G31"), ("G12", "G22", "G32")]
    for j in range(K.shape[1]):
        for i in range(3):
            assert K[i, j] == pytest.approx(consts.float_gains[names[j][i]], rel=1e-6)


@pytest.mark.parametrize("program", ["kalman_baro", "kalman_accel"])
def test_mirror_equals_steady_state_ideal_and_time_varying_converges(program):
    """With a one-sample pad calibration and no gate the mirror is the steady-state ideal filter in metres (same
    algebra, two codes); the time-varying filter from P0 converges to it."""
    cfg = BuildConfig(program=program, k=6, ratio=50000.0 if program == "kalman_baro" else 100.0, cal_p=0,
                      gate_sigmas=0.0)
    consts = build_constants(cfg)
    rng = np.random.default_rng(5)
    n = 3000
    adc = np.clip(np.round(30000 + rng.normal(0, 2, n)), 0, 65535).astype(np.int64)
    acc = np.round(rng.normal(0, 20, n)).astype(np.int64)
    fm = mirror(consts, adc, acc)
    ss = ideal_kalman(cfg, adc, acc, steady=True)
    tv = ideal_kalman(cfg, adc, acc)
    assert (fm.column("EVENTS").astype(int) & DECISION_BITS).sum() == 0
    for i, name in enumerate(("X1", "X2", "X3")):
        scale = max(1.0, np.abs(ss.column(name)).max())
        assert np.abs(fm.column(name) - ss.column(name)).max() <= 1e-9 * 2 ** 24 + 1e-12 * scale
        late = slice(n - 200, n)
        assert np.abs(tv.column(name)[late] - ss.column(name)[late]).max() <= 0.02 * 256


@settings(max_examples=examples(30), deadline=None)
@given(cfg=fst.build_configs(programs=("kalman_baro", "kalman_accel")), data=st.data())
def test_kalman_table_translation_invariant_exactly(cfg, data):
    """Adding an integer c to every altitude-table node gives X1 + c, GND + c, HMAX + c, HP + c, SUMZ + 2^CAL_P c,
    identical X2, X3, EVENTS, APFRAC and counters (HT too: the descent record compares altitudes only): the
    predict never reads X1's absolute value and e1 = h - X1, the pad average rs(SUMZ + 2^p c, p) = rs(SUMZ, p) + c
    exactly."""
    adc = data.draw(fst.adc_streams(max_len=150))
    acc = data.draw(fst.accel_streams(min_len=len(adc), max_len=len(adc)))
    consts = build_constants(cfg)
    c = data.draw(st.integers(-(1 << 22), 1 << 22))
    shifted = dataclasses.replace(consts, ALT_TABLE=tuple(v + c for v in consts.ALT_TABLE))
    t0, t1 = run_model(consts, adc, acc), run_model(shifted, adc, acc)
    assert t0.first_wrap == -1 and t1.first_wrap == -1
    ok = (adc >= consts.BARO_MIN) & (adc <= consts.BARO_MAX)
    if not ok[0]:
        return   # init stores 0 for an invalid first sample: X1 is not translated until calibration ends
    cal = t0.column("CAL")
    done = cal >= (1 << consts.CAL_P)
    assert np.array_equal(t1.column("X1"), t0.column("X1") + c)
    assert np.array_equal(t1.column("GND")[done], t0.column("GND")[done] + c)
    assert np.array_equal(t1.column("SUMZ"), t0.column("SUMZ") + c * cal)
    assert np.array_equal(t1.column("HMAX"), t0.column("HMAX") + c)
    if "HP" in t0.names:                 # kalman_accel: the last valid altitude (its steady test is a difference)
        assert np.array_equal(t1.column("HP"), t0.column("HP") + c)
    for name in t0.names:
        if name not in ("X1", "GND", "SUMZ", "HMAX", "HP"):
            assert np.array_equal(t1.column(name), t0.column(name)), name


def _fixed_point_box(consts) -> tuple[tuple[int, int], tuple[int, int], tuple[int, int]]:
    """Bounds on (X1 - h, X2, X3), h = alt(adc), at any fixed point of kalman_baro under a constant input (no flight
    logic firing, no gate). At a fixed point: mulg(e, G31) = 0; rs(X3, K) = -mulg(e, G21); rs(X2, K) + rs(X3, 2K+1) =
    -mulg(e, G11); X1 - h = mulg(e, G11) - e, with e = h - X1_predicted. Enumerating e over the (small) zero set of
    mulg(., G31) gives the box."""
    mode = "half_up" if consts.ROUND else "floor"
    g = consts.gains
    K = consts.K
    es = np.arange(-(1 << 20), 1 << 20, dtype=np.int64)
    es = es[mulg(es, g["G31"], mode) == 0]
    c1 = mulg(es, g["G11"], mode)
    c2 = mulg(es, g["G21"], mode)
    d1 = c1 - es
    # rs(X3, K) = -c2  ->  X3 in [-c2 * 2^K - (floor: 0 | half_up: 2^(K-1)), ... + 2^K - 1]
    lo3 = (-c2.max()) * 2 ** K - 2 ** K
    hi3 = (-c2.min()) * 2 ** K + 2 ** K
    r3 = max(abs(lo3), abs(hi3)) >> (K + 1)   # |rs(X3, 2K+1)| <= that + 1
    lo2 = (-c1.max() - r3 - 1) * 2 ** K - 2 ** K
    hi2 = (-c1.min() + r3 + 1) * 2 ** K + 2 ** K
    return (int(d1.min()), int(d1.max())), (int(lo2), int(hi2)), (int(lo3), int(hi3))


@pytest.mark.parametrize("k", [4, 6, 8])
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
def test_kalman_constant_input_settles_into_fixed_point_box(k, rounding):
    """After a step to a constant level the integer filter stops inside the fixed-point box above (floor: always
    a fixed point; half_up at k >= 7 can end in a small limit cycle instead, reported in docs/numerics.md, and
    then the box is checked on the cycle's extent too)."""
    consts = build_constants(BuildConfig(program="kalman_baro", k=k, rounding=rounding, gate_sigmas=0.0))
    rng = np.random.default_rng(100 + k)
    n = 6000 * 2 ** max(0, k - 7)   # settling takes longer as the closed-loop poles approach 1
    a = rng.integers(27000, 65536, size=(8, 1))   # pressures above the table floor (a constant altitude)
    b = rng.integers(27000, 65536, size=(8, 1))
    adc = np.repeat(b, n, axis=1)
    adc[:, :20] = a
    tr = run_model(consts, adc, np.zeros_like(adc))
    assert not tr.any_wrap
    tail = tr.words[:, -500:, :3]
    (l1, h1), (l2, h2), (l3, h3) = _fixed_point_box(consts)
    from firmware_model.spec.alt_table import AltTable

    table = AltTable(consts.ALT_TABLE, consts.ALT_SHIFT, 16)
    d1 = tail[..., 0] - table.lookup(b, rounding)
    stationary = np.all(tail[:, -1] == tail[:, -2], axis=-1)
    if rounding == "floor":
        assert stationary.all()
    for s in np.flatnonzero(stationary):
        assert l1 <= d1[s, -1] <= h1, (d1[s, -1], l1, h1)
        assert l2 <= tail[s, -1, 1] <= h2 and l3 <= tail[s, -1, 2] <= h3


@pytest.mark.parametrize("program", ["kalman_baro", "kalman_accel"])
@pytest.mark.parametrize("k", [4, 6, 8, 10])
def test_no_wrap_for_worst_case_inputs_inside_the_range(program, k):
    """Full-scale alternation (0 / 65535 every sample), full-scale steps, and the accelerometer swinging between
    -32768 and 32767: no .l value leaves int32 for the default designs (headroom: docs/numerics.md)."""
    cfg = BuildConfig(program=program, k=k, ratio=50000.0 if program == "kalman_baro" else 100.0)
    consts = build_constants(cfg)
    n = 3000
    alt = np.tile([0, 65535], n // 2)
    step = np.where(np.arange(n) < n // 2, 0, 65535)
    adc = np.stack([alt, 65535 - alt, step, 65535 - step])
    acc = np.stack([np.tile([-32768, 32767], n // 2), np.tile([32767, -32768], n // 2),
                    np.where(np.arange(n) < 10, -32768, 32767), np.zeros(n, dtype=np.int64)])
    tr = run_model(consts, adc, acc)
    assert not tr.any_wrap, (tr.first_wrap, tr.wrap_word)


def test_wrap_detected_outside_the_design_range():
    """A design far outside the documented tuning range (R/q = 1e-5 at k = 10) wraps on full-scale steps of the
    altitude (count 0 = 16 km, count 65535 = -6 km, 40-sample square wave); the model reports the first sample
    and the word. (The metres scale bounds |altitude| by ~31 km, so R/q = 1e-3 no longer wraps.)"""
    cfg = BuildConfig(program="kalman_baro", k=10, ratio=1e-5, noise_model="accel_only", cal_p=0, gate_sigmas=0.0)
    consts = build_constants(cfg)
    adc = np.where(np.arange(400) % 40 < 20, 0, 65535)
    tr = run_model(consts, adc)
    assert tr.any_wrap and tr.first_wrap >= 20
    assert tr.wrap_word in ("X1", "X2", "X3", "e1") or tr.wrap_word.startswith("mulg")


# ---------------------------------------------------------------------------------------------------- transonic flight
# Spec §6 (history: kalman_baro used to lock out too, and kalman_accel's lockout (Schultz n.d.) set X1 to the
# measurement; the field-ready change replaced the lockout by transonic barometer gains in kalman_accel and an
# innovation gate; issue 20 brought back a lockout in kalman_accel, keyed on the accelerometer's velocity, with a
# settling time and a re-base of X1 when the barometer returns).
# The transonic flight of the committed vectors: 14 g for 2.5 s, peak ~307 m/s,
# the barometer reads 60 m high while the true speed is in 290..375 m/s (a step up entering, down leaving).
def _fast_flight(program: str, k: int, rounding: str, error_m: float = 60.0):
    from firmware_model.model.streams import flight_params_for, synthetic_flight, true_trajectory
    from firmware_model.vectors.cases import FAST_FLIGHT_SEED, case_config

    cfg = case_config(program, rounding, k, 16)
    p = dataclasses.replace(flight_params_for(cfg, fast=True), transonic_error_m=error_m)
    s = synthetic_flight(k, 16, FAST_FLIGHT_SEED, p)
    _, speed, _ = true_trajectory(k, p)
    lo, hi = p.transonic_band_mps
    band = np.flatnonzero((speed > lo) & (speed < hi))
    return run_model(build_constants(cfg), s.adc, s.acc), s, band


@pytest.mark.parametrize("rounding", ["floor", "half_up"])
@pytest.mark.parametrize("k", [4, 5, 6, 7, 8])
def test_kalman_baro_transonic_flight_declares_apogee_without_lockout(k, rounding):
    """kalman_baro never sets MACH_LOCKOUT and declares apogee after the transonic band; the 60 m transonic
    barometer error (gated for GATE_N samples, then absorbed) moves the detection by at most 0.15 s against the
    same flight without it (measured floor: 1, 1, 2, 2, 29 samples at k = 4..8); for k >= 5 the detection is
    within 0.5 s of the true apogee (measured +0.31, +0.02, -0.02, +0.08 s). k = 4 is excluded from the truth
    window: at 16 samples/s the default R/q = 50,000 is so slow that the velocity overshoots and undershoots
    (3.5 s early with or without the transonic error; a tuning limit, docs/firmware-spec.md History)."""
    tr, s, band = _fast_flight("kalman_baro", k, rounding)
    assert band.size > 0
    ev = tr.column("EVENTS")
    assert not (ev & EVENT_BITS["MACH_LOCKOUT"]).any()
    apogee = tr.first_event("APOGEE")
    assert apogee > band.max(), (apogee, band.max())
    clean, _, _ = _fast_flight("kalman_baro", k, rounding, error_m=0.0)
    assert abs(apogee - clean.first_event("APOGEE")) * 2.0 ** -k <= 0.15
    if k >= 5:
        assert abs(apogee - s.truth["apogee_sample"]) * 2.0 ** -k <= 0.5, (apogee, s.truth)


@pytest.mark.parametrize("rounding", ["floor", "half_up"])
@pytest.mark.parametrize("k", [5, 6, 7, 8])
def test_kalman_accel_transonic_flight_locks_out_the_barometer_and_rebases(k, rounding):
    """Spec §6 step 4 (issue 20, issue 30): kalman_accel does not use the barometer (MACH_LOCKOUT) on exactly the
    samples after liftoff whose predicted X2 exceeds MACH_VLO or whose previous sample left PHASE in BOOST (the
    thrust guard) and the MACH_N settling samples after the last of them (one
    contiguous run covering the transonic band); meanwhile the filter integrates the accelerometer (X2 keeps
    changing); on the next sample X1 is re-based on the barometer's altitude (X1 = alt(adc) + the accelerometer
    correction) with no velocity step; apogee comes after, within 0.25 s of the true apogee and within 0.05 s of
    the same flight without the transonic error."""
    tr, s, band = _fast_flight("kalman_accel", k, rounding)
    ev = tr.column("EVENTS")
    locked = np.flatnonzero(ev & EVENT_BITS["MACH_LOCKOUT"])
    assert locked.size >= 2 and np.all(np.diff(locked) == 1), locked
    assert locked.min() <= band.min() and locked.max() >= band.max(), (locked, band.min(), band.max())
    x1, x2, x3 = tr.column("X1"), tr.column("X2"), tr.column("X3")
    consts = build_constants(tr_cfg := _fast_cfg("kalman_accel", k, rounding))
    from firmware_model.spec.fixed import rs

    pred = x2[:-1] + rs(x3[:-1], consts.K, rounding)
    lift = np.flatnonzero(ev & EVENT_BITS["LIFTOFF"]).min()
    # issue 30, thrust guard: also every sample whose previous sample left PHASE in BOOST, and every pad sample
    # (after the calibration) whose raw accelerometer reads more than A_COAST above 1 g
    prev = tr.column("PHASE")[:-1]
    acc0 = tr.column("ACC0")[1:]
    a = np.array([mulg(int(v) - int(z), consts.gains["ACC_G"], rounding) for v, z in zip(s.acc[1:], acc0)])
    calibrated = tr.column("CAL")[:-1] == 1 << consts.CAL_P
    thrust = calibrated & ((prev == 1) | ((prev == 0) & (a > consts.A_COAST)))
    fast = np.flatnonzero(((pred > consts.MACH_VLO) & (np.arange(1, len(x2)) > lift)) | thrust) + 1
    assert fast.min() <= lift + 1                                 # from the sample after liftoff on, or before
    want = np.arange(fast.min(), fast.max() + consts.MACH_N)      # the fast samples, then MACH_N - 1 settling
    assert np.array_equal(locked, want), (locked[[0, -1]], want[[0, -1]])
    assert len(np.unique(x2[locked])) > locked.size // 2      # velocity is not frozen
    r = locked.max() + 1                                      # the barometer is back: the re-base sample
    h = _alt_int(consts, int(s.adc[r]), rounding)
    acc0 = int(tr.column("ACC0")[r])
    e2 = mulg(int(s.acc[r]) - acc0, consts.gains["ACC_G"], rounding) - int(x3[r - 1])
    assert int(x1[r]) == h + mulg(e2, consts.gains["G12"], rounding), (x1[r], h)   # X1 = h + the accel correction
    assert not ev[r] & EVENT_BITS["BARO_REJECT"] and tr.column("LOCK")[r] == 0
    step = np.abs(np.diff(x2[r - 8:r + 2**k].astype(np.int64))).max()
    assert step <= 3 * 256, step          # no velocity step at the return (the accelerometer's <= 3 m/s per sample)
    apogee = tr.first_event("APOGEE")
    assert apogee > locked.max()
    assert abs(apogee - s.truth["apogee_sample"]) * 2.0 ** -k <= 0.25, (apogee, s.truth)
    clean, _, _ = _fast_flight("kalman_accel", k, rounding, error_m=0.0)
    assert abs(apogee - clean.first_event("APOGEE")) * 2.0 ** -k <= 0.05
    assert tr_cfg.program == "kalman_accel"


def _alt_int(consts, adc: int, rounding: str) -> int:
    """alt(adc) of spec §2a, written out here with exact Python ints."""
    from firmware_model.spec.fixed import rs

    t, sh = consts.ALT_TABLE, consts.ALT_SHIFT
    i, f = adc >> sh, adc & ((1 << sh) - 1)
    return t[i] + int(rs((t[i + 1] - t[i]) * f, sh, rounding))


def _fast_cfg(program, k, rounding):
    from firmware_model.vectors.cases import case_config

    return case_config(program, rounding, k, 16)


# ---------------------------------------------------------------------------------------------------- issue 20
def _dip_case(program: str, k: int, rounding: str):
    """A supersonic flight with a 400 m transonic dip (tests/support/transonic.py) under the vectors' case sensor."""
    from firmware_model.model.streams import flight_params_for
    from firmware_model.vectors.cases import case_config
    from tests.support.transonic import DipFlight, dip_stream

    cfg = case_config(program, rounding, k, 16)
    f = DipFlight(k=k, boost_g=12.0, burn_s=3.5, drag_per_m=0.0002, dip_m=400.0, dip_s=1.5, jump_m=150.0,
                  burst_m=50.0, burst_at=0.1, seed=k)
    s = dip_stream(f, flight_params_for(cfg))
    return build_constants(cfg), s["adc"], s["acc"]


@pytest.mark.parametrize("program", ["kalman_baro", "kalman_accel"])
@pytest.mark.parametrize("k", [5, 7])
@pytest.mark.parametrize("rounding", ["floor", "half_up"])
def test_kalman_bound_on_supersonic_dip_flights(program, k, rounding):
    """The switched bound (re-derived for issue 20: no barometer row while locked out, the re-base sample's X1
    from the table) holds on a supersonic flight with a 400 m transonic dip, a jump and a noise burst, through the
    Mach lockout and the re-base (kalman_accel, half_up, k = 5: both inside the compared samples)."""
    consts, adc, acc = _dip_case(program, k, rounding)
    fm = mirror(consts, adc, acc)
    ratio = _check_bound(consts, adc, acc, fm=fm)
    assert ratio.max() > 0.005
    if program == "kalman_accel":
        tr = run_model(consts, adc, acc)
        lock = tr.column("LOCK")
        back = np.flatnonzero((lock[:-1] == 1) & (lock[1:] == 0)) + 1
        differ = np.flatnonzero(lock != fm.column("LOCK").astype(np.int64))
        assert back.size
        if rounding == "half_up" and k == 5:
            # the end of the lockout (X2 back to MACH_VLO) may differ by a sample between the runs (allowed: within
            # the bound; floor's velocity bias, ~1 m/s here, docs/numerics.md, makes it likely), which ends the
            # comparison before the re-base; on this flight with half_up at k = 5 and 6 it does not (measured:
            # first lockout difference at 1096 of 1159 at k = 7, at 245 of 260 with floor at k = 5)
            assert differ.size == 0 or differ[0] > back[0], (back, differ[:3])


def test_bound_has_teeth_a_wrong_settling_time_breaks_it():
    """An integer model whose Mach lockout settles one sample longer (MACH_N + 1, an off-by-one in a port) fails
    the check: the lockout decisions differ where the velocity is far from MACH_VLO."""
    consts, adc, acc = _dip_case("kalman_accel", 6, "half_up")
    _check_pair(consts, consts, adc, acc)
    with pytest.raises(AssertionError):
        _check_pair(dataclasses.replace(consts, MACH_N=consts.MACH_N + 1), consts, adc, acc)
    with pytest.raises(AssertionError):      # and a Mach threshold 10 m/s off
        _check_pair(dataclasses.replace(consts, MACH_VLO=consts.MACH_VLO + 2560), consts, adc, acc)


def _kernels_variant(old: str, new: str):
    """A plain-Python copy of the integer model's kernels with one piece of source replaced (a porting bug)."""
    import types
    from pathlib import Path

    import firmware_model.model.kernels as mk

    src = Path(mk.__file__).read_text()
    assert src.count(old) == 1, old
    mod = types.ModuleType("kernels_variant")
    mod.FORCE_PURE = True
    exec(compile(src.replace(old, new), "kernels_variant", "exec"), mod.__dict__)
    return mod


class _VariantTrace:
    """The words of a kernels variant in the shape _check_bound reads (a ModelTrace without the wrap report)."""

    def __init__(self, kern, consts, adc, acc):
        from firmware_model.model.run import _run_kernels
        from firmware_model.model.trace import word_names

        init, words, first, _ = _run_kernels(kern, consts, np.atleast_2d(adc), np.atleast_2d(acc))
        self.names, self.words, self.init_words = word_names(consts.program), words[0], init[0]
        self.first_wrap, self.wrap_word = int(first[0]), ""

    def column(self, name):
        return self.words[..., self.names.index(name)]


@pytest.mark.parametrize("bug", ["filtered X3 while locked out", "no re-base"])
def test_bound_has_teeth_a_wrong_lockout_or_rebase_breaks_it(bug, monkeypatch):
    """The locked rows (X3 = a, X1/X2 predicted) and the re-base row of the switched bound have teeth: a model that
    keeps correcting X3 with the filter gains while locked out, or that feeds the returning barometer through the
    gate instead of re-basing X1, fails the check on a supersonic dip flight with a 3 % accelerometer scale error
    (the stale offset a lockout accumulates); the correct kernels pass it."""
    import tests.model.test_kalman as me

    consts, adc, acc = _dip_case("kalman_accel", 5, "half_up")
    acc = acc.copy()
    pad = 16
    a0 = int(np.round(acc[:pad].mean()))
    acc[pad:] = np.clip(np.rint(a0 + (acc[pad:] - a0) * 1.03), -32768, 32767).astype(np.int64)
    _check_bound(consts, adc, acc)
    if bug == "no re-base":
        kern = _kernels_variant("                st[LOCK] = 0\n                rebase = True",
                                "                st[LOCK] = 0")
    else:
        kern = _kernels_variant("    if locked:\n        x3 = a\n    else:", "    if False:\n        x3 = a\n    else:")
    monkeypatch.setattr(me, "run_model", lambda c, a, b: _VariantTrace(kern, c, a, b))
    with pytest.raises(AssertionError):
        _check_bound(consts, adc, acc)


def _clip_case(k: int, rounding: str):
    """A 30 g, 1.4 s boost (the +-16 g accelerometer at its rail for the whole burn, Mach ~1.2) with a 400 m dip, a
    jump and a noise burst, then a long coast whose drag reading falls below the clip drag bound (g/4 at ~110 m/s)."""
    from firmware_model.model.streams import flight_params_for
    from firmware_model.vectors.cases import case_config
    from tests.support.transonic import DipFlight, dip_stream

    cfg = case_config("kalman_accel", rounding, k, 16)
    f = DipFlight(k=k, boost_g=30.0, burn_s=1.4, drag_per_m=0.0002, dip_m=400.0, dip_s=1.5, jump_m=150.0,
                  burst_m=50.0, burst_at=0.1, seed=k)
    s = dip_stream(f, flight_params_for(cfg))
    return build_constants(cfg), s["adc"], s["acc"]


@pytest.mark.parametrize("k, rounding", [(5, "floor"), (5, "half_up"), (6, "half_up"), (7, "half_up")])
def test_kalman_bound_through_the_clip_velocity_rebase(k, rounding):
    """The switched bound with the clip re-base term (X2 += rs(E0, K): the window's innovation error 2^-K plus
    rho(K)) holds on a clipped supersonic flight, and the re-base sample is inside the compared samples; the
    re-base removes most of the velocity the rail cut off (the integer X2 moves by more than 100 m/s there).
    (With floor at k = 7 on this flight the two runs lift off a sample apart, an allowed ambiguity that ends the
    comparison before the re-base: measured, LIFTOFF 91 / 90, ACC_CLIP 122 / 121; so that case is not listed.)"""
    consts, adc, acc = _clip_case(k, rounding)
    assert (acc == 32767).sum() >= consts.CLIP_N * 4
    fm = mirror(consts, adc, acc)
    tr = run_model(consts, adc, acc)
    clear = tr.first_event("CLIP_CLEAR")
    assert tr.first_event("ACC_CLIP") > 0 and clear > 0
    differ = np.flatnonzero((tr.column("CLP") != fm.column("CLP").astype(np.int64))
                            | (tr.column("LOCK") != fm.column("LOCK").astype(np.int64)))
    assert differ.size == 0 or differ[0] > clear, (clear, differ[:3])
    _check_bound(consts, adc, acc, fm=fm)
    dv = (tr.column("X2")[clear] - tr.column("X2")[clear - 1]) / 256.0
    assert dv > 100.0, dv


@pytest.mark.parametrize("bug", ["half the re-base", "no velocity re-base"])
def test_bound_has_teeth_a_wrong_clip_rebase_breaks_it(bug, monkeypatch):
    """The clip re-base row has teeth: a model that adds half the window's drift (rs(E0, K + 1), a shift off by
    one in a port) or none fails the check on the clipped flight; the correct kernels pass it."""
    import tests.model.test_kalman as me

    consts, adc, acc = _clip_case(6, "half_up")
    _check_bound(consts, adc, acc)
    old = "                    x2 = x2 + rs(st[E0], K, rnd)\n"
    new = ("                    x2 = x2 + rs(st[E0], K + 1, rnd)\n" if bug == "half the re-base"
           else "                    x2 = x2 + 0\n")
    kern = _kernels_variant(old, new)
    monkeypatch.setattr(me, "run_model", lambda c, a, b: _VariantTrace(kern, c, a, b))
    with pytest.raises(AssertionError):
        _check_bound(consts, adc, acc)
