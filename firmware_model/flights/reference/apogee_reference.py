"""What a flight's firmware answers are judged against: liftoff, the pad, and the reference apogee.

:func:`reference_apogee` (docs/flights.md, "Reference apogee"):

* a record with truth (simulators): the true apogee, uncertainty 0, source ``"truth"``;
* a real log: a robust least-squares parabola through the **barometric altitude** near its peak, source
  ``"baro_parabola"``. Altitude: standard-atmosphere altitude of each pressure minus that of the ground pressure
  (``record.ground_pressure_pa``, else the median pad pressure, :func:`ground_pressure`).

  1. Isolated spikes: within 3.75 s of the highest point of the 7-sample running median, a sample is a spike when it
     differs from the median of its 7-sample neighbourhood by more than max(6 sigma, 3 m), sigma from
     :func:`noise_scale`; spikes are never used.
  2. The peak: the highest point of the 7-sample running median of the samples left.
  3. Fit: ``h = c0 + c1 (t - tp) + c2 (t - tp)^2`` by least squares over the samples with |t - tp| <= w, each
     sample weighted by the time it represents (half the sum of its two intervals: a 100 samples/s ascent and a
     10 samples/s descent count by duration, not by rows), iterated: residuals beyond 3 x their robust scale
     (1.4826 x weighted MAD, at least 0.25 m) are dropped and the fit repeated, at most 10 times. A fit needs
     c2 < 0, at least 8 samples, and samples on both sides of the vertex; the vertex ``tp - c1 / (2 c2)`` must lie
     inside the window.
  4. Nominal window w = 1.5 s; the uncertainty is the largest distance of the vertex time from the nominal one over
     the windows w = 1.0, 1.25, 1.5, 2.0, 2.5 s and the nominal window shifted by +-0.25 s (all that give a valid
     fit), at least half the log's median interval near the peak (the time resolution of the data).
  5. The log's recovery charge (:func:`firmware_model.flights.reference.charge.recovery_charge`: its own computer's
     event, else an accelerometer shock or the ejection's pressure pulse in the flight's top): after it the flight is
     not free (separation, a parachute) and the ejection disturbs the pressure for seconds, so **only the samples
     before it are used** (:func:`_pre_charge_reference`, issue 31). Spikes and the running-median peak as in 1-2 on
     those samples; windows [tp - w, min(tp + w, t_c)] for the w of rule 4 (and the nominal one shifted by
     +-0.25 s), each a robust weighted parabola **with a prior on its curvature**, -g +- 15 % (near apogee the
     vertical velocity is small and so is the vertical drag: the barometric height falls at g times the ratio of
     the standard to the real temperature; Gaussian prior, so a long two-sided window follows the data and a short
     one-sided window, a flat noisy top just before the charge, leans on physics). The vertex's standard error comes
     from the posterior covariance, its residual scale inflated by sqrt((1 + rho) / (1 - rho)) for residuals
     correlated (:func:`_correlation_inflation`: a real barometer's noise is not white). Half-width u = max(2 standard
     errors, the spread over the windows, half the log's interval, the distance from the vertex of the same fit with
     its curvature pinned at -g: the model's own error on a one-sided window). The windows are symmetric about their
     centre (the running-median peak, then the nominal vertex, iterated) when the charge leaves 0.5 s after it,
     else one-sided up to the charge. Then, with the vertex tv:

     * tv + u <= t_c: a point, tv +- u;
     * tv > t_c, the vertex with the curvature pinned at -g too, and the fitted velocity at the charge is above twice
       its standard error: the flight was still rising at the charge:
       the charge fired before apogee; the point tv +- u lies after the charge and the notes say why
       (``after_charge``);
     * otherwise (the usual case of a flat, noisy top that ends at the charge): **an interval** [tv - u, t_c]
       (its lower end the lowest of tv - u, the pinned vertex - u and the charge minus the log's interval):
       a computer that fires at apogee fires at or after the apogee it sees; ``time_s`` is the median of the vertex's
       normal distribution (sigma u / 2) cut at the charge, ``uncertainty_s`` the interval's half-width.

     When the samples before the charge hold no top (fewer than 8 in the window, or no fit: a charge long before
     the barometric peak, such as a motor that failed in boost) rules 3-4 are applied to the whole log and the
     reference carries a warning (its data run past the charge).
"""

from __future__ import annotations

import math
from statistics import NormalDist
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from firmware_model.flights.reference.charge import RecoveryCharge, recovery_charge
from firmware_model.flights.readers import read_flight
from firmware_model.flights.record import FlightRecord
from firmware_model.runtime.errors import UserError
from firmware_model.spec.atmosphere import G0, altitude_m

NOMINAL_WINDOW_S: float = 1.5
WINDOWS_S: tuple[float, ...] = (1.0, 1.25, 1.5, 2.0, 2.5)
SHIFTS_S: tuple[float, ...] = (-0.25, 0.25)
SPIKE_MIN_M: float = 3.0
SPIKE_SIGMAS: float = 6.0
MEDIAN_HALF: int = 3
#: Rule 5: the curvature prior (a fraction of -g, 1 sigma), the samples left out just before the charge (s: the
#: charge's pressure pulse can show one sample before the event row), the largest residual-correlation inflation.
CURVATURE_PRIOR_FRACTION: float = 0.15
CHARGE_GUARD_S: float = 0.02
MAX_INFLATION: float = 5.0
CORRELATION_S: float = 0.5
#: ... and at least sqrt(INDEPENDENT_S / interval): a real barometer's samples are taken as independent at most
#: every 0.1 s (its filtering, the port's airflow), whatever the estimate from the residuals of one window says.
INDEPENDENT_S: float = 0.1
#: Rule 5's windows are symmetric about their centre when the charge is at least this far (s) after it.
MIN_SYMMETRIC_S: float = 0.5


@dataclass(frozen=True)
class ReferenceApogee:
    """The reference apogee: ``time_s`` on the record's axis, ``altitude_m`` above the pad, ``uncertainty_s``
    (the half-width: 2 sigma, or the interval's half), ``source`` (``truth`` / ``baro_parabola`` /
    ``baro_interval``), ``window_s`` (the nominal fit half-width; 0 for truth), ``notes`` (per-window vertices,
    spikes rejected, the charge ...); ``interval_s``: (a, b) when the reference is "apogee lies in [a, b]" (rule 5),
    else None."""

    time_s: float
    altitude_m: float
    uncertainty_s: float
    source: str
    window_s: float
    notes: dict[str, Any] = field(default_factory=dict)
    interval_s: tuple[float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


# ---------------------------------------------------------------------------------------------- liftoff and pad
def liftoff_time(record: FlightRecord) -> float:
    """Time of liftoff on the record's axis.

    In order: truth (the sample before the true velocity first exceeds 0.01 m/s, or the altitude 1 mm), else the
    accelerometer (the first time the specific force stays above pad + 2 g for 50 ms, backed off to the last
    sample before it below pad + 0.5 g), else the log's ``altos_boost`` event, else the barometer (the last
    sample below 3 m and the first above 30 m over the pad median, extrapolated back to rest assuming constant
    acceleration), else the record's first time."""
    t = np.asarray(record.time_s, dtype=np.float64)
    tr = record.truth
    if tr is not None and tr.velocity_mps is not None:
        up = np.nonzero(np.asarray(tr.velocity_mps) > 0.01)[0]
        if up.size:
            return float(t[max(0, int(up[0]) - 1)])
    if tr is not None and tr.altitude_m is not None:
        up = np.nonzero(np.asarray(tr.altitude_m) > 0.001)[0]
        if up.size:
            return float(t[max(0, int(up[0]) - 1)])
    f = record.specific_force_mps2()
    if f is not None and np.sum(np.isfinite(f)) > 10:
        first = np.isfinite(f) & (t <= t[0] + 0.25)
        pad = float(np.median(f[first])) if first.any() else G0
        if pad > 1.5 * G0:      # the log starts accelerating (after liftoff / during ignition): the nominal 1 g
            pad = G0
        hi = np.nan_to_num(f, nan=-np.inf) > pad + 2.0 * G0
        for i in np.nonzero(hi)[0]:
            j = np.searchsorted(t, t[i] + 0.05)
            if j <= t.size and np.all(hi[i:j]):
                low = np.nonzero(np.nan_to_num(f[: i + 1], nan=np.inf) < pad + 0.5 * G0)[0]
                return float(t[int(low[-1])]) if low.size else float(t[0])
    if "altos_boost" in record.events:
        return float(record.events["altos_boost"])
    p = np.asarray(record.pressure_pa, dtype=np.float64)
    ok = np.isfinite(p)
    h = np.full(p.shape, np.nan)
    h[ok] = altitude_m(p[ok])
    h0 = float(np.nanmedian(h[: max(10, min(100, h.size // 20))]))
    above = np.nonzero(np.nan_to_num(h - h0, nan=-np.inf) > 30.0)[0]
    if above.size:
        low = np.nonzero(np.nan_to_num(h[: above[0]] - h0, nan=np.inf) < 3.0)[0]
        if not low.size:
            return float(t[0])
        t3, t30 = float(t[int(low[-1])]), float(t[int(above[0])])
        # constant acceleration from rest: h ~ t^2, so 3 m is reached at sqrt(3/30) of the time to 30 m
        return max(float(t[0]), t30 - (t30 - t3) / (1.0 - (3.0 / 30.0) ** 0.5))
    return float(t[0])


def ground_pressure(record: FlightRecord) -> float:
    """Pressure at the pad: ``record.ground_pressure_pa`` if stated, else the median pressure over the samples
    before liftoff (at least the first 5 finite samples when the log starts at liftoff)."""
    if record.ground_pressure_pa is not None:
        return float(record.ground_pressure_pa)
    t = np.asarray(record.time_s)
    p = np.asarray(record.pressure_pa, dtype=np.float64)
    ok = np.isfinite(p)
    if not ok.any():
        raise UserError(f"{record.provenance.get('source', record.name)}: no pressure values")
    before = ok & (t < liftoff_time(record))
    if before.sum() < 5:
        before = ok & (np.cumsum(ok) <= 5)
    return float(np.median(p[before]))


def baro_altitude(record: FlightRecord) -> np.ndarray:
    """Barometric altitude above the pad (m): standard atmosphere, NaN where the pressure is missing."""
    p = np.asarray(record.pressure_pa, dtype=np.float64)
    h = np.full(p.shape, np.nan)
    ok = np.isfinite(p) & (p > 0)
    h[ok] = np.asarray(altitude_m(p[ok])) - float(altitude_m(ground_pressure(record)))
    return h


# --------------------------------------------------------------------------------------------- reference apogee
def _running_median(y: np.ndarray, half: int) -> np.ndarray:
    padded = np.pad(y, half, mode="edge")
    return np.median(np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1), axis=1)


def noise_scale(h: np.ndarray, pad: np.ndarray) -> float:
    """Robust noise of an altitude series (m): the largest of 1.4826 x MAD of the residuals from the 7-sample
    running median over the flight, 1.4826 x MAD of the pad samples, and the pad's quantization step / sqrt(12)
    (quantized logs often have a MAD of exactly 0)."""
    r = h - _running_median(h, MEDIAN_HALF)
    parts = [1.4826 * float(np.median(np.abs(r - np.median(r))))]
    hp = h[pad]
    if hp.size >= 10:
        parts.append(1.4826 * float(np.median(np.abs(hp - np.median(hp)))))
        steps = np.abs(np.diff(np.unique(hp)))
        if steps.size:
            parts.append(float(np.min(steps)) / math.sqrt(12.0))
    return max(parts)


def spikes(h: np.ndarray, noise: float) -> np.ndarray:
    """Mask of isolated spikes of a finite altitude series (rule 1 above)."""
    r = h - _running_median(h, MEDIAN_HALF)
    return np.abs(r) > max(SPIKE_SIGMAS * noise, SPIKE_MIN_M)


def _weights(t: np.ndarray) -> np.ndarray:
    d = np.diff(t)
    w = np.empty_like(t)
    w[1:-1] = 0.5 * (d[:-1] + d[1:])
    w[0], w[-1] = d[0], d[-1]
    return w


def _fit(t: np.ndarray, h: np.ndarray, w: np.ndarray, tp: float, lo: float, hi: float
         ) -> tuple[float, float, int, int, float] | None:
    """Robust weighted parabola over lo <= t <= hi: (vertex time, vertex altitude, used, rejected, curvature
    m/s^2) or None."""
    sel = (t >= lo) & (t <= hi)
    ts, hs, ws = t[sel] - tp, h[sel], w[sel]
    keep = np.ones(ts.size, dtype=bool)
    for _ in range(10):
        if keep.sum() < 8:
            return None
        a = np.vstack([np.ones(keep.sum()), ts[keep], ts[keep] ** 2]).T
        sw = np.sqrt(ws[keep])
        coef, *_ = np.linalg.lstsq(a * sw[:, None], hs[keep] * sw, rcond=None)
        r = hs - (coef[0] + coef[1] * ts + coef[2] * ts ** 2)
        rk = np.abs(r[keep])
        order = np.argsort(rk)
        cw = np.cumsum(ws[keep][order])
        wmad = rk[order][np.searchsorted(cw, 0.5 * cw[-1])]
        scale = max(1.4826 * wmad, 0.25)
        new = np.abs(r) <= 3.0 * scale
        if np.array_equal(new, keep):
            break
        keep = new
    c0, c1, c2 = coef
    if not c2 < 0:
        return None
    tv = -c1 / (2.0 * c2)
    if not (lo - tp <= tv <= hi - tp) or not (np.any(ts[keep] < tv) and np.any(ts[keep] > tv)):
        return None
    return float(tp + tv), float(c0 + c1 * tv + c2 * tv * tv), int(keep.sum()), int((~keep).sum()), float(2 * c2)


def _fit_prior(t: np.ndarray, h: np.ndarray, w: np.ndarray, tp: float, lo: float, hi: float
               ) -> dict[str, float] | None:
    """Rule 5's fit over lo <= t <= hi: a robust weighted parabola about ``tp`` with the curvature prior, or None
    (fewer than 8 samples, no maximum, or a vertex further than the window's length beyond its last sample).
    Returns the vertex time and altitude, its standard error, the curvature, the counts, and the coefficients with
    their covariance (for the velocity at the charge)."""
    sel = (t >= lo) & (t <= hi)
    x, y, ww = t[sel] - tp, h[sel], w[sel]
    if x.size < 8:
        return None
    ww = ww / float(np.mean(ww))
    c20 = -0.5 * G0
    prior = 1.0 / (CURVATURE_PRIOR_FRACTION * 0.5 * G0) ** 2
    d = np.diff(y)
    s = max(1.4826 * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2.0), 0.25)
    keep = np.ones(x.size, dtype=bool)
    for _ in range(10):
        if keep.sum() < 8:
            return None
        a = np.vstack([np.ones(keep.sum()), x[keep], x[keep] ** 2]).T
        wk = ww[keep]
        m = (a.T * wk) @ a / s ** 2
        m[2, 2] += prior
        rhs = (a.T * wk) @ y[keep] / s ** 2
        rhs[2] += prior * c20
        coef = np.linalg.solve(m, rhs)
        r = y - (coef[0] + coef[1] * x + coef[2] * x ** 2)
        rk = np.abs(r[keep])
        order = np.argsort(rk)
        cw = np.cumsum(wk[order])
        s_new = max(1.4826 * float(rk[order][np.searchsorted(cw, 0.5 * cw[-1])]), 0.25)
        new = np.abs(r) <= 3.0 * s_new
        if np.array_equal(new, keep) and abs(s_new - s) <= 0.01 * s:
            s = s_new
            break
        keep, s = new, s_new
    c0, c1, c2 = (float(v) for v in coef)
    if not c2 < 0:
        return None
    tv = -c1 / (2.0 * c2)
    if tv + tp > float(t[sel][-1]) + (hi - lo) or tv + tp < lo:
        return None
    infl = _correlation_inflation(x[keep], r[keep])
    cov = np.linalg.inv(m) * infl ** 2
    g = np.array([0.0, -1.0 / (2 * c2), c1 / (2 * c2 * c2)])
    # the same samples with the curvature pinned at -g: how far the vertex moves with the curvature is the model's
    # own error on a one-sided or short window (drag decelerates the ascent beyond g; the day's temperature scales
    # the barometric height); on a long symmetric window it is small
    a = np.vstack([np.ones(keep.sum()), x[keep]]).T
    b0 = np.linalg.solve((a.T * ww[keep]) @ a, (a.T * ww[keep]) @ (y[keep] - c20 * x[keep] ** 2))
    pinned = -float(b0[1]) / (2.0 * c20)
    return {"time_s": tp + tv, "altitude_m": c0 + c1 * tv + c2 * tv * tv, "se_s": float(math.sqrt(max(g @ cov @ g,
            0.0))), "curvature_mps2": 2.0 * c2, "used": int(keep.sum()), "rejected": int((~keep).sum()),
            "inflation": infl, "tp": tp, "c1": c1, "c2": c2, "cov": cov, "pinned_s": tp + pinned,
            "model_s": abs(pinned - tv)}


def _correlation_inflation(x: np.ndarray, r: np.ndarray) -> float:
    """sqrt(1 + 2 sum_k (1 - k/K) rho_k) over the lags k < K spanning CORRELATION_S of residuals ``r`` at times
    ``x`` (Bartlett's weights; a real barometer's noise is correlated over tenths of a second), at least
    sqrt(INDEPENDENT_S / interval), at most MAX_INFLATION."""
    if r.size < 8 or not np.std(r) > 0:
        return 1.0
    dt = float(np.median(np.diff(x))) if x.size > 1 else 0.0
    kmax = int(min(max(CORRELATION_S / dt, 1.0) if dt > 0 else 1, r.size // 4))
    rc = r - r.mean()
    var = float(rc @ rc) / rc.size
    total = 1.0
    for k in range(1, kmax + 1):
        rho = float(rc[:-k] @ rc[k:]) / (rc.size * var)
        total += 2.0 * (1.0 - k / (kmax + 1)) * rho
    floor = math.sqrt(max(INDEPENDENT_S / dt, 1.0)) if dt > 0 else 1.0
    return float(min(max(math.sqrt(max(total, 0.0)), floor), MAX_INFLATION))


def _velocity_at(fit: dict[str, Any], tc: float) -> tuple[float, float]:
    """The fitted vertical velocity (m/s) at ``tc`` and its standard error."""
    dx = tc - fit["tp"]
    j = np.array([0.0, 1.0, 2.0 * dx])
    return fit["c1"] + 2.0 * fit["c2"] * dx, float(math.sqrt(max(j @ fit["cov"] @ j, 0.0)))


def _pre_charge_reference(t: np.ndarray, h: np.ndarray, noise: float, charge: RecoveryCharge, base: dict[str, Any]
                          ) -> ReferenceApogee | None:
    """Rule 5 on the finite samples (t, h) of a log whose recovery charge is ``charge``; None when the samples
    before it hold no top (the caller falls back to rules 3-4, flagged)."""
    tc = charge.time_s
    pre = t < tc - CHARGE_GUARD_S
    t, h = t[pre], h[pre]
    if t.size < 20:
        return None
    tp0 = float(t[int(np.argmax(_running_median(h, MEDIAN_HALF)))])
    region = np.abs(t - tp0) <= max(WINDOWS_S) + max(abs(x) for x in SHIFTS_S) + 1.0
    spike = np.zeros(t.shape, dtype=bool)
    spike[region] = spikes(h[region], noise)
    t_c, h_c = t[~spike], h[~spike]
    ip = int(np.argmax(_running_median(h_c, MEDIAN_HALF)))
    tp = float(t_c[ip])
    w = _weights(t_c)

    def window(centre: float, half: float) -> tuple[float, float]:
        # symmetric about the centre when the charge leaves room (a symmetric window cancels the ascent/descent
        # asymmetry of drag to first order), else one-sided up to the charge
        room = tc - centre
        if room >= MIN_SYMMETRIC_S:
            half = min(half, room)
            return centre - half, centre + half
        return centre - half, tc

    fits: dict[str, dict[str, Any]] = {}
    centre = tp
    for _ in range(3):          # the running-median peak, then the nominal vertex (a noisy top's peak wanders)
        fits = {}
        for win in WINDOWS_S:
            f = _fit_prior(t_c, h_c, w, centre, *window(centre, win))
            if f is not None:
                fits[f"+-{win:g}"] = f
        for sh in SHIFTS_S:
            f = _fit_prior(t_c, h_c, w, centre, *window(centre + sh, NOMINAL_WINDOW_S))
            if f is not None:
                fits[f"+-{NOMINAL_WINDOW_S:g} shifted {sh:+g}"] = f
        if not fits:
            return None
        nominal = fits.get(f"+-{NOMINAL_WINDOW_S:g}") or min(fits.values(), key=lambda f: abs(f["time_s"] - centre))
        new = min(nominal["time_s"], tc)
        if abs(new - centre) < 0.01:
            break
        centre = new
    near = (t_c > tp - NOMINAL_WINDOW_S) & (t_c < tp + NOMINAL_WINDOW_S)
    resolution = 0.5 * float(np.median(np.diff(t_c[near]))) if near.sum() > 2 else 0.0
    spread = max(abs(f["time_s"] - nominal["time_s"]) for f in fits.values())
    tv = nominal["time_s"]
    u = max(2.0 * nominal["se_s"], spread, resolution, nominal["model_s"])
    v, sv = _velocity_at(nominal, tc)
    notes = dict(base)
    notes.update({
        "peak_sample_s": tp, "peak_sample_m": float(h_c[ip]), "spikes_rejected": int(spike.sum()),
        "spike_times_s": [float(x) for x in t[spike][:20]],
        "fits": {k: {key: f[key] for key in ("time_s", "altitude_m", "se_s", "used", "rejected", "curvature_mps2",
                                            "inflation", "pinned_s")} for k, f in fits.items()},
        "curvature_mps2": nominal["curvature_mps2"], "resolution_s": resolution, "vertex_s": tv,
        "vertex_se_s": nominal["se_s"], "vertex_pinned_s": nominal["pinned_s"], "velocity_at_charge_mps": v,
        "velocity_at_charge_se_mps": sv,
        "deployment_cut": True,
    })
    interval = None
    if tv + u <= tc:
        time_s, source = tv, "baro_parabola"
    elif min(tv, nominal["pinned_s"]) > tc and v > 2.0 * sv:
        time_s, source = tv, "baro_parabola"
        notes["after_charge"] = (f"later than the charge at {tc:.2f} s: the flight before it was still rising at "
                                 f"{v:.1f} +- {sv:.1f} m/s (the charge fired before apogee; vertex extrapolated "
                                 f"{tv - tc:.2f} s past it)")
    else:
        interval = (min(tv - u, nominal["pinned_s"] - u, tc - 2.0 * resolution), tc)
        # the point inside it: the median of the vertex's normal distribution (sigma u/2) cut at the charge
        sd = max(0.5 * u, 1e-6)
        nd = NormalDist(tv, sd)
        time_s = min(max(nd.inv_cdf(max(0.5 * nd.cdf(tc), 1e-12)), interval[0]), interval[1])
        u, source = 0.5 * (interval[1] - interval[0]), "baro_interval"
        notes["interval"] = (f"apogee in [{interval[0]:.2f}, {tc:.2f}] s: the pre-charge vertex {tv:.2f} +- "
                             f"{nominal['se_s'] * 2:.2f} s does not lie before the charge; a computer fires at or "
                             "after the apogee it sees")
    if not -2.0 * G0 <= nominal["curvature_mps2"] <= -0.25 * G0:
        notes["warning"] = (f"fitted curvature {nominal['curvature_mps2']:.2f} m/s^2 is far from -g: the flight is "
                            "not ballistic before its charge; treat this reference with care")
    return ReferenceApogee(time_s=time_s, altitude_m=nominal["altitude_m"], uncertainty_s=u, source=source,
                           window_s=NOMINAL_WINDOW_S, notes=notes, interval_s=interval)


def reference_apogee(record: FlightRecord) -> ReferenceApogee:
    """The reference apogee of ``record`` (module docstring)."""
    tr = record.truth
    if tr is not None and tr.apogee_time_s is not None:
        alt = tr.apogee_altitude_m
        if alt is None and tr.altitude_m is not None:
            alt = float(np.interp(tr.apogee_time_s, record.time_s, tr.altitude_m))
        return ReferenceApogee(time_s=float(tr.apogee_time_s), altitude_m=float(alt) if alt is not None else math.nan,
                               uncertainty_s=0.0, source="truth", window_s=0.0, notes={})
    where = record.provenance.get("source", record.name)
    t_all = np.asarray(record.time_s, dtype=np.float64)
    h_all = baro_altitude(record)
    ok = np.isfinite(h_all)
    t, h = t_all[ok], h_all[ok]
    if t.size < 20:
        raise UserError(f"{where}: too few barometer samples ({t.size}) for a reference apogee")
    pad = t < liftoff_time(record)
    noise = noise_scale(h, pad)
    charge = recovery_charge(record)
    base = {"noise_m": noise, "ground_pressure_pa": ground_pressure(record),
            "deployment_s": None if charge is None else charge.time_s,
            "charge": None if charge is None else charge.to_dict()}
    if charge is not None:
        ref = _pre_charge_reference(t, h, noise, charge, base)
        if ref is not None:
            return ref
    # the peak of the running median (robust to up to 3 consecutive outliers), then spikes near it only: far
    # from the peak a fast, irregularly sampled descent differs from its running median without being a spike
    tp0 = float(t[int(np.argmax(_running_median(h, MEDIAN_HALF)))])
    region = np.abs(t - tp0) <= max(WINDOWS_S) + max(abs(s) for s in SHIFTS_S) + 1.0
    spike = np.zeros(t.shape, dtype=bool)
    spike[region] = spikes(h[region], noise)
    t_c, h_c = t[~spike], h[~spike]
    smooth = _running_median(h_c, MEDIAN_HALF)
    ip = int(np.argmax(smooth))
    tp = float(t_c[ip])
    w = _weights(t_c)
    fits: dict[str, tuple[float, float, int, int, float]] = {}
    for win in WINDOWS_S:
        f = _fit(t_c, h_c, w, tp, tp - win, tp + win)
        if f is not None:
            fits[f"+-{win:g}"] = f
    for sh in SHIFTS_S:
        f = _fit(t_c, h_c, w, tp, tp + sh - NOMINAL_WINDOW_S, tp + sh + NOMINAL_WINDOW_S)
        if f is not None:
            fits[f"+-{NOMINAL_WINDOW_S:g} shifted {sh:+g}"] = f
    nominal = fits.get(f"+-{NOMINAL_WINDOW_S:g}")
    if nominal is None:
        if not fits:
            raise UserError(f"{where}: no parabola fits the barometric altitude near its peak "
                            f"(t = {tp:.3f} s, {h_c[ip]:.1f} m): is there an apogee in this log?")
        nominal = min(fits.values(), key=lambda f: abs(f[0] - tp))
    near = (t_c > tp - NOMINAL_WINDOW_S) & (t_c < tp + NOMINAL_WINDOW_S)
    resolution = 0.5 * float(np.median(np.diff(t_c[near]))) if near.sum() > 2 else 0.0
    spread = max(abs(f[0] - nominal[0]) for f in fits.values())
    notes = dict(base)
    notes.update({
        "peak_sample_s": tp, "peak_sample_m": float(h_c[ip]), "spikes_rejected": int(spike.sum()),
        "spike_times_s": [float(x) for x in t[spike][:20]],
        "fits": {k: {"time_s": v[0], "altitude_m": v[1], "used": v[2], "rejected": v[3], "curvature_mps2": v[4]}
                 for k, v in fits.items()},
        "curvature_mps2": nominal[4],
        "resolution_s": resolution,
        "deployment_cut": False,
    })
    warnings = []
    if charge is not None:
        warnings.append(f"the samples before the log's charge at {charge.time_s:.2f} s ({charge.evidence}) hold no "
                        "top: this reference is fitted across the charge (the charge fired long before apogee, or "
                        "the log has no free flight near its peak)")
    if not -2.0 * G0 <= nominal[4] <= -0.25 * G0:
        warnings.append(f"fitted curvature {nominal[4]:.2f} m/s^2 is far from -g: the flight is not ballistic near "
                        "its peak (early deployment?); treat this reference with care")
    if warnings:
        notes["warning"] = "; ".join(warnings)
    return ReferenceApogee(time_s=nominal[0], altitude_m=nominal[1], uncertainty_s=max(spread, resolution),
                           source="baro_parabola", window_s=NOMINAL_WINDOW_S, notes=notes)


# ------------------------------------------------------------------------------------------------ a table
def reference_table(paths: list[str], format: str | None = None) -> str:
    """The Markdown table of docs/flights.md for flight logs ``paths``: reference apogee, its uncertainty,
    altitude, fitted curvature, spikes rejected, and the log's own computer's apogee against it where the log has
    one (AltOS's first drogue state, an RRC3's Drogue event, CATS's EV_APOGEE, ...: ``FlightRecord.own_apogee``).
    ``python -m firmware_model.flights.reference.apogee_reference LOG...`` prints it."""

    out = ["| log | reference apogee (s) | ± (s) | altitude AGL (m) | curvature (m/s²) | spikes rejected "
           "| own computer's apogee (s) | own − reference (s) |", "|---|---|---|---|---|---|---|---|"]
    for path in paths:
        rec = read_flight(path, format=format)
        ref = reference_apogee(rec)
        own = rec.own_apogee()
        warn = " ⚠" if "warning" in ref.notes else ""
        curv = ref.notes.get("curvature_mps2")
        out.append(f"| {rec.name} | {ref.time_s:.3f}{warn} | {ref.uncertainty_s:.3f} | {ref.altitude_m:.1f} | "
                   + ("—" if curv is None else f"{curv:.1f}") + f" | {ref.notes.get('spikes_rejected', 0)} | "
                   + ("— | — |" if own is None else f"{own[0]} {own[1]:.2f} | {own[1] - ref.time_s:+.2f} |"))
    return "\n".join(out)


if __name__ == "__main__":  # pragma: no cover
    import sys

    try:
        print(reference_table(sys.argv[1:]))
    except UserError as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
