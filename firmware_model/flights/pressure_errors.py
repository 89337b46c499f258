"""Static-pressure errors applied to a flight record (sensor-side effects, before any ADC model).

* :func:`transonic_pressure_error`: the Mach-transition error of Schultz n.d. ("a step increase in pressure altitude
  when going above Mach 1 and a step decrease when dropping below"): while the rocket flies above the switching
  Mach number the barometer reads the standard pressure of an altitude ``altitude_step_m`` higher than the true
  one. Positive ``altitude_step_m`` (the default, +60 m) is the seed's sign: the pressure reads *low* above Mach 1
  and steps back *up* when the rocket slows through Mach 1, which makes the pressure altitude drop by the step
  while the rocket still climbs -- the dangerous direction for a barometric apogee detector. A negative value
  models the opposite sign. The seed gives no magnitude: 60 m (about 200 ft) is our choice, stated in
  docs/flights-sim.md; ``shape`` "step" switches instantly, "ramp" blends linearly over ``width_mach``, and
  ``mach_on``/``mach_off`` give hysteresis (on while accelerating through ``mach_on``, off when slowing through
  ``mach_off``).
* :func:`pressure_spikes`: isolated single-sample outliers (a sensor glitch or a bad ADC read), for robustness
  tests: each chosen sample's pressure is offset by +-``magnitude_pa``.

Both take and return a :class:`FlightRecord` (so they apply to 1-DOF and RocketPy flights alike), leave every
other field untouched and append what they did to ``provenance["effects"]``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from firmware_model.flights.record import FlightRecord
from firmware_model.flights.sim1dof import mach_of
from firmware_model.runtime.errors import UserError
from firmware_model.spec import atmosphere as atm

#: Default transonic step in pressure altitude (m, positive = reads higher above Mach 1; Schultz n.d.'s sign).
DEFAULT_TRANSONIC_STEP_M: float = 60.0


def _with_effect(record: FlightRecord, pressure: np.ndarray, effect: dict) -> FlightRecord:
    prov = dict(record.provenance)
    prov["effects"] = list(prov.get("effects", [])) + [effect]
    return replace(record, pressure_pa=pressure, provenance=prov)


def supersonic_fraction(mach: np.ndarray, mach_on: float = 1.0, mach_off: float = 1.0, shape: str = "step",
                        width_mach: float = 0.04) -> np.ndarray:
    """How much of the step is applied at each sample (0..1). "step": 1 from the first sample at or above
    ``mach_on`` (while not already on) until the first later sample below ``mach_off``; a flight can switch on
    and off more than once. "ramp": ``clip((M - (M_switch - width/2)) / width, 0, 1)`` with ``M_switch`` =
    ``mach_on`` while accelerating (dM/dt >= 0) and ``mach_off`` while slowing."""
    m = np.asarray(mach, dtype=np.float64)
    if shape == "step":
        out = np.zeros_like(m)
        on = False
        for i, x in enumerate(m):
            if not on and x >= mach_on:
                on = True
            elif on and x < mach_off:
                on = False
            out[i] = 1.0 if on else 0.0
        return out
    if shape == "ramp":
        if not width_mach > 0:
            raise UserError(f"transonic error: width_mach must be > 0, got {width_mach}")
        rising = np.gradient(m) >= 0 if m.size > 1 else np.ones_like(m, dtype=bool)
        centre = np.where(rising, mach_on, mach_off)
        return np.clip((m - (centre - width_mach / 2)) / width_mach, 0.0, 1.0)
    raise UserError(f"transonic error: unknown shape {shape!r} (step, ramp)")


def transonic_pressure_error(record: FlightRecord, mach: np.ndarray | None = None,
                             altitude_step_m: float = DEFAULT_TRANSONIC_STEP_M, mach_on: float = 1.0,
                             mach_off: float = 1.0, shape: str = "step", width_mach: float = 0.04) -> FlightRecord:
    """The record with the transonic static-pressure error applied (see the module doc). ``mach``: the Mach number
    per sample; default from the record's truth (|vertical velocity| / standard speed of sound at the site
    altitude + AGL: exact for vertical still-air flights; RocketPy records pass their own airspeed Mach)."""
    if mach is None:
        mach = mach_of(record)
    mach = np.asarray(mach, dtype=np.float64)
    if mach.shape != (record.n,):
        raise UserError(f"{record.name}: mach has shape {mach.shape}, record has ({record.n},)")
    frac = supersonic_fraction(mach, mach_on, mach_off, shape, width_mach)
    p = np.asarray(record.pressure_pa, dtype=np.float64)
    out = p.copy()
    sel = (frac > 0) & np.isfinite(p)
    if np.any(sel):
        out[sel] = atm.pressure_pa(atm.altitude_m(p[sel]) + altitude_step_m * frac[sel])
    on = np.nonzero(np.diff(np.concatenate([[0.0], (frac > 0).astype(float)])) > 0)[0]
    off = np.nonzero(np.diff(np.concatenate([(frac > 0).astype(float), [0.0]])) < 0)[0]
    t = np.asarray(record.time_s)
    effect = {"effect": "transonic_pressure_error", "altitude_step_m": altitude_step_m, "mach_on": mach_on,
              "mach_off": mach_off, "shape": shape, "width_mach": width_mach,
              "intervals_s": [[float(t[a]), float(t[b])] for a, b in zip(on, off)]}
    return _with_effect(record, out, effect)


def pressure_spikes(record: FlightRecord, times_s=None, count: int = 3, magnitude_pa: float = 1500.0,
                    sign: int = 0, seed: int = 0, window_s: tuple[float, float] | None = None) -> FlightRecord:
    """The record with single-sample pressure spikes: at the samples nearest ``times_s`` (or ``count`` samples drawn
    by ``numpy.random.default_rng(seed)`` inside ``window_s``, default from t = 0 to the end) the pressure is
    offset by ``sign * magnitude_pa`` (``sign`` 0: each spike's sign drawn at random). 1500 Pa is about 125 m of
    altitude at sea level: an obvious outlier that a robust detector must ride through."""
    t = np.asarray(record.time_s, dtype=np.float64)
    rng = np.random.default_rng(seed)
    if times_s is not None:
        idx = np.unique(np.clip(np.searchsorted(t, np.asarray(times_s, dtype=np.float64)), 0, t.size - 1))
    else:
        lo, hi = window_s if window_s is not None else (0.0, float(t[-1]))
        cand = np.nonzero((t >= lo) & (t <= hi))[0]
        if count < 0 or count > cand.size:
            raise UserError(f"{record.name}: cannot place {count} spikes in {cand.size} samples of {lo}..{hi} s")
        idx = np.sort(rng.choice(cand, size=count, replace=False))
    if sign not in (-1, 0, 1):
        raise UserError(f"pressure spikes: sign must be -1, 0 or +1, got {sign}")
    signs = rng.choice([-1.0, 1.0], size=idx.size) if sign == 0 else np.full(idx.size, float(sign))
    p = np.asarray(record.pressure_pa, dtype=np.float64).copy()
    p[idx] += signs * magnitude_pa
    if np.any(p[idx] <= 0):
        raise UserError(f"{record.name}: a pressure spike of {magnitude_pa} Pa makes the pressure <= 0")
    effect = {"effect": "pressure_spikes", "times_s": [float(x) for x in t[idx]],
              "delta_pa": [float(s * magnitude_pa) for s in signs], "seed": seed}
    return _with_effect(record, p, effect)
