"""Static-pressure errors applied to a flight record (sensor-side effects, before any ADC model).

* :func:`real_flight_errors` (**use this one**): what a barometer in a rocket really reads near and above Mach 1,
  from the signatures measured on the shared logs (docs/flights.md, "Barometer signatures of real flights") and
  the ranges of the unseen logs in ``../shared/flights/README.md``. Parameters in :class:`BaroErrorModel`
  (defaults and ranges in :data:`BARO_ERROR_RANGES`); five parts, each a function of the Mach number, the
  static pressure and the time since an event:

  1. *port error* ``cp_port * q``: the static port reads a fraction of the dynamic pressure ``q = 0.7 p M^2``
     too high at subsonic speed (prometheus: ~0.04 of q at Mach 0.45), fading out above the transonic range
     (``dip_mach_off``): the unseen supersonic logs dip for 1-2 s, not for the whole supersonic phase;
  2. *transonic dip* ``dip_cp * bump(M) * q``: an extra error that grows from ``dip_mach_on`` (0.8), peaks at
     ``dip_mach_peak`` (1.0) and is gone by ``dip_mach_off``; the pressure reads high, the barometric altitude
     falls by hundreds of metres while the rocket climbs (prometheus 320-330 m at Mach 0.97, piccard ~940 m at
     Mach 1.0, below the pad on piccard; unseen logs 100-800 m);
  3. *shock jump*: when the Mach number crosses ``jump_mach`` (either way: the shock passes the port) the
     altitude jumps by ``jump_m`` within ``jump_rise_s`` and relaxes with time constant ``jump_decay_s``
     (piccard +176 m in 0.3 s at Mach 1.0; unseen logs several hundred m);
  4. *noise bursts* of ``burst_sigma_m`` (altitude, Gaussian, seeded) for ``burst_s`` at staging/separation:
     at burnout and at the drogue deployment (unseen logs +-100-300 m);
  5. *ejection spike* at the deployment (apogee + the launch's drogue delay): ``ejection_m`` rising at once and
     decaying over ``ejection_s`` (measured +14..+135 m for 0.1-0.8 s; unseen logs tens to hundreds of m for
     0.1-0.5 s);
  6. *ram error in boost* (issue 30) ``ram_cp * ramp(M) * fade(t) * q``: the port reads a fraction of the
     dynamic pressure above static from the Mach onset ``ram_mach_on`` (smoothstep over
     :data:`RAM_ONSET_WIDTH_MACH`) until burnout, fading to nothing over ``ram_fade_s`` after it (the two unseen
     flights of issue 30: an EasyMega 86.0 -> 95.0 kPa at Mach ~1.5, -790 m apparent, and a TeleMega-class
     log 1.1 kPa over the pad at Mach ~1.1). Off by default (``ram_cp`` = 0), so the issue-20 scenarios keep
     their meaning; docs/flights-sim.md, "Ram error in boost", has the law and the arithmetic behind the range.

  Parts 3-5 are altitude offsets at the current altitude, turned into pressure through the standard atmosphere.
  The Mach number comes from the simulator (1-DOF: |v|/c; RocketPy: its airspeed Mach), so it works on both.
* :func:`transonic_pressure_error`: the **step (Kumar-style, not realistic)**: a pressure-altitude step of
  ``altitude_step_m`` (default +60 m, our choice; positive = the pressure reads low above Mach 1, the source's sign)
  while above Mach 1, from the one-line description of Schultz n.d. ("a step increase in pressure altitude when
  going above Mach 1 and a step decrease when dropping below"); ``shape`` "step" or "ramp" (over ``width_mach``),
  ``mach_on``/``mach_off`` hysteresis. Kept so the old scenarios keep their meaning and as a contrast; it
  resembles nothing measured.
* :func:`pressure_spikes`: isolated single-sample outliers (a sensor glitch or a bad ADC read), for robustness
  tests: each chosen sample's pressure is offset by +-``magnitude_pa``.

All take and return a :class:`FlightRecord` (so they apply to 1-DOF and RocketPy flights alike), leave every
other field untouched and append what they did to ``provenance["effects"]``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np

from firmware_model.flights.record import FlightRecord
from firmware_model.flights.simulate.sim1dof import mach_of
from firmware_model.runtime.errors import UserError
from firmware_model.spec import atmosphere as atm

#: Default of the step (Kumar-style, not realistic), in pressure altitude (m, positive = reads higher above Mach 1;
#: Schultz n.d.'s sign).
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


# ---------------------------------------------------------------------------------------------------------------
# Barometer errors of real flight
@dataclass(frozen=True)
class BaroErrorModel:
    """Parameters of :func:`real_flight_errors` (module doc). Altitudes in m (positive: the barometric altitude
    reads higher, i.e. the pressure reads low), times in s, pressure coefficients as fractions of ``q``."""

    cp_port: float = 0.04          # port error at every speed, fraction of q (pressure high)
    dip_cp: float = 0.06           # extra transonic error at its peak, fraction of q (pressure high)
    dip_mach_on: float = 0.8
    dip_mach_peak: float = 1.0
    dip_mach_off: float = 1.25
    jump_m: float = 200.0          # altitude jump when the shock passes the port (each crossing of jump_mach)
    jump_mach: float = 1.0
    jump_rise_s: float = 0.1
    jump_decay_s: float = 0.4
    burst_sigma_m: float = 50.0    # noise bursts at burnout (staging) and at the drogue deployment (separation)
    burst_s: float = 0.3
    ejection_m: float = 100.0      # ejection-charge spike at the deployment
    ejection_s: float = 0.3
    ram_cp: float = 0.0            # ram error in boost (issue 30), fraction of q (pressure high); 0 = off
    ram_mach_on: float = 0.7       # Mach at which it sets in (full RAM_ONSET_WIDTH_MACH above)
    ram_fade_s: float = 0.2        # after burnout it fades to 0 over this long (0: gone at burnout)

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not np.isfinite(v):
                raise UserError(f"barometer error model: {f.name} must be finite, got {v!r}")
        for name in ("jump_rise_s", "jump_decay_s", "burst_s", "ejection_s"):
            if getattr(self, name) <= 0:
                raise UserError(f"barometer error model: {name} must be > 0, got {getattr(self, name)!r}")
        if self.ram_cp < 0 or self.ram_fade_s < 0 or self.ram_mach_on <= 0:
            raise UserError("barometer error model: need ram_cp >= 0, ram_fade_s >= 0, ram_mach_on > 0, got "
                            f"{self.ram_cp!r}, {self.ram_fade_s!r}, {self.ram_mach_on!r}")
        if self.burst_sigma_m < 0:
            raise UserError(f"barometer error model: burst_sigma_m must be >= 0, got {self.burst_sigma_m!r}")
        if not self.dip_mach_on < self.dip_mach_peak < self.dip_mach_off:
            raise UserError("barometer error model: need dip_mach_on < dip_mach_peak < dip_mach_off, got "
                            f"{self.dip_mach_on}, {self.dip_mach_peak}, {self.dip_mach_off}")

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


#: Plausible range of each parameter (what scenarios and the hypothesis strategy draw from), with its source:
#: the shared logs (docs/flights.md) and the unseen logs of ../shared/flights/README.md.
BARO_ERROR_RANGES: dict[str, tuple[float, float]] = {
    "cp_port": (0.0, 0.06),          # prometheus ~0.04 of q at Mach 0.45
    "dip_cp": (0.02, 0.10),          # totals near Mach 1: prometheus ~0.06, piccard ~0.15 of q; unseen 100-800 m
    "dip_mach_on": (0.7, 0.9),
    "dip_mach_peak": (0.95, 1.05),
    "dip_mach_off": (1.15, 1.5),
    "jump_m": (-400.0, 400.0),       # piccard +176 m; unseen "several hundred metres"
    "jump_mach": (0.95, 1.05),
    "jump_rise_s": (0.03, 0.3),      # "in a few samples"; piccard 0.3 s
    "jump_decay_s": (0.2, 1.0),      # piccard back on the dip after ~0.8 s
    "burst_sigma_m": (10.0, 120.0),  # shared logs <= 22 m; unseen +-100-300 m peaks
    "burst_s": (0.1, 0.6),
    "ejection_m": (-300.0, 300.0),   # shared logs +14..+135 m; unseen tens to hundreds of m
    "ejection_s": (0.1, 0.5),
    # issue 30: the ram error in boost (docs/flights-sim.md, "Ram error in boost": the two unseen flights'
    # kPa figures need 0.06-0.2 of q; the issue's summary says 0.02-0.05)
    "ram_cp": (0.01, 0.20),
    "ram_mach_on": (0.6, 0.9),
    "ram_fade_s": (0.0, 0.5),
}

#: The parameters of issue 20's model (drawn for ``draw_error_model(..., ram=False)``: the ram error off, so the
#: issue-20 scenarios and Monte Carlo specs that draw from the ranges keep their draws).
ISSUE20_PARAMS: tuple[str, ...] = tuple(BARO_ERROR_RANGES)[:13]
#: The ram error's parameters (issue 30).
RAM_PARAMS: tuple[str, ...] = ("ram_cp", "ram_mach_on", "ram_fade_s")
#: Mach width over which the ram error sets in above ``ram_mach_on`` (smoothstep).
RAM_ONSET_WIDTH_MACH: float = 0.1


def draw_error_model(rng: np.random.Generator | None = None, u: Any = None, ram: bool = False) -> BaroErrorModel:
    """A :class:`BaroErrorModel` with every parameter uniform in :data:`BARO_ERROR_RANGES`: from ``u`` (one number
    in [0, 1) per parameter, in the order of the ranges; e.g. drawn by hypothesis) or from ``rng``. ``ram``:
    draw the ram error in boost too (16 numbers), else only issue 20's 13 (:data:`ISSUE20_PARAMS`; ram off), so
    a generator seeded as before draws the same issue-20 model."""
    names = list(BARO_ERROR_RANGES) if ram else list(ISSUE20_PARAMS)
    if u is None:
        u = (rng or np.random.default_rng()).random(len(names))
    if len(u) != len(names):
        raise UserError(f"draw_error_model: need {len(names)} unit numbers, got {len(u)}")
    return BaroErrorModel(**{n: BARO_ERROR_RANGES[n][0] + (BARO_ERROR_RANGES[n][1] - BARO_ERROR_RANGES[n][0]) * float(x)
                             for n, x in zip(names, u)})


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def dip_shape(mach: np.ndarray, model: BaroErrorModel) -> np.ndarray:
    """0..1: rises from ``dip_mach_on`` to 1 at ``dip_mach_peak``, back to 0 at ``dip_mach_off`` (smoothstep)."""
    m = np.asarray(mach, dtype=np.float64)
    up = _smoothstep((m - model.dip_mach_on) / (model.dip_mach_peak - model.dip_mach_on))
    down = 1.0 - _smoothstep((m - model.dip_mach_peak) / (model.dip_mach_off - model.dip_mach_peak))
    return np.where(m <= model.dip_mach_peak, up, down)


def pressure_coefficient(mach: np.ndarray, model: BaroErrorModel) -> np.ndarray:
    """The static-pressure error as a fraction of ``q``: ``cp_port`` below ``dip_mach_peak`` fading to 0 at
    ``dip_mach_off`` (above it the port sits in supersonic flow behind the nose shock: no measured error), plus
    ``dip_cp * dip_shape``."""
    m = np.asarray(mach, dtype=np.float64)
    sub = 1.0 - _smoothstep((m - model.dip_mach_peak) / (model.dip_mach_off - model.dip_mach_peak))
    return model.cp_port * sub + model.dip_cp * dip_shape(m, model)


def ram_coefficient(time_s: np.ndarray, mach: np.ndarray, burnout_s: Any, model: Any) -> np.ndarray:
    """The ram error in boost as a fraction of ``q`` (issue 30): ``ram_cp * onset(M) * fade(t)``, where onset is a
    smoothstep from 0 at ``ram_mach_on`` to 1 at ``ram_mach_on + RAM_ONSET_WIDTH_MACH`` and fade is 1 until
    ``burnout_s`` and falls to 0 over ``ram_fade_s`` after it (a smoothstep; ``ram_fade_s`` 0: a step at
    burnout). Broadcasts: the Monte Carlo passes (nf, n) arrays and (nf, 1) parameters."""
    m = np.asarray(mach, dtype=np.float64)
    onset = _smoothstep((m - model.ram_mach_on) / RAM_ONSET_WIDTH_MACH)
    after = np.asarray(time_s, dtype=np.float64) - burnout_s
    fade_s = np.asarray(model.ram_fade_s, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):     # a tiny fade is a step
        frac = np.where(fade_s > 0, after / np.where(fade_s > 0, fade_s, 1.0), np.where(after >= 0, 1.0, 0.0))
    fade = np.where(after < 0, 1.0, 1.0 - _smoothstep(frac))
    return model.ram_cp * onset * fade


def shock_crossings(time_s: np.ndarray, mach: np.ndarray, mach_cross: float, min_gap_s: float = 0.2) -> list[float]:
    """Times at which ``mach`` crosses ``mach_cross`` (either way; crossings closer than ``min_gap_s`` to the
    previous one are dropped), linearly interpolated between samples."""
    t = np.asarray(time_s, dtype=np.float64)
    d = np.asarray(mach, dtype=np.float64) - mach_cross
    idx = np.nonzero(np.sign(d[1:]) * np.sign(d[:-1]) < 0)[0]
    out: list[float] = []
    for i in idx:
        tc = float(t[i] + (t[i + 1] - t[i]) * d[i] / (d[i] - d[i + 1]))
        if not out or tc - out[-1] >= min_gap_s:
            out.append(tc)
    return out


def dynamic_pressure_pa(pressure_pa: np.ndarray, mach: np.ndarray) -> np.ndarray:
    """``q = gamma/2 p M^2`` (gamma = 1.4): the dynamic pressure from the static pressure and the Mach number."""
    return 0.7 * np.asarray(pressure_pa, dtype=np.float64) * np.asarray(mach, dtype=np.float64) ** 2


def _event_times(record: FlightRecord) -> tuple[float | None, float | None]:
    """(burnout, drogue deployment) of a simulated record, from its provenance and truth."""
    summ = record.provenance.get("summary", {}) if record.provenance else {}
    burn = summ.get("burnout_s")
    apo = record.truth.apogee_time_s if record.truth is not None else summ.get("apogee_time_s")
    delay = (record.provenance.get("launch") or {}).get("drogue_delay_s", 0.0) if record.provenance else 0.0
    deploy = None if apo is None else float(apo) + float(delay or 0.0)
    return (None if burn is None else float(burn)), deploy


def real_flight_errors(record: FlightRecord, mach: np.ndarray | None = None,
                       model: BaroErrorModel = BaroErrorModel(), seed: int = 0,
                       burst_times_s: Any = None, deploy_s: float | None = None,
                       burnout_s: float | None = None) -> FlightRecord:
    """The record with the barometer errors of real flight (module doc). ``mach``: per sample (default: the
    record's truth, :func:`sim1dof.mach_of`); ``burst_times_s``: where the noise bursts start (default: burnout
    and the deployment); ``deploy_s``: the ejection charge (default: true apogee + the launch's drogue delay);
    ``burnout_s``: the end of the ram error (default: the simulator's burnout; needed when ``ram_cp`` > 0).
    ``seed``: the bursts' noise. The effect lists every part's times and its largest altitude error."""
    if mach is None:
        mach = mach_of(record)
    mach = np.asarray(mach, dtype=np.float64)
    if mach.shape != (record.n,):
        raise UserError(f"{record.name}: mach has shape {mach.shape}, record has ({record.n},)")
    t = np.asarray(record.time_s, dtype=np.float64)
    p = np.asarray(record.pressure_pa, dtype=np.float64)
    burn, deploy = _event_times(record)
    if deploy_s is not None:
        deploy = float(deploy_s)
    ram_end = burn if burnout_s is None else float(burnout_s)
    if model.ram_cp > 0 and ram_end is None:
        raise UserError(f"{record.name}: the ram error in boost (ram_cp {model.ram_cp:g}) needs the burnout time: "
                        "pass burnout_s (the record's provenance has no summary.burnout_s)")
    bursts = [x for x in (burn, deploy) if x is not None] if burst_times_s is None else \
        [float(x) for x in np.atleast_1d(burst_times_s)]
    q = dynamic_pressure_pa(p, mach)
    cp = pressure_coefficient(mach, model)
    ram = ram_coefficient(t, mach, ram_end, model) if model.ram_cp > 0 else np.zeros_like(t)
    p1 = p + (cp + ram) * q
    offset = np.zeros_like(t)                       # altitude offsets of parts 3-5 (m)
    crossings = shock_crossings(t, mach, model.jump_mach)
    for tc in crossings:
        tau = t - tc
        rise = np.clip(tau / model.jump_rise_s, 0.0, 1.0)
        decay = np.exp(-np.clip(tau - model.jump_rise_s, 0.0, None) / model.jump_decay_s)
        offset += model.jump_m * np.where(tau >= 0, rise * decay, 0.0)
    rng = np.random.default_rng(seed)
    burst_offset = np.zeros_like(t)
    for tb in bursts:
        sel = (t >= tb) & (t < tb + model.burst_s)
        burst_offset[sel] += rng.normal(0.0, model.burst_sigma_m, int(sel.sum()))
    offset += burst_offset
    if deploy is not None and model.ejection_m != 0:
        tau = t - deploy
        offset += np.where(tau >= 0, model.ejection_m * np.exp(-np.clip(tau, 0.0, None) / (model.ejection_s / 3.0)),
                           0.0)
    out = p1.copy()
    ok = np.isfinite(p1)
    if np.any(ok & (offset != 0)):
        sel = ok & (offset != 0)
        out[sel] = atm.pressure_pa(atm.altitude_m(p1[sel]) + offset[sel])
    if np.any(~(out[ok] > 0)):
        raise UserError(f"{record.name}: the barometer error model made a pressure <= 0")
    err_m = np.full_like(t, np.nan)
    err_m[ok] = atm.altitude_m(out[ok]) - atm.altitude_m(p[ok])
    i_min = int(np.nanargmin(err_m))
    effect = {"effect": "real_flight_errors", "model": model.to_dict(), "seed": seed,
              "shock_crossings_s": crossings, "burst_times_s": bursts, "deploy_s": deploy,
              "max_dip_m": float(err_m[i_min]), "max_dip_time_s": float(t[i_min]),
              "max_dip_mach": float(mach[i_min]), "peak_mach": float(np.max(mach))}
    if model.ram_cp > 0:
        dp = ram * q
        on = np.nonzero(dp > 0)[0]
        j = int(np.argmax(dp))
        # the lowest barometric height above the pad the record reads while the ram error is on
        h_pad = atm.altitude_m(np.asarray(record.ground_pressure_pa if record.ground_pressure_pa else p[0]))
        h_read = np.where(dp > 0, np.asarray(atm.altitude_m(np.where(ok, out, 1.0))) - h_pad, np.inf)
        k = int(np.argmin(h_read))
        effect["ram"] = {"burnout_s": ram_end, "on_s": float(t[on[0]]) if on.size else None,
                         "off_s": float(t[on[-1]]) if on.size else None, "max_pa": float(dp[j]),
                         "max_time_s": float(t[j]), "max_mach": float(mach[j]),
                         "lowest_height_m": float(h_read[k]) if on.size else None,
                         "lowest_height_time_s": float(t[k]) if on.size else None}
    return _with_effect(record, out, effect)

