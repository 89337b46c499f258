"""A batched 3-DOF point-mass simulator for dispersed flights: wind, rail inclination, non-standard temperature.

The 1-DOF model of :mod:`firmware_model.flights.simulate.sim1dof` is vertical; a Monte Carlo over wind and rail angle needs
the flight path to bend. This is the same point mass (thrust table, propellant mass proportional to the impulse
still to come, Mach-dependent drag times a scale, constant g0, RK4 with a fixed step), in three dimensions:

* on the rail (until the rocket has moved ``rail_length_m`` along it) the motion is along the rail direction
  ``r`` (``rail_inclination_deg`` from vertical), held while thrust cannot lift it, drag from the speed along it;
* off the rail the rocket flies at zero angle of attack (weathercocked): thrust and drag act along the air-relative
  velocity ``v - w(z)``, with the horizontal wind ``w(z) = u10 (max(z, 2 m) / 10 m)^a`` blowing towards
  ``wind_direction_deg`` from the rail's heading;
* the drogue (drag area ``drogue_cd_area_m2``) opens ``drogue_delay_s`` after the true apogee (vertical speed
  through zero, interpolated in the step as in sim1dof); the record ends ``descent_s`` later or at landing.

The atmosphere is the standard one shifted by ``temperature_offset_k`` at every height with the standard
sea-level pressure: in the troposphere this is exactly the standard atmosphere at the scaled height ``s h``,
``s = T0 / (T0 + dT)`` (pressure ``p_std(s h)``, density ``s rho_std(s h)``, speed of sound ``c_std(s h) /
sqrt(s)``); above 11 km it is the same formula (the stratosphere's offset becomes ``dT x 216.65/288.15``),
stated as an approximation.

Recorded per flight on the firmware's grid (every ``m_per`` steps, ``h = 2^-k / m_per``): altitude AGL ``z``,
vertical velocity and acceleration (truth), the **axial specific force** (what an accelerometer on the rocket's
axis reads: along the rail on it, along the air-relative velocity off it, the magnitude of the specific force
once the drogue pulls) and the airspeed Mach number (for the transonic pressure error). With no wind and a
vertical rail this is sim1dof's flight (cross-checked in tests/flights/test_montecarlo.py).

The kernel is compiled with numba (``prange`` over flights) on first use when numba is importable; every flight is integrated
alone with the same arithmetic, so a flight's bytes do not depend on its batch.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from firmware_model.spec import atmosphere as atm

G0 = atm.G0
T0_K = 288.15
_TAB_LO_M, _TAB_HI_M, _TAB_STEP_M = -1000.0, 40_000.0, 1.0
_MACH_STEP, _MACH_MAX = 0.01, 4.0
#: Columns of the per-flight events array.
EVENTS = ("n_rec", "t_apo", "z_apo", "t_lift", "max_mach", "t_rail", "max_speed")


@lru_cache(maxsize=1)
def atmosphere_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(log-height table for the wind law, density, speed of sound) of the standard atmosphere on a 1 m grid."""
    h = np.arange(_TAB_LO_M, _TAB_HI_M + _TAB_STEP_M / 2, _TAB_STEP_M)
    return np.log(np.maximum(np.arange(0.0, 40_001.0), 2.0) / 10.0), atm.density_kg_m3(h), atm.speed_of_sound_mps(h)


def drag_table(mach: np.ndarray, cd: np.ndarray) -> np.ndarray:
    """Cd on the uniform Mach grid 0..4 step 0.01 (+1 guard), held constant outside the given table."""
    grid = np.arange(0.0, _MACH_MAX + _MACH_STEP / 2, _MACH_STEP)
    out = np.empty(grid.size + 1)
    out[:-1] = np.interp(grid, mach, cd)
    out[-1] = out[-2]
    return out


def _lookup(tab, u):
    n = tab.shape[0]
    uc = min(max(u, 0.0), n - 1.000001)
    i = int(uc)
    f = min(max(u - i, 0.0), 1.0)
    return tab[i] * (1.0 - f) + tab[i + 1] * f


def _flight(h, m_per, max_rec, max_steps, mt, mf, mcum, cd_tab, logz, rho_tab, c_tab,  # noqa: C901 - one numba-compiled RK4 loop: motor, drag, wind, rail, recovery events inline for speed
            dry, prop, ts, fs, cd_scale, area, cda_d, site, tscale, wind, wdir, wexp, incl, rail, delay, descent,
            z_out, vz_out, az_out, fax_out, mach_out, ev):
    """One flight (scalar RK4). Writes the recorded columns and ``ev`` (see :data:`EVENTS`)."""
    nk = mt.shape[0]
    n_mach = cd_tab.shape[0] - 1
    burn = mt[nk - 1]
    itot = mcum[nk - 1]
    sroot = math.sqrt(tscale)
    rx = math.sin(incl)
    rz = math.cos(incl)
    wcx = math.cos(wdir)
    wcy = math.sin(wdir)
    x = 0.0
    y = 0.0
    z = 0.0
    vx = 0.0
    vy = 0.0
    vz = 0.0
    on_rail = True
    apo = False
    landed = False
    t_apo = np.nan
    z_apo = np.nan
    t_lift = np.nan
    t_rail = np.nan
    max_mach = 0.0
    max_speed = 0.0
    end_t = np.inf
    seg = 0
    kx = np.empty(4)
    ky = np.empty(4)
    kz = np.empty(4)
    kvx = np.empty(4)
    kvy = np.empty(4)
    kvz = np.empty(4)
    n_rec = 0
    n = 0
    finished = False
    while True:
        t = n * h
        drogue = apo and t >= t_apo + delay
        f0 = 0.0
        m0 = 0.0
        for s in range(4):
            if s == 0:
                cz, cvx, cvy, cvz, ts_ = z, vx, vy, vz, t   # (x, y: the forces do not depend on them)
            elif s == 1 or s == 2:
                cz = z + 0.5 * h * kz[s - 1]
                cvx = vx + 0.5 * h * kvx[s - 1]
                cvy = vy + 0.5 * h * kvy[s - 1]
                cvz = vz + 0.5 * h * kvz[s - 1]
                ts_ = t + 0.5 * h
            else:
                cz = z + h * kz[2]
                cvx = vx + h * kvx[2]
                cvy = vy + h * kvy[2]
                cvz = vz + h * kvz[2]
                ts_ = t + h
            if landed:
                kx[s] = ky[s] = kz[s] = kvx[s] = kvy[s] = kvz[s] = 0.0
                continue
            # motor: the base table at time t/ts, thrust x fs; propellant left ~ impulse still to come
            tau = ts_ / ts
            if tau >= burn:
                thrust = 0.0
                mass = dry
            else:
                while seg < nk - 2 and tau >= mt[seg + 1]:
                    seg += 1
                d = tau - mt[seg]
                slope = (mf[seg + 1] - mf[seg]) / (mt[seg + 1] - mt[seg])
                thrust = fs * (mf[seg] + slope * d)
                imp = mcum[seg] + mf[seg] * d + 0.5 * slope * d * d
                mass = dry + prop * (1.0 - imp / itot)
            u = (tscale * (site + cz) - _TAB_LO_M) * (1.0 / _TAB_STEP_M)
            rho = tscale * _lookup(rho_tab, u)
            c = _lookup(c_tab, u) / sroot
            if on_rail:
                va = cvx * rx + cvz * rz
                spd = abs(va)
                xm = spd / c * (1.0 / _MACH_STEP)
                i0 = min(int(xm), n_mach - 1)
                fr = min(xm - i0, 1.0)
                cd = (cd_tab[i0] * (1.0 - fr) + cd_tab[i0 + 1] * fr) * cd_scale
                drag = 0.5 * rho * va * spd * cd * area
                a_al = (thrust - drag) / mass - G0 * rz
                if a_al < 0.0 and va <= 0.0:
                    a_al = 0.0                     # held on the rail until thrust exceeds weight
                ax = a_al * rx
                ay = 0.0
                az = a_al * rz
                fax = a_al + G0 * rz
                mach = spd / c
            else:
                w = 0.0
                if wind != 0.0:
                    iz = min(max(int(cz), 0), logz.shape[0] - 1)
                    w = wind * math.exp(wexp * logz[iz]) if wexp != 0.0 else wind
                ux = cvx - w * wcx
                uy = cvy - w * wcy
                uz = cvz
                spd = math.sqrt(ux * ux + uy * uy + uz * uz)
                if spd > 1e-9:
                    ux /= spd
                    uy /= spd
                    uz /= spd
                else:
                    ux = 0.0
                    uy = 0.0
                    uz = 1.0
                xm = spd / c * (1.0 / _MACH_STEP)
                i0 = min(int(xm), n_mach - 1)
                fr = min(xm - i0, 1.0)
                cd = (cd_tab[i0] * (1.0 - fr) + cd_tab[i0 + 1] * fr) * cd_scale
                drag = 0.5 * rho * spd * spd * (cd * area + (cda_d if drogue else 0.0))
                fmag = (thrust - drag) / mass      # specific force along the air-relative velocity
                ax = fmag * ux
                ay = fmag * uy
                az = fmag * uz - G0
                fax = abs(fmag) if drogue else fmag
                mach = spd / c
                if (not apo) and cz <= 0.0 and cvz <= 0.0 and az < 0.0:
                    ax = 0.0                       # on the ground before lift-off: held
                    ay = 0.0
                    az = 0.0
                    fax = G0
            kx[s] = cvx
            ky[s] = cvy
            kz[s] = cvz
            kvx[s] = ax
            kvy[s] = ay
            kvz[s] = az
            if s == 0:
                f0 = fax
                m0 = mach
        if landed:
            f0 = G0
            m0 = 0.0
        if n % m_per == 0:
            z_out[n_rec] = z
            vz_out[n_rec] = vz
            az_out[n_rec] = kvz[0]
            fax_out[n_rec] = f0
            mach_out[n_rec] = m0
            n_rec += 1
            if t >= end_t:
                finished = True
                break
        if n >= max_steps or n_rec >= max_rec:
            break
        xn = x + h / 6.0 * (kx[0] + 2.0 * kx[1] + 2.0 * kx[2] + kx[3])
        yn = y + h / 6.0 * (ky[0] + 2.0 * ky[1] + 2.0 * ky[2] + ky[3])
        zn = z + h / 6.0 * (kz[0] + 2.0 * kz[1] + 2.0 * kz[2] + kz[3])
        vxn = vx + h / 6.0 * (kvx[0] + 2.0 * kvx[1] + 2.0 * kvx[2] + kvx[3])
        vyn = vy + h / 6.0 * (kvy[0] + 2.0 * kvy[1] + 2.0 * kvy[2] + kvy[3])
        vzn = vz + h / 6.0 * (kvz[0] + 2.0 * kvz[1] + 2.0 * kvz[2] + kvz[3])
        if np.isnan(t_lift) and (vxn * rx + vzn * rz) > 0.0:
            t_lift = t + h
        if on_rail and (xn * rx + zn * rz) >= rail:
            on_rail = False
            t_rail = t + h
        if (not apo) and (not np.isnan(t_lift)) and vz > 0.0 and vzn <= 0.0:
            tau_ = vz / (vz - vzn) * h
            acc = (vzn - vz) / h
            t_apo = t + tau_
            z_apo = z + vz * tau_ + 0.5 * acc * tau_ * tau_
            apo = True
            end_t = t_apo + descent
        if zn < 0.0 and apo and not landed:
            landed = True
            end_t = min(end_t, t + h)
        if zn < 0.0 and not apo:
            zn = 0.0
            vzn = max(vzn, 0.0)
        if landed:
            zn = 0.0
            vxn = vyn = vzn = 0.0
        spd = math.sqrt(vxn * vxn + vyn * vyn + vzn * vzn)
        max_speed = max(max_speed, spd)
        max_mach = max(max_mach, m0)
        x, y, z, vx, vy, vz = xn, yn, zn, vxn, vyn, vzn
        n += 1
    ev[0] = n_rec if finished else -n_rec
    ev[1] = t_apo
    ev[2] = z_apo
    ev[3] = t_lift
    ev[4] = max_mach
    ev[5] = t_rail
    ev[6] = max_speed


def _batch(h, m_per, max_rec, max_steps, mt, mf, mcum, cd_tab, logz, rho_tab, c_tab, p, z_out, vz_out, az_out,
           fax_out, mach_out, ev):
    """Every flight of the batch; ``p`` (nf, 16) holds the per-flight parameters (:data:`P_COLS`)."""
    for i in _prange(p.shape[0]):
        _flight_k(h, m_per, max_rec, max_steps, mt, mf, mcum, cd_tab, logz, rho_tab, c_tab,
                  p[i, 0], p[i, 1], p[i, 2], p[i, 3], p[i, 4], p[i, 5], p[i, 6], p[i, 7], p[i, 8], p[i, 9],
                  p[i, 10], p[i, 11], p[i, 12], p[i, 13], p[i, 14], p[i, 15],
                  z_out[i], vz_out[i], az_out[i], fax_out[i], mach_out[i], ev[i])


#: Per-flight parameter columns of :func:`simulate_batch`'s ``params``.
P_COLS = ("dry_kg", "prop_kg", "time_scale", "thrust_scale", "cd_scale", "area_m2", "drogue_cda_m2", "site_m",
          "tscale", "wind_mps", "wind_dir_rad", "wind_exp", "incl_rad", "rail_m", "drogue_delay_s", "descent_s")

_KERNELS: list = []


def _batch_kernel():
    """The batch kernel, compiled on first use when numba is importable (a lazy load of a heavy optional
    dependency: importing this module stays cheap for the CLI); else the same source in Python."""
    global _lookup, _flight_k, _prange
    if not _KERNELS:
        try:
            import numba
        except ImportError:  # pragma: no cover - exercised where numba is absent
            _flight_k, _prange = _flight, range
            _KERNELS.append(_batch)
        else:
            _lookup = numba.njit(cache=True, nogil=True, inline="always")(_lookup)
            _flight_k = numba.njit(cache=True, nogil=True)(_flight)
            _prange = numba.prange
            _KERNELS.append(numba.njit(cache=True, nogil=True, parallel=True)(_batch))
    return _KERNELS[0]


_flight_k = _flight
_prange = range


def simulate_batch(params: np.ndarray, motor_t: np.ndarray, motor_f: np.ndarray, cd_tab: np.ndarray,
                   record_hz: float, internal_hz: float, max_time_s: float) -> dict[str, np.ndarray]:
    """Integrate every flight of ``params`` ((nf, len(P_COLS)) float64) with the base motor table ``motor_t``,
    ``motor_f`` (time scaled by ``time_scale``, thrust by ``thrust_scale`` per flight). Returns the recorded
    columns (nf, max_rec) ``z``, ``vz``, ``az``, ``fax``, ``mach`` and ``events`` (nf, len(EVENTS));
    ``events[:, 0]`` is the number of recorded samples, negative when the flight did not end within
    ``max_time_s``."""
    m_per = max(1, int(math.ceil(internal_hz / record_hz - 1e-9)))
    h = 1.0 / (record_hz * m_per)
    max_rec = int(math.ceil(max_time_s * record_hz)) + 2
    max_steps = max_rec * m_per
    nf = params.shape[0]
    cols = {name: np.zeros((nf, max_rec)) for name in ("z", "vz", "az", "fax", "mach")}
    ev = np.zeros((nf, len(EVENTS)))
    mt = np.ascontiguousarray(motor_t, dtype=np.float64)
    mf = np.ascontiguousarray(motor_f, dtype=np.float64)
    mcum = np.concatenate([[0.0], np.cumsum(0.5 * (mf[1:] + mf[:-1]) * np.diff(mt))])
    logz, rho_tab, c_tab = atmosphere_tables()
    _batch_kernel()(h, m_per, max_rec, max_steps, mt, mf, mcum, np.ascontiguousarray(cd_tab, dtype=np.float64), logz,
             rho_tab, c_tab, np.ascontiguousarray(params, dtype=np.float64), cols["z"], cols["vz"], cols["az"],
             cols["fax"], cols["mach"], ev)
    cols["events"] = ev
    return cols


__all__ = ["EVENTS", "P_COLS", "atmosphere_tables", "drag_table", "simulate_batch"]
