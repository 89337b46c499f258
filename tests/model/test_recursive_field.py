"""Field-ready logic of the recursive filter (docs/firmware-spec.md §5 steps 1, 3, 5, 6): pad calibration of ACC0,
the barometer rate gate, the accelerometer-clip latch and the apogee evidence after a clip.

* CPU == model on every word for streams that exercise the new branches (spikes, steps, a clipped accelerometer,
  a short pad), beside the generic hypothesis runs of tests/firmware/test_cpu_vs_model.py.
* Model vs float mirror (docs/numerics.md, "Recursive bound"): the gate reads raw inputs only, so model and mirror
  take the same gate decisions and the EST/EXT bound is unchanged; ACC0 is rs(SUMA, CAL_P) against the mirror's
  exact mean, so ``VEL_int - VEL_float = m * (mean - ACC0_int)`` after m velocity steps: in ``[0, m)`` (floor),
  ``(-m/2, m/2]`` (half_up). Each bound has a teeth test (a deliberate defect must break it).
* Behaviour: a single pressure spike after arming does not fire apogee (it does without the gate); after a clip a
  dip shorter than APO_N samples does not fire (it does without the clip).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_model.spec.config import BuildConfig
from firmware_model.spec.build_constants import build_constants
from firmware_model.model.run import run_model
from firmware_model.model.float_reference import mirror
from firmware_model.model.trace import EVENT_BITS
from tests.support.profiles import examples

FLOAT_SLACK = 1e-6
CLIP = EVENT_BITS["ACC_CLIP"]
REJECT = EVENT_BITS["BARO_REJECT"]


def assert_same(cfg: BuildConfig, adc: np.ndarray, acc: np.ndarray):
    """CPU (the assembly on isa) and the integer model on the same stream: equal on every word of every sample."""
    from firmware_model.firmware.assemble import build_firmware
    from firmware_model.firmware.harness import run_firmware

    build = build_firmware(cfg)
    cpu = run_firmware(build, adc, acc)
    model = run_model(build.consts, adc, acc)
    assert cpu.names == model.names
    assert np.array_equal(cpu.init_words, model.init_words), (cpu.init_words, model.init_words)
    if not np.array_equal(cpu.words, model.words):
        i, j = np.argwhere(cpu.words != model.words)[0]
        pytest.fail(f"sample {i} word {cpu.names[j]}: cpu {cpu.words[i].tolist()} != model {model.words[i].tolist()}; "
                    f"{cfg}; adc[:{i + 1}]={adc[:i + 1].tolist()}; acc[:{i + 1}]={acc[:i + 1].tolist()}")
    return cpu


def _consts(**kw: object):
    return build_constants(BuildConfig(program="recursive", **kw))  # type: ignore[arg-type]  # **kw of mixed BuildConfig field types


def _flight(k: int, seed: int = 7, **params):
    from firmware_model.model.streams import FlightParams, synthetic_flight

    return synthetic_flight(k, 16, seed, FlightParams(**params))


# ---------------------------------------------------------------------------------------------------- CPU == model
@st.composite
def _field_streams(draw: st.DrawFn):
    """A flight-like stream with spikes, steps and accelerometer samples at the rail (32767)."""
    n = draw(st.integers(20, 160))
    base = draw(st.integers(2000, 63000))
    slope = draw(st.integers(-40, 40))
    i = np.arange(n)
    adc = np.clip(base + slope * i + draw(st.integers(-3, 3)) * (i % 3), 0, 65535).astype(np.int64)
    for _ in range(draw(st.integers(0, 4))):                    # spikes (1-3 samples) and steps
        at = draw(st.integers(0, n - 1))
        width = draw(st.sampled_from((1, 2, 3, n)))
        adc[at:at + width] = np.clip(adc[at:at + width] + draw(st.integers(-30000, 30000)), 0, 65535)
    boost = draw(st.integers(0, n))
    acc = np.full(n, 2048, dtype=np.int64)
    acc[:boost] = draw(st.sampled_from((2048, 20480, 32767)))
    acc[boost:] = draw(st.integers(-4000, 2048))
    for _ in range(draw(st.integers(0, 3))):
        acc[draw(st.integers(0, n - 1))] = draw(st.sampled_from((32767, 32766, -32768)))
    return adc, acc


@settings(max_examples=examples(25), deadline=None)
@given(k=st.sampled_from((4, 5, 7)), rounding=st.sampled_from(("floor", "half_up")), cal_p=st.sampled_from((0, 1, 3)),
       apo_s=st.sampled_from((0.06, 0.3)), streams=_field_streams())
def test_cpu_equals_model_spikes_steps_and_clipped_accelerometer(k, rounding, cal_p, apo_s, streams):
    adc, acc = streams
    cfg = BuildConfig(program="recursive", k=k, rounding=rounding, cal_p=cal_p, apogee_hold_s=apo_s,
                      liftoff_mps=1.0, gate_mps=2.0, baro_rate_mps=50.0)
    assert_same(cfg, adc, acc)


def test_cpu_equals_model_on_a_clipped_flight_with_spikes_sets_every_recursive_bit():
    """A synthetic 20 g boost (the accelerometer at its rail), spikes on the way up and near apogee: LIFTOFF,
    ACC_CLIP, GATE_HIGH, ARMED, BARO_REJECT and APOGEE all occur, and CPU == model on every word."""
    s = _flight(5, boost_accel_g=20.0, burn_s=0.5)
    adc = s.adc.copy()
    top = s.truth["apogee_sample"]
    adc[top - 40] += 5000
    adc[top - 3] += 3000
    cfg = BuildConfig(program="recursive", k=5)
    cpu = assert_same(cfg, adc, s.acc)
    seen = int(np.bitwise_or.reduce(cpu.column("EVENTS")))
    for bit in ("LIFTOFF", "ACC_CLIP", "GATE_HIGH", "ARMED", "BARO_REJECT", "APOGEE"):
        assert seen & EVENT_BITS[bit], bit


# ---------------------------------------------------------------------------------------------------- model vs mirror
def _vel_bound_ok(consts, adc, acc) -> tuple[bool, float, float]:
    """(within, min, max) of (VEL_int - VEL_float) / m over the samples after calibration (m velocity steps)."""
    tr = run_model(consts, adc, acc)
    fm = mirror(consts, adc, acc)
    d = tr.column("VEL") - fm.column("VEL")
    ncal = 1 << consts.CAL_P
    m = np.arange(1, len(adc) + 1) - ncal                # velocity steps so far (0 during calibration)
    live = m > 0
    assert np.all(np.abs(d[~live]) <= FLOAT_SLACK)
    r = d[live] / m[live]
    lo, hi = (0.0, 1.0) if consts.ROUND == 0 else (-0.5, 0.5)
    ok = bool(r.min() >= lo - FLOAT_SLACK and r.max() < hi + FLOAT_SLACK and
              (consts.ROUND == 0 or r.max() <= hi + FLOAT_SLACK))
    return ok, float(r.min()), float(r.max())


@settings(max_examples=examples(40, ci=10), deadline=None)
@given(k=st.integers(4, 8), rounding=st.sampled_from(("floor", "half_up")), cal_p=st.integers(0, 8),
       seed=st.integers(0, 2 ** 32 - 1), n_extra=st.integers(1, 300))
def test_velocity_within_derived_bound_of_float_mirror(k, rounding, cal_p, seed, n_extra):
    consts = _consts(k=k, rounding=rounding, cal_p=cal_p)
    rng = np.random.default_rng(seed)
    n = (1 << cal_p) + n_extra
    acc = rng.integers(-32768, 32768, size=n)
    adc = rng.integers(0, 65536, size=n)
    ok, lo, hi = _vel_bound_ok(consts, adc, acc)
    assert ok, (lo, hi)
    tr, fm = run_model(consts, adc, acc), mirror(consts, adc, acc)
    for name in ("EST", "EXT"):                              # the gate takes the same decisions in both
        d = tr.column(name) - fm.column(name)
        blo, bhi = (0.0, 2.0 ** consts.S - 1) if rounding == "floor" else (-(2.0 ** (consts.S - 1)),
                                                                            2.0 ** (consts.S - 1))
        assert d.min() >= blo - FLOAT_SLACK and d.max() <= bhi + FLOAT_SLACK, (name, d.min(), d.max())
    assert np.array_equal(tr.column("REJ"), fm.column("REJ").astype(np.int64))
    assert np.array_equal(tr.column("ZL"), fm.column("ZL").astype(np.int64))


def test_velocity_bound_is_reached_and_has_teeth():
    """The floor bound is approached (a pad mean of x.97 makes every step add 0.97 to the difference) and a
    defect breaks it: the integer model built with a pad average over half the samples (CAL_P - 1) against the
    mirror of the real build."""
    consts = _consts(k=5, cal_p=3)
    acc = np.full(400, 2048, dtype=np.int64)
    acc[:8] = [2048, 2049, 2049, 2049, 2049, 2049, 2049, 2049]   # mean 2048.875, floor 2048
    adc = np.full(400, 40000, dtype=np.int64)
    ok, lo, hi = _vel_bound_ok(consts, adc, acc)
    assert ok and hi > 0.85
    tr = run_model(dataclasses.replace(consts, CAL_P=2), adc, acc)            # the defect
    fm = mirror(consts, adc, acc)
    m = np.arange(1, 401) - 8
    r = (tr.column("VEL") - fm.column("VEL"))[m > 0] / m[m > 0]
    assert r.min() < -FLOAT_SLACK or r.max() >= 1.0


def test_gate_decisions_identical_and_a_defect_breaks_the_est_bound():
    """A step of exactly E_GATE counts is used, E_GATE + 1 is held out: model and mirror agree; a mirror whose gate
    is one count wider (the defect) uses the held-out samples and leaves the EST bound."""
    consts = _consts(k=5, baro_sign=1)
    g = consts.E_GATE
    adc = np.array([30000] * 40 + [30000 + g] * 40 + [30000 + 2 * g + 1] * 3 + [30000 + g] * 60, dtype=np.int64)
    acc = np.zeros_like(adc)
    tr, fm = run_model(consts, adc, acc), mirror(consts, adc, acc)
    rej = tr.column("EVENTS") & REJECT
    assert not rej[:80].any() and rej[80:83].all() and not rej[83:].any()
    d = tr.column("EST") - fm.column("EST")
    assert d.min() >= 0 and d.max() <= 2 ** consts.S - 1
    wide = mirror(dataclasses.replace(consts, E_GATE=g + 1), adc, acc)
    d = tr.column("EST") - wide.column("EST")
    assert d.min() < -FLOAT_SLACK or d.max() > 2 ** consts.S - 1


# ---------------------------------------------------------------------------------------------------- behaviour
@pytest.mark.parametrize("k", [5, 6, 7])
def test_single_pressure_spike_after_arming_does_not_fire_apogee(k):
    """A one-sample pressure spike (3000 counts, altitude down: as on 2012-04-07-serial-882) one second before the
    true apogee fires APOGEE at the spike without the gate (gate_sigmas = 0) and not with it, where the apogee
    sample is within 2 samples of the spike-free stream's."""
    s = _flight(k)
    top = s.truth["apogee_sample"]
    clean = run_model(_consts(k=k), s.adc, s.acc)
    armed = clean.first_event("ARMED")
    at = top - 2 ** k
    assert 0 <= armed < at
    adc = s.adc.copy()
    adc[at] += 3000
    gated = run_model(_consts(k=k), adc, s.acc)
    open_ = run_model(_consts(k=k, gate_sigmas=0.0), adc, s.acc)
    assert open_.first_event("APOGEE") == at
    assert abs(gated.first_event("APOGEE") - clean.first_event("APOGEE")) <= 2
    assert gated.column("EVENTS")[at] & REJECT


@pytest.mark.parametrize("k", [5, 7])
def test_after_a_clip_a_short_dip_does_not_fire_apogee(k):
    """A dip of the barometer (inside the rate gate) shorter than APO_N samples at the true apogee (before the lagging
    EST peaks): without a clip it fires APOGEE (one sample of evidence); after an accelerometer clip it does not,
    and the apogee is declared later, within 2 APO_N samples of the dip-free unclipped run's (barometer noise
    can reset the evidence count once or twice)."""
    s = _flight(k)
    consts = _consts(k=k, apogee_hold_s=0.3)
    clean = run_model(consts, s.adc, s.acc)
    apogee = clean.first_event("APOGEE")
    at = s.truth["apogee_sample"]
    assert clean.first_event("ARMED") < at < apogee
    n = consts.APO_N // 2
    adc = s.adc.copy()
    adc[at:at + n] += consts.E_GATE * 2 // 3          # pressure up (altitude down), inside the gate
    dipped = run_model(consts, adc, s.acc)
    assert not (dipped.column("EVENTS")[at:at + n] & REJECT).any()
    assert at <= dipped.first_event("APOGEE") < at + n
    acc = s.acc.copy()
    lift = clean.first_event("LIFTOFF")
    shock = run_model(consts, adc, np.where(np.arange(len(acc)) == lift + 1, 32767, acc))
    assert not shock.column("EVENTS").max() & CLIP      # one sample at the rail (a shock) is not a clip
    assert shock.first_event("APOGEE") == dipped.first_event("APOGEE")
    acc[lift + 1:lift + 1 + consts.CLIP_N] = 32767      # CLIP_N samples at the rail during the boost
    clipped = run_model(consts, adc, acc)
    ev = clipped.column("EVENTS")
    assert not ev[lift + consts.CLIP_N - 1] & CLIP and ev[lift + consts.CLIP_N] & CLIP
    assert clipped.first_event("CLIP_CLEAR") < at       # the coast's drag reading is low long before apogee
    assert clipped.first_event("APOGEE") >= at + n
    assert clipped.first_event("APOGEE") <= apogee + 2 * consts.APO_N


@pytest.mark.parametrize("k", [5, 6, 7])
def test_lasting_pressure_step_after_arming_is_a_re_base_not_an_apogee(k):
    """A lasting pressure step (+300 counts, altitude down ~86 m, as a transonic step) between ARMED and the true
    apogee: without the gate it fires APOGEE at the step; with it the step is held out for GATE_N samples, then EST
    and EXT are re-based by it, and APOGEE comes within GATE_N + 2 samples of the step-free stream's."""
    s = _flight(k)
    consts = _consts(k=k)
    clean = run_model(consts, s.adc, s.acc)
    armed, apogee = clean.first_event("ARMED"), clean.first_event("APOGEE")
    at = (armed + s.truth["apogee_sample"]) // 2
    adc = s.adc.copy()
    adc[at:] += 300
    assert 300 > consts.E_GATE
    stepped = run_model(consts, adc, s.acc)
    open_ = run_model(_consts(k=k, gate_sigmas=0.0), adc, s.acc)
    assert at <= open_.first_event("APOGEE") <= at + 2
    ev = stepped.column("EVENTS")
    assert (ev[at:at + consts.GATE_N] & REJECT).all() and not ev[at + consts.GATE_N] & REJECT
    assert abs(stepped.first_event("APOGEE") - apogee) <= consts.GATE_N + 2
