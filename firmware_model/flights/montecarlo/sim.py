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
:func:`_flight` (the step loop and the events) over :func:`_slopes` (the four RK4 stages: motor, atmosphere, on
the rail or off it), its parameters grouped: the grid (:class:`Grid`), the batch's tables (:class:`Tables`), the
flight's row of ``params`` (:data:`P_COLS`) and its output columns.
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


def _motor_at(tb, seg, tau, fs, dry, prop):
    """(thrust, mass, segment) at time ``tau`` of the base motor table (the flight's time / its time scale), thrust
    x ``fs``; the propellant left is proportional to the impulse still to come. ``seg`` only moves forward."""
    mt, mf, mcum = tb.mt, tb.mf, tb.mcum
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


def _rail_accel(p, cd_tab, rho, c, thrust, mass, cvx, cvz, rx, rz):
    """(ax, ay, az, axial specific force, Mach) on the rail: motion along the rail, held while thrust cannot lift
    the rocket; drag from the speed along it."""
    va = cvx * rx + cvz * rz
    spd = abs(va)
    cd = pm.cd_at(cd_tab, spd, c) * p[_CDS]
    drag = pm.drag_force(rho, va, spd, cd) * p[_AREA]   # ((0.5 rho va spd) cd) area: the rail's own order
    a_al = (thrust - drag) / mass - G0 * rz
    if a_al < 0.0 and va <= 0.0:
        a_al = 0.0                     # held on the rail until thrust exceeds weight
    return a_al * rx, 0.0, a_al * rz, a_al + G0 * rz, spd / c


def _free_accel(p, cd_tab, rho, c, thrust, mass, drogue, w, wcx, wcy, cvx, cvy, cvz):
    """(ax, ay, az, axial specific force, Mach) off the rail: thrust and drag along the velocity relative to the
    wind ``w`` (zero angle of attack), the drogue's drag area added once it is open."""
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
    cd = pm.cd_at(cd_tab, spd, c) * p[_CDS]
    drag = pm.drag_force(rho, spd, spd, cd * p[_AREA] + (p[_CDA_D] if drogue else 0.0))
    fmag = (thrust - drag) / mass      # specific force along the air-relative velocity
    return fmag * ux, fmag * uy, fmag * uz - G0, abs(fmag) if drogue else fmag, spd / c


def _wind_at(p, logz, z):
    """The horizontal wind speed at height ``z`` AGL: ``u10 (max(z, 2 m) / 10 m)^a`` (the log heights are
    tabulated per metre)."""
    wind = p[_WIND]
    if wind == 0.0:
        return 0.0
    iz = min(max(int(z), 0), logz.shape[0] - 1)
    return wind * math.exp(p[_WEXP] * logz[iz]) if p[_WEXP] != 0.0 else wind


def _slopes(k, y, t, h, tb, p, geo, on_rail, apo, drogue, seg):
    """The four RK4 slopes of the state ``y`` (x, y, z, vx, vy, vz) from time ``t`` into ``k`` (6, 4); returns the
    axial specific force and Mach of the first stage (what is recorded) and the motor segment."""
    rx, rz, wcx, wcy, sroot = geo
    f0 = 0.0
    m0 = 0.0
    for s in range(4):
        if s == 0:
            cz, cvx, cvy, cvz, ts_ = y[2], y[3], y[4], y[5], t   # (x, y: the forces do not depend on them)
        else:
            cz = pm.rk4_stage(y[2], h, k[2, s - 1], s)
            cvx = pm.rk4_stage(y[3], h, k[3, s - 1], s)
            cvy = pm.rk4_stage(y[4], h, k[4, s - 1], s)
            cvz = pm.rk4_stage(y[5], h, k[5, s - 1], s)
            ts_ = t + h if s == 3 else t + 0.5 * h
        thrust, mass, seg = _motor_at(tb, seg, ts_ / p[_TS], p[_FS], p[_DRY], p[_PROP])
        u = pm.table_coord(p[_TSCALE] * (p[_SITE] + cz))
        rho = p[_TSCALE] * pm.table_at(tb.rho_tab, u)
        c = pm.table_at(tb.c_tab, u) / sroot
        if on_rail:
            ax, ay, az, fax, mach = _rail_accel(p, tb.cd_tab, rho, c, thrust, mass, cvx, cvz, rx, rz)
        else:
            w = _wind_at(p, tb.logz, cz)
            ax, ay, az, fax, mach = _free_accel(p, tb.cd_tab, rho, c, thrust, mass, drogue, w, wcx, wcy,
                                                cvx, cvy, cvz)
            if (not apo) and cz <= 0.0 and cvz <= 0.0 and az < 0.0:
                ax, ay, az, fax = 0.0, 0.0, 0.0, G0    # on the ground before lift-off: held
        k[0, s] = cvx
        k[1, s] = cvy
        k[2, s] = cvz
        k[3, s] = ax
        k[4, s] = ay
        k[5, s] = az
        if s == 0:
            f0 = fax
            m0 = mach
    return f0, m0, seg


def _flight(grid, tb, p, out, ev):
    """One flight (scalar RK4) with the parameters ``p`` (:data:`P_COLS`). Writes the recorded columns ``out`` (z,
    vz, az, fax, mach) and ``ev`` (see :data:`EVENTS`)."""
    h, m_per, max_rec, max_steps = grid
    rx = math.sin(p[_INCL])
    rz = math.cos(p[_INCL])
    geo = (rx, rz, math.cos(p[_WDIR]), math.sin(p[_WDIR]), math.sqrt(p[_TSCALE]))
    y = np.zeros(6)                    # x, y, z, vx, vy, vz
    yn = np.empty(6)
    k = np.empty((6, 4))
    on_rail, apo, landed, finished = True, False, False, False
    t_apo = z_apo = t_lift = t_rail = np.nan
    max_mach = 0.0
    max_speed = 0.0
    end_t = np.inf
    seg = 0
    n_rec = 0
    n = 0
    while True:
        t = n * h
        if landed:
            k[:, :] = 0.0
            f0, m0 = G0, 0.0
        else:
            drogue = apo and t >= t_apo + p[_DELAY]
            f0, m0, seg = _slopes(k, y, t, h, tb, p, geo, on_rail, apo, drogue, seg)
        if n % m_per == 0:
            out[0][n_rec] = y[2]
            out[1][n_rec] = y[5]
            out[2][n_rec] = k[5, 0]
            out[3][n_rec] = f0
            out[4][n_rec] = m0
            n_rec += 1
            if t >= end_t:
                finished = True
                break
        if n >= max_steps or n_rec >= max_rec:
            break
        for i in range(6):
            yn[i] = pm.rk4_step(y[i], h, k[i])
        if np.isnan(t_lift) and (yn[3] * rx + yn[5] * rz) > 0.0:
            t_lift = t + h
        if on_rail and (yn[0] * rx + yn[2] * rz) >= p[_RAIL]:
            on_rail = False
            t_rail = t + h
        if (not apo) and (not np.isnan(t_lift)) and y[5] > 0.0 and yn[5] <= 0.0:
            t_apo, z_apo = pm.apogee_in_step(t, h, y[2], y[5], yn[5])
            apo = True
            end_t = t_apo + p[_DESCENT]
        if yn[2] < 0.0 and apo and not landed:
            landed = True
            end_t = min(end_t, t + h)
        if yn[2] < 0.0 and not apo:
            yn[2] = 0.0
            yn[5] = max(yn[5], 0.0)
        if landed:
            yn[2] = yn[3] = yn[4] = yn[5] = 0.0
        max_speed = max(max_speed, math.sqrt(yn[3] * yn[3] + yn[4] * yn[4] + yn[5] * yn[5]))
        max_mach = max(max_mach, m0)
        y[:] = yn
        n += 1
    ev[0] = n_rec if finished else -n_rec
    ev[1] = t_apo
    ev[2] = z_apo
    ev[3] = t_lift
    ev[4] = max_mach
    ev[5] = t_rail
    ev[6] = max_speed


def _batch(grid, tb, p, outs, ev):
    """Every flight of the batch; ``p`` (nf, len(P_COLS)) holds the per-flight parameters, ``outs`` the recorded
    columns (z, vz, az, fax, mach), each (nf, max_rec)."""
    for i in _prange(p.shape[0]):
        _flight(grid, tb, p[i], (outs[0][i], outs[1][i], outs[2][i], outs[3][i], outs[4][i]), ev[i])


#: The loop over flights: numba.prange once the kernel is compiled (a parallel loop), else range.
_prange = range
_KERNELS: list = []


def _batch_kernel():
    """The batch kernel, compiled on first use when numba is importable (a lazy load of a heavy optional
    dependency: importing this module stays cheap for the CLI); else the same source in Python."""
    global _prange
    if not _KERNELS:
        if pm.register_for_numba(_motor_at, _rail_accel, _free_accel, _wind_at, _slopes, _flight):
            import numba  # lazy: heavy, optional

            _prange = numba.prange
            _KERNELS.append(numba.njit(cache=True, nogil=True, parallel=True)(_batch))
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
