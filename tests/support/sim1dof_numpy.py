"""The numpy 1-DOF integrator (vectorised over flights, one Python loop over steps): the ``numpy`` engine that
:mod:`firmware_model.flights.simulate.sim1dof` had before its integration was shared with the Monte Carlo
(:mod:`firmware_model.flights.simulate.pointmass`, issue 34), kept as an independent second implementation of the
same RK4 for the cross-check test (tests/flights/test_sim.py: the same bytes as the ``kernel`` and ``python``
engines) and as a baseline of bench/bench_sim1dof.py. Not used by any command.

It is written differently from the per-flight loop (whole-array ``np.where`` per step, the table lookups
vectorised, the RK4 stages spelled out), so a slip in one is unlikely to be repeated in the other; it shares only
the prepared batch (``sim1dof._prepare``: motor tables at half steps, drag rows, atmosphere tables) and the record
building (``sim1dof._records``). **A change to the 1-DOF physics must be made here too** (or this module retired
with its cross-check).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from firmware_model.flights.record import FlightRecord
from firmware_model.flights.simulate import sim1dof as s1
from firmware_model.flights.simulate.pointmass import MACH_STEP as _MACH_STEP
from firmware_model.flights.simulate.pointmass import TABLE_LO_M as _TABLE_LO_M
from firmware_model.flights.simulate.pointmass import TABLE_STEP_M as _TABLE_STEP_M
from firmware_model.runtime.errors import UserError

G0 = s1.G0


def simulate_numpy(rockets: Sequence[s1.Rocket] | s1.Rocket, launch: s1.Launch | Sequence[s1.Launch] = s1.Launch(),
                   names: Sequence[str] | None = None, provenance: dict | None = None) -> list[FlightRecord]:
    """:func:`sim1dof.simulate_1dof` with this integrator (all flights of the batch at once)."""
    rockets = [rockets] if isinstance(rockets, s1.Rocket) else list(rockets)
    launches = [launch] * len(rockets) if isinstance(launch, s1.Launch) else list(launch)
    b = s1._prepare(rockets, launches)
    return s1._records(rockets, launches, b, integrate_numpy(b), names, provenance)


def _lookup(tab, x):
    """Linear interpolation in a table on the uniform atmosphere grid (clamped at the ends)."""
    u = (x - _TABLE_LO_M) * (1.0 / _TABLE_STEP_M)
    i = np.minimum(np.maximum(u, 0.0), tab.shape[0] - 1.000001).astype(np.int64)
    fr = np.minimum(np.maximum(u - i, 0.0), 1.0)
    return tab[i] * (1.0 - fr) + tab[i + 1] * fr


def integrate_numpy(b: s1._Batch):
    """RK4 over all flights at once (numpy arrays over flights). Returns recorded (z, v, a) lists per flight and
    the per-flight event arrays."""
    nf = b.dry.size
    nj = b.thrust.shape[0]
    n_mach = b.cd_tab.shape[1] - 1
    rows = np.arange(nf)
    h = b.h

    def deriv(j, zz, v, apo, drogue, landed):
        if j < nj:
            tm, mm = b.thrust[j], b.mass[j]
        else:
            tm, mm = 0.0, b.dry
        alt = b.site + zz
        rho = _lookup(b.rho_tab, alt)
        c = _lookup(b.c_tab, alt)
        x = np.abs(v) / c * (1.0 / _MACH_STEP)
        i0 = np.minimum(x.astype(np.int64), n_mach - 1)
        fr = np.minimum(x - i0, 1.0)
        cd = b.cd_tab[rows, i0] * (1.0 - fr) + b.cd_tab[rows, i0 + 1] * fr
        drag = 0.5 * rho * v * np.abs(v) * (cd * b.area + drogue * b.cda_d)
        a = (tm - drag) / mm - G0
        held = ~apo & (zz <= 0.0) & (v <= 0.0) & (a < 0.0)   # on the pad: held until thrust exceeds weight
        return np.where(landed | held, 0.0, a)

    z = np.zeros(nf)
    v = np.zeros(nf)
    apo = np.zeros(nf, dtype=bool)
    landed = np.zeros(nf, dtype=bool)
    t_apo = np.full(nf, np.nan)
    z_apo = np.full(nf, np.nan)
    t_lift = np.full(nf, np.nan)
    t_land = np.full(nf, np.nan)
    vmax = np.zeros(nf)
    mach_max = np.zeros(nf)
    end_t = np.full(nf, np.inf)
    rec_z, rec_v, rec_a = [], [], []
    n = 0
    while True:
        t = n * h
        j = 2 * n
        drogue = (apo & (t >= t_apo + b.delay)).astype(np.float64)
        k1v = deriv(j, z, v, apo, drogue, landed)
        if n % b.m_per == 0:
            rec_z.append(z)
            rec_v.append(v)
            rec_a.append(k1v)
            if np.all(t >= end_t):
                break
        if n >= b.max_steps:
            raise UserError(f"1-DOF: flights not finished after {b.max_steps * h:g} s (apogee found: "
                            f"{int(apo.sum())} of {nf})")
        k1z = np.where(landed, 0.0, v)
        v2 = v + 0.5 * h * k1v
        k2v = deriv(j + 1, z + 0.5 * h * k1z, v2, apo, drogue, landed)
        k2z = np.where(landed, 0.0, v2)
        v3 = v + 0.5 * h * k2v
        k3v = deriv(j + 1, z + 0.5 * h * k2z, v3, apo, drogue, landed)
        k3z = np.where(landed, 0.0, v3)
        v4 = v + h * k3v
        k4v = deriv(j + 2, z + h * k3z, v4, apo, drogue, landed)
        k4z = np.where(landed, 0.0, v4)
        z_new = z + h / 6.0 * (k1z + 2.0 * k2z + 2.0 * k3z + k4z)
        v_new = v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        lift = np.isnan(t_lift) & (v_new > 0.0)
        t_lift[lift] = t + h
        cross = ~apo & (v > 0.0) & (v_new <= 0.0)
        if np.any(cross):
            frac = v[cross] / (v[cross] - v_new[cross])
            tau = frac * h
            acc = (v_new[cross] - v[cross]) / h
            t_apo[cross] = t + tau
            z_apo[cross] = z[cross] + v[cross] * tau + 0.5 * acc * tau * tau
            apo = apo | cross
            end_t[cross] = t_apo[cross] + b.descent[cross]
        below = z_new < 0.0
        sink = below & ~apo
        z_new = np.where(sink, 0.0, z_new)
        v_new = np.where(sink, np.maximum(v_new, 0.0), v_new)
        land = below & apo & ~landed
        if np.any(land):
            t_land[land] = t + h
            end_t[land] = np.minimum(end_t[land], t + h)
            landed = landed | land
        z_new = np.where(landed, 0.0, z_new)
        v_new = np.where(landed, 0.0, v_new)
        vmax = np.maximum(vmax, v_new)
        mach_max = np.maximum(mach_max, np.abs(v_new) / _lookup(b.c_tab, b.site + z_new))
        z, v = z_new, v_new
        n += 1
    Z, V, A = np.array(rec_z), np.array(rec_v), np.array(rec_a)
    out = []
    for i in range(nf):
        out.append((Z[:, i], V[:, i], A[:, i]))
    return out, t_apo, z_apo, t_lift, t_land, vmax, mach_max, end_t
