"""Simulated flights that end in an ejection, logged as AltOS logs them (issue 31; docs/evaluation.md, "The reference
apogee and the log's own charge"): the 1-DOF simulator's trajectory (:func:`firmware_model.flights.simulate.sim1dof`),
whose
drogue opens when the charge fires (separation), sensed and logged like a real log:

* the barometer: a non-standard day (the barometric height is the true one times 0.95-1.05: the standard
  atmosphere's temperature is not the day's), white noise 2-25 Pa plus correlated noise 0-6 Pa (first-order, 0.3 s),
  integer pascals;
* the log: 100 samples/s up to the charge, 10 or 5 samples/s from it on (AltOS drops its rate at apogee), except
  as below;
* the charge fires 0-1.5 s after the true apogee (a computer fires at or after the apogee it sees); from the first
  logged sample at or after it: a pressure pulse (the barometric height 20-300 m low for 0.1-0.5 s), then the
  separated section's barometer 0-30 m high, decaying over 0.5-2 s, and 40 Pa of extra noise; the accelerometer
  (axial specific force, 0.5 m/s^2 noise) reads one sample of 10-60 g;
* what the log says: ``state``: an AltOS-like ``altos_drogue`` event at the charge; ``rate``: no event (an AltosUI
  CSV without its state column), the rate drop and the shock; ``shock``: a log at 10 or 5 samples/s throughout (a
  telemetry record), no event, the shock alone; ``pressure``: a barometer-only log at 20 samples/s throughout, no
  event: the pressure pulse alone.

No truth in the returned record (the reference must not see it); the truth comes beside it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from firmware_model.flights.record import FlightRecord
from firmware_model.flights.simulate.sim1dof import Box, Launch, rocket_from_unit, simulate_1dof
from firmware_model.spec import atmosphere as atm

G0 = 9.80665
EVIDENCE = ("state", "rate", "shock", "pressure")


@dataclass(frozen=True)
class EjectionLog:
    record: FlightRecord        # the log (no truth)
    apogee_s: float             # the true apogee
    charge_s: float             # when the charge fired
    logged_charge_s: float      # the first logged sample at or after it (where the shock / pulse shows)
    tail_hz: float
    evidence: str
    scale: float                # barometric height / true height


def ejection_logs(n: int, seed: int) -> list[EjectionLog]:
    """``n`` ejection logs (module docstring), deterministic in ``seed``."""
    rng = np.random.default_rng(seed)
    rockets, launches, lags = [], [], []
    while len(rockets) < n:
        u = rng.random(8)
        r = rocket_from_unit(u, Box(), name=f"eject-{seed}-{len(rockets)}")
        if r is None:
            continue
        lag = float(rng.uniform(0.0, 1.5))
        rockets.append(r)
        lags.append(lag)
        launches.append(Launch(site_altitude_m=1500.0 * float(u[7]), pad_s=2.0, descent_s=6.0,
                               drogue_delay_s=lag, record_hz=100.0))
    recs = simulate_1dof(rockets, launches)
    return [_logged(rec, lag, i, rng) for i, (rec, lag) in enumerate(zip(recs, lags))]


def _logged(rec: FlightRecord, lag: float, i: int, rng: np.random.Generator) -> EjectionLog:
    tr = rec.truth
    assert tr is not None and tr.apogee_time_s is not None and tr.altitude_m is not None
    t = np.asarray(rec.time_s, dtype=np.float64)
    ta = float(tr.apogee_time_s)
    tc = ta + lag
    tail_hz = float(rng.choice([10.0, 5.0]))
    evidence = str(EVIDENCE[i % len(EVIDENCE)])
    # the log: 100/s until the charge, then tail_hz on a grid whose phase is random (a barometer-only log: 20/s
    # throughout, as an RRC3 or an Eggtimer logs)
    ic = int(np.searchsorted(t, tc))
    keep = np.ones(t.size, dtype=bool)
    if evidence == "pressure":
        tail_hz = 20.0
        keep = (np.arange(t.size) % 5) == int(rng.integers(0, 5))
    elif evidence == "shock":
        step = int(round(100.0 / tail_hz))
        keep = (np.arange(t.size) % step) == int(rng.integers(0, step))
    else:
        step = int(round(100.0 / tail_hz))
        keep[ic:] = (np.arange(t.size - ic) % step) == int(rng.integers(0, step))
    idx = np.nonzero(keep)[0]
    tl = t[idx]
    z = np.asarray(tr.altitude_m, dtype=np.float64)[idx]
    site = float(atm.altitude_m(rec.ground_pressure_pa))
    scale = float(rng.uniform(0.95, 1.05))
    hb = scale * z
    after = tl >= tc
    j0 = int(np.argmax(after)) if after.any() else tl.size
    t_log_c = float(tl[j0]) if j0 < tl.size else float("nan")
    if j0 < tl.size:
        dur = rng.uniform(0.1, 0.5)
        pulse = (tl >= t_log_c) & (tl < t_log_c + dur)
        pulse[j0] = True
        hb[pulse] -= rng.uniform(20.0, 300.0)
        lift, tau = rng.uniform(0.0, 30.0), rng.uniform(0.5, 2.0)
        late = tl >= t_log_c + dur
        hb[late] += lift * np.exp(-(tl[late] - t_log_c - dur) / tau)
    p = np.asarray(atm.pressure_pa(site + hb), dtype=np.float64)
    sw, sc = rng.uniform(2.0, 25.0), rng.uniform(0.0, 6.0)
    corr = np.zeros(tl.size)
    for k in range(1, tl.size):
        a = np.exp(-(tl[k] - tl[k - 1]) / 0.3)
        corr[k] = a * corr[k - 1] + np.sqrt(1 - a * a) * sc * rng.standard_normal()
    p = p + rng.normal(0.0, sw, tl.size) + corr
    p[after] += rng.normal(0.0, 40.0, int(after.sum()))
    p = np.round(p)
    accel = None
    if evidence != "pressure":
        accel = np.asarray(rec.accel_mps2, dtype=np.float64)[idx] + rng.normal(0.0, 0.5, tl.size)
        if j0 < tl.size:
            accel[j0] += rng.choice([-1.0, 1.0]) * rng.uniform(10.0, 60.0) * G0
    events = {"altos_drogue": tc} if evidence == "state" else {}
    log = FlightRecord(name=f"{rec.name} [{evidence}, {tail_hz:g}/s]", time_s=tl, pressure_pa=p, accel_mps2=accel,
                       events=events, provenance={"source": rec.name, "format": "simulation (ejection log)"})
    return EjectionLog(log, ta, tc, t_log_c, tail_hz, evidence, scale)
