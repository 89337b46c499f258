"""Supersonic test flights with the barometer errors of real transonic passages (docs/firmware-spec.md §6 step 4,
/work/shared/flights README "What real supersonic barometers look like"), written for the flight-logic tests of
issue 20 and independent of the simulator's own error model:

* a **dip**: the barometric altitude reads low by ``dip_m`` (100-800 m) for about ``dip_s`` (1-2 s) around each
  time the true speed passes Mach 1 (a raised-cosine bump centred on the crossing; the static port sees the
  pressure rise behind the shock);
* a **jump** when the shock passes the port: the reading then overshoots high by ``jump_m`` for 0.1 s;
* a **noise burst**: ``burst_m`` m rms (up to 200 m: the README's +-100-300 m) of extra barometer noise for 0.3 s at
  a staging-like time, in the first 40 % of the ascent. (Not later: a 60 m rms burst 4.7 s before apogee, when the
  recursive filter is already armed by its accelerometer velocity gate, fires it -4.67 s early, measured; the
  README places bursts at staging and separation, and a barometer-only evidence rule cannot tell such a burst in
  the last seconds of coast from a descent.)

The trajectory is :func:`firmware_model.inputs._trajectory` (1-DOF: constant-thrust boost, gravity and quadratic
drag); the barometer and accelerometer are mapped to counts as :func:`firmware_model.inputs.synthetic_flight`
does, so the Kalman programs' altitude table (the vectors' case sensor) fits them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from firmware_model.model.streams import (ACC_MAX, ACC_MIN, MACH1_MPS, FlightParams, _trajectory, pressure_pa,
                                          transonic_dip_error)


@dataclass(frozen=True)
class DipFlight:
    """Parameters of one supersonic flight with transonic barometer errors (see the module docstring)."""

    k: int
    boost_g: float
    burn_s: float
    drag_per_m: float
    dip_m: float
    dip_s: float
    jump_m: float
    burst_m: float
    burst_at: float      # fraction of the time from ignition to apogee at which the noise burst starts
    seed: int


def dip_stream(f: DipFlight, params: FlightParams, pascal: bool = False) -> dict:
    """The (adc, acc) stream of ``f`` with ``params``' sensors (units_per_metre, baro_sign, pad_fraction, noise,
    accelerometer scale); also the truth: ``apogee_sample``, ``peak_mps``, the samples of the dips
    (``dip_samples``) and the barometric error (m) per sample (``error_m``). ``pascal``: the barometer word is the
    pressure in integer pascals (a sea-level pad, 3 Pa rms noise, clipped to the MS5607's 1,000..120,000 Pa)."""
    p = FlightParams(boost_accel_g=f.boost_g, burn_s=f.burn_s, drag_per_m=f.drag_per_m, after_apogee_s=2.0,
                     units_per_metre=params.units_per_metre, baro_sign=params.baro_sign,
                     pad_fraction=params.pad_fraction, baro_sigma=params.baro_sigma,
                     accel_counts_per_mps2=params.accel_counts_per_mps2, accel_sigma=params.accel_sigma)
    dt = 2.0 ** -f.k
    h, a, apogee_t = _trajectory(p, dt, 8)
    n = h.shape[0]
    t = np.arange(n) * dt
    v = np.gradient(h, dt)
    err = transonic_dip_error(t, v, f.dip_m, f.dip_s, f.jump_m)
    above = v > MACH1_MPS
    cross = list(np.flatnonzero(above[1:] != above[:-1]) + 1) or [int(np.argmax(v))]
    dips = [np.flatnonzero(np.abs(t - t[c]) < f.dip_s / 2) for c in cross]
    rng = np.random.default_rng(f.seed)
    t0 = p.pad_s + f.burst_at * (apogee_t - p.pad_s)
    burst = (t >= t0) & (t < t0 + 0.3)
    err += np.where(burst, rng.standard_normal(n) * f.burst_m, 0.0)
    full = 65535
    p_pad = float(pressure_pa(0.0))
    counts_per_pa = p.units_per_metre / (p_pad - float(pressure_pa(1.0)))
    drop = (p_pad - pressure_pa(h + err)) * counts_per_pa
    baro = p.pad_fraction * full + p.baro_sign * drop + rng.standard_normal(n) * p.baro_sigma
    adc = np.clip(np.rint(baro), 0, full).astype(np.int64)
    if pascal:
        adc = np.clip(np.rint(pressure_pa(h + err) + rng.standard_normal(n) * 3.0), 1000, 120000).astype(np.int64)
    acc_f = (a + 9.80665) * p.accel_counts_per_mps2 + rng.standard_normal(n) * p.accel_sigma
    acc = np.clip(np.rint(acc_f), ACC_MIN, ACC_MAX).astype(np.int64)
    return {"adc": adc, "acc": acc, "apogee_sample": int(math.floor(apogee_t / dt)), "peak_mps": float(v.max()),
            "dip_samples": np.concatenate(dips), "error_m": err, "pad_s": p.pad_s}


def _draw_dip_flight(draw, k: st.SearchStrategy[int], boost: tuple[float, float], min_burn_s: float) -> DipFlight:
    """One flight of the strategies below: a boost of ``boost`` g (uniform) to Mach 1.05-2.0, burning at least
    ``min_burn_s``, with the barometer errors of the module docstring."""
    boost_g = draw(st.floats(*boost), label="boost_g")
    mach = draw(st.floats(1.05, 2.0), label="target_mach")
    drag = draw(st.floats(0.0001, 0.0004), label="drag_per_m")
    # burn time to reach the target speed, with the drag at the target speed subtracted from the thrust
    net = boost_g * 9.80665 - drag * (mach * MACH1_MPS) ** 2 * 0.5
    burn = max(min_burn_s, min(8.0, mach * MACH1_MPS / max(net, 20.0)))
    return DipFlight(k=draw(k, label="k"), boost_g=boost_g, burn_s=burn, drag_per_m=drag,
                     dip_m=draw(st.floats(100.0, 800.0), label="dip_m"),
                     dip_s=draw(st.floats(1.0, 2.0), label="dip_s"),
                     jump_m=draw(st.floats(0.0, 300.0), label="jump_m"),
                     burst_m=draw(st.floats(0.0, 200.0), label="burst_m"),
                     burst_at=draw(st.floats(0.02, 0.4), label="burst_at"),
                     seed=draw(st.integers(0, 2**31 - 1), label="seed"))


@st.composite
def dip_flights(draw, k: st.SearchStrategy[int] = st.sampled_from((5, 6, 7))) -> DipFlight:
    """Hypothesis strategy: supersonic 1-DOF flights (peak Mach ~1-2 at 8-14 g, so the +-16 g accelerometer does
    not clip) with a 100-800 m dip of 1-2 s around each Mach 1 crossing, a 0-300 m jump after it and a noise
    burst of 0-200 m rms in the first 40 % of the ascent (staging)."""
    return _draw_dip_flight(draw, k, (8.0, 14.0), 0.0)


@st.composite
def clipped_dip_flights(draw, k: st.SearchStrategy[int] = st.sampled_from((5, 6, 7))) -> DipFlight:
    """Hypothesis strategy: supersonic flights of :func:`dip_flights`' kind whose boost (20-50 g) exceeds the
    +-16 g accelerometer for the whole burn (0.3 s or more): the integrated velocity then misses up to ~34 g x the
    burn time, the case of docs/firmware-spec.md History "Clipped accelerometer"."""
    return _draw_dip_flight(draw, k, (20.0, 50.0), 0.3)
