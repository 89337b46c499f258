"""A batched 3-DOF point-mass simulator for dispersed flights: wind, rail inclination, non-standard temperature.

The 1-DOF model of :mod:`firmware_model.flights.simulate.sim1dof` is vertical; a Monte Carlo over wind and rail
angle needs the flight path to bend. This is the same point mass (thrust table, propellant mass proportional to the
impulse still to come, Mach-dependent drag times a scale, constant g0, RK4 with a fixed step), in three dimensions,
integrated with the RK4 step, tables and drag of :mod:`firmware_model.flights.simulate.pointmass` (shared with
sim1dof):

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

The kernel is compiled with numba (``prange`` over flights) on first use when numba is importable; every flight is
integrated alone with the same arithmetic, so a flight's bytes do not depend on its batch. One flight is
:func:`_flight` (the four RK4 stages, the step and its events) over :func:`_motor_at`, :func:`_rail_accel`,
:func:`_free_accel` and :func:`_wind_at`, its parameters grouped: the grid (:class:`Grid`), the
batch's tables (:class:`Tables`), the flight's row of ``params`` (:data:`P_COLS`) and its output columns.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from firmware_model.flights.simulate import pointmass as pm
from firmware_model.spec import atmosphere as atm

G0 = atm.G0
T0_K = 288.15
#: Columns of the per-flight events array.
EVENTS = ("n_rec", "t_apo", "z_apo", "t_lift", "max_mach", "t_rail", "max_speed")
#: Per-flight parameter columns of :func:`simulate_batch`'s ``params``.
P_COLS = ("dry_kg", "prop_kg", "time_scale", "thrust_scale", "cd_scale", "area_m2", "drogue_cda_m2", "site_m",
          "tscale", "wind_mps", "wind_dir_rad", "wind_exp", "incl_rad", "rail_m", "drogue_delay_s", "descent_s")
(_DRY, _PROP, _TS, _FS, _CDS, _AREA, _CDA_D, _SITE, _TSCALE, _WIND, _WDIR, _WEXP, _INCL, _RAIL, _DELAY,
 _DESCENT) = range(len(P_COLS))


@lru_cache(maxsize=1)
def atmosphere_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(log-height table for the wind law, density, speed of sound) of the standard atmosphere on a 1 m grid
    (the last two: :func:`.pointmass.atmosphere_tables`)."""
    return (np.log(np.maximum(np.arange(0.0, 40_001.0), 2.0) / 10.0),) + pm.atmosphere_tables()


drag_table = pm.drag_table


class Grid(NamedTuple):
    """The integration grid: step ``h``, steps per record period, record and step limits."""

    h: float
    m_per: int
    max_rec: int
    max_steps: int


class Tables(NamedTuple):
    """The batch's tables: the base motor (time, thrust, impulse so far), the drag row (:func:`drag_table`, before
    the flight's ``cd_scale``), the wind law's log heights and the atmosphere (:func:`atmosphere_tables`)."""

    mt: np.ndarray
    mf: np.ndarray
    mcum: np.ndarray
    cd_tab: np.ndarray
    logz: np.ndarray
    rho_tab: np.ndarray
    c_tab: np.ndarray


def _motor_at(mt, mf, mcum, seg, tau, fs, dry, prop):
    """(thrust, mass, segment) at time ``tau`` of the base motor table (the flight's time / its time scale), thrust
    x ``fs``; the propellant left is proportional to the impulse still to come. ``seg`` only moves forward."""
    nk = mt.shape[0]
    if tau >= mt[nk - 1]:
        return 0.0, dry, seg
    while seg < nk - 2 and tau >= mt[seg + 1]:
        seg += 1
    d = tau - mt[seg]
    slope = (mf[seg + 1] - mf[seg]) / (mt[seg + 1] - mt[seg])
    thrust = fs * (mf[seg] + slope * d)
    imp = mcum[seg] + mf[seg] * d + 0.5 * slope * d * d
    return thrust, dry + prop * (1.0 - imp / mcum[nk - 1]), seg


def _rail_accel(cd_tab, cd_scale, area, rho, c, thrust, mass, cvx, cvz, rx, rz):
    """(ax, ay, az, axial specific force, Mach) on the rail: motion along the rail, held while thrust cannot lift
    the rocket; drag from the speed along it."""
    va = cvx * rx + cvz * rz
    spd = abs(va)
    cd = pm.cd_at(cd_tab, spd, c) * cd_scale
    drag = pm.drag_force(rho, va, spd, cd) * area   # ((0.5 rho va spd) cd) area: the rail's own order
    a_al = (thrust - drag) / mass - G0 * rz
    if a_al < 0.0 and va <= 0.0:
        a_al = 0.0                     # held on the rail until thrust exceeds weight
    return a_al * rx, 0.0, a_al * rz, a_al + G0 * rz, spd / c


def _free_accel(cd_tab, cd_scale, area, cda_d, drogue, rho, c, thrust, mass, ux, uy, uz):
    """(ax, ay, az, axial specific force, Mach) off the rail: thrust and drag along the air-relative velocity ``u``
    (zero angle of attack), the drogue's drag area ``cda_d`` added once it is open; the accelerometer reads the
    magnitude of the specific force once the drogue pulls."""
    spd = math.sqrt(ux * ux + uy * uy + uz * uz)
    if spd > 1e-9:
        ux /= spd
        uy /= spd
        uz /= spd
    else:
        ux = 0.0
        uy = 0.0
        uz = 1.0
    cd = pm.cd_at(cd_tab, spd, c) * cd_scale
    fmag = (thrust - pm.drag_force(rho, spd, spd, cd * area + (cda_d if drogue else 0.0))) / mass   # along u
    return fmag * ux, fmag * uy, fmag * uz - G0, abs(fmag) if drogue else fmag, spd / c


def _wind_at(wind, wexp, logz, z):
    """The horizontal wind speed at height ``z`` AGL: ``u10 (max(z, 2 m) / 10 m)^a`` (log heights per metre)."""
    if wind == 0.0:
        return 0.0
    iz = min(max(int(z), 0), logz.shape[0] - 1)
    return wind * math.exp(wexp * logz[iz]) if wexp != 0.0 else wind


def _flight(grid, tb, p, out, ev):
    """One flight (scalar RK4) with the parameters ``p`` (a row of :data:`P_COLS`). Writes the recorded columns
    ``out`` (z, vz, az, fax, mach) and ``ev`` (see :data:`EVENTS`)."""
    h, m_per, max_rec, max_steps = grid
    mt, mf, mcum, cd_tab, logz, rho_tab, c_tab = tb
    z_out, vz_out, az_out, fax_out, mach_out = out
    dry, prop, ts, fs, cd_scale, area, cda_d = p[_DRY], p[_PROP], p[_TS], p[_FS], p[_CDS], p[_AREA], p[_CDA_D]
    site, tscale, wind, wexp = p[_SITE], p[_TSCALE], p[_WIND], p[_WEXP]
    sroot = math.sqrt(tscale)
    rx, rz = math.sin(p[_INCL]), math.cos(p[_INCL])
    wcx, wcy = math.cos(p[_WDIR]), math.sin(p[_WDIR])
    x = y = z = vx = vy = vz = 0.0
    on_rail, apo, landed, finished = True, False, False, False
    t_apo = z_apo = t_lift = t_rail = np.nan
    max_mach = max_speed = 0.0
    end_t = np.inf
    seg = n_rec = n = 0
    kx, ky, kz, kvx, kvy, kvz = np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4)
    while True:
        t = n * h
        drogue = apo and t >= t_apo + p[_DELAY]
        f0 = m0 = 0.0
        for s in range(4):
            if landed:
                kx[s] = ky[s] = kz[s] = kvx[s] = kvy[s] = kvz[s] = 0.0
                continue
            if s == 0:
                cz, cvx, cvy, cvz, ts_ = z, vx, vy, vz, t   # (x, y: the forces do not depend on them)
            else:
                cz = pm.rk4_stage(z, h, kz[s - 1], s)
                cvx = pm.rk4_stage(vx, h, kvx[s - 1], s)
                cvy = pm.rk4_stage(vy, h, kvy[s - 1], s)
                cvz = pm.rk4_stage(vz, h, kvz[s - 1], s)
                ts_ = t + h if s == 3 else t + 0.5 * h
            thrust, mass, seg = _motor_at(mt, mf, mcum, seg, ts_ / ts, fs, dry, prop)
            u = pm.table_coord(tscale * (site + cz))
            rho = tscale * pm.table_at(rho_tab, u)
            c = pm.table_at(c_tab, u) / sroot
            if on_rail:
                ax, ay, az, fax, mach = _rail_accel(cd_tab, cd_scale, area, rho, c, thrust, mass, cvx, cvz, rx, rz)
            else:
                w = _wind_at(wind, wexp, logz, cz)
                ax, ay, az, fax, mach = _free_accel(cd_tab, cd_scale, area, cda_d, drogue, rho, c, thrust, mass,
                                                    cvx - w * wcx, cvy - w * wcy, cvz)
                if (not apo) and cz <= 0.0 and cvz <= 0.0 and az < 0.0:
                    ax, ay, az, fax = 0.0, 0.0, 0.0, G0    # on the ground before lift-off: held
            kx[s], ky[s], kz[s], kvx[s], kvy[s], kvz[s] = cvx, cvy, cvz, ax, ay, az
            if s == 0:
                f0, m0 = fax, mach
        if landed:
            f0, m0 = G0, 0.0
        if n % m_per == 0:
            z_out[n_rec], vz_out[n_rec], az_out[n_rec], fax_out[n_rec], mach_out[n_rec] = z, vz, kvz[0], f0, m0
            n_rec += 1
            if t >= end_t:
                finished = True
                break
        if n >= max_steps or n_rec >= max_rec:
            break
        xn, yn, zn = pm.rk4_step(x, h, kx), pm.rk4_step(y, h, ky), pm.rk4_step(z, h, kz)
        vxn, vyn, vzn = pm.rk4_step(vx, h, kvx), pm.rk4_step(vy, h, kvy), pm.rk4_step(vz, h, kvz)
        if np.isnan(t_lift) and (vxn * rx + vzn * rz) > 0.0:
            t_lift = t + h
        if on_rail and (xn * rx + zn * rz) >= p[_RAIL]:
            on_rail = False
            t_rail = t + h
        if (not apo) and (not np.isnan(t_lift)) and vz > 0.0 and vzn <= 0.0:
            t_apo, z_apo = pm.apogee_in_step(t, h, z, vz, vzn)
            apo = True
            end_t = t_apo + p[_DESCENT]
        if zn < 0.0 and apo and not landed:
            landed = True
            end_t = min(end_t, t + h)
        if zn < 0.0 and not apo:
            zn = 0.0
            vzn = max(vzn, 0.0)
        if landed:
            zn = vxn = vyn = vzn = 0.0
        max_speed = max(max_speed, math.sqrt(vxn * vxn + vyn * vyn + vzn * vzn))
        max_mach = max(max_mach, m0)
        x, y, z, vx, vy, vz = xn, yn, zn, vxn, vyn, vzn
        n += 1
    ev[0] = n_rec if finished else -n_rec
    ev[1], ev[2], ev[3], ev[4], ev[5], ev[6] = t_apo, z_apo, t_lift, max_mach, t_rail, max_speed


def _batch(grid, tb, p, outs, ev):
    """Every flight of the batch; ``p`` (nf, len(P_COLS)) holds the per-flight parameters, ``outs`` the recorded
    columns (z, vz, az, fax, mach), each (nf, max_rec)."""
    for i in _prange(p.shape[0]):
        _flight_k(grid, tb, p[i], (outs[0][i], outs[1][i], outs[2][i], outs[3][i], outs[4][i]), ev[i])


#: The loop over flights and the flight :func:`_batch` runs: numba.prange and :func:`_flight` compiled on its own
#: once the kernel is compiled (as a call, not inlined into the parallel loop: inlining it there costs tens of
#: seconds of compile time), else range and :func:`_flight`.
_prange = range
_flight_k = _flight
_KERNELS: list = []


def _batch_kernel():
    """The batch kernel, compiled on first use when numba is importable (a lazy load of a heavy optional
    dependency: importing this module stays cheap for the CLI); else the same source in Python."""
    global _prange, _flight_k
    if not _KERNELS:
        if pm.register_for_numba(_motor_at, _rail_accel, _free_accel, _wind_at):
            import numba  # lazy: heavy, optional

            _prange = numba.prange
            _flight_k = pm.njit_cached(_flight, nogil=True)
            _KERNELS.append(pm.njit_cached(_batch, nogil=True, parallel=True))
        else:  # pragma: no cover - exercised where numba is absent
            _KERNELS.append(_batch)
    return _KERNELS[0]


def simulate_batch(params: np.ndarray, motor_t: np.ndarray, motor_f: np.ndarray, cd_tab: np.ndarray,
                   record_hz: float, internal_hz: float, max_time_s: float) -> dict[str, np.ndarray]:
    """Integrate every flight of ``params`` ((nf, len(P_COLS)) float64) with the base motor table ``motor_t``,
    ``motor_f`` (time scaled by ``time_scale``, thrust by ``thrust_scale`` per flight). Returns the recorded
    columns (nf, max_rec) ``z``, ``vz``, ``az``, ``fax``, ``mach`` and ``events`` (nf, len(EVENTS));
    ``events[:, 0]`` is the number of recorded samples, negative when the flight did not end within
    ``max_time_s``."""
    m_per, h = pm.step_size(record_hz, internal_hz)
    max_rec = int(math.ceil(max_time_s * record_hz)) + 2
    max_steps = max_rec * m_per
    nf = params.shape[0]
    cols = {name: np.zeros((nf, max_rec)) for name in ("z", "vz", "az", "fax", "mach")}
    ev = np.zeros((nf, len(EVENTS)))
    mt = np.ascontiguousarray(motor_t, dtype=np.float64)
    mf = np.ascontiguousarray(motor_f, dtype=np.float64)
    mcum = np.concatenate([[0.0], np.cumsum(0.5 * (mf[1:] + mf[:-1]) * np.diff(mt))])
    logz, rho_tab, c_tab = atmosphere_tables()
    tables = Tables(mt, mf, mcum, np.ascontiguousarray(cd_tab, dtype=np.float64), logz, rho_tab, c_tab)
    _batch_kernel()(Grid(h, m_per, max_rec, max_steps), tables, np.ascontiguousarray(params, dtype=np.float64),
                    (cols["z"], cols["vz"], cols["az"], cols["fax"], cols["mach"]), ev)
    cols["events"] = ev
    return cols


__all__ = ["EVENTS", "P_COLS", "atmosphere_tables", "drag_table", "simulate_batch"]
